//! The training panel's state machine (idle → running ⇄ paused → finished) over the trainer's
//! [`TrainerHandle`]: the UI sends commands and drains events once per frame; training itself
//! runs on the trainer's own thread, never on the UI thread.

use std::path::PathBuf;
use std::sync::Arc;

use neural_cloth_core::scene::Scene;
use neural_cloth_core::scene::config::SceneConfig;
use neural_cloth_model::ModelArtifact;
use neural_cloth_physics::FabricParams;
use neural_cloth_train::handle::{Preparing, TrainCommand, TrainEvent, TrainerHandle};
use neural_cloth_train::{TrainConfig, TrainError};

use super::error::AppError;
use super::metrics::{MetricHistory, SettingMarker, push_marker};

/// Where the training run is.
#[derive(Clone, Debug)]
pub enum TrainingState {
    /// Nothing started (or reset).
    Idle,
    /// The trainer is stepping.
    Running,
    /// The trainer waits for Resume.
    Paused,
    /// Stop was requested; waiting for the final checkpoint.
    Stopping,
    /// The run ended: a summary line, or the error that ended it (shared with the trainer's
    /// event; shown as text by the training panel).
    Finished(Result<String, Arc<TrainError>>),
}

/// States are equal when they are the same state; two failed runs when they share the one
/// error (the trainer's event hands it out shared).
impl PartialEq for TrainingState {
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (Self::Finished(Ok(a)), Self::Finished(Ok(b))) => a == b,
            (Self::Finished(Err(a)), Self::Finished(Err(b))) => Arc::ptr_eq(a, b),
            (a, b) => {
                !matches!(a, Self::Finished(_))
                    && std::mem::discriminant(a) == std::mem::discriminant(b)
            }
        }
    }
}

impl TrainingState {
    /// Short label for the panel.
    pub fn label(&self) -> &'static str {
        match self {
            Self::Idle => "idle",
            Self::Running => "running",
            Self::Paused => "paused",
            Self::Stopping => "stopping",
            Self::Finished(Ok(_)) => "finished",
            Self::Finished(Err(_)) => "failed",
        }
    }

    /// True while a trainer thread is alive (running, paused or stopping).
    pub fn is_active(&self) -> bool {
        matches!(self, Self::Running | Self::Paused | Self::Stopping)
    }
}

/// Everything a trainer needs to start a run from the app's current setup.
#[derive(Clone, Debug)]
pub struct TrainingRequest {
    /// Avatar, garment, motions with splits, effects, fabric and training frame rate, as
    /// loaded from `scene_config`.
    pub scene: Arc<Scene>,
    /// Window, batch and schedule (the frame rate is `scene.training_fps`).
    pub config: TrainConfig,
    /// Where checkpoints go.
    pub run_dir: PathBuf,
    /// The app's scene description (file paths absolute), which the run records so that
    /// `eval` and `bake` rebuild the scene it trained on.
    pub scene_config: SceneConfig,
}

/// Starts a trainer thread for a request (the real one builds a training session from the
/// scene; tests pass a double). `notify` must be called after each event (it requests a
/// repaint).
pub trait TrainerLauncher: Send {
    /// Starts training; errors are shown in the UI.
    fn launch(
        &mut self,
        request: TrainingRequest,
        notify: Arc<dyn Fn() + Send + Sync>,
    ) -> Result<TrainerHandle, AppError>;
}

/// Progress numbers shown under the buttons.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Progress {
    /// Last optimiser step.
    pub step: u64,
    /// Recent optimiser steps per second.
    pub steps_per_sec: f64,
    /// Seconds of training (pauses excluded).
    pub elapsed_secs: f64,
    /// Step limit of the run, if any (for the progress bar).
    pub max_steps: Option<u64>,
    /// Limit of the run in seconds of training, if any (for the progress bar).
    pub max_secs: Option<f64>,
}

