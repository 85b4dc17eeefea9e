//! The background training thread and its handle: a bounded command channel (pause, resume,
//! stop, new fabric, new window), a stop flag and a bounded event stream. The app and the CLI
//! both drive training through exactly this API.
//!
//! Which commands act live: fabric parameters (loss weights, density, collision threshold) and
//! the window length take effect at the next step; the frame rate, the effect set and the
//! network sizes change the model or its inputs and need a restart (the app restarts the run).

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TryRecvError, TrySendError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use neural_cloth_physics::FabricParams;

use super::TrainError;
use super::metrics::{MetricHistory, MetricRecord};

/// Capacity of the command channel.
pub const COMMAND_CAPACITY: usize = 32;
/// Capacity of the event channel. Step events and snapshots are dropped (not blocked on)
/// when it is full; the history in the checkpoint keeps every step.
pub const EVENT_CAPACITY: usize = 1024;

/// A request from the UI or CLI to the trainer.
#[derive(Clone, Debug)]
pub enum TrainCommand {
    /// Stop stepping until `Resume`.
    Pause,
    /// Continue after `Pause`.
    Resume,
    /// Write a final checkpoint and finish.
    Stop,
    /// Use new fabric parameters from the next step (live).
    SetFabric(Box<FabricParams>),
    /// Use a new temporal window in seconds from the next step (live).
    SetWindow(f32),
}

/// A setting changed while a run trains ([`TrainCommand::SetFabric`],
/// [`TrainCommand::SetWindow`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LiveSetting {
    /// New fabric parameters.
    Fabric,
    /// A new temporal window.
    Window {
        /// Window length, s.
        secs: f32,
    },
}

impl std::fmt::Display for LiveSetting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Fabric => write!(f, "fabric"),
            Self::Window { secs } => write!(f, "window {secs} s"),
        }
    }
}

/// What the trainer reports.
#[derive(Clone, Debug)]
pub enum TrainEvent {
    /// The run started (or resumed at `step`) in `run_dir`.
    Started {
        /// Run directory.
        run_dir: PathBuf,
        /// First step of this session (non-zero when resuming).
        step: u64,
    },
    /// Metrics of one training step.
    Step(MetricRecord),
    /// Metrics of a validation pass.
    Validation(MetricRecord),
    /// Current weights for the UI's preview model.
    Snapshot {
        /// Step of the weights.
        step: u64,
        /// The weights, in the fast inference engine's layout, with the descriptor settings
        /// and frame rate they are trained with.
        weights: Arc<neural_cloth_model::ModelArtifact>,
    },
    /// A checkpoint was written.
    Checkpoint {
        /// Step of the checkpoint.
        step: u64,
        /// Checkpoint directory.
        path: PathBuf,
    },
    /// The loss or weights went non-finite; training went back to the last good checkpoint.
    RolledBack {
        /// Step at which divergence was detected.
        diverged_at: u64,
        /// Step of the checkpoint restored.
        restored_step: u64,
        /// New learning rate.
        learning_rate: f64,
    },
    /// Work before the first step that takes a while (the warm start's simulation of the
    /// training motions); sent at most once per simulated frame, may be dropped under
    /// back-pressure.
    Preparing(Preparing),
    /// A problem found before training ([`super::preflight`]): the scene is unlikely to learn.
    Warning(String),
    /// Something the run did on its own schedule that shows in its curves (not a problem):
    /// e.g. the mirrored copies joining the batches.
    Note(String),
    /// Training stopped learning (dead units, or validation frozen); the remedy was applied.
    Stalled {
        /// Step of the validation pass that detected it.
        step: u64,
        /// What was detected, in words.
        reason: String,
        /// What was done about it, in words.
        remedy: String,
    },
    /// Training paused.
    Paused,
    /// Training resumed.
    Resumed,
    /// A live setting took effect.
    Applied(LiveSetting),
    /// A live setting was refused; training goes on with the one before.
    Rejected {
        /// The setting asked for.
        setting: LiveSetting,
        /// Why it was refused (shared: events are cloned).
        error: Arc<TrainError>,
    },
    /// The run ended: a summary, or the error that stopped it (shared: events are cloned).
    Finished(Result<RunSummary, Arc<TrainError>>),
}

