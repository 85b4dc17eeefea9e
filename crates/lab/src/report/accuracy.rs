//! Accuracy against time (also the app's "Cost" panel): the reference simulator at several
//! L-BFGS iteration budgets and the neural model after several training durations, each
//! measured against a converged reference simulation of the same motion clip.
//!
//! Error: distance of every vertex of every clip frame to the reference (pooled mean and 95th
//! percentile, mm). Residual: the Eq. 8 objective's gradient at each frame given the method's
//! own two previous frames ([`Stepper::residual_at`]), relative to the mean vertex weight.
//! Cost: wall-clock milliseconds per output frame on one thread — the simulator's solve plus
//! posing the body it collides with; the network's pose-to-garment inference.
//!
//! The simulators settle on the first pose for `settle_secs` before the clip; the network
//! starts from a reset state at the clip's first frame (its still-body output is its drape).

use std::sync::Arc;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use neural_cloth_core::geometry::Vec3;
use neural_cloth_core::scene::config::Split;
use neural_cloth_core::scene::{Motion, Pose, Scene};
use neural_cloth_physics::simulator::{FrameResidual, SimOptions, StepInput, Stepper};
use neural_cloth_physics::{FabricParams, GarmentRest, PosedBody};
use neural_cloth_train::{BackendKind, MetricHistory, TrainConfig, device_for};

use super::runs::{RunSpec, engine_for, poses_at, predict, time_inference, train_run};
use super::{Progress, ProgressFn, ReportError};

/// Settings of the accuracy/time experiment.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CostOptions {
    /// Wall-clock budget of the whole experiment, seconds; > 0, default 120.
    pub budget_secs: f64,
    /// Share of the budget spent training the network, 0..=0.95, default 0.6.
    pub train_share: f64,
    /// Simulator iteration budgets per frame, each 1..=10000; default [1, 2, 5, 10, 20, 50].
    pub sim_iterations: Vec<usize>,
    /// Iterations per frame of the reference, 1..=10000; default 200.
    pub reference_iterations: usize,
    /// Longest clip, seconds; > 0, default 2.
    pub max_clip_secs: f32,
    /// Shortest clip (taken even when over budget), seconds; > 0, default 0.3.
    pub min_clip_secs: f32,
    /// Seconds the simulators hold the first pose before the clip; 0..=5, default 0.2.
    pub settle_secs: f32,
    /// Training durations evaluated, as fractions of the training time; default
    /// [0.125, 0.25, 0.5, 1].
    pub train_fractions: Vec<f64>,
    /// Training settings (the frame rate is the scene's); default: [`TrainConfig::default`].
    pub train: TrainConfig,
    /// Optimiser steps done whatever the budget; default 2.
    pub min_steps: u64,
    /// Seed of the training run; default 0.
    pub seed: u64,
}

impl Default for CostOptions {
    fn default() -> Self {
        Self {
            budget_secs: 120.0,
            train_share: 0.6,
            sim_iterations: vec![1, 2, 5, 10, 20, 50],
            reference_iterations: 200,
            max_clip_secs: 2.0,
            min_clip_secs: 0.3,
            settle_secs: 0.2,
            train_fractions: vec![0.125, 0.25, 0.5, 1.0],
            train: TrainConfig::default(),
            min_steps: 2,
            seed: 0,
        }
    }
}

/// Which kind of solver a point is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// The reference simulator at a given iteration budget.
    Simulator,
    /// The neural model after a given training time.
    Neural,
}

/// How exact a speed-up is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Bound {
    /// Interpolated between two simulator budgets.
    Exact,
    /// The network beats every simulator budget tried: the speed-up is at least this.
    AtLeast,
    /// The cheapest simulator budget is already as accurate: the speed-up is at most this.
    AtMost,
}

/// The network's speed-up over the simulator at equal mean error.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SpeedUp {
    /// Simulator milliseconds per frame at the network's mean error (log-log interpolation).
    pub sim_ms_at_equal_error: f64,
    /// `sim_ms_at_equal_error / neural ms per frame`.
    pub factor: f64,
    /// Exact, or a bound.
    pub bound: Bound,
}