impl Progress {
    /// Share of the run's budget spent, 0..=1: the larger of its steps and its time, as the
    /// trainer counts them; 0 for an open-ended run.
    pub fn fraction(&self) -> f32 {
        neural_cloth_train::config::run_progress(
            self.step,
            self.max_steps,
            self.elapsed_secs,
            self.max_secs,
        )
        .map_or(0.0, |p| p.clamp(0.0, 1.0) as f32)
    }
}

/// The training panel's model: state, progress, metric history, preview weights and messages.
pub struct TrainingControl {
    state: TrainingState,
    /// Progress of the current or last run.
    pub progress: Progress,
    /// Every metric record of the current or last run.
    pub history: MetricHistory,
    /// Settings changed during the run (fabric, window, learning rate), for the curves.
    pub markers: Vec<SettingMarker>,
    /// Latest weight snapshot for the preview, with its step.
    pub latest_weights: Option<(u64, Arc<ModelArtifact>)>,
    /// Run directory of the current or last run.
    pub run_dir: Option<PathBuf>,
    /// The work before the first step (the warm start's simulation), until a step arrives.
    pub preparing: Option<Preparing>,
    /// The scene revision ([`crate::state::SceneState::revision`]) the current or last run
    /// was started on (`None`: no run started from this app since the last reset).
    pub scene_revision: Option<u64>,
    /// Last checkpoint written.
    pub last_checkpoint: Option<PathBuf>,
    /// Recent messages (applied settings, rollbacks, errors), newest last, at most 50.
    pub log: Vec<String>,
    handle: Option<TrainerHandle>,
    launcher: Option<Box<dyn TrainerLauncher>>,
}

impl std::fmt::Debug for TrainingControl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TrainingControl")
            .field("state", &self.state)
            .field("progress", &self.progress)
            .field("records", &self.history.train.len())
            .field("has_launcher", &self.launcher.is_some())
            .finish()
    }
}

impl Default for TrainingControl {
    fn default() -> Self {
        Self::new(None)
    }
}

impl TrainingControl {
    /// A control that starts runs with `launcher` (None: the Train button reports that no
    /// trainer is available).
    pub fn new(launcher: Option<Box<dyn TrainerLauncher>>) -> Self {
        Self {
            state: TrainingState::Idle,
            progress: Progress::default(),
            history: MetricHistory::default(),
            markers: Vec::new(),
            latest_weights: None,
            run_dir: None,
            preparing: None,
            scene_revision: None,
            last_checkpoint: None,
            log: Vec::new(),
            handle: None,
            launcher,
        }
    }

    /// Current state.
    pub fn state(&self) -> &TrainingState {
        &self.state
    }

    fn note(&mut self, message: String) {
        self.log.push(message);
        if self.log.len() > 50 {
            self.log.remove(0);
        }
    }

    /// Starts a run (from idle or finished); the history starts empty.
    pub fn start(
        &mut self,
        request: TrainingRequest,
        notify: Arc<dyn Fn() + Send + Sync>,
    ) -> Result<(), AppError> {
        if self.state.is_active() {
            return Err(AppError::AlreadyRunning("training"));
        }
        let Some(launcher) = self.launcher.as_mut() else {
            return Err(AppError::Missing("no trainer is available in this build"));
        };
        let max_steps = request.config.max_steps;
        let max_secs = request.config.max_minutes.map(|m| m * 60.0);
        let run_dir = request.run_dir.clone();
        let handle = launcher.launch(request, notify)?;
        self.handle = Some(handle);
        self.history = MetricHistory::default();
        self.markers.clear();
        self.progress = Progress {
            max_steps,
            max_secs,
            ..Default::default()
        };
        self.run_dir = Some(run_dir);
        self.last_checkpoint = None;
        self.state = TrainingState::Running;
        Ok(())
    }

    fn send(&mut self, command: TrainCommand) -> bool {
        let sent = self.handle.as_ref().is_some_and(|h| h.send(command));
        if !sent {
            self.note("the trainer did not accept the command (busy or gone)".into());
        }
        sent
    }

