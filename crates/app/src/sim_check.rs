//! "Check against simulation" in the Cost panel: compares the current run's trained network
//! with the reference simulator ([`neural_cloth_train::compare`]) on a background thread with
//! progress and cancel, and tabulates the result.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use neural_cloth_train::compare::{CompareOptions, CompareProgress, CompareReport, compare};
use neural_cloth_train::load_trained;

use super::background::{BackgroundJob, poll_job};
use super::error::AppError;

/// State of the "Check against simulation" action.
pub struct SimCheck {
    /// L-BFGS iterations per frame of the reference, 1..=10000; default 200.
    pub iterations: usize,
    /// Compare only the motion shown in the viewport (otherwise the validation motions);
    /// default false.
    pub shown_motion_only: bool,
    job: Option<BackgroundJob<Option<CompareProgress>, CompareReport>>,
    /// The last result, or the error that ended the last check.
    pub result: Option<Result<CompareReport, AppError>>,
}

impl Default for SimCheck {
    fn default() -> Self {
        Self {
            iterations: 200,
            shown_motion_only: false,
            job: None,
            result: None,
        }
    }
}

/// Why the check cannot run on `run_dir` (`None`: it can): no run yet, or no checkpoint in it.
pub fn unavailable_reason(run_dir: Option<&Path>) -> Option<String> {
    let Some(dir) = run_dir else {
        return Some("No trained run yet: train a model first (Training panel).".into());
    };
    if !dir.join("run.json").is_file() || !dir.join("latest.json").is_file() {
        return Some(format!(
            "The run has no checkpoint yet; one is written as training goes on: {}",
            dir.display()
        ));
    }
    None
}

impl SimCheck {
    /// True while a comparison runs.
    pub fn is_running(&self) -> bool {
        self.job.is_some()
    }

    /// Starts comparing the newest checkpoint of the run at `run_dir` on the thread
    /// `neural-cloth-compare` (on `motion`, or the validation motions when `None`); `notify`
    /// requests a repaint when progress moves.
    pub fn start(
        &mut self,
        run_dir: PathBuf,
        motion: Option<String>,
        notify: Arc<dyn Fn() + Send + Sync>,
    ) -> Result<(), AppError> {
        if self.job.is_some() {
            return Err(AppError::AlreadyRunning("a check"));
        }
        let options = CompareOptions {
            iterations: self.iterations.clamp(1, 10_000),
            ..Default::default()
        };
        self.job = Some(BackgroundJob::spawn(
            "neural-cloth-compare",
            None,
            notify,
            move |reporter| {
                let trained = load_trained(&run_dir)?;
                let mut report = |now: CompareProgress| reporter.report(Some(now));
                Ok(compare(&trained, motion.as_deref(), &options, &mut report)?)
            },
        )?);
        Ok(())
    }

    /// Asks the running comparison to stop at its next frame.
    pub fn cancel(&self) {
        if let Some(job) = &self.job {
            job.cancel();
        }
    }

    /// Collects a finished comparison (never blocks on a running one).
    pub fn poll(&mut self) {
        if let Some(result) = poll_job(&mut self.job) {
            self.result = Some(result);
        }
    }

    /// Progress of the running comparison.
    pub fn progress(&self) -> Option<CompareProgress> {
        self.job.as_ref().and_then(|j| j.progress().flatten())
    }
}

impl super::NeuralClothApp {
    /// "Check against simulation": settings, start/cancel with progress, and the result.
    pub fn sim_check_ui(&mut self, ui: &mut egui::Ui) {
        ui.separator();
        ui.strong("Check against simulation");
        ui.label("The current run's network against the reference simulator on the same motion: distance, swing and the paper's metrics.");
        let check = &mut self.cost.check;
        if check.is_running() {
            if let Some(p) = check.progress() {
                let text = format!("{}: {} ({}/{})", p.motion, p.phase.label(), p.done, p.total);
                ui.add(egui::ProgressBar::new(p.fraction() as f32).text(text));
            }
            if ui.button("Cancel check").clicked() {
                check.cancel();
            }
            ui.ctx()
                .request_repaint_after(std::time::Duration::from_millis(250));
        } else {
            let shown = self.state.current_motion().map(|m| m.name.clone());
            ui.horizontal(|ui| {
                let label = ui.label("iterations per frame");
                ui.add(egui::DragValue::new(&mut check.iterations).range(1..=10_000))
                    .labelled_by(label.id);
            });
            let label = match &shown {
                Some(name) => format!("only the shown motion ('{name}')"),
                None => "only the shown motion".into(),
            };
            ui.add_enabled(
                shown.is_some(),
                egui::Checkbox::new(&mut check.shown_motion_only, label),
            )
            .on_hover_text("Otherwise: every motion of the scene's validation split");
            let run_dir = self.state.training.run_dir.clone();
            let reason = unavailable_reason(run_dir.as_deref());
            let button = ui
                .add_enabled(
                    reason.is_none(),
                    egui::Button::new("Check against simulation"),
                )
                .on_disabled_hover_text(reason.unwrap_or_default());
            if button.clicked()
                && let Some(dir) = run_dir
            {
                let motion = shown.filter(|_| check.shown_motion_only);
                if let Err(e) = check.start(dir, motion, self.notify.clone()) {
                    check.result = Some(Err(e));
                }
            }
        }
        match &self.cost.check.result {
            Some(Ok(r)) => compare_table_ui(ui, r),
            Some(Err(e)) => {
                ui.colored_label(ui.visuals().error_fg_color, e.to_string());
            }
            None => {}
        }
    }
}