/// One method's cost and accuracy.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CostPoint {
    /// Simulator or network.
    pub method: Method,
    /// Name in tables and plots, e.g. "sim 10 it" or "net 60 s".
    pub label: String,
    /// Simulator: L-BFGS iterations per frame.
    pub iterations: Option<usize>,
    /// Network: seconds of training.
    pub train_secs: Option<f64>,
    /// Network: optimiser steps.
    pub train_steps: Option<u64>,
    /// Milliseconds per output frame.
    pub ms_per_frame: f64,
    /// Mean vertex distance to the reference over the clip, mm.
    pub mean_mm: f64,
    /// 95th percentile of the vertex distances, mm.
    pub p95_mm: f64,
    /// Mean over frames of the RMS Eq. 8 residual (relative to the mean vertex weight).
    pub residual_rms: f64,
    /// Mean over frames of the largest Eq. 8 residual (relative to the mean vertex weight).
    pub residual_max: f64,
    /// Network: speed-up over the simulator at equal mean error.
    pub speedup: Option<SpeedUp>,
}

/// Result of [`run_cost_experiment`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CostResult {
    /// Scene name.
    pub scene: String,
    /// Motion of the clip.
    pub motion: String,
    /// Garment vertices.
    pub vertices: usize,
    /// Frame rate of the clip and of training, fps.
    pub fps: f32,
    /// Frames in the clip.
    pub clip_frames: usize,
    /// Frames the simulators settled before the clip.
    pub settle_frames: usize,
    /// Iterations per frame of the reference.
    pub reference_iterations: usize,
    /// The reference's own residual and cost (its error is 0 by definition).
    pub reference: CostPoint,
    /// Simulator and network points.
    pub points: Vec<CostPoint>,
    /// Training curves of the network's run.
    pub training: MetricHistory,
    /// Median milliseconds per training step.
    pub train_step_ms: f64,
    /// Optimiser steps of the run.
    pub train_steps: u64,
    /// Seconds the experiment took.
    pub elapsed_secs: f64,
}

impl CostResult {
    /// The simulator points, in the order of their iteration budgets.
    pub fn simulator_points(&self) -> impl Iterator<Item = &CostPoint> {
        self.points.iter().filter(|p| p.method == Method::Simulator)
    }

    /// The network points, in the order of their training time.
    pub fn neural_points(&self) -> impl Iterator<Item = &CostPoint> {
        self.points.iter().filter(|p| p.method == Method::Neural)
    }
}

/// The motion of the clip: the first test motion, else validation, else training.
fn clip_motion(scene: &Scene) -> Result<&Motion, ReportError> {
    [Split::Test, Split::Validation, Split::Train]
        .into_iter()
        .find_map(|s| scene.motions_in(s).next())
        .ok_or_else(|| ReportError::Invalid(format!("scene '{}' has no motion", scene.name)))
}

/// Posed bodies and pin targets of each pose, with the mean milliseconds per body.
fn step_inputs(scene: &Scene, poses: &[Pose]) -> Result<(Vec<StepInput>, f64), ReportError> {
    let started = Instant::now();
    let pin = scene.effects.pinning && !scene.garment.pinned.is_empty();
    let mut inputs = Vec::with_capacity(poses.len());
    for pose in poses {
        let body = match scene.effects.collision {
            true => Some(Arc::new(PosedBody::from_avatar(&scene.avatar, pose)?)),
            false => None,
        };
        let quasi_static = !scene.effects.dynamics;
        let skinned =
            (pin || quasi_static).then(|| scene.garment.pose_vertices(&scene.avatar, pose));
        let body_before = inputs.last().and_then(|i: &StepInput| i.body.clone());
        inputs.push(StepInput {
            body,
            pin_targets: if pin { skinned.clone() } else { None },
            skinned: if quasi_static { skinned } else { None },
            body_before,
        });
    }
    Ok((
        inputs,
        started.elapsed().as_secs_f64() * 1e3 / poses.len().max(1) as f64,
    ))
}

/// Everything a simulator run needs.
struct SimContext<'a> {
    scene: &'a Scene,
    rest: Arc<GarmentRest>,
    fabric: FabricParams,
    initial: Vec<Vec3>,
    dt_secs: f32,
    settle: StepInput,
    settle_frames: usize,
    inputs: Vec<StepInput>,
    device: burn::tensor::Device,
}

