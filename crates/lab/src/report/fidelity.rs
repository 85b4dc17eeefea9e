//! Fidelity experiments (paper §4.4–4.6) on a small built-in skirt with a fixed seed:
//!
//! - the Tab. 2 ablation: entangled encoder, disentangled, + pose mirroring, + motion
//!   augmentation, each trained for the same time; metrics on the validation motion;
//! - SNUG-style inertia (gradients into the past frames) against ours on the spin: the mean
//!   radius of the skirt's hem about the body's vertical axis, with the static prediction
//!   (`w = 0`) and the reference simulator for comparison;
//! - disentanglement: a still body gives `z_D = 0` exactly (network and engine) and an output
//!   that neither changes over time nor with `w`; the garment's displacement from the static
//!   prediction on a spin frame as `w` goes from 0 to 2; the decay of `z_D` after the body
//!   stops.

use std::time::Instant;

use burn::module::Module;
use burn::tensor::{Tensor, TensorData};
use serde::{Deserialize, Serialize};

use neural_cloth_core::geometry::Vec3;
use neural_cloth_model::{DescriptorConfig, DescriptorExtractor, EncoderKind};
use std::sync::Arc;

use neural_cloth_core::scene::config::{
    AvatarSource, BuiltinAvatar, Effects, GarmentSource, MotionSource, SceneConfig, Split,
};
use neural_cloth_core::scene::procedural::{GarmentKind, MotionKind, build_builtin};
use neural_cloth_core::scene::{Pose, Scene};
use neural_cloth_physics::simulator::{SimOptions, StepInput, Stepper};
use neural_cloth_physics::{FabricParams, GarmentRest, PosedBody};
use neural_cloth_train::compare::{hem_radius_m, hem_vertices};
use neural_cloth_train::{BackendKind, InertiaMode, MetricRecord, TrainConfig, device_for};

use super::runs::{
    RunOutcome, RunSpec, RunSummary, engine_for, max_distance_m, mean_distance_m, poses_at,
    predict, train_run,
};
use super::{Progress, ProgressFn, ReportError};

/// Settings of the fidelity experiments.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FidelityOptions {
    /// Wall-clock budget, seconds; > 0.
    pub budget_secs: f64,
    /// Skirt vertex count, 200..=500000.
    pub resolution: usize,
    /// Duration of the spin motion, seconds (> 1).
    pub spin_secs: f32,
    /// Seed of every run.
    pub seed: u64,
}

/// One row of the ablation table.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct AblationRow {
    /// "Entangled", "Disentangled", "+Mirror", "+Aug. motions".
    pub label: String,
    /// Metrics of the last validation pass.
    pub validation: MetricRecord,
    /// The run.
    pub run: RunSummary,
}

/// The disentanglement checks.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct Disentanglement {
    /// Frames of the still body.
    pub still_frames: usize,
    /// Largest |z_D| of the network (burn) on the still body's real descriptors (`None`
    /// without a dynamic branch).
    pub zd_max_network: Option<f32>,
    /// Largest |z_D| of the inference engine over the still frames.
    pub zd_max_engine: f32,
    /// Largest vertex displacement over the still frames and across `w` in {0, 1, 2}, mm.
    pub still_change_mm: f64,
    /// Time of the spin frame of the sweep, seconds.
    pub sweep_time_secs: f32,
    /// The `w` values of the sweep.
    pub w: Vec<f32>,
    /// Mean displacement from the static prediction (`w = 0`) at each `w`, mm.
    pub displacement_mm: Vec<f64>,
    /// True when the displacement never decreases and ends above its start.
    pub monotone: bool,
    /// Seconds after the body stops (mid-spin) and |z_D| (L2 norm) there.
    pub decay: Vec<(f32, f32)>,
    /// |z_S| (L2) at the sweep frame (absent in results written before it was recorded).
    #[serde(default)]
    pub zs_norm: Option<f32>,
}

