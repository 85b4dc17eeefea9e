//! The state of "Check against simulation" in the Cost panel
//! ([`super::sim_check_panel`]): compares the current run's trained network with the
//! reference simulator ([`neural_cloth_train::compare`]) on a background thread with progress
//! and cancel, and keeps the result.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use neural_cloth_core::scene::MIRRORED_NAME_SUFFIX;
use neural_cloth_train::compare::{CompareOptions, CompareProgress, CompareReport, compare};
use neural_cloth_train::load_trained;

use super::background::JobSlot;
use super::error::AppError;

/// State of the "Check against simulation" action.
pub struct SimCheck {
    /// L-BFGS iterations per frame of the reference, 1..=10000; default 200.
    pub iterations: usize,
    /// Compare only the motion shown in the viewport (otherwise the validation motions);
    /// default false.
    pub shown_motion_only: bool,
    /// With `shown_motion_only`, check the left/right mirror image of the shown motion
    /// instead (does the network behave alike both ways); default false.
    pub mirrored: bool,
    /// Also simulate with twice the iterations and show how far the two references are
    /// apart (whether the reference is converged); default false.
    pub spread: bool,
    /// Also simulate from a start moved by a micrometre and show how far it is from the
    /// reference (whether the motion is predictable at all); default false.
    pub sensitivity: bool,
    /// The running comparison and the last result (or the error that ended the last check).
    pub job: JobSlot<Option<CompareProgress>, CompareReport>,
}

impl Default for SimCheck {
    fn default() -> Self {
        Self {
            iterations: 200,
            shown_motion_only: false,
            mirrored: false,
            spread: false,
            sensitivity: false,
            job: JobSlot::default(),
        }
    }
}

/// One line for the curves: the step checked and, per motion, the mean distance from the
/// simulator, the swings of both and the GRU state's drift where measured, e.g. "checked
/// against simulation at step 1200: spin 22.2 mm (swing 19.2 / 32.2 mm, drift 0.3 mm)".
pub fn check_summary(report: &CompareReport) -> String {
    let motions: Vec<String> = report
        .motions
        .iter()
        .map(|m| {
            let s = &m.measures;
            let mut text = format!("{} {:.1} mm", m.name, s.all.mean_mm);
            let mut details = Vec::new();
            if let (Some(net), Some(sim)) = (
                s.amplitude.network.moving_mm,
                s.amplitude.simulator.moving_mm,
            ) {
                details.push(format!("swing {net:.1} / {sim:.1} mm"));
            }
            if let Some(d) = s.drift {
                details.push(format!("drift {:.1} mm", d.mean_mm));
            }
            if !details.is_empty() {
                text.push_str(&format!(" ({})", details.join(", ")));
            }
            text
        })
        .collect();
    format!(
        "checked against simulation at step {}: {}",
        report.step,
        motions.join("; ")
    )
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
    /// Starts comparing the newest checkpoint of the run at `run_dir` on the thread
    /// `neural-cloth-compare` (on `motion`, or the validation motions when `None`); `notify`
    /// requests a repaint when progress moves.
    pub fn start(
        &mut self,
        run_dir: PathBuf,
        motion: Option<String>,
        notify: Arc<dyn Fn() + Send + Sync>,
    ) -> Result<(), AppError> {
        let options = CompareOptions {
            iterations: self.iterations.clamp(1, 10_000),
            spread: self.spread,
            sensitivity: self.sensitivity,
            ..Default::default()
        };
        self.job.start(
            "a check",
            "neural-cloth-compare",
            None,
            notify,
            move |reporter| {
                let trained = load_trained(&run_dir)?;
                let mut report = |now: CompareProgress| reporter.report(Some(now));
                Ok(compare(&trained, motion.as_deref(), &options, &mut report)?)
            },
        )
    }

    /// Progress of the running comparison.
    pub fn progress(&self) -> Option<CompareProgress> {
        self.job.progress().flatten()
    }

    /// The motion to check: the one shown (`shown`), or its mirror image, when only that
    /// one is asked for; `None` (the validation motions) otherwise.
    pub fn checked_motion(&self, shown: Option<String>) -> Option<String> {
        let name = shown.filter(|_| self.shown_motion_only)?;
        Some(if self.mirrored {
            format!("{name}{MIRRORED_NAME_SUFFIX}")
        } else {
            name
        })
    }

    /// "Check against simulation" pressed: compares the run at `run_dir` (none: nothing to
    /// check) on the motion shown (`shown`) when only that one is asked for, else on the
    /// validation motions; why it cannot start becomes the result.
    pub fn check_clicked(
        &mut self,
        run_dir: Option<PathBuf>,
        shown: Option<String>,
        notify: Arc<dyn Fn() + Send + Sync>,
    ) {
        let Some(dir) = run_dir else {
            return;
        };
        if let Err(e) = self.start(dir, self.checked_motion(shown), notify) {
            self.job.result = Some(Err(e));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shown_motion_or_its_mirror_image_is_checked_when_asked() {
        let mut check = SimCheck::default();
        let spin = || Some("spin".to_string());
        assert_eq!(check.checked_motion(spin()), None, "validation motions");
        check.mirrored = true;
        assert_eq!(check.checked_motion(spin()), None);
        check.shown_motion_only = true;
        assert_eq!(
            check.checked_motion(spin()).as_deref(),
            Some("spin (mirrored)")
        );
        check.mirrored = false;
        assert_eq!(check.checked_motion(spin()).as_deref(), Some("spin"));
        assert_eq!(check.checked_motion(None), None);
    }

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
        assert!(check.job.is_running());
        while check.job.is_running() {
            check.job.poll();
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        let error = match &check.job.result {
            Some(Err(e)) => e.to_string(),
            _ => String::from("no error"),
        };
        assert!(error.contains("run.json"), "{error}");
    }
}
