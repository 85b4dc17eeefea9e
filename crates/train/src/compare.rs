//! "Check against simulation": a trained run against the reference simulator on the same
//! motion — same garment, fabric, effects and body, at the run's training frame rate.
//!
//! Per motion:
//! - **distance**: every vertex of every frame of the network's output to the simulator's,
//!   pooled mean and 95th percentile (mm), over all frames, the still frames and the moving
//!   ones;
//! - **still frames** ([`still_frames`]): frame `k` is still when every joint of the body
//!   (world positions, so root translation and turning count) moved slower than
//!   [`CompareOptions::still_speed_m_per_s`] in every frame of the last
//!   [`CompareOptions::still_window_secs`] up to `k`; frames before the first count as still
//!   (the simulator holds the first pose while it settles, the network starts from rest);
//! - **dynamic amplitude** ("how much does it swing"): the mean vertex distance of each frame
//!   from its own quasi-static counterpart — for the network its `w = 0` output on the same
//!   poses, for the simulator a simulation of the same motion with dynamics off (every step
//!   a static solve started from the previous frame);
//! - **quasi-static and motion distance** ([`static_motion_split`]): the network's `w = 0`
//!   answer against the quasi-static simulation, and the network's motion (`w` minus `w = 0`)
//!   against the simulator's (dynamic minus quasi-static): which of the two the distance
//!   comes from, and whether the dynamic branch also corrects the static drape;
//! - **hem radius** for garments whose hem reaches below the hips ([`reaches_below_hips`]):
//!   the mean horizontal distance of the hem vertices (lowest 15 % of the template) from the
//!   vertical axis through the root joint, on still and on moving frames;
//! - **rigid slip and shape** ([`rigid_split`]): the distance and both swings after each
//!   frame's best rigid motion of the whole garment, which a frictionless garment's sliding
//!   over the body makes up much of;
//! - the **state drift** ([`state_drift`]): the network's frames with the GRU state carried
//!   over the whole motion against the same network restarted one training window (and its
//!   burn-in) before each frame, which shows a recurrent state that wanders where training
//!   never took it;
//! - the **one-step check** ([`one_step`], on request): each network frame against one
//!   simulator step from the network's own two previous frames, which says whether the
//!   network's motion obeys the physics frame by frame, and which way physics pushes it;
//! - the **reference spread** ([`reference_spread`], on request): the reference against the
//!   same simulation at twice the iterations, whether the reference is converged;
//! - the **reference sensitivity** ([`reference_sensitivity`], on request): the reference
//!   against the same simulation from a start moved by a micrometre, whether the motion is
//!   predictable at all (a loose garment on a fast turn can slip at one frame or another);
//! - the paper's §4.2 **metrics** of both sequences (as `eval`).
//!
//! The reference is simulated with the report's reference settings (200 L-BFGS iterations per
//! frame, tolerance 1e-6) after settling on the first pose, and cached under `RUN/reference/`
//! (see [`reference_for`]).

mod cache;
mod drift;
mod measure;
mod one_step;
mod record;
mod rigid;
mod rows;
mod split;
mod spread;

pub use cache::{
    REFERENCE_TOLERANCE, Reference, SimulatedScene, reference_dir, reference_for, simulation_for,
    simulation_in,
};
pub use drift::{StateDrift, drift_window_frames, state_drift};
pub use measure::{
    Amplitude, AmplitudeStats, DistanceStats, HEM_BAND, HemComparison, HemPair, MotionMeasures,
    Sequences, compare_frames, distance_stats, hem_radius_m, hem_vertices, joint_speeds_m_per_s,
    mean_where, measure_motion, reaches_below_hips, still_frames,
};
pub use one_step::{OneStep, TURNING_DEG_PER_FRAME, one_step, turn_about_vertical};
pub use record::{TrainingCheck, append_checks, read_checks};
pub use rigid::{RigidFit, RigidSplit, best_rigid_fit, rigid_split};
pub use rows::{MeasureRow, MetricRow};
pub use split::{StaticMotionSplit, static_motion_split};
pub use spread::{
    ReferenceSpread, SENSITIVITY_JITTER_M, reference_sensitivity, reference_spread, spread_between,
};

