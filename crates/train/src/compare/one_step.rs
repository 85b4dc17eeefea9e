//! One step of physics from the network's own history: how far each frame of the network is
//! from the reference simulator's step taken from the network's two previous frames (same
//! body, pins, fabric and effects, the comparison's L-BFGS budget).
//!
//! Zero means the network's motion obeys the physics frame by frame (the simulator's own
//! frames give zero, to the solver's tolerance). A network far from the simulator's
//! trajectory but near its one-step solutions follows the physics from a different state
//! (another equilibrium, or a drift that each step allows); one whose frames are far from
//! their one-step solutions has not learnt the physics. Where the body turns, the step's turn
//! of the garment about the vertical axis says which way physics pushes: docs/TRAINING.md
//! round 12 found every skirt run's steps turning the skirt back against the body's spin
//! (more lag than the network learnt), and more so the less lag a run has.

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use neural_cloth_core::geometry::Vec3;
use neural_cloth_core::scene::{Motion, Pose, Skeleton};
use neural_cloth_physics::simulator::{SimOptions, StepInput, Stepper};
use neural_cloth_physics::{GarmentRest, PhysicsError, PosedBody};

use super::super::trained::TrainedModel;
use super::super::{BackendKind, TrainError, device_for};
use super::{ComparePhase, REFERENCE_TOLERANCE, best_rigid_fit};

/// The network's frames against one simulator step from their own history, over frames
/// `2..` of a motion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct OneStep {
    /// Frames measured (every frame from the third on).
    pub frames: usize,
    /// Mean vertex distance from the step's solution to the network's frame, mm.
    pub mean_mm: f64,
    /// The same after each frame's best rigid motion (the reshaping the step asks for), mm.
    pub shape_mm: f64,
    /// Mean height the step adds, mm (positive: physics lifts the garment higher than the
    /// network has it).
    pub height_mm: f64,
    /// Mean turn the step adds about the vertical axis, degrees, signed along the body's own
    /// turn over the frames where the body turns faster than [`TURNING_DEG_PER_FRAME`]
    /// (negative: physics holds the garment further back than the network does); `None`
    /// when the body does not turn.
    pub turn_deg: Option<f64>,
}

/// The body turns in a frame when its root turns by more than this about the vertical,
/// degrees.
pub const TURNING_DEG_PER_FRAME: f64 = 0.1;

/// Angle about +Y (the vertical) of the root joint's forward axis, radians.
fn root_yaw(skeleton: &Skeleton, pose: &Pose) -> f64 {
    skeleton
        .world_from_joint(pose)
        .first()
        .map_or(0.0, |m| f64::from(m[(0, 2)]).atan2(f64::from(m[(2, 2)])))
}

/// The rotation about +Y (radians) that best takes `from` onto `to` after centring each,
/// the same vertices in the same order (0 for empty, degenerate or unequal frames).
pub fn turn_about_vertical(from: &[Vec3], to: &[Vec3]) -> f64 {
    if from.len() != to.len() || from.is_empty() {
        return 0.0;
    }
    let n = from.len() as f32;
    let centre = |ps: &[Vec3]| ps.iter().fold(Vec3::zeros(), |s, p| s + p) / n;
    let (cf, ct) = (centre(from), centre(to));
    let (mut s, mut c) = (0.0f64, 0.0f64);
    for (a, b) in from.iter().zip(to) {
        let (a, b) = (a - cf, b - ct);
        s += f64::from(a.z * b.x - a.x * b.z);
        c += f64::from(a.x * b.x + a.z * b.z);
    }
    if s == 0.0 && c == 0.0 {
        0.0
    } else {
        s.atan2(c)
    }
}

/// `angle` wrapped into (-π, π].
fn wrap(angle: f64) -> f64 {
    let a = angle.rem_euclid(std::f64::consts::TAU);
    if a > std::f64::consts::PI {
        a - std::f64::consts::TAU
    } else {
        a
    }
}