/// Progress of the work before the first step ([`TrainEvent::Preparing`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Preparing {
    /// What is being done, in words ("simulating walk for the warm start (1 of 5)").
    pub stage: String,
    /// Units done of this stage.
    pub done: usize,
    /// Units in this stage.
    pub total: usize,
}

impl Preparing {
    /// Done fraction of the stage, in [0, 1].
    pub fn fraction(&self) -> f64 {
        match self.total {
            0 => 0.0,
            t => (self.done as f64 / t as f64).clamp(0.0, 1.0),
        }
    }
}

/// What a long preparation reports its progress to; returns false when the run was asked to
/// stop (the preparation then ends with a cancelled error).
pub type PrepareProgress<'a> = &'a mut dyn FnMut(Preparing) -> bool;

/// Final numbers of a run.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RunSummary {
    /// Run directory.
    pub run_dir: PathBuf,
    /// Last step.
    pub steps: u64,
    /// Training wall-clock seconds (pauses excluded).
    pub wall_secs: f64,
    /// Last training metrics.
    pub last_train: Option<MetricRecord>,
    /// Last validation metrics.
    pub last_validation: Option<MetricRecord>,
    /// How many times a divergence was rolled back.
    pub rollbacks: u32,
    /// Metrics of the last validation (or, without one, training) pass beyond the health
    /// limits ([`super::health`]): empty for a garment that looks healthy.
    pub health: Vec<super::health::Unhealthy>,
}

impl RunSummary {
    /// One line saying what looks broken about the trained garment, or `None`.
    pub fn health_warning(&self) -> Option<String> {
        super::health::verdict_line(&self.health)
    }
}

/// The work the loop drives; implemented by the real trainer and by test doubles.
pub trait Session: Send {
    /// One optimiser step; returns its metrics (step and wall time are filled in by the loop).
    fn step(&mut self) -> Result<MetricRecord, TrainError>;
    /// Metrics on the validation split.
    fn validate(&mut self) -> Result<MetricRecord, TrainError>;
    /// True when every weight is finite.
    fn weights_finite(&self) -> bool;
    /// Current weights for the preview, with the settings needed to run them.
    fn snapshot(&self) -> Result<neural_cloth_model::ModelArtifact, TrainError>;
    /// Writes a checkpoint for `step` with `history`; returns its path.
    fn checkpoint(&mut self, step: u64, history: &MetricHistory) -> Result<PathBuf, TrainError>;
    /// Restores the newest checkpoint; returns its step, or an error when none exists.
    fn restore_last_checkpoint(&mut self) -> Result<u64, TrainError>;
    /// Current learning rate.
    fn learning_rate(&self) -> f64;
    /// Sets the learning rate.
    fn set_learning_rate(&mut self, lr: f64);
    /// Sets the schedule's factor on the learning rate for the next steps (1 = the rate as
    /// set; see [`super::config::lr_schedule_factor`]). Sessions without a schedule ignore it.
    fn set_schedule_factor(&mut self, _factor: f64) {}
    /// Tells the session how far the run is: the fraction of its step or minute budget spent
    /// (the larger of the two), `None` for an open-ended run. Sessions that do not use it
    /// ignore it.
    fn set_run_progress(&mut self, _progress: Option<f64>) {}
    /// What the last step changed on the run's own schedule, in words, once (`None` most
    /// steps); the loop sends it as [`TrainEvent::Note`].
    fn take_note(&mut self) -> Option<String> {
        None
    }
    /// Applies new fabric parameters.
    fn set_fabric(&mut self, fabric: FabricParams) -> Result<(), TrainError>;
    /// Applies a new window length in seconds.
    fn set_window(&mut self, window_secs: f32) -> Result<(), TrainError>;
    /// Per-layer dead units of the last validation pass, in words (`None` when not measured).
    fn activity_summary(&self) -> Option<String> {
        None
    }
    /// Re-initialises dead units without changing the network's output; returns how many.
    fn revive_dead_units(&mut self) -> Result<usize, TrainError> {
        Ok(0)
    }
}