    /// Pauses a running trainer.
    pub fn pause(&mut self) {
        if matches!(self.state, TrainingState::Running) && self.send(TrainCommand::Pause) {
            self.state = TrainingState::Paused;
        }
    }

    /// Resumes a paused trainer.
    pub fn resume(&mut self) {
        if matches!(self.state, TrainingState::Paused) && self.send(TrainCommand::Resume) {
            self.state = TrainingState::Running;
        }
    }

    /// Asks the trainer to write a final checkpoint and finish.
    pub fn stop(&mut self) {
        if matches!(self.state, TrainingState::Running | TrainingState::Paused) {
            if let Some(h) = &self.handle {
                h.stop();
            }
            self.state = TrainingState::Stopping;
        }
    }

    /// Stops any run and forgets it (history, progress, preview weights, run folder; the
    /// folder stays on disk).
    pub fn reset(&mut self) {
        if let Some(h) = self.handle.take() {
            h.stop();
            // Dropping the handle joins the thread (at its next step boundary): do that on a
            // helper thread so the UI never waits for a training step.
            let joined = std::thread::Builder::new()
                .name("neural-cloth-trainer-join".into())
                .spawn(move || drop(h));
            if let Err(e) = joined {
                self.note(format!("could not stop the trainer in the background: {e}"));
            }
        }
        self.scene_revision = None;
        self.state = TrainingState::Idle;
        self.progress = Progress::default();
        self.history = MetricHistory::default();
        self.markers.clear();
        self.latest_weights = None;
        self.last_checkpoint = None;
        self.run_dir = None;
        self.preparing = None;
    }

    /// Shows a run opened from its folder (not while a run is active): its curves, its step
    /// and the weights of its newest checkpoint, as a finished run.
    pub fn show_run(
        &mut self,
        run_dir: PathBuf,
        step: u64,
        history: MetricHistory,
        weights: Arc<ModelArtifact>,
    ) {
        if self.state.is_active() {
            return;
        }
        self.progress = Progress {
            step,
            elapsed_secs: history.train.last().map_or(0.0, |r| r.wall_secs),
            ..Default::default()
        };
        self.history = history;
        self.markers.clear();
        self.latest_weights = Some((step, weights));
        self.state = TrainingState::Finished(Ok(format!(
            "opened run at step {step}: {}",
            run_dir.display()
        )));
        self.last_checkpoint = None;
        self.run_dir = Some(run_dir);
    }

    /// Sends new fabric parameters to a live run (no-op when idle).
    pub fn set_fabric(&mut self, fabric: &FabricParams) {
        if matches!(self.state, TrainingState::Running | TrainingState::Paused) {
            self.send(TrainCommand::SetFabric(Box::new(fabric.clone())));
        }
    }

    /// Sends a new window length to a live run (no-op when idle).
    pub fn set_window(&mut self, window_secs: f32) {
        if matches!(self.state, TrainingState::Running | TrainingState::Paused) {
            self.send(TrainCommand::SetWindow(window_secs));
        }
    }

    /// Drains the trainer's events without blocking (the channel is bounded, so this is
    /// bounded too) and applies them; returns how many were handled.
    pub fn poll(&mut self) -> usize {
        let Some(handle) = &self.handle else { return 0 };
        let events = handle.drain();
        let n = events.len();
        for event in events {
            self.apply(event);
        }
        n
    }