/// [`OneStep`] of `network` (the network's frames on `motion` at `w = 1`, resampled to the
/// training rate) on `bodies` (the motion's posed bodies, [`TrainedModel::bodies_of`]) with
/// `iterations` L-BFGS iterations per step; `None` when there is nothing
/// to check: fewer than three frames, or a scene without dynamics (whose steps are static
/// solves, with no history to take). `say` sees the frames done; returning false cancels.
pub fn one_step(
    trained: &TrainedModel,
    motion: &Motion,
    network: &[Vec<Vec3>],
    bodies: Option<&[Arc<PosedBody>]>,
    iterations: usize,
    say: &mut dyn FnMut(ComparePhase, usize, usize) -> bool,
) -> Result<Option<OneStep>, TrainError> {
    let scene = &trained.scene;
    let poses = &motion.frames;
    let n = poses.len().min(network.len());
    if n < 3 || !scene.effects.dynamics {
        return Ok(None);
    }
    let device = device_for(BackendKind::Cpu, false);
    let rest = Arc::new(GarmentRest::from_garment(&scene.garment, &scene.fabric)?);
    let options = SimOptions {
        iterations_per_step: iterations,
        tolerance: REFERENCE_TOLERANCE,
        ..SimOptions::default()
    };
    let mut stepper = Stepper::new(
        rest,
        &scene.fabric,
        &scene.effects,
        &network[0],
        1.0 / motion.fps,
        &options,
        &device,
    )?;
    let pinned = scene.effects.pinning && !scene.garment.pinned.is_empty();
    let skeleton = &scene.avatar.skeleton;
    let (mut sum_mm, mut shape_mm, mut height_mm) = (0.0f64, 0.0f64, 0.0f64);
    let (mut turn_deg, mut turning) = (0.0f64, 0usize);
    for t in 2..n {
        stepper.set_history(&network[t - 2], &network[t - 1])?;
        let body = |k: usize| bodies.and_then(|b| b.get(k).cloned());
        let input = StepInput {
            body: body(t),
            body_before: body(t - 1),
            pin_targets: pinned.then(|| scene.garment.pose_vertices(&scene.avatar, &poses[t])),
            skinned: None,
        };
        let (stepped, _) = stepper.step(&input)?;
        let frame = &network[t];
        let count = stepped.len().min(frame.len()).max(1) as f64;
        let (mut d, mut dy) = (0.0f64, 0.0f64);
        for (a, b) in stepped.iter().zip(frame) {
            d += f64::from((a - b).norm());
            dy += f64::from(a.y - b.y);
        }
        sum_mm += 1e3 * d / count;
        height_mm += 1e3 * dy / count;
        shape_mm += best_rigid_fit(frame, &stepped).map_or(0.0, |f| 1e3 * f.residual_m);
        let body_turn = wrap(root_yaw(skeleton, &poses[t]) - root_yaw(skeleton, &poses[t - 1]));
        if body_turn.abs().to_degrees() > TURNING_DEG_PER_FRAME {
            turn_deg += body_turn.signum() * turn_about_vertical(frame, &stepped).to_degrees();
            turning += 1;
        }
        if !say(ComparePhase::OneStep, t - 1, n - 2) {
            return Err(PhysicsError::Cancelled { frames: t + 1 }.into());
        }
    }
    let frames = n - 2;
    Ok(Some(OneStep {
        frames,
        mean_mm: sum_mm / frames as f64,
        shape_mm: shape_mm / frames as f64,
        height_mm: height_mm / frames as f64,
        turn_deg: (turning > 0).then(|| turn_deg / turning as f64),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring(angle: f64, shift: Vec3) -> Vec<Vec3> {
        (0..12)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / 12.0 + angle;
                Vec3::new(
                    (0.3 * a.sin()) as f32,
                    0.1 * (k % 3) as f32,
                    (0.3 * a.cos()) as f32,
                ) + shift
            })
            .collect()
    }

    #[test]
    fn the_turn_about_the_vertical_is_the_angle_between_rotated_copies() {
        let a = ring(0.0, Vec3::zeros());
        for angle in [-2.0, -0.3, 0.0, 0.25, 1.5] {
            let b = ring(angle, Vec3::new(0.5, -0.2, 0.1));
            let found = turn_about_vertical(&a, &b);
            assert!((found - angle).abs() < 1e-5, "{found} against {angle}");
        }
        assert_eq!(turn_about_vertical(&[], &[]), 0.0);
        assert_eq!(turn_about_vertical(&a, &a[1..]), 0.0, "unequal frames");
        let point = vec![Vec3::new(0.1, 0.2, 0.3); 4];
        assert_eq!(turn_about_vertical(&point, &point), 0.0);
    }

    #[test]
    fn the_root_yaw_turns_with_the_root_about_the_vertical() {
        use neural_cloth_core::geometry::Quat;
        let avatar = neural_cloth_core::scene::procedural::mannequin().unwrap();
        let skeleton = &avatar.skeleton;
        let rest = skeleton.rest_pose();
        let at_rest = root_yaw(skeleton, &rest);
        for angle in [-1.0f32, 0.4, 2.5] {
            let mut turned = rest.clone();
            turned.rotations[0] = Quat::from_axis_angle(&Vec3::y_axis(), angle) * rest.rotations[0];
            let found = wrap(root_yaw(skeleton, &turned) - at_rest);
            assert!(
                (found - f64::from(angle)).abs() < 1e-5,
                "{found} against {angle}"
            );
            // The garment turned with the root turns the same way.
            let ring0 = ring(0.0, Vec3::zeros());
            let ring1 = ring(f64::from(angle), Vec3::zeros());
            assert!((turn_about_vertical(&ring0, &ring1) - found).abs() < 1e-5);
        }
    }

    #[test]
    fn wrapped_angles_stay_within_half_a_turn() {
        use std::f64::consts::PI;
        assert!((wrap(2.0 * PI - 0.1) + 0.1).abs() < 1e-12);
        assert!((wrap(-2.0 * PI + 0.1) - 0.1).abs() < 1e-12);
        assert!((wrap(0.3) - 0.3).abs() < 1e-12);
        assert!((wrap(PI) - PI).abs() < 1e-12);
    }
}