/// Validation passes whose loss must be bit-identical before a run counts as frozen.
pub const FROZEN_PASSES: usize = 3;

/// Why the newest validation pass of `validation` shows a run that stopped learning, if it
/// does: a layer the remedy can revive with at least `dead_limit_pct` % dead units (the
/// record's `dead_units_pct`), or the last
/// [`FROZEN_PASSES`] passes (all after step `since`) with bit-identical losses.
pub fn stall_reason(
    validation: &[MetricRecord],
    dead_limit_pct: f64,
    since: u64,
) -> Option<String> {
    let last = validation.last()?;
    if last.dead_units_pct >= dead_limit_pct {
        return Some(format!(
            "{:.0} % of the units of a layer are dead (limit {dead_limit_pct:.0} %)",
            last.dead_units_pct
        ));
    }
    let tail: Vec<&MetricRecord> = validation
        .iter()
        .rev()
        .take(FROZEN_PASSES)
        .filter(|r| r.step > since)
        .collect();
    (tail.len() == FROZEN_PASSES && tail.iter().all(|r| r.loss == last.loss)).then(|| {
        format!(
            "validation unchanged over {FROZEN_PASSES} passes (loss {})",
            last.loss
        )
    })
}

/// Limits and cadence of the loop.
#[derive(Clone, Debug)]
pub struct LoopConfig {
    /// Run directory (for events).
    pub run_dir: PathBuf,
    /// First step number (the resumed step, or 0).
    pub start_step: u64,
    /// Metric history carried over from a resumed run.
    pub history: MetricHistory,
    /// Stop after this step.
    pub max_steps: Option<u64>,
    /// Stop after this many seconds of training.
    pub max_secs: Option<f64>,
    /// Validation cadence in steps.
    pub validate_every: u64,
    /// Snapshot cadence in steps.
    pub snapshot_every: u64,
    /// Checkpoint cadence in steps.
    pub checkpoint_every: u64,
    /// Give up after this many rollbacks.
    pub max_rollbacks: u32,
    /// Warnings found while preparing the run, sent right after `Started`.
    pub warnings: Vec<String>,
    /// A validation pass with this percentage of dead units in one revivable layer (or
    /// [`FROZEN_PASSES`] bit-identical passes) triggers the stall remedy; 0..=100.
    pub dead_limit_pct: f64,
    /// Learning-rate decay at the end of a bounded run: the fraction of the run it spans
    /// (0 = none) and the final factor ([`super::config::lr_schedule_factor`]).
    pub lr_decay: (f64, f64),
    /// Steps over which the learning rate rises linearly from `1/warmup_steps` of its value to
    /// all of it at the start of a run (0 = none).
    pub warmup_steps: u64,
}

/// The handle the UI or CLI keeps. Dropping it stops the trainer and joins the thread.
pub struct TrainerHandle {
    commands: SyncSender<TrainCommand>,
    events: Receiver<TrainEvent>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl TrainerHandle {
    /// Starts `session` on a named background thread. `notify` is called after every event
    /// sent (the app passes a closure that requests a repaint).
    pub fn spawn_session<S: Session + 'static>(
        session: S,
        config: LoopConfig,
        notify: Option<Arc<dyn Fn() + Send + Sync>>,
    ) -> std::io::Result<Self> {
        Self::spawn_with(move |_| Ok((session, config)), notify)
    }