/// Hem radius under the spin.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct SkirtSpin {
    /// Frame times, seconds.
    pub times: Vec<f32>,
    /// Hem radius per frame for ours, metres.
    pub ours_m: Vec<f32>,
    /// SNUG-style.
    pub snug_m: Vec<f32>,
    /// Our static prediction (`w = 0`).
    pub static_m: Vec<f32>,
    /// The SNUG-style network's static prediction (`w = 0`).
    pub snug_static_m: Vec<f32>,
    /// The template skinned with the body (no network offsets), the drape-free baseline.
    pub skinned_m: Vec<f32>,
    /// The reference simulator (may stop early when over budget).
    pub reference_m: Vec<f32>,
    /// Iterations per frame of the reference.
    pub reference_iterations: usize,
    /// The averaging window, seconds.
    pub window_secs: (f32, f32),
    /// Mean hem radius over the window, ours, metres.
    pub mean_ours_m: f64,
    /// SNUG-style.
    pub mean_snug_m: f64,
    /// Our static prediction.
    pub mean_static_m: f64,
    /// The SNUG-style network's static prediction.
    pub mean_snug_static_m: f64,
    /// The skinned template.
    pub mean_skinned_m: f64,
    /// Reference simulator (`None` when it did not reach the window within the budget).
    pub mean_reference_m: Option<f64>,
    /// Hem vertices used.
    pub hem_vertices: usize,
    /// The ours run.
    pub ours_run: RunSummary,
    /// The SNUG-style run.
    pub snug_run: RunSummary,
    /// Seconds of the spin the reference simulator reached (it stops when over budget).
    pub reference_until_secs: f32,
}

/// Everything the fidelity experiments measured.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FidelityResult {
    /// Garment vertices.
    pub vertices: usize,
    /// Training motions and the validation motion.
    pub motions: String,
    /// Seconds of each ablation run.
    pub ablation_run_secs: f64,
    /// Seconds of the ours and SNUG-style runs.
    pub spin_run_secs: f64,
    /// The ablation, Tab. 2 order.
    pub ablation: Vec<AblationRow>,
    /// Disentanglement checks on the "ours" model (the "+Aug. motions" setup, trained longer).
    pub disentanglement: Disentanglement,
    /// SNUG-style against ours on the spin.
    pub skirt: SkirtSpin,
    /// Seconds the experiments took.
    pub elapsed_secs: f64,
}

/// The fidelity scene: built-in skirt at `resolution`, idle/walk/spin to train, turn to
/// validate.
pub fn fidelity_scene(
    resolution: usize,
    spin_secs: f32,
) -> Result<(Scene, SceneConfig), ReportError> {
    let m = |builtin, duration_secs, split| MotionSource::Builtin {
        builtin,
        duration_secs,
        speed: 1.0,
        fps: None,
        split,
        name: None,
        mirrored: false,
    };
    let config = SceneConfig {
        name: "fidelity skirt".into(),
        avatar: AvatarSource::Builtin {
            builtin: BuiltinAvatar::Mannequin,
        },
        garment: GarmentSource::Builtin {
            builtin: GarmentKind::Skirt,
            resolution,
            smoothing_passes: None,
        },
        motions: vec![
            m(MotionKind::Idle, 2.0, Split::Train),
            m(MotionKind::Walk, 3.0, Split::Train),
            m(MotionKind::Spin, spin_secs, Split::Train),
            m(MotionKind::Turn, 3.2, Split::Validation),
        ],
        effects: Effects::default(),
        fabric: FabricParams::default(),
        training_fps: neural_cloth_core::scene::config::DEFAULT_TRAINING_FPS,
    };
    Ok((build_builtin(&config)?, config))
}

/// Mean of `values` at `times` inside `window`; `None` when no frame falls inside.
fn window_mean(times: &[f32], values: &[f32], window: (f32, f32)) -> Option<f64> {
    let picked: Vec<f64> = times
        .iter()
        .zip(values)
        .filter(|(t, _)| **t >= window.0 && **t <= window.1)
        .map(|(_, v)| f64::from(*v))
        .collect();
    (!picked.is_empty()).then(|| picked.iter().sum::<f64>() / picked.len() as f64)
}