    /// Applies one event to the state, progress and history.
    pub fn apply(&mut self, event: TrainEvent) {
        match event {
            TrainEvent::Started { run_dir, step } => {
                self.run_dir = Some(run_dir);
                self.progress.step = step;
            }
            TrainEvent::Preparing(p) => {
                if self
                    .preparing
                    .as_ref()
                    .is_none_or(|old| old.stage != p.stage)
                {
                    self.note(p.stage.clone());
                }
                self.preparing = Some(p);
            }
            TrainEvent::Step(record) => {
                self.preparing = None;
                if let Some(prev) = self.history.train.last() {
                    let dt = record.wall_secs - prev.wall_secs;
                    let ds = record.step.saturating_sub(prev.step) as f64;
                    if dt > 0.0 && dt.is_finite() {
                        let rate = ds / dt;
                        let s = &mut self.progress.steps_per_sec;
                        *s = if *s > 0.0 {
                            0.9 * *s + 0.1 * rate
                        } else {
                            rate
                        };
                    }
                }
                self.progress.step = record.step;
                self.progress.elapsed_secs = record.wall_secs;
                self.history.train.push(record);
            }
            TrainEvent::Validation(record) => self.history.validation.push(record),
            TrainEvent::Snapshot { step, weights } => self.latest_weights = Some((step, weights)),
            TrainEvent::Checkpoint { path, .. } => self.last_checkpoint = Some(path),
            TrainEvent::RolledBack {
                diverged_at,
                restored_step,
                learning_rate,
            } => {
                self.history.truncate_after(restored_step);
                self.markers.retain(|m| m.step <= restored_step);
                let wall_secs = self.history.train.last().map_or(0.0, |r| r.wall_secs);
                self.markers.push(SettingMarker {
                    step: restored_step,
                    wall_secs,
                    name: format!("learning rate {learning_rate:.1e}"),
                });
                self.note(format!("diverged at step {diverged_at}; back to step {restored_step}, learning rate {learning_rate:.2e}"));
            }
            TrainEvent::Paused => {
                if matches!(self.state, TrainingState::Running) {
                    self.state = TrainingState::Paused;
                }
            }
            TrainEvent::Resumed => {
                if matches!(self.state, TrainingState::Paused) {
                    self.state = TrainingState::Running;
                }
            }
            TrainEvent::Applied(setting) => {
                let marker = SettingMarker {
                    step: self.progress.step,
                    wall_secs: self.progress.elapsed_secs,
                    name: setting.to_string(),
                };
                push_marker(&mut self.markers, marker);
                self.note(format!("applied: {setting}"));
            }
            // Nothing changed: no marker.
            TrainEvent::Rejected { setting, error } => {
                self.note(format!("{setting} rejected: {error}"));
            }
            TrainEvent::Warning(w) => self.note(format!("⚠ {w}")),
            TrainEvent::Note(n) => self.note(n),
            TrainEvent::Stalled {
                step,
                reason,
                remedy,
            } => self.note(format!(
                "⚠ training stalled at step {step}: {reason}; {remedy}"
            )),
            TrainEvent::Finished(result) => {
                self.preparing = None;
                if let Some(warning) = result.as_ref().ok().and_then(|s| s.health_warning()) {
                    self.note(format!("⚠ {warning}"));
                }
                let result = result.map(|s| {
                    format!(
                        "{} steps in {:.1} s, run {}",
                        s.steps,
                        s.wall_secs,
                        s.run_dir.display()
                    )
                });
                if let Err(e) = &result {
                    self.note(format!("training failed: {e}"));
                }
                self.state = TrainingState::Finished(result);
                self.handle = None;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Progress;

    #[test]
    fn the_progress_bar_counts_the_larger_of_steps_and_minutes_spent() {
        let open = Progress {
            step: 50,
            elapsed_secs: 30.0,
            ..Default::default()
        };
        assert_eq!(open.fraction(), 0.0);
        let by_time = Progress {
            max_secs: Some(120.0),
            ..open
        };
        assert_eq!(by_time.fraction(), 0.25);
        let both = Progress {
            max_steps: Some(100),
            ..by_time
        };
        assert_eq!(both.fraction(), 0.5);
        let over = Progress {
            elapsed_secs: 500.0,
            ..both
        };
        assert_eq!(over.fraction(), 1.0);
    }
}