/// `value` with `decimals`, or a dash.
fn cell(value: Option<f64>, decimals: usize) -> String {
    value.map_or_else(|| "—".into(), |v| format!("{v:.decimals$}"))
}

/// The comparison as one table per motion.
fn compare_table_ui(ui: &mut egui::Ui, r: &CompareReport) {
    ui.label(format!(
        "step {}, '{}' ({} vertices), {} fps, w = {}, reference {} iterations per frame",
        r.step, r.garment, r.vertices, r.fps, r.options.w, r.options.iterations
    ));
    for m in &r.motions {
        let s = &m.measures;
        ui.label(format!(
            "'{}': {} frames ({} still), reference {}",
            m.name,
            s.frames,
            s.still_frames,
            if m.reference.cached {
                "cached"
            } else {
                "simulated"
            }
        ));
        egui::Grid::new(("compare table", m.name.as_str()))
            .striped(true)
            .show(ui, |ui| {
                for h in ["", "all", "still", "moving"] {
                    ui.strong(h);
                }
                ui.end_row();
                let mut row = |label: &str, values: [Option<f64>; 3], decimals: usize| {
                    ui.label(label);
                    for v in values {
                        ui.label(cell(v, decimals));
                    }
                    ui.end_row();
                };
                row(
                    "mean mm",
                    [
                        Some(s.all.mean_mm),
                        s.still.map(|d| d.mean_mm),
                        s.moving.map(|d| d.mean_mm),
                    ],
                    1,
                );
                row(
                    "p95 mm",
                    [
                        Some(s.all.p95_mm),
                        s.still.map(|d| d.p95_mm),
                        s.moving.map(|d| d.p95_mm),
                    ],
                    1,
                );
                let (n, q) = (s.amplitude.network, s.amplitude.simulator);
                row("swing net mm", [Some(n.all_mm), n.still_mm, n.moving_mm], 1);
                row("swing sim mm", [Some(q.all_mm), q.still_mm, q.moving_mm], 1);
                if let Some(h) = &s.hem {
                    row(
                        "hem net m",
                        [
                            None,
                            h.still.map(|p| p.network_m),
                            h.moving.map(|p| p.network_m),
                        ],
                        3,
                    );
                    row(
                        "hem sim m",
                        [
                            None,
                            h.still.map(|p| p.simulator_m),
                            h.moving.map(|p| p.simulator_m),
                        ],
                        3,
                    );
                }
            });
        egui::Grid::new(("compare metrics", m.name.as_str()))
            .striped(true)
            .show(ui, |ui| {
                for h in ["metric", "network", "simulator"] {
                    ui.strong(h);
                }
                ui.end_row();
                let sim = m.metrics.simulator.named();
                for ((name, a), (_, b)) in m.metrics.network.named().iter().zip(&sim) {
                    ui.label(*name);
                    ui.label(format!("{a:.4}"));
                    ui.label(format!("{b:.4}"));
                    ui.end_row();
                }
            });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unavailable_without_a_run_or_checkpoint() {
        assert!(unavailable_reason(None).is_some_and(|r| r.contains("train")));
        let dir = tempfile::tempdir().unwrap();
        assert!(unavailable_reason(Some(dir.path())).is_some_and(|r| r.contains("checkpoint")));
        std::fs::write(dir.path().join("run.json"), "{}").unwrap();
        std::fs::write(dir.path().join("latest.json"), "{\"step\": 1}").unwrap();
        assert_eq!(unavailable_reason(Some(dir.path())), None);
    }

    #[test]
    fn a_broken_run_reports_an_error_in_the_background() {
        let dir = tempfile::tempdir().unwrap();
        let mut check = SimCheck::default();
        check
            .start(dir.path().to_path_buf(), None, Arc::new(|| {}))
            .unwrap();
        assert!(check.is_running());
        while check.is_running() {
            check.poll();
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        let error = match &check.result {
            Some(Err(e)) => e.to_string(),
            _ => String::from("no error"),
        };
        assert!(error.contains("run.json"), "{error}");
    }
}