/// The reference simulator over `poses` (after settling 0.5 s on the first), stopping early
/// when `budget_secs` is spent.
fn reference_spin(
    scene: &Scene,
    poses: &[Pose],
    fps: f32,
    iterations: usize,
    budget_secs: f64,
    progress: &mut ProgressFn<'_>,
) -> Result<Vec<Vec<Vec3>>, ReportError> {
    let started = Instant::now();
    let Some(first) = poses.first() else {
        return Ok(Vec::new());
    };
    let fabric = scene.fabric.clone();
    let rest = Arc::new(GarmentRest::from_garment(&scene.garment, &fabric)?);
    let options = SimOptions {
        iterations_per_step: iterations,
        ..SimOptions::default()
    };
    let device = device_for(BackendKind::Cpu, false);
    let initial = scene.garment.pose_vertices(&scene.avatar, first);
    let mut stepper = Stepper::new(
        rest,
        &fabric,
        &scene.effects,
        &initial,
        1.0 / fps,
        &options,
        &device,
    )?;
    let input = |pose: &Pose| -> Result<StepInput, ReportError> {
        let body = match scene.effects.collision {
            true => Some(Arc::new(PosedBody::from_avatar(&scene.avatar, pose)?)),
            false => None,
        };
        let pinned = scene.effects.pinning && !scene.garment.pinned.is_empty();
        let quasi_static = !scene.effects.dynamics;
        let skinned =
            (pinned || quasi_static).then(|| scene.garment.pose_vertices(&scene.avatar, pose));
        Ok(StepInput {
            body,
            pin_targets: if pinned { skinned.clone() } else { None },
            skinned: if quasi_static { skinned } else { None },
            body_before: None,
        })
    };
    let settle = input(first)?;
    for _ in 0..(0.5 * fps).round() as usize {
        stepper.step(&settle)?;
    }
    let mut frames = Vec::with_capacity(poses.len());
    for (k, pose) in poses.iter().enumerate() {
        if started.elapsed().as_secs_f64() >= budget_secs {
            break;
        }
        frames.push(stepper.step(&input(pose)?)?.0);
        let fraction = 0.88 + 0.12 * (k + 1) as f64 / poses.len() as f64;
        if !progress(&Progress {
            phase: "fidelity".into(),
            fraction,
            detail: "reference simulation of the spin".into(),
        }) {
            return Err(ReportError::Cancelled);
        }
    }
    Ok(frames)
}

/// Runs the ablation, the SNUG comparison and the disentanglement checks within
/// `options.budget_secs`. `progress` sees 0..1; returning false cancels.
pub fn run_fidelity(
    options: &FidelityOptions,
    progress: &mut ProgressFn<'_>,
) -> Result<FidelityResult, ReportError> {
    let started = Instant::now();
    let (scene, config) = fidelity_scene(options.resolution, options.spin_secs)?;
    let fps = scene.training_fps;
    // Four ablation runs share 44% of the budget, ours and SNUG-style (longer, so that
    // dynamics have time to appear) 44%; the reference spin and the checks get the rest.
    let ablation_budget = 0.44 * options.budget_secs / 4.0;
    let spin_budget = 0.44 * options.budget_secs / 2.0;
    let base = TrainConfig {
        seed: options.seed,
        batch_size: 16,
        window_secs: 0.5,
        ..TrainConfig::default()
    };
    let variants: [(&str, EncoderKind, bool, f32, InertiaMode, f64); 6] = [
        (
            "Entangled",
            EncoderKind::Entangled,
            false,
            0.0,
            InertiaMode::Ours,
            ablation_budget,
        ),
        (
            "Disentangled",
            EncoderKind::Disentangled,
            false,
            0.0,
            InertiaMode::Ours,
            ablation_budget,
        ),
        (
            "+Mirror",
            EncoderKind::Disentangled,
            true,
            0.0,
            InertiaMode::Ours,
            ablation_budget,
        ),
        (
            "+Aug. motions",
            EncoderKind::Disentangled,
            true,
            0.2,
            InertiaMode::Ours,
            ablation_budget,
        ),
        (
            "ours",
            EncoderKind::Disentangled,
            true,
            0.2,
            InertiaMode::Ours,
            spin_budget,
        ),
        (
            "SNUG-style inertia",
            EncoderKind::Disentangled,
            true,
            0.2,
            InertiaMode::Snug,
            spin_budget,
        ),
    ];
    let total: f64 = variants.iter().map(|v| v.5).sum::<f64>().max(1e-9);
    let mut outcomes: Vec<RunOutcome> = Vec::new();
    let mut start = 0.0;
    for (label, encoder, mirror, aug, inertia, budget_secs) in variants {
        let spec = RunSpec {
            label: label.into(),
            scene: scene.clone(),
            config: Some(config.clone()),
            train: TrainConfig {
                mirror_poses: mirror,
                augmentation_fraction: aug,
                inertia_mode: inertia,
                ..base.clone()
            },
            model: neural_cloth_model::ClothNetConfig {
                encoder,
                ..Default::default()
            },
            budget_secs,
            min_steps: 2,
            validations: 8,
            snapshot_fractions: Vec::new(),
        };
        let span = 0.88 * budget_secs / total;
        let run = train_run(spec, &mut |f| {
            progress(&Progress {
                phase: "fidelity".into(),
                fraction: start + span * f,
                detail: format!("training '{label}'"),
            })
        })?;
        start += span;
        outcomes.push(run);
    }
    let (Some(ours), Some(snug)) = (outcomes.get(4), outcomes.get(5)) else {
        return Err(ReportError::Invalid("fidelity runs missing".into()));
    };
    let ablation = outcomes
        .iter()
        .take(4)
        .map(|o| AblationRow {
            label: o.label.clone(),
            validation: o.validation,
            run: o.summary(),
        })
        .collect();
    let disentanglement = disentangle(&scene, ours, fps)?;
    if !progress(&Progress {
        phase: "fidelity".into(),
        fraction: 0.88,
        detail: "skirt under the spin".into(),
    }) {
        return Err(ReportError::Cancelled);
    }
    let left = (options.budget_secs - started.elapsed().as_secs_f64()).max(1.0);
    let skirt = skirt_spin(&scene, ours, snug, fps, left, progress)?;
    Ok(FidelityResult {
        vertices: scene.garment.vertex_count(),
        motions: "train: idle, walk, spin (+ mirrored); validation: turn".into(),
        ablation_run_secs: ablation_budget,
        spin_run_secs: spin_budget,
        ablation,
        disentanglement,
        skirt,
        elapsed_secs: started.elapsed().as_secs_f64(),
    })
}

