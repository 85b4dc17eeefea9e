//! Timed training runs for the experiments: a [`neural_cloth_train::session::NeuralSession`] stepped
//! synchronously until a wall-clock budget is spent, with validation passes and weight
//! snapshots spread over the run; and inference over pose sequences with per-frame timing.

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use neural_cloth_core::geometry::Vec3;
use neural_cloth_core::scene::config::SceneConfig;
use neural_cloth_core::scene::{Pose, Scene};
use neural_cloth_model::{
    ClothNet, ClothNetConfig, DescriptorConfig, InferenceEngine, InferenceOptions, ModelArtifact,
};
use neural_cloth_train::handle::Session;
use neural_cloth_train::{
    MetricHistory, MetricRecord, RunLocation, TrainConfig, TrainError, TrainSetup, prepare,
};

use super::ReportError;

/// One training run of an experiment.
#[derive(Clone)]
pub struct RunSpec {
    /// Name in tables and plots.
    pub label: String,
    /// The scene trained on.
    pub scene: Scene,
    /// Its description (`None`: a placeholder is written to the temporary run folder).
    pub config: Option<SceneConfig>,
    /// Training settings.
    pub train: TrainConfig,
    /// Architecture.
    pub model: ClothNetConfig,
    /// Wall-clock budget of the run (steps and validation passes), seconds; >= 0.
    pub budget_secs: f64,
    /// Optimiser steps done whatever the budget; >= 1.
    pub min_steps: u64,
    /// Validation passes spread evenly over the budget (one more at the end); >= 1.
    pub validations: usize,
    /// Fractions of the budget (0..=1) at which the weights are kept for evaluation.
    pub snapshot_fractions: Vec<f64>,
}

/// Weights kept during a run.
#[derive(Clone, Debug)]
pub struct Snapshot {
    /// Seconds of the run when they were taken.
    pub run_secs: f64,
    /// Optimiser step.
    pub step: u64,
    /// The weights, with the settings they were trained with.
    pub weights: ModelArtifact,
}

/// What a run produced.
pub struct RunOutcome {
    /// The run's label.
    pub label: String,
    /// Optimiser steps done.
    pub steps: u64,
    /// Seconds the run took (steps and validation).
    pub run_secs: f64,
    /// Median milliseconds per optimiser step.
    pub step_ms: f64,
    /// Metrics per step (`wall_secs` = seconds into the run) and per validation pass.
    pub history: MetricHistory,
    /// The last validation pass.
    pub validation: MetricRecord,
    /// Weights at each requested fraction (in order; the final weights fill fractions the
    /// run did not reach).
    pub snapshots: Vec<Snapshot>,
    /// Final weights, with the settings they were trained with.
    pub weights: ModelArtifact,
    /// The final network (autodiff CPU device).
    pub model: ClothNet,
    /// True when a step went non-finite and the run stopped there.
    pub diverged: bool,
}

/// A compact record of a run for the results file.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct RunSummary {
    /// Optimiser steps done.
    pub steps: u64,
    /// Seconds the run took.
    pub run_secs: f64,
    /// Median milliseconds per step.
    pub step_ms: f64,
    /// Validation passes.
    pub validation: Vec<MetricRecord>,
    /// True when the run stopped on a non-finite step.
    pub diverged: bool,
}

impl RunOutcome {
    /// The compact record.
    pub fn summary(&self) -> RunSummary {
        RunSummary {
            steps: self.steps,
            run_secs: self.run_secs,
            step_ms: self.step_ms,
            validation: self.history.validation.clone(),
            diverged: self.diverged,
        }
    }
}

static RUN_COUNTER: AtomicUsize = AtomicUsize::new(0);

fn temp_run_dir(label: &str) -> PathBuf {
    let clean: String = label
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .collect();
    let n = RUN_COUNTER.fetch_add(1, Ordering::Relaxed);
    std::env::temp_dir().join(format!(
        "neural-cloth-report-{}-{n}-{clean}",
        std::process::id()
    ))
}

/// Median of `values` (0 when empty).
pub fn median(values: &[f64]) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Trains `spec` until its budget is spent (and at least `min_steps` steps are done).
/// `keep_going(fraction of the budget)` is asked after each step; false cancels. The
/// temporary run folder is removed afterwards.
pub fn train_run(
    spec: RunSpec,
    keep_going: &mut dyn FnMut(f64) -> bool,
) -> Result<RunOutcome, ReportError> {
    let dir = temp_run_dir(&spec.label);
    let _ = std::fs::remove_dir_all(&dir);
    let result = train_in(spec, dir.clone(), keep_going);
    let _ = std::fs::remove_dir_all(&dir);
    result
}