impl SimContext<'_> {
    fn stepper(&self, iterations: usize) -> Result<Stepper, ReportError> {
        let options = SimOptions {
            iterations_per_step: iterations,
            tolerance: 1e-6,
            ..SimOptions::default()
        };
        Ok(Stepper::new(
            self.rest.clone(),
            &self.fabric,
            &self.scene.effects,
            &self.initial,
            self.dt_secs,
            &options,
            &self.device,
        )?)
    }

    /// Clip frames at `iterations` per frame and the mean solve milliseconds per frame.
    fn run(
        &self,
        iterations: usize,
        keep_going: &mut dyn FnMut() -> bool,
    ) -> Result<(Vec<Vec<Vec3>>, f64), ReportError> {
        let mut stepper = self.stepper(iterations)?;
        for _ in 0..self.settle_frames {
            stepper.step(&self.settle)?;
        }
        let mut frames = Vec::with_capacity(self.inputs.len());
        let mut secs = 0.0;
        for input in &self.inputs {
            let t = Instant::now();
            let (x, _) = stepper.step(input)?;
            secs += t.elapsed().as_secs_f64();
            frames.push(x);
            if !keep_going() {
                return Err(ReportError::Cancelled);
            }
        }
        Ok((frames, secs * 1e3 / self.inputs.len().max(1) as f64))
    }
}

/// Mean over frames `2..` of the Eq. 8 residuals of `frames` (RMS and max), history from the
/// same frames.
fn residuals(
    evaluator: &Stepper,
    frames: &[Vec<Vec3>],
    inputs: &[StepInput],
) -> Result<(f64, f64), ReportError> {
    let mut found: Vec<FrameResidual> = Vec::new();
    for (k, input) in inputs.iter().enumerate().skip(2) {
        let (Some(a), Some(b), Some(x)) = (frames.get(k - 2), frames.get(k - 1), frames.get(k))
        else {
            break;
        };
        found.push(evaluator.residual_at(a, b, x, input)?);
    }
    let n = found.len().max(1) as f64;
    Ok((
        found.iter().map(|r| r.residual_rms).sum::<f64>() / n,
        found.iter().map(|r| r.residual_max).sum::<f64>() / n,
    ))
}

/// Pooled mean and 95th percentile of the vertex distances between `frames` and `reference`, mm.
fn errors_mm(frames: &[Vec<Vec3>], reference: &[Vec<Vec3>]) -> (f64, f64) {
    let mut d: Vec<f64> = frames
        .iter()
        .zip(reference)
        .flat_map(|(f, r)| {
            f.iter()
                .zip(r)
                .map(|(p, q)| 1e3 * f64::from((p - q).norm()))
        })
        .collect();
    if d.is_empty() {
        return (0.0, 0.0);
    }
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    d.sort_by(f64::total_cmp);
    let idx = ((0.95 * (d.len() - 1) as f64).round() as usize).min(d.len() - 1);
    (mean, d[idx])
}

/// Simulator milliseconds per frame at `error_mm`, interpolated log-log along `sims` (in
/// the order of their iteration budgets).
pub fn equal_error_ms(sims: &[(f64, f64)], error_mm: f64, neural_ms: f64) -> Option<SpeedUp> {
    let (first, last) = (sims.first()?, sims.last()?);
    let ln = |v: f64| v.max(1e-12).ln();
    let speed = |ms: f64, bound| SpeedUp {
        sim_ms_at_equal_error: ms,
        factor: ms / neural_ms.max(1e-12),
        bound,
    };
    if first.1 <= error_mm {
        return Some(speed(first.0, Bound::AtMost));
    }
    for pair in sims.windows(2) {
        let [(ms0, e0), (ms1, e1)] = [pair[0], pair[1]];
        if e1 <= error_mm && e0 > error_mm {
            let t = (ln(e0) - ln(error_mm)) / (ln(e0) - ln(e1)).max(1e-12);
            return Some(speed(
                (ln(ms0) + t * (ln(ms1) - ln(ms0))).exp(),
                Bound::Exact,
            ));
        }
    }
    Some(speed(last.0, Bound::AtLeast))
}