fn spin_motion(scene: &Scene) -> Result<&neural_cloth_core::scene::Motion, ReportError> {
    scene
        .motions
        .iter()
        .map(|(m, _)| m)
        .find(|m| m.name == MotionKind::Spin.name())
        .ok_or_else(|| ReportError::Invalid("no spin motion".into()))
}

fn disentangle(scene: &Scene, ours: &RunOutcome, fps: f32) -> Result<Disentanglement, ReportError> {
    let spin = spin_motion(scene)?;
    let still_frames = 30usize;
    let still_pose = spin.sample(0.5 * spin.duration_secs());
    let still: Vec<Pose> = vec![still_pose.clone(); still_frames];
    // The network on the still body's real descriptors.
    let mut extractor =
        DescriptorExtractor::new(&scene.avatar.skeleton, &DescriptorConfig::default(), fps)?;
    let desc = extractor.poses(&still)?;
    let device = ours
        .model
        .devices()
        .into_iter()
        .next()
        .unwrap_or_else(|| device_for(BackendKind::Cpu, true));
    let dynamic = Tensor::<4>::from_data(
        TensorData::new(desc.dynamic_desc.clone(), [1, desc.frames, desc.joints, 12]),
        &device,
    );
    let zd_max_network = ours
        .model
        .encode_dynamic(dynamic, None)
        .map(|z| z.abs().max().into_scalar::<f32>());
    // The engine on the same frames at w = 0, 1, 2.
    let mut engine = engine_for(&ours.weights, scene)?;
    let mut zd_max_engine = 0.0f32;
    let mut first: Option<Vec<Vec3>> = None;
    let mut still_change_mm = 0.0f64;
    for w in [0.0, 1.0, 2.0] {
        engine.reset();
        for pose in &still {
            engine.step(pose, w)?;
            zd_max_engine = engine
                .dynamic_code()
                .iter()
                .fold(zd_max_engine, |m, v| m.max(v.abs()));
            let x = engine.garment_positions();
            match &first {
                Some(f) => still_change_mm = still_change_mm.max(1e3 * max_distance_m(f, x)),
                None => first = Some(x.to_vec()),
            }
        }
    }
    // The w sweep on a spin frame at full speed.
    let frame = ((0.5 * spin.duration_secs() * fps).round() as usize).max(1);
    let poses = poses_at(spin, fps, frame + 1);
    let w: Vec<f32> = (0..=10).map(|k| k as f32 * 0.2).collect();
    let mut outputs = Vec::with_capacity(w.len());
    for &wk in &w {
        let frames = predict(&mut engine, &poses, wk)?;
        outputs.push(frames.last().cloned().unwrap_or_default());
    }
    let static_out = outputs.first().cloned().unwrap_or_default();
    let displacement_mm: Vec<f64> = outputs
        .iter()
        .map(|x| 1e3 * mean_distance_m(x, &static_out))
        .collect();
    let monotone = displacement_mm.windows(2).all(|p| p[1] >= p[0])
        && displacement_mm
            .last()
            .zip(displacement_mm.first())
            .is_some_and(|(l, f)| l > f);
    // Decay of z_D after the body stops mid-spin.
    let mut decay = Vec::new();
    engine.reset();
    for pose in &poses {
        engine.step(pose, 1.0)?;
    }
    let norm = |z: &[f32]| z.iter().map(|v| v * v).sum::<f32>().sqrt();
    decay.push((0.0, norm(engine.dynamic_code())));
    let zs_norm = Some(norm(engine.static_code()));
    let hold = poses.last().cloned().unwrap_or(still_pose);
    for k in 1..=(2.0 * fps).round() as usize {
        engine.step(&hold, 1.0)?;
        if k % ((0.25 * fps).round() as usize).max(1) == 0 {
            decay.push((k as f32 / fps, norm(engine.dynamic_code())));
        }
    }
    Ok(Disentanglement {
        still_frames,
        zd_max_network,
        zd_max_engine,
        still_change_mm,
        sweep_time_secs: frame as f32 / fps,
        w,
        displacement_mm,
        monotone,
        zs_norm,
        decay,
    })
}