use std::path::PathBuf;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use neural_cloth_core::geometry::Vec3;
use neural_cloth_core::scene::config::Split;
use neural_cloth_core::scene::{MIRRORED_NAME_SUFFIX, Motion, Pose};
use neural_cloth_model::ModelError;
use neural_cloth_physics::metrics::sequence_metrics;
use neural_cloth_physics::{ClothMetrics, StaticTerms};
use neural_cloth_physics::{PhysicsError, PhysicsTerms, PosedBody};

use super::config::ConfigError;
use super::metrics::MetricRecord;
use super::trained::TrainedModel;
use super::{BackendKind, TrainError, device_for};

/// Settings of a comparison.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct CompareOptions {
    /// Dynamic weight of the network, 0..=2; default 1 (as trained).
    pub w: f32,
    /// L-BFGS iterations per frame of the reference simulation, 1..=10000; default 200.
    pub iterations: usize,
    /// Seconds the simulator holds the first pose before the motion, 0..=5; default 3. Long
    /// enough to come to rest: after 0.5 s the built-in skirt is still swinging in from its
    /// flared template (hem radius 0.136 m, against 0.170 m at rest after 3 s; its
    /// quasi-static solve 0.168 m), so a shorter settle compares with a transient.
    pub settle_secs: f32,
    /// Joint speed below which the body counts as still, m/s, > 0; default 0.1.
    pub still_speed_m_per_s: f32,
    /// How long the body must have been below that speed, seconds, 0..=10; default 0.5.
    pub still_window_secs: f32,
    /// Read and write the reference cache under `RUN/reference/`; default true.
    pub use_cache: bool,
    /// Measure the GRU state's drift ([`state_drift`]; costs about one play of the motion
    /// per frame of a training window); default true.
    pub drift: bool,
    /// Check each network frame against one simulator step from the network's own history
    /// ([`one_step`]; at `w = 1` only; costs about one simulation of the motion); default
    /// false.
    pub one_step: bool,
    /// Also simulate each motion with twice the iterations and report how far the two
    /// simulations are apart ([`reference_spread`]: whether the reference is converged; a
    /// network's distance to an unconverged one means little; costs about two references
    /// more); default false.
    pub spread: bool,
    /// Also simulate each motion from the settled garment moved by at most
    /// [`SENSITIVITY_JITTER_M`] per coordinate and report how far it is from the reference
    /// ([`reference_sensitivity`]: a motion whose simulation forks on such a change cannot be
    /// matched frame by frame by any model; costs about one reference more); default false.
    pub sensitivity: bool,
    /// Largest change of each coordinate of the reference's settled garment before the
    /// motion plays, metres ([`neural_cloth_physics::simulator::SimOptions::start_jitter_m`]),
    /// 0..=0.01; default 0. The sensitivity check sets it; a reference has none.
    pub start_jitter_m: f64,
}

impl Default for CompareOptions {
    fn default() -> Self {
        Self {
            w: 1.0,
            iterations: 200,
            settle_secs: 3.0,
            still_speed_m_per_s: 0.1,
            still_window_secs: 0.5,
            use_cache: true,
            drift: true,
            one_step: false,
            spread: false,
            sensitivity: false,
            start_jitter_m: 0.0,
        }
    }
}