/// Runs the accuracy/time experiment on `scene` within `options.budget_secs`: trains the
/// network for `train_share` of it, then sizes the clip so that the reference, the simulator
/// sweep and the evaluation fit in the rest. `progress` sees 0..1; returning false cancels.
pub fn run_cost_experiment(
    scene: &Scene,
    options: &CostOptions,
    progress: &mut ProgressFn<'_>,
) -> Result<CostResult, ReportError> {
    let started = Instant::now();
    let budget_ok = options.budget_secs.is_finite() && options.budget_secs > 0.0;
    if !(budget_ok && (0.0..=0.95).contains(&options.train_share)) {
        return Err(ReportError::Invalid(
            "budget must be positive and train_share in [0, 0.95]".into(),
        ));
    }
    if options
        .sim_iterations
        .iter()
        .chain([&options.reference_iterations])
        .any(|&n| !(1..=10_000).contains(&n))
    {
        return Err(ReportError::Invalid(
            "iteration budgets must be in 1..=10000".into(),
        ));
    }
    let fps = scene.training_fps;
    let motion = clip_motion(scene)?.clone();
    let mut say = |fraction: f64, detail: String| {
        progress(&Progress {
            phase: "accuracy".into(),
            fraction,
            detail,
        })
    };

    // 1. The network, with snapshots at the requested training durations.
    let train_budget = options.train_share * options.budget_secs;
    let train_span = options.train_share;
    let spec = RunSpec {
        label: "default run".into(),
        scene: scene.clone(),
        config: None,
        train: TrainConfig {
            seed: options.seed,
            ..options.train.clone()
        },
        model: Default::default(),
        budget_secs: train_budget,
        min_steps: options.min_steps,
        validations: 12,
        snapshot_fractions: options.train_fractions.clone(),
    };
    let run = train_run(spec, &mut |f| {
        say(
            train_span * f,
            format!("training the network ({:.0}%)", 100.0 * f),
        )
    })?;

    // 2. Size the clip from the measured cost of one solver iteration.
    let fabric = scene.fabric.clone();
    let rest = Arc::new(GarmentRest::from_garment(&scene.garment, &fabric)?);
    let device = device_for(BackendKind::Cpu, false);
    let first = motion.sample(0.0);
    let (settle_inputs, body_ms) = step_inputs(scene, std::slice::from_ref(&first))?;
    let settle = settle_inputs.into_iter().next().unwrap_or_default();
    let settle_frames = (options.settle_secs.clamp(0.0, 5.0) * fps).round() as usize;
    let mut ctx = SimContext {
        scene,
        rest,
        fabric,
        initial: scene.garment.pose_vertices(&scene.avatar, &first),
        dt_secs: 1.0 / fps,
        settle,
        settle_frames,
        inputs: Vec::new(),
        device,
    };
    // The first step pays one-off costs; time the second.
    let mut probe = ctx.stepper(10)?;
    probe.step(&ctx.settle)?;
    let probe_started = Instant::now();
    let (_, report) = probe.step(&ctx.settle)?;
    let secs_per_iteration =
        probe_started.elapsed().as_secs_f64() / report.iterations.max(1) as f64;
    let iterations_per_frame: usize =
        options.sim_iterations.iter().sum::<usize>() + options.reference_iterations;
    let methods = options.sim_iterations.len() + options.train_fractions.len() + 1;
    let left = (options.budget_secs - started.elapsed().as_secs_f64()).max(0.0);
    // Per clip frame: every solve, the residual of every method (about 2 evaluations each),
    // the network's inference and the body; plus the settle frames of every simulator run.
    let per_frame = secs_per_iteration * (1.1 * iterations_per_frame as f64 + 2.0 * methods as f64)
        + body_ms * 1e-3;
    let settle_cost = secs_per_iteration * 1.1 * (settle_frames * iterations_per_frame) as f64;
    let fit = ((left - settle_cost) / per_frame.max(1e-9))
        .floor()
        .max(0.0) as usize;
    let (min_frames, max_frames) = (
        (options.min_clip_secs * fps).ceil() as usize,
        (options.max_clip_secs * fps).floor() as usize,
    );
    let clip_frames = fit
        .clamp(min_frames.max(3), max_frames.max(min_frames.max(3)))
        .min(motion.frame_count().max(3));
    let poses = poses_at(&motion, fps, clip_frames);
    let (inputs, body_ms) = step_inputs(scene, &poses)?;
    ctx.inputs = inputs;
    let evaluator = ctx.stepper(1)?;
    let eval_span = 1.0 - train_span;
    let runs = 1 + options.sim_iterations.len();

    // 3. The reference, then the sweep.
    let at = |run_index: usize, frames_done: usize| {
        let frac =
            (run_index as f64 + frames_done as f64 / clip_frames.max(1) as f64) / (runs + 1) as f64;
        train_span + eval_span * frac.min(1.0)
    };
    let detail = format!(
        "reference simulation ({} iterations per frame)",
        options.reference_iterations
    );
    let mut done = 0usize;
    let (reference, reference_ms) = ctx.run(options.reference_iterations, &mut || {
        done += 1;
        say(at(0, done), detail.clone())
    })?;
    let (res_rms, res_max) = residuals(&evaluator, &reference, &ctx.inputs)?;
    let reference_point = CostPoint {
        method: Method::Simulator,
        label: format!("reference {} it", options.reference_iterations),
        iterations: Some(options.reference_iterations),
        train_secs: None,
        train_steps: None,
        ms_per_frame: reference_ms + body_ms,
        mean_mm: 0.0,
        p95_mm: 0.0,
        residual_rms: res_rms,
        residual_max: res_max,
        speedup: None,
    };
    let mut points = Vec::new();
    let mut sweep: Vec<usize> = options.sim_iterations.clone();
    sweep.sort_unstable();
    sweep.dedup();
    for (k, &iterations) in sweep.iter().enumerate() {
        let detail = format!("simulator at {iterations} iterations per frame");
        let mut done = 0usize;
        let (frames, ms) = ctx.run(iterations, &mut || {
            done += 1;
            say(at(k + 1, done), detail.clone())
        })?;
        let (mean_mm, p95_mm) = errors_mm(&frames, &reference);
        let (residual_rms, residual_max) = residuals(&evaluator, &frames, &ctx.inputs)?;
        points.push(CostPoint {
            method: Method::Simulator,
            label: format!("sim {iterations} it"),
            iterations: Some(iterations),
            train_secs: None,
            train_steps: None,
            ms_per_frame: ms + body_ms,
            mean_mm,
            p95_mm,
            residual_rms,
            residual_max,
            speedup: None,
        });
    }

    // 4. The network at each training duration.
    let sims: Vec<(f64, f64)> = points.iter().map(|p| (p.ms_per_frame, p.mean_mm)).collect();
    for snapshot in &run.snapshots {
        if !say(
            train_span + eval_span * (runs as f64 + 0.5) / (runs + 1) as f64,
            format!("network after {:.0} s", snapshot.run_secs),
        ) {
            return Err(ReportError::Cancelled);
        }
        let mut engine = engine_for(&snapshot.weights, scene)?;
        let frames = predict(&mut engine, &poses, 1.0)?;
        let ms = time_inference(&mut engine, &poses, 60)?;
        let (mean_mm, p95_mm) = errors_mm(&frames, &reference);
        let (residual_rms, residual_max) = residuals(&evaluator, &frames, &ctx.inputs)?;
        points.push(CostPoint {
            method: Method::Neural,
            label: if snapshot.run_secs < 10.0 {
                format!("net {:.1} s", snapshot.run_secs)
            } else {
                format!("net {:.0} s", snapshot.run_secs)
            },
            iterations: None,
            train_secs: Some(snapshot.run_secs),
            train_steps: Some(snapshot.step),
            ms_per_frame: ms,
            mean_mm,
            p95_mm,
            residual_rms,
            residual_max,
            speedup: equal_error_ms(&sims, mean_mm, ms),
        });
    }
    say(1.0, "accuracy done".into());
    Ok(CostResult {
        scene: scene.name.clone(),
        motion: motion.name.clone(),
        vertices: scene.garment.vertex_count(),
        fps,
        clip_frames,
        settle_frames,
        reference_iterations: options.reference_iterations,
        reference: reference_point,
        points,
        training: run.history.clone(),
        train_step_ms: run.step_ms,
        train_steps: run.steps,
        elapsed_secs: started.elapsed().as_secs_f64(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_error_interpolates_and_bounds() {
        let sims = [(1.0, 100.0), (10.0, 10.0), (100.0, 1.0)];
        let s = equal_error_ms(&sims, 10.0f64.sqrt() * 1.0, 0.5).unwrap();
        // Halfway in log error between 10 and 1 mm is halfway in log cost between 10 and 100.
        assert!(
            (s.sim_ms_at_equal_error - 10.0f64.powf(1.5)).abs() < 1e-6,
            "{s:?}"
        );
        assert_eq!(s.bound, Bound::Exact);
        assert!((s.factor - s.sim_ms_at_equal_error / 0.5).abs() < 1e-9);
        assert_eq!(
            equal_error_ms(&sims, 200.0, 1.0).unwrap().bound,
            Bound::AtMost
        );
        assert_eq!(
            equal_error_ms(&sims, 0.5, 1.0).unwrap().bound,
            Bound::AtLeast
        );
        assert!(equal_error_ms(&[], 1.0, 1.0).is_none());
    }

    #[test]
    fn pooled_errors() {
        let a = vec![vec![Vec3::zeros(), Vec3::zeros()]];
        let b = vec![vec![Vec3::new(0.001, 0.0, 0.0), Vec3::new(0.003, 0.0, 0.0)]];
        let (mean, p95) = errors_mm(&a, &b);
        assert!(
            (mean - 2.0).abs() < 1e-4 && (p95 - 3.0).abs() < 1e-4,
            "{mean} {p95}"
        );
    }
}