fn skirt_spin(
    scene: &Scene,
    ours: &RunOutcome,
    snug: &RunOutcome,
    fps: f32,
    budget_secs: f64,
    progress: &mut ProgressFn<'_>,
) -> Result<SkirtSpin, ReportError> {
    let spin = spin_motion(scene)?;
    let frames = (spin.duration_secs() * fps).floor() as usize + 1;
    let poses = poses_at(spin, fps, frames);
    let times: Vec<f32> = (0..frames).map(|k| k as f32 / fps).collect();
    let hem = hem_vertices(&scene.garment);
    let radii = |xs: &[Vec<Vec3>]| -> Vec<f32> {
        xs.iter()
            .zip(&poses)
            .map(|(x, p)| hem_radius_m(&scene.avatar, p, x, &hem))
            .collect()
    };
    let mut engine = engine_for(&ours.weights, scene)?;
    let ours_m = radii(&predict(&mut engine, &poses, 1.0)?);
    let static_m = radii(&predict(&mut engine, &poses, 0.0)?);
    let mut snug_engine = engine_for(&snug.weights, scene)?;
    let snug_m = radii(&predict(&mut snug_engine, &poses, 1.0)?);
    let snug_static_m = radii(&predict(&mut snug_engine, &poses, 0.0)?);
    let skinned: Vec<Vec<Vec3>> = poses
        .iter()
        .map(|p| scene.garment.pose_vertices(&scene.avatar, p))
        .collect();
    let skinned_m = radii(&skinned);
    // The reference simulator up to the end of the window, stopped when the budget is spent.
    let reference_iterations = 40;
    let window = (0.25 * spin.duration_secs(), 0.75 * spin.duration_secs());
    let sim_frames = ((window.1 * fps).ceil() as usize + 1).min(frames);
    let reference_frames = reference_spin(
        scene,
        &poses[..sim_frames.min(poses.len())],
        fps,
        reference_iterations,
        budget_secs,
        progress,
    )?;
    let reference_m = radii(&reference_frames);
    let mean_reference_m = window_mean(&times, &reference_m, window);
    let mean_ours_m = window_mean(&times, &ours_m, window).unwrap_or(f64::NAN);
    let mean_snug_m = window_mean(&times, &snug_m, window).unwrap_or(f64::NAN);
    let mean_static_m = window_mean(&times, &static_m, window).unwrap_or(f64::NAN);
    let mean_snug_static_m = window_mean(&times, &snug_static_m, window).unwrap_or(f64::NAN);
    let mean_skinned_m = window_mean(&times, &skinned_m, window).unwrap_or(f64::NAN);
    Ok(SkirtSpin {
        times,
        ours_m,
        snug_m,
        static_m,
        snug_static_m,
        skinned_m,
        reference_m,
        reference_iterations,
        window_secs: window,
        mean_ours_m,
        mean_snug_m,
        mean_static_m,
        mean_snug_static_m,
        mean_skinned_m,
        mean_reference_m,
        hem_vertices: hem.len(),
        ours_run: ours.summary(),
        snug_run: snug.summary(),
        reference_until_secs: reference_frames.len().saturating_sub(1) as f32 / fps,
    })
}
