//! Baking a whole motion with the reference simulator.

use std::sync::Arc;

use burn::tensor::Device;

use crate::collision::PosedBody;
use crate::rest::GarmentRest;
use crate::{Effects, FabricParams, PhysicsError};
use neural_cloth_core::geometry::Vec3;
use neural_cloth_core::scene::{Avatar, Garment, Motion};

use super::{FrameReport, SimOptions, StepInput, Stepper};

/// A baked sequence with its per-frame reports.
#[derive(Clone, Debug, Default)]
pub struct Simulation {
    /// Garment positions per output frame.
    pub frames: Vec<Vec<Vec3>>,
    /// Per output frame, the report of its last step.
    pub reports: Vec<FrameReport>,
    /// Output frame rate.
    pub fps: f32,
}

/// Progress of [`simulate`]: output frame `frame` of `total` is done.
#[derive(Clone, Copy, Debug)]
pub struct SimProgress {
    /// Output frames done.
    pub frame: usize,
    /// Output frames in total.
    pub total: usize,
    /// Report of that frame.
    pub report: FrameReport,
}

/// Bakes `garment` on `avatar` playing `motion` at `fps` with the reference simulator.
/// `progress` is called after each output frame; returning `false` cancels.
#[allow(clippy::too_many_arguments)]
pub fn simulate(
    avatar: &Avatar,
    garment: &Garment,
    fabric: &FabricParams,
    effects: &Effects,
    motion: &Motion,
    fps: f32,
    options: &SimOptions,
    device: &Device,
    progress: &mut dyn FnMut(&SimProgress) -> bool,
) -> Result<Simulation, PhysicsError> {
    options.validate()?;
    fabric.validate()?;
    if !(fps.is_finite() && (1.0..=1000.0).contains(&fps)) {
        return Err(PhysicsError::InvalidOptions(format!(
            "frame rate {fps} is not in [1, 1000]"
        )));
    }
    let rest = Arc::new(GarmentRest::from_garment(garment, fabric)?);
    let steps_per_frame = options.substeps;
    let dt = 1.0 / (fps * steps_per_frame as f32);
    let total = (motion.duration_secs() * fps + 1e-3).floor() as usize + 1;
    let settle_steps = (options.settle_secs / dt).round() as usize;
    let first = motion.sample(0.0);
    let initial = garment.pose_vertices(avatar, &first);
    let initial_count = initial.len();
    let mut stepper = Stepper::new(rest, fabric, effects, &initial, dt, options, device)?;
    let mut cached: Option<(neural_cloth_core::scene::Pose, Arc<PosedBody>)> = None;
    let mut input_at = |time: f32| -> Result<StepInput, PhysicsError> {
        let pose = motion.sample(time);
        let body = if effects.collision {
            match &cached {
                Some((p, b)) if *p == pose => Some(b.clone()),
                _ => {
                    let b = Arc::new(PosedBody::from_avatar(avatar, &pose)?);
                    cached = Some((pose.clone(), b.clone()));
                    Some(b)
                }
            }
        } else {
            None
        };
        let pinned = effects.pinning && !garment.pinned.is_empty();
        let skinned = (pinned || !effects.dynamics).then(|| garment.pose_vertices(avatar, &pose));
        let pin_targets = if pinned { skinned.clone() } else { None };
        Ok(StepInput {
            body,
            pin_targets,
            skinned: (!effects.dynamics).then_some(skinned).flatten(),
            body_before: None,
        })
    };
    for _ in 0..settle_steps {
        stepper.step(&input_at(0.0)?)?;
    }
    if options.start_jitter_m > 0.0 {
        stepper.displace(&start_jitter(initial_count, options.start_jitter_m))?;
    }
    let mut sim = Simulation {
        fps,
        ..Default::default()
    };
    for frame in 0..total {
        let mut last = FrameReport::default();
        for sub in 0..steps_per_frame {
            let time = (frame as f32 - 1.0 + (sub + 1) as f32 / steps_per_frame as f32) / fps;
            let (_, report) = stepper.step(&input_at(time.max(0.0))?)?;
            last = report;
        }
        sim.frames.push(stepper.positions());
        sim.reports.push(last);
        if !progress(&SimProgress {
            frame: frame + 1,
            total,
            report: last,
        }) {
            return Err(PhysicsError::Cancelled { frames: frame + 1 });
        }
    }
    Ok(sim)
}

/// Offsets of `vertices` vertices with every coordinate in `[-amplitude_m, amplitude_m]`,
/// pseudo-random but the same on every call (SplitMix64 of the coordinate's index): the
/// start jitter of [`SimOptions::start_jitter_m`].
pub fn start_jitter(vertices: usize, amplitude_m: f64) -> Vec<Vec3> {
    let unit = |i: u64| {
        let mut z = i.wrapping_add(1).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        // The top 53 bits as a fraction in [0, 1), mapped to [-1, 1).
        2.0 * ((z >> 11) as f64 / (1u64 << 53) as f64) - 1.0
    };
    (0..vertices as u64)
        .map(|v| {
            let c = |k: u64| (amplitude_m * unit(3 * v + k)) as f32;
            Vec3::new(c(0), c(1), c(2))
        })
        .collect()
}

/// The garment after `settle_secs` of simulation on `avatar`'s held rest pose (a one-frame
/// still motion, `iterations` L-BFGS iterations per step at `fps` steps per second): the
/// settled positions, checked finite. The warm start's drape and garment fitting's relax.
#[allow(clippy::too_many_arguments)]
pub fn settle_on_rest_pose(
    avatar: &Avatar,
    garment: &Garment,
    fabric: &FabricParams,
    effects: &Effects,
    settle_secs: f32,
    fps: f32,
    iterations: usize,
    device: &Device,
) -> Result<Vec<Vec3>, PhysicsError> {
    let still = Motion::still("rest", avatar.skeleton.rest_pose(), fps, 1);
    let options = SimOptions {
        iterations_per_step: iterations,
        settle_secs,
        ..Default::default()
    };
    let sim = simulate(
        avatar,
        garment,
        fabric,
        effects,
        &still,
        fps,
        &options,
        device,
        &mut |_| true,
    )?;
    match sim.frames.into_iter().last() {
        Some(frame) if frame.iter().all(|p| p.iter().all(|c| c.is_finite())) => Ok(frame),
        _ => Err(PhysicsError::NonFinite("settled garment".into())),
    }
}
