//! The "Cost" panel: what accuracy costs in time for the current scene. It runs the report's
//! accuracy/time experiment (reference simulator at several iteration budgets against a
//! network trained for a few durations, all on the current scene) on a background thread
//! with a budget, shows its progress, can cancel it, and tabulates the result. It also holds
//! "Check against simulation" of the current run ([`super::sim_check`]).

use std::sync::Arc;

use neural_cloth_core::scene::Scene;
use neural_cloth_lab::report::Progress;
use neural_cloth_lab::report::accuracy::{CostOptions, CostResult, run_cost_experiment};

use super::background::{BackgroundJob, poll_job};
use super::error::AppError;
use super::state::AppState;

/// State of the Cost panel.
pub struct CostPanel {
    /// Budget of one experiment, seconds; 30..=1800, default 120.
    pub budget_secs: f64,
    job: Option<BackgroundJob<Progress, CostResult>>,
    /// The last result, or the error that ended the last run.
    pub result: Option<Result<CostResult, AppError>>,
    /// "Check against simulation" of the current run.
    pub check: super::sim_check::SimCheck,
}

impl Default for CostPanel {
    fn default() -> Self {
        Self {
            budget_secs: 120.0,
            job: None,
            result: None,
            check: Default::default(),
        }
    }
}

impl CostPanel {
    /// True while an experiment runs.
    pub fn is_running(&self) -> bool {
        self.job.is_some()
    }

    /// Starts the experiment on `scene` on the thread `neural-cloth-cost`; `notify` requests a
    /// repaint when progress moves.
    pub fn start(
        &mut self,
        scene: Scene,
        notify: Arc<dyn Fn() + Send + Sync>,
    ) -> Result<(), AppError> {
        if self.job.is_some() {
            return Err(AppError::AlreadyRunning("an experiment"));
        }
        let options = CostOptions {
            budget_secs: self.budget_secs.clamp(30.0, 1800.0),
            ..Default::default()
        };
        self.job = Some(BackgroundJob::spawn(
            "neural-cloth-cost",
            Progress::default(),
            notify,
            move |reporter| {
                let mut report = |now: &Progress| reporter.report(now.clone());
                Ok(run_cost_experiment(&scene, &options, &mut report)?)
            },
        )?);
        Ok(())
    }

    /// Asks the running experiment to stop at its next check.
    pub fn cancel(&self) {
        if let Some(job) = &self.job {
            job.cancel();
        }
    }

    /// Collects a finished experiment (never blocks on a running one).
    pub fn poll(&mut self) {
        if let Some(result) = poll_job(&mut self.job) {
            self.result = Some(result);
        }
    }

    /// Progress of the running experiment.
    pub fn progress(&self) -> Option<Progress> {
        self.job.as_ref().and_then(BackgroundJob::progress)
    }

    /// "Measure": starts the experiment on the state's scene (its garment, avatar, motions and
    /// settings); why it cannot start becomes the result.
    pub fn measure(&mut self, state: &AppState, notify: Arc<dyn Fn() + Send + Sync>) {
        let started = match state.scene.garment.as_deref() {
            Some(garment) => state
                .assemble_scene(garment)
                .and_then(|scene| self.start(scene, notify)),
            None => Err(AppError::Missing("load a garment first")),
        };
        if let Err(e) = started {
            self.result = Some(Err(e));
        }
    }
}

impl super::NeuralClothApp {
    /// The Cost panel: budget, run/cancel, progress and the accuracy/time table.
    pub fn cost_ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Cost").default_open(false).show(ui, |ui| {
            ui.label("What accuracy costs in time on this scene: the reference simulator at several iteration budgets against the network trained for a few durations.");
            ui.horizontal(|ui| {
                ui.add(egui::Slider::new(&mut self.cost.budget_secs, 30.0..=1800.0).logarithmic(true).suffix(" s").text("budget"));
            });
            if self.cost.is_running() {
                if let Some(p) = self.cost.progress() {
                    ui.add(egui::ProgressBar::new(p.fraction as f32).text(format!("{} {}", p.phase, p.detail)));
                }
                if ui.button("Cancel").clicked() {
                    self.cost.cancel();
                }
                ui.ctx().request_repaint_after(std::time::Duration::from_millis(250));
            } else if ui.button("Measure").clicked() {
                self.cost.measure(&self.state, self.notify.clone());
            }
            match &self.cost.result {
                Some(Ok(r)) => cost_table_ui(ui, r),
                Some(Err(e)) => {
                    ui.colored_label(ui.visuals().error_fg_color, e.to_string());
                }
                None => {}
            }
            self.sim_check_ui(ui);
        });
    }
}

/// The result as a table.
fn cost_table_ui(ui: &mut egui::Ui, r: &CostResult) {
    ui.label(format!(
        "{}: '{}', {} frames, {} vertices; reference {} iterations ({:.0} ms/frame)",
        r.scene,
        r.motion,
        r.clip_frames,
        r.vertices,
        r.reference_iterations,
        r.reference.ms_per_frame
    ));
    egui::Grid::new("cost table").striped(true).show(ui, |ui| {
        for h in [
            "method", "ms/frame", "mean mm", "p95 mm", "residual", "speed-up",
        ] {
            ui.strong(h);
        }
        ui.end_row();
        for p in &r.points {
            ui.label(&p.label);
            ui.label(format!("{:.2}", p.ms_per_frame));
            ui.label(format!("{:.1}", p.mean_mm));
            ui.label(format!("{:.1}", p.p95_mm));
            ui.label(format!("{:.1}", p.residual_rms));
            ui.label(
                p.speedup
                    .as_ref()
                    .map(|s| format!("{:.0}×", s.factor))
                    .unwrap_or_else(|| "—".into()),
            );
            ui.end_row();
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_in_the_background_and_cancels() {
        let text = "name = \"tiny\"\n[avatar]\nbuiltin = \"mannequin\"\n[garment]\nbuiltin = \"tshirt\"\nresolution = 300\n[[motions]]\nbuiltin = \"spin\"\nduration_secs = 1.0\n";
        let config = neural_cloth_core::scene::config::SceneConfig::from_toml_str(text).unwrap();
        let scene = neural_cloth_core::scene::procedural::build_builtin(&config).unwrap();
        let mut panel = CostPanel::default();
        let started = std::time::Instant::now();
        panel.start(scene.clone(), Arc::new(|| {})).unwrap();
        // Starting returns at once and a second start is refused while it runs.
        assert!(panel.is_running());
        assert!(panel.start(scene, Arc::new(|| {})).is_err());
        panel.cancel();
        while panel.is_running() {
            panel.poll();
            std::thread::sleep(std::time::Duration::from_millis(20));
            assert!(
                started.elapsed().as_secs() < 120,
                "cancel must end the experiment"
            );
        }
        assert!(
            matches!(panel.result, Some(Err(_))),
            "a cancelled run reports an error, not a result"
        );
    }
}