fn train_in(
    spec: RunSpec,
    dir: PathBuf,
    keep_going: &mut dyn FnMut(f64) -> bool,
) -> Result<RunOutcome, ReportError> {
    let RunSpec {
        label,
        scene,
        config,
        train,
        model,
        budget_secs,
        min_steps,
        validations,
        mut snapshot_fractions,
    } = spec;
    let run_err = |e: TrainError| ReportError::Run {
        label: label.clone(),
        reason: e.to_string(),
    };
    let budget = budget_secs.max(0.0);
    let setup = TrainSetup {
        scene,
        scene_config: config.unwrap_or_else(SceneConfig::default_scene),
        train,
        model,
        descriptors: DescriptorConfig::default(),
        location: RunLocation::At(dir),
    };
    let (mut session, _) = prepare(setup)?;
    snapshot_fractions.sort_by(f64::total_cmp);
    let validate_every = budget / validations.max(1) as f64;
    let started = Instant::now();
    let mut history = MetricHistory::default();
    let mut step_times = Vec::new();
    let mut snapshots = Vec::new();
    let (mut steps, mut next_validation, mut diverged) = (0u64, validate_every, false);
    loop {
        let elapsed = started.elapsed().as_secs_f64();
        if steps >= min_steps.max(1) && elapsed >= budget {
            break;
        }
        let t = Instant::now();
        let mut record = session.step().map_err(&run_err)?;
        step_times.push(t.elapsed().as_secs_f64() * 1e3);
        if !record.is_finite() {
            diverged = true;
            break;
        }
        steps += 1;
        let run_secs = started.elapsed().as_secs_f64();
        record.step = steps;
        record.wall_secs = run_secs;
        history.train.push(record);
        while snapshots.len() < snapshot_fractions.len()
            && snapshot_fractions
                .get(snapshots.len())
                .is_some_and(|f| run_secs >= f * budget && *f < 1.0)
        {
            snapshots.push(Snapshot {
                run_secs,
                step: steps,
                weights: session.snapshot().map_err(&run_err)?,
            });
        }
        if run_secs >= next_validation && run_secs < budget {
            let mut v = session.validate().map_err(&run_err)?;
            v.step = steps;
            v.wall_secs = started.elapsed().as_secs_f64();
            history.validation.push(v);
            next_validation += validate_every.max(1e-9);
        }
        if !keep_going((run_secs / budget.max(1e-9)).min(1.0)) {
            return Err(ReportError::Cancelled);
        }
    }
    let mut validation = session.validate().map_err(&run_err)?;
    validation.step = steps;
    validation.wall_secs = started.elapsed().as_secs_f64();
    history.validation.push(validation);
    let weights = session.snapshot().map_err(&run_err)?;
    let run_secs = started.elapsed().as_secs_f64();
    while snapshots.len() < snapshot_fractions.len() {
        snapshots.push(Snapshot {
            run_secs,
            step: steps,
            weights: weights.clone(),
        });
    }
    Ok(RunOutcome {
        label,
        steps,
        run_secs,
        step_ms: median(&step_times),
        history,
        validation,
        snapshots,
        weights,
        model: session.model().clone(),
        diverged,
    })
}