    /// Like [`Self::spawn_session`], but builds the session on the trainer thread with
    /// `prepare` (which may take seconds, or minutes with the warm start: it reports to the
    /// [`PrepareProgress`] it is given, which says false once the run is stopped); its error
    /// ends the run with `Finished(Err)`.
    pub fn spawn_with<S, F>(
        prepare: F,
        notify: Option<Arc<dyn Fn() + Send + Sync>>,
    ) -> std::io::Result<Self>
    where
        S: Session + 'static,
        F: FnOnce(PrepareProgress<'_>) -> Result<(S, LoopConfig), TrainError> + Send + 'static,
    {
        let (cmd_tx, cmd_rx) = std::sync::mpsc::sync_channel(COMMAND_CAPACITY);
        let (ev_tx, ev_rx) = std::sync::mpsc::sync_channel(EVENT_CAPACITY);
        let stop = Arc::new(AtomicBool::new(false));
        let stop_flag = stop.clone();
        let thread = std::thread::Builder::new()
            .name("neural-cloth-trainer".into())
            .spawn(move || {
                let emit = Emitter { tx: ev_tx, notify };
                let stopping = stop_flag.clone();
                let mut progress = |p: Preparing| {
                    emit.offer(TrainEvent::Preparing(p));
                    !stopping.load(Ordering::Relaxed)
                };
                let result = prepare(&mut progress).and_then(|(mut session, config)| {
                    run_loop(&mut session, config, &cmd_rx, &stop_flag, &emit)
                });
                // The session is dropped: give the buffers the allocator kept for the next
                // step back to the system (the app lives on after a run).
                super::alloc::release_freed_buffers();
                emit.send(TrainEvent::Finished(result.map_err(Arc::new)));
            })?;
        Ok(Self {
            commands: cmd_tx,
            events: ev_rx,
            stop,
            thread: Some(thread),
        })
    }

    /// Sends a command without blocking; returns false when the channel is full or closed.
    pub fn send(&self, command: TrainCommand) -> bool {
        self.commands.try_send(command).is_ok()
    }

    /// Asks the trainer to stop at the next step boundary (also via the stop flag, so it works
    /// when the command channel is full).
    pub fn stop(&self) {
        self.stop.store(true, Ordering::Relaxed);
        let _ = self.commands.try_send(TrainCommand::Stop);
    }

    /// Every event available now, without blocking.
    pub fn drain(&self) -> Vec<TrainEvent> {
        self.events.try_iter().collect()
    }

    /// Waits up to `timeout` for the next event.
    pub fn recv_timeout(&self, timeout: Duration) -> Option<TrainEvent> {
        self.events.recv_timeout(timeout).ok()
    }

    /// True once the thread has ended.
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(|t| t.is_finished())
    }