impl CompareOptions {
    /// Checks every field against its documented range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let check = |ok: bool, field: &'static str, value: String, range: &'static str| match ok {
            true => Ok(()),
            false => Err(ConfigError {
                field,
                value,
                range,
            }),
        };
        check(
            (0.0..=2.0).contains(&self.w),
            "compare.w",
            self.w.to_string(),
            "0..=2",
        )?;
        check(
            (1..=10_000).contains(&self.iterations),
            "compare.iterations",
            self.iterations.to_string(),
            "1..=10000",
        )?;
        check(
            (0.0..=5.0).contains(&self.settle_secs),
            "compare.settle_secs",
            self.settle_secs.to_string(),
            "0..=5 s",
        )?;
        check(
            self.still_speed_m_per_s.is_finite() && self.still_speed_m_per_s > 0.0,
            "compare.still_speed_m_per_s",
            self.still_speed_m_per_s.to_string(),
            "> 0 m/s",
        )?;
        check(
            (0.0..=10.0).contains(&self.still_window_secs),
            "compare.still_window_secs",
            self.still_window_secs.to_string(),
            "0..=10 s",
        )?;
        check(
            (0.0..=0.01).contains(&self.start_jitter_m),
            "compare.start_jitter_m",
            self.start_jitter_m.to_string(),
            "0..=0.01 m",
        )
    }
}

/// What a comparison is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ComparePhase {
    /// Simulating the reference (not cached yet).
    Simulating,
    /// Simulating the quasi-static reference (dynamics off).
    SimulatingStatic,
    /// Playing the network at `w` and at `w = 0`.
    Network,
    /// Replaying the network in training windows ([`state_drift`]).
    Drift,
    /// Stepping the simulator from the network's frames ([`one_step`]).
    OneStep,
    /// Measuring.
    Metrics,
}

impl ComparePhase {
    /// Share of one motion's work before and after this phase.
    fn span(self) -> (f64, f64) {
        match self {
            Self::Simulating => (0.0, 0.45),
            Self::SimulatingStatic => (0.45, 0.9),
            Self::Network => (0.9, 0.91),
            Self::Drift => (0.91, 0.94),
            Self::OneStep => (0.94, 0.97),
            Self::Metrics => (0.97, 1.0),
        }
    }

    /// Words for progress bars.
    pub fn label(self) -> &'static str {
        match self {
            Self::Simulating => "simulating the reference",
            Self::SimulatingStatic => "simulating the quasi-static reference",
            Self::Network => "playing the network",
            Self::Drift => "replaying the network in training windows",
            Self::OneStep => "stepping the simulator from the network's frames",
            Self::Metrics => "measuring",
        }
    }
}

/// Progress of [`compare`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CompareProgress {
    /// Motion being compared.
    pub motion: String,
    /// Its index among the motions compared.
    pub motion_index: usize,
    /// Motions compared in all.
    pub motions: usize,
    /// What is being done.
    pub phase: ComparePhase,
    /// Units done of the phase (frames).
    pub done: usize,
    /// Units of the phase.
    pub total: usize,
}

impl CompareProgress {
    /// Share of the whole comparison done, 0..=1.
    pub fn fraction(&self) -> f64 {
        let (a, b) = self.phase.span();
        let within = self.done as f64 / self.total.max(1) as f64;
        ((self.motion_index as f64 + a + (b - a) * within.min(1.0)) / self.motions.max(1) as f64)
            .clamp(0.0, 1.0)
    }
}

/// The §4.2 metrics of both sides (means over the frames, inertia from the third frame on).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MetricPair {
    /// The network.
    pub network: MetricRecord,
    /// The simulator.
    pub simulator: MetricRecord,
}

/// The training objective of one side term by term, joules: means over all frames, the
/// dynamic terms counting 0 on the first two (no history), so the terms sum to that side's
/// `loss` in [`MetricPair`]. Each side is scored from its own previous frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ObjectiveTerms {
    /// The static terms (in-plane, bending, collision, gravity).
    #[serde(flatten)]
    pub fixed: StaticTerms,
    /// Inertia.
    pub inertia_j: f64,
    /// Friction.
    pub friction_j: f64,
}