/// Median milliseconds per optimiser step of each spec, measured round-robin: every session
/// is prepared and warmed up by one step, then `rounds` rounds time `steps` steps of each in
/// turn, so that a change of machine load affects all specs alike. `keep_going(fraction)`
/// false cancels. The specs' budgets are ignored.
pub fn interleaved_step_ms(
    specs: &[RunSpec],
    rounds: usize,
    steps: usize,
    keep_going: &mut dyn FnMut(f64) -> bool,
) -> Result<Vec<f64>, ReportError> {
    let dirs: Vec<PathBuf> = specs
        .iter()
        .map(|s| temp_run_dir(&format!("timing-{}", s.label)))
        .collect();
    let result = (|| {
        let mut sessions = Vec::with_capacity(specs.len());
        for (k, (spec, dir)) in specs.iter().zip(&dirs).enumerate() {
            let run_err = |e: TrainError| ReportError::Run {
                label: spec.label.clone(),
                reason: e.to_string(),
            };
            let _ = std::fs::remove_dir_all(dir);
            let setup = TrainSetup {
                scene: spec.scene.clone(),
                scene_config: spec
                    .config
                    .clone()
                    .unwrap_or_else(SceneConfig::default_scene),
                train: spec.train.clone(),
                model: spec.model.clone(),
                descriptors: DescriptorConfig::default(),
                location: RunLocation::At(dir.clone()),
            };
            let (mut session, _) = prepare(setup)?;
            session.step().map_err(run_err)?;
            sessions.push(session);
            if !keep_going(0.3 * (k + 1) as f64 / specs.len().max(1) as f64) {
                return Err(ReportError::Cancelled);
            }
        }
        let mut times: Vec<Vec<f64>> = vec![Vec::new(); specs.len()];
        for round in 0..rounds {
            for ((session, spec), t) in sessions.iter_mut().zip(specs).zip(times.iter_mut()) {
                for _ in 0..steps.max(1) {
                    let started = Instant::now();
                    session.step().map_err(|e| ReportError::Run {
                        label: spec.label.clone(),
                        reason: e.to_string(),
                    })?;
                    t.push(started.elapsed().as_secs_f64() * 1e3);
                }
            }
            if !keep_going(0.3 + 0.7 * (round + 1) as f64 / rounds.max(1) as f64) {
                return Err(ReportError::Cancelled);
            }
        }
        Ok(times.iter().map(|t| median(t)).collect())
    })();
    for dir in &dirs {
        let _ = std::fs::remove_dir_all(dir);
    }
    result
}

/// An engine for `model` on `scene` at the model's training rate: one thread, garment only
/// (no body skinning).
pub fn engine_for(model: &ModelArtifact, scene: &Scene) -> Result<InferenceEngine, ReportError> {
    let options = InferenceOptions {
        threads: 1,
        skin_body: false,
        ..Default::default()
    };
    Ok(model.engine(&scene.avatar, &scene.garment, options)?)
}

/// Garment frames of `poses` (consecutive, at the engine's rate, from a reset state) at
/// dynamic weight `w`.
pub fn predict(
    engine: &mut InferenceEngine,
    poses: &[Pose],
    w: f32,
) -> Result<Vec<Vec<Vec3>>, ReportError> {
    engine.reset();
    let mut out = Vec::with_capacity(poses.len());
    for pose in poses {
        engine.step(pose, w)?;
        out.push(engine.garment_positions().to_vec());
    }
    Ok(out)
}

/// Median milliseconds per frame of `engine` stepping through `poses` (cycled, from a reset
/// state each cycle) for at least `frames` frames after a few warm-up frames.
pub fn time_inference(
    engine: &mut InferenceEngine,
    poses: &[Pose],
    frames: usize,
) -> Result<f64, ReportError> {
    if poses.is_empty() {
        return Err(ReportError::Invalid("no poses to time inference on".into()));
    }
    let mut times = Vec::with_capacity(frames);
    let mut k = 0usize;
    engine.reset();
    while times.len() < frames.max(1) {
        let i = k % poses.len();
        if i == 0 {
            engine.reset();
        }
        let t = Instant::now();
        engine.step(&poses[i], 1.0)?;
        std::hint::black_box(engine.garment_positions());
        if k >= 3 {
            times.push(t.elapsed().as_secs_f64() * 1e3);
        }
        k += 1;
    }
    Ok(median(&times))
}

/// Poses of `motion` sampled at `fps` for `frames` frames from time 0.
pub fn poses_at(motion: &neural_cloth_core::scene::Motion, fps: f32, frames: usize) -> Vec<Pose> {
    (0..frames).map(|k| motion.sample(k as f32 / fps)).collect()
}

/// Mean distance between two frames, metres (0 for empty or mismatched frames).
pub fn mean_distance_m(a: &[Vec3], b: &[Vec3]) -> f64 {
    if a.is_empty() || a.len() != b.len() {
        return 0.0;
    }
    a.iter()
        .zip(b)
        .map(|(p, q)| f64::from((p - q).norm()))
        .sum::<f64>()
        / a.len() as f64
}

/// Largest distance between two frames, metres.
pub fn max_distance_m(a: &[Vec3], b: &[Vec3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| f64::from((p - q).norm()))
        .fold(0.0, f64::max)
}
