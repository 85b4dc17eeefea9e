//! The state of the "Cost" panel ([`super::cost_panel`]): what accuracy costs in time for the
//! current scene. It runs the report's accuracy/time experiment (reference simulator at
//! several iteration budgets against a network trained for a few durations, all on the
//! current scene) on a background thread with a budget, reports its progress, can cancel it,
//! and keeps the result. It also holds "Check against simulation" of the current run
//! ([`super::sim_check`]).

use std::sync::Arc;

use neural_cloth_core::scene::Scene;
use neural_cloth_lab::report::Progress;
use neural_cloth_lab::report::accuracy::{CostOptions, CostResult, run_cost_experiment};

use super::background::JobSlot;
use super::error::AppError;
use super::state::AppState;

/// State of the Cost panel.
pub struct CostState {
    /// Budget of one experiment, seconds; 30..=1800, default 120.
    pub budget_secs: f64,
    /// The running experiment and the last result (or the error that ended the last run).
    pub job: JobSlot<Progress, CostResult>,
    /// "Check against simulation" of the current run.
    pub check: super::sim_check::SimCheck,
}

impl Default for CostState {
    fn default() -> Self {
        Self {
            budget_secs: 120.0,
            job: JobSlot::default(),
            check: Default::default(),
        }
    }
}

impl CostState {
    /// Starts the experiment on `scene` on the thread `neural-cloth-cost`; `notify` requests a
    /// repaint when progress moves.
    pub fn start(
        &mut self,
        scene: Scene,
        notify: Arc<dyn Fn() + Send + Sync>,
    ) -> Result<(), AppError> {
        let options = CostOptions {
            budget_secs: self.budget_secs.clamp(30.0, 1800.0),
            ..Default::default()
        };
        self.job.start(
            "an experiment",
            "neural-cloth-cost",
            Progress::default(),
            notify,
            move |reporter| {
                let mut report = |now: &Progress| reporter.report(now.clone());
                Ok(run_cost_experiment(&scene, &options, &mut report)?)
            },
        )
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
            self.job.result = Some(Err(e));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_in_the_background_and_cancels() {
        let text = "name = \"tiny\"\n[avatar]\nbuiltin = \"mannequin\"\n[garment]\nbuiltin = \"tshirt\"\nresolution = 300\n[[motions]]\nbuiltin = \"spin\"\nduration_secs = 1.0\n";
        let config = neural_cloth_core::scene::config::SceneConfig::from_toml_str(text).unwrap();
        let scene = neural_cloth_core::scene::procedural::build_builtin(&config).unwrap();
        let mut panel = CostState::default();
        let started = std::time::Instant::now();
        panel.start(scene.clone(), Arc::new(|| {})).unwrap();
        // Starting returns at once and a second start is refused while it runs.
        assert!(panel.job.is_running());
        assert!(panel.start(scene, Arc::new(|| {})).is_err());
        panel.job.cancel();
        while panel.job.is_running() {
            panel.job.poll();
            std::thread::sleep(std::time::Duration::from_millis(20));
            assert!(
                started.elapsed().as_secs() < 120,
                "cancel must end the experiment"
            );
        }
        assert!(
            matches!(panel.job.result, Some(Err(_))),
            "a cancelled run reports an error, not a result"
        );
    }
}