impl ObjectiveTerms {
    /// The sum of the terms: the training objective (pinning left out).
    pub fn total(&self) -> f64 {
        self.fixed.total() + self.inertia_j + self.friction_j
    }

    /// Each term with its row label.
    pub fn named(&self) -> [(&'static str, f64); 6] {
        [
            ("objective: in-plane, J", self.fixed.cloth_j),
            ("objective: bending, J", self.fixed.bending_j),
            ("objective: collision, J", self.fixed.collision_j),
            ("objective: gravity, J", self.fixed.gravity_j),
            ("objective: inertia, J", self.inertia_j),
            ("objective: friction, J", self.friction_j),
        ]
    }

    /// Mean over `frames` of each term.
    fn mean_of(frames: &[ClothMetrics]) -> Self {
        let n = frames.len().max(1) as f64;
        let mut sum = Self::default();
        for m in frames {
            let t = m.static_terms.unwrap_or_default();
            sum.fixed.cloth_j += t.cloth_j / n;
            sum.fixed.bending_j += t.bending_j / n;
            sum.fixed.collision_j += t.collision_j / n;
            sum.fixed.gravity_j += t.gravity_j / n;
            sum.inertia_j += m.inertia_j.unwrap_or(0.0) / n;
            sum.friction_j += m.friction_j.unwrap_or(0.0) / n;
        }
        sum
    }
}

/// The training objective of both sides, term by term.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ObjectivePair {
    /// The network.
    pub network: ObjectiveTerms,
    /// The simulator.
    pub simulator: ObjectiveTerms,
}

/// Where the reference came from.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ReferenceInfo {
    /// The cached simulation file.
    pub path: PathBuf,
    /// True when read from the cache.
    pub cached: bool,
    /// Seconds spent simulating (0 when cached).
    pub simulate_secs: f64,
}

/// The comparison of one motion.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MotionComparison {
    /// Motion name.
    pub name: String,
    /// Distances, amplitude and hem.
    #[serde(flatten)]
    pub measures: MotionMeasures,
    /// The paper's metrics of both sides.
    pub metrics: MetricPair,
    /// The training objective of both sides, term by term (absent in records made before
    /// it existed: zeros).
    #[serde(default)]
    pub objective: ObjectivePair,
    /// The reference simulation.
    pub reference: ReferenceInfo,
}

/// Result of [`compare`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CompareReport {
    /// The run folder.
    pub run: PathBuf,
    /// Checkpoint step of the network.
    pub step: u64,
    /// Garment name.
    pub garment: String,
    /// Garment vertices.
    pub vertices: usize,
    /// Training frame rate the motions play at, fps.
    pub fps: f32,
    /// True when the hem radius is measured (the garment reaches below the hips).
    pub below_hips: bool,
    /// The settings used.
    pub options: CompareOptions,
    /// Per motion.
    pub motions: Vec<MotionComparison>,
}

/// Mean §4.2 metrics of `frames` (inertia averaged from the third frame on, as `eval`), with
/// `loss` the mean training objective of the frames: static energies (pinning left out),
/// plus inertia and friction from the third frame on, each side from its own previous
/// frames; so the two sides' values compare as minima on still poses only.
pub fn sequence_mean_metrics(
    terms: &PhysicsTerms,
    frames: &[Vec<Vec3>],
    bodies: Option<&[Arc<PosedBody>]>,
    fps: f32,
    cloth_model: neural_cloth_physics::ClothModel,
) -> Result<(MetricRecord, ObjectiveTerms), TrainError> {
    let per_frame = sequence_metrics(terms, frames, bodies, 1.0 / fps)?;
    let records: Vec<MetricRecord> = per_frame
        .iter()
        .map(|m| {
            let objective = m.static_energy_j.unwrap_or(0.0)
                + m.inertia_j.unwrap_or(0.0)
                + m.friction_j.unwrap_or(0.0);
            MetricRecord::from_metrics(cloth_model, m, objective)
        })
        .collect();
    let mut mean = MetricRecord::mean(&records);
    let with_inertia: Vec<f64> = per_frame.iter().filter_map(|m| m.inertia_j).collect();
    mean.inertia = with_inertia.iter().sum::<f64>() / with_inertia.len().max(1) as f64;
    Ok((mean, ObjectiveTerms::mean_of(&per_frame)))
}