    /// Stops and waits for the thread.
    pub fn join(mut self) {
        self.stop();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for TrainerHandle {
    fn drop(&mut self) {
        self.stop();
        if let Some(t) = self.thread.take() {
            // Drain so a blocked sender can finish, then join.
            while !t.is_finished() {
                let _ = self.events.recv_timeout(Duration::from_millis(10));
            }
            let _ = t.join();
        }
    }
}

struct Emitter {
    tx: SyncSender<TrainEvent>,
    notify: Option<Arc<dyn Fn() + Send + Sync>>,
}

impl Emitter {
    /// Sends an event that must arrive (blocks while the channel is full).
    fn send(&self, event: TrainEvent) {
        let _ = self.tx.send(event);
        self.poke();
    }

    /// Sends an event that may be dropped under back-pressure.
    fn offer(&self, event: TrainEvent) {
        match self.tx.try_send(event) {
            Ok(()) | Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {}
        }
        self.poke();
    }

    fn poke(&self) {
        if let Some(n) = &self.notify {
            n();
        }
    }
}

/// The event for a live setting's outcome.
fn live_outcome(setting: LiveSetting, result: Result<(), TrainError>) -> TrainEvent {
    match result {
        Ok(()) => TrainEvent::Applied(setting),
        Err(e) => TrainEvent::Rejected {
            setting,
            error: Arc::new(e),
        },
    }
}

/// The remedy for a stalled run: revive dead units (function-preserving); when none are dead,
/// halve the learning rate. Returns what was done, in words.
fn remedy_stall<S: Session>(session: &mut S) -> Result<String, TrainError> {
    let layers = session.activity_summary().unwrap_or_default();
    let revived = session.revive_dead_units()?;
    if revived > 0 {
        Ok(format!(
            "revived {revived} dead units with fresh weights (output unchanged); dead per layer before: {layers}"
        ))
    } else {
        let lr = session.learning_rate() * 0.5;
        session.set_learning_rate(lr);
        Ok(format!(
            "no dead unit to revive: learning rate halved to {lr:e}"
        ))
    }
}

/// Writes the periodic checkpoint of `step`. A failure (a full disk, say) does not stop
/// training: it is reported as a warning and the next checkpoint, `every` steps later, tries
/// again; the previous checkpoints stay as they were.
fn checkpoint_or_warn<S: Session>(
    session: &mut S,
    step: u64,
    history: &MetricHistory,
    every: u64,
    emit: &Emitter,
) {
    match session.checkpoint(step, history) {
        Ok(path) => emit.send(TrainEvent::Checkpoint { step, path }),
        Err(e) => emit.send(TrainEvent::Warning(format!(
            "the checkpoint of step {step} could not be written; training goes on and tries \
             again at step {}: {e}",
            step + every
        ))),
    }
}

fn run_loop<S: Session>(
    session: &mut S,
    config: LoopConfig,
    commands: &Receiver<TrainCommand>,
    stop: &AtomicBool,
    emit: &Emitter,
) -> Result<RunSummary, TrainError> {
    let mut history = config.history;
    let mut step = config.start_step;
    let mut rollbacks = 0u32;
    let mut trained_secs = history.train.last().map(|r| r.wall_secs).unwrap_or(0.0);
    let mut paused = false;
    let mut last_remedy = 0u64;
    // The newest snapshot sent in the loop: the step it was taken at, and the weights.
    let mut last_snapshot: Option<(u64, Arc<neural_cloth_model::ModelArtifact>)> = None;
    emit.send(TrainEvent::Started {
        run_dir: config.run_dir.clone(),
        step,
    });
    for w in &config.warnings {
        emit.send(TrainEvent::Warning(w.clone()));
    }
    'outer: loop {
        // Commands first, so pause/stop act within one step.
        loop {
            let command = if paused {
                match commands.recv_timeout(Duration::from_millis(50)) {
                    Ok(c) => c,
                    Err(RecvTimeoutError::Timeout) if stop.load(Ordering::Relaxed) => break 'outer,
                    Err(RecvTimeoutError::Timeout) => continue,
                    Err(RecvTimeoutError::Disconnected) => break 'outer,
                }
            } else {
                match commands.try_recv() {
                    Ok(c) => c,
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => break 'outer,
                }
            };
            match command {
                TrainCommand::Pause => {
                    paused = true;
                    emit.send(TrainEvent::Paused);
                }
                TrainCommand::Resume => {
                    paused = false;
                    emit.send(TrainEvent::Resumed);
                }
                TrainCommand::Stop => break 'outer,
                TrainCommand::SetFabric(f) => {
                    emit.send(live_outcome(LiveSetting::Fabric, session.set_fabric(*f)));
                }
                TrainCommand::SetWindow(secs) => {
                    let setting = LiveSetting::Window { secs };
                    emit.send(live_outcome(setting, session.set_window(secs)));
                }
            }
        }
        if stop.load(Ordering::Relaxed) {
            break;
        }
        if config.max_steps.is_some_and(|m| step >= m)
            || config.max_secs.is_some_and(|m| trained_secs >= m)
        {
            break;
        }
        let progress =
            super::config::run_progress(step, config.max_steps, trained_secs, config.max_secs);
        let (fraction, final_factor) = config.lr_decay;
        let decay = progress.map_or(1.0, |p| {
            super::config::lr_schedule_factor(p, fraction, final_factor)
        });
        session.set_run_progress(progress);
        let warmup = super::config::warmup_factor(step, config.warmup_steps);
        if progress.is_some() || config.warmup_steps > 0 {
            session.set_schedule_factor(decay * warmup);
        }
        let started = Instant::now();
        let result = session.step();
        trained_secs += started.elapsed().as_secs_f64();
        // Reading every weight back costs a copy of the model, so weights are checked on the
        // snapshot and checkpoint cadence; a non-finite weight shows in the loss soon anyway.
        // On a snapshot step the snapshot's own copy is checked and then sent: one read-back.
        let snapshot_due = (step + 1).is_multiple_of(config.snapshot_every);
        let check_weights = snapshot_due || (step + 1).is_multiple_of(config.checkpoint_every);
        let mut snapshot = None;
        let weights_ok = |snapshot: &mut Option<_>| {
            if !check_weights {
                return true;
            }
            match snapshot_due.then(|| session.snapshot()) {
                Some(Ok(s)) => {
                    let ok = s.weights.validate().is_ok();
                    if ok {
                        *snapshot = Some(s);
                    }
                    ok
                }
                Some(Err(_)) | None => session.weights_finite(),
            }
        };
        let record = match result {
            Ok(mut r) if r.is_finite() && weights_ok(&mut snapshot) => {
                step += 1;
                r.step = step;
                r.wall_secs = trained_secs;
                r
            }
            Ok(_) | Err(_) => {
                // Divergence (or a failed step): go back to the last good weights, lower the rate.
                rollbacks += 1;
                if rollbacks > config.max_rollbacks {
                    return Err(TrainError::Diverged { rollbacks, step });
                }
                let restored =
                    session
                        .restore_last_checkpoint()
                        .map_err(|e| TrainError::RollbackFailed {
                            step,
                            source: Box::new(e),
                        })?;
                let lr = session.learning_rate() * 0.5;
                session.set_learning_rate(lr);
                history.truncate_after(restored);
                emit.send(TrainEvent::RolledBack {
                    diverged_at: step + 1,
                    restored_step: restored,
                    learning_rate: lr,
                });
                step = restored;
                continue;
            }
        };
        if let Some(note) = session.take_note() {
            emit.send(TrainEvent::Note(note));
        }
        history.train.push(record);
        emit.offer(TrainEvent::Step(record));
        if step.is_multiple_of(config.validate_every) {
            let started = Instant::now();
            let mut v = session.validate()?;
            trained_secs += started.elapsed().as_secs_f64();
            v.step = step;
            v.wall_secs = trained_secs;
            history.validation.push(v);
            emit.send(TrainEvent::Validation(v));
            if let Some(reason) =
                stall_reason(&history.validation, config.dead_limit_pct, last_remedy)
            {
                last_remedy = step;
                // The remedy changes weights: a snapshot read before it is stale.
                snapshot = None;
                let remedy = remedy_stall(session)?;
                emit.send(TrainEvent::Stalled {
                    step,
                    reason,
                    remedy,
                });
            }
        }
        if step.is_multiple_of(config.snapshot_every)
            && let Some(weights) = snapshot.map_or_else(|| session.snapshot().ok(), Some)
        {
            let weights = Arc::new(weights);
            last_snapshot = Some((step, weights.clone()));
            emit.offer(TrainEvent::Snapshot { step, weights });
        }
        if step.is_multiple_of(config.checkpoint_every) {
            checkpoint_or_warn(session, step, &history, config.checkpoint_every, emit);
        }
    }
    if history.validation.last().is_none_or(|v| v.step != step)
        && step > 0
        && let Ok(mut v) = session.validate()
    {
        v.step = step;
        v.wall_secs = trained_secs;
        history.validation.push(v);
        emit.send(TrainEvent::Validation(v));
    }
    // The last step's snapshot, when it had one, is these weights: sent again (an offered
    // snapshot may have been dropped) without reading them back a second time.
    let last = match last_snapshot {
        Some((at, weights)) if at == step => Some(weights),
        _ => session.snapshot().ok().map(Arc::new),
    };
    if let Some(weights) = last {
        emit.send(TrainEvent::Snapshot { step, weights });
    }
    let path = session
        .checkpoint(step, &history)
        .map_err(|e| TrainError::FinalCheckpoint {
            step,
            source: Box::new(e),
        })?;
    emit.send(TrainEvent::Checkpoint { step, path });
    let last_validation = history.validation.last().copied();
    let last_train = history.train.last().copied();
    let health = last_validation
        .or(last_train)
        .map(|m| super::health::assess(&m, &super::health::HealthLimits::default()))
        .unwrap_or_default();
    Ok(RunSummary {
        run_dir: config.run_dir,
        steps: step,
        wall_secs: trained_secs,
        last_train,
        last_validation,
        rollbacks,
        health,
    })
}

#[cfg(test)]
#[path = "handle_tests.rs"]
mod tests;