/// The motions to check: the one named (or the mirror image of the one named without
/// [`MIRRORED_NAME_SUFFIX`], the name [`Motion::mirrored`] gives it), else every validation motion.
fn pick_motions(trained: &TrainedModel, name: Option<&str>) -> Result<Vec<Motion>, TrainError> {
    let scene = &trained.scene;
    let by_name = |wanted: &str| {
        scene
            .motions
            .iter()
            .map(|(m, _)| m)
            .find(|m| m.name == wanted)
    };
    let picked: Vec<Motion> = match name {
        Some(name) => match by_name(name) {
            Some(m) => vec![m.clone()],
            None => name
                .strip_suffix(MIRRORED_NAME_SUFFIX)
                .and_then(by_name)
                .map(|m| m.mirrored(&scene.avatar.skeleton))
                .into_iter()
                .collect(),
        },
        None => scene.motions_in(Split::Validation).cloned().collect(),
    };
    if picked.is_empty() {
        let names: Vec<&str> = scene.motions.iter().map(|(m, _)| m.name.as_str()).collect();
        return Err(TrainError::Data(match name {
            Some(name) => format!(
                "unknown motion '{name}' (the scene has: {}; any of them also as \"NAME{MIRRORED_NAME_SUFFIX}\", its left/right mirror image)",
                names.join(", ")
            ),
            None => "the scene has no motion in the validation split; name one".into(),
        }));
    }
    Ok(picked)
}

/// Compares the trained network of `trained` with the reference simulator on the motion
/// named `motion` (every validation motion when `None`). `progress` sees every simulated and
/// played frame; returning false cancels (a [`PhysicsError::Cancelled`] error).
pub fn compare(
    trained: &TrainedModel,
    motion: Option<&str>,
    options: &CompareOptions,
    progress: &mut dyn FnMut(CompareProgress) -> bool,
) -> Result<CompareReport, TrainError> {
    options.validate()?;
    let motions = pick_motions(trained, motion)?;
    let fps = trained.meta.training_fps;
    let device = device_for(BackendKind::Cpu, false);
    let scene = &trained.scene;
    let terms = PhysicsTerms::new(&scene.garment, &scene.fabric, &scene.effects, &device)?;
    let count = motions.len();
    let mut out = Vec::with_capacity(count);
    for (index, motion) in motions.into_iter().enumerate() {
        let motion = motion.resample(fps).map_err(ModelError::from)?;
        let mut say = |phase: ComparePhase, done: usize, total: usize| {
            progress(CompareProgress {
                motion: motion.name.clone(),
                motion_index: index,
                motions: count,
                phase,
                done,
                total,
            })
        };
        out.push(compare_motion(trained, &motion, &terms, options, &mut say)?);
    }
    Ok(CompareReport {
        run: trained.run.root.clone(),
        step: trained.step,
        garment: scene.garment.name.clone(),
        vertices: scene.garment.vertex_count(),
        fps,
        below_hips: reaches_below_hips(&scene.avatar, &scene.garment),
        options: options.clone(),
        motions: out,
    })
}

/// Garment positions per frame.
type Frames = Vec<Vec<Vec3>>;

/// The network's frames on `poses` at `w` and at `w = 0`.
fn play_network(
    trained: &TrainedModel,
    poses: &[Pose],
    w: f32,
    say: &mut dyn FnMut(ComparePhase, usize, usize) -> bool,
) -> Result<(Frames, Frames), TrainError> {
    let mut engine = trained.garment_engine()?;
    let total = 2 * poses.len();
    let mut passes = Vec::with_capacity(2);
    for (pass, weight) in [w, 0.0].into_iter().enumerate() {
        engine.reset();
        let mut frames = Vec::with_capacity(poses.len());
        for pose in poses {
            engine.step(pose, weight)?;
            frames.push(engine.garment_positions().to_vec());
            let done = pass * poses.len() + frames.len();
            if !say(ComparePhase::Network, done, total) {
                return Err(PhysicsError::Cancelled { frames: done }.into());
            }
        }
        passes.push(frames);
    }
    let quiet = passes.pop().unwrap_or_default();
    let dynamic = passes.pop().unwrap_or_default();
    Ok((dynamic, quiet))
}

/// Compares one motion already resampled to the training rate.
fn compare_motion(
    trained: &TrainedModel,
    motion: &Motion,
    terms: &PhysicsTerms,
    options: &CompareOptions,
    say: &mut dyn FnMut(ComparePhase, usize, usize) -> bool,
) -> Result<MotionComparison, TrainError> {
    let scene = &trained.scene;
    let fps = motion.fps;
    let reference = reference_for(trained, motion, options, say)?;
    let (network, network_static) = play_network(trained, &motion.frames, options.w, say)?;
    let recurrent = trained.meta.model.encoder != neural_cloth_model::EncoderKind::StaticOnly;
    let drift = match options.drift && recurrent && options.w > 0.0 {
        true => Some(state_drift(
            trained,
            &motion.frames,
            options.w,
            &network,
            drift_window_frames(trained),
            say,
        )?),
        false => None,
    };
    // Only the frames as trained are meant to follow the physics (w = 0 and w = 2 are not).
    let bodies = trained.bodies_of(motion)?;
    let checked = match options.one_step && options.w == 1.0 {
        true => one_step(
            trained,
            motion,
            &network,
            bodies.as_deref(),
            options.iterations,
            say,
        )?,
        false => None,
    };
    if !say(ComparePhase::Metrics, 0, 1) {
        return Err(PhysicsError::Cancelled {
            frames: motion.frames.len(),
        }
        .into());
    }
    let still = still_frames(
        &scene.avatar,
        &motion.frames,
        fps,
        options.still_speed_m_per_s,
        options.still_window_secs,
    );
    let mut measures = measure_motion(
        &scene.avatar,
        &scene.garment,
        &motion.frames,
        &still,
        &Sequences {
            network: &network,
            network_static: &network_static,
            simulator: &reference.dynamic,
            simulator_static: &reference.quasi_static,
        },
    )?;
    measures.drift = drift;
    measures.one_step = checked;
    // The reference against other simulations of the motion, each when asked for.
    let dynamic = &reference.dynamic;
    measures.spread = options
        .spread
        .then(|| reference_spread(trained, motion, options, dynamic, say))
        .transpose()?;
    measures.sensitivity = options
        .sensitivity
        .then(|| reference_sensitivity(trained, motion, options, dynamic, say))
        .transpose()?;
    let model = scene.fabric.cloth_model;
    let (mut network_metrics, network_objective) =
        sequence_mean_metrics(terms, &network, bodies.as_deref(), fps, model)?;
    network_metrics.step = trained.step;
    let (simulator_metrics, simulator_objective) =
        sequence_mean_metrics(terms, &reference.dynamic, bodies.as_deref(), fps, model)?;
    say(ComparePhase::Metrics, 1, 1);
    Ok(MotionComparison {
        name: motion.name.clone(),
        measures,
        metrics: MetricPair {
            network: network_metrics,
            simulator: simulator_metrics,
        },
        objective: ObjectivePair {
            network: network_objective,
            simulator: simulator_objective,
        },
        reference: ReferenceInfo {
            path: reference.path,
            cached: reference.cached,
            simulate_secs: reference.simulate_secs,
        },
    })
}
