//! Procedural motions for the mannequin: smooth joint-rotation curves as functions of time,
//! sampled to a [`Motion`] at any frame rate and duration.
//!
//! Every curve is built for the left side and mirrored onto the right, so the motions are
//! left/right consistent. Walk, run and spin ease in and out over their first and last
//! 0.6 s; idle and turn start at rest with zero velocity; jump repeats a 1.8 s
//! crouch-takeoff-flight-landing cycle that starts and ends at rest, and twirl a 7.6 s cycle
//! that does too (takes of other lengths end mid-cycle).

use std::f32::consts::{PI, TAU};

use serde::{Deserialize, Serialize};

use crate::geometry::{Quat, Vec3};

use super::super::config::Split;
use super::super::skeleton::Pose;
use super::super::{Motion, SceneError};
use super::body::joint::*;
use super::body::{ARM_DROP_RAD, JOINT_COUNT, mirror_joint, rest_joint_positions};

/// Which procedural motion.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MotionKind {
    /// Standing still, breathing and swaying slightly.
    Idle,
    /// Walking forward (+Z) at 1.25 m/s.
    Walk,
    /// Running forward (+Z) at 3.2 m/s.
    Run,
    /// Jumping in place: 0.25 m high, root accelerations up to about 10 m/s².
    Jump,
    /// Turning in place by 180° and back, 1.6 s each way, with small steps.
    Turn,
    /// Spinning about Y at 4π rad/s (two turns per second) with the arms out.
    Spin,
    /// Turning on the spot one way and then the other at changing speeds (up to 2.6 turns
    /// per second), the arms rising and falling: rotations of every speed the spin has, in
    /// a different clip, so that a network trained on it meets fast turns before the spin.
    Twirl,
    /// A range-of-motion clip, as rigging and cloth departments use to test a character: the
    /// arms out, up, forward and one at a time, the elbows bent, the spine bent, leaned and
    /// twisted, each knee raised, one slow move after another (13.8 s cycle, starting and
    /// ending at rest), so that a network trained on it has seen the poses other clips
    /// hold only while moving fast (the spin's arms out).
    Rom,
}

impl MotionKind {
    /// All kinds.
    pub const ALL: [MotionKind; 8] = [
        MotionKind::Idle,
        MotionKind::Walk,
        MotionKind::Run,
        MotionKind::Jump,
        MotionKind::Twirl,
        MotionKind::Rom,
        MotionKind::Turn,
        MotionKind::Spin,
    ];

    /// Name used in configs and as the motion name.
    pub fn name(self) -> &'static str {
        match self {
            MotionKind::Idle => "idle",
            MotionKind::Walk => "walk",
            MotionKind::Run => "run",
            MotionKind::Jump => "jump",
            MotionKind::Turn => "turn",
            MotionKind::Spin => "spin",
            MotionKind::Twirl => "twirl",
            MotionKind::Rom => "rom",
        }
    }

    /// Parses a config name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The split this motion gets in the default scene.
    pub fn default_split(self) -> Split {
        match self {
            MotionKind::Idle
            | MotionKind::Walk
            | MotionKind::Run
            | MotionKind::Jump
            | MotionKind::Twirl
            | MotionKind::Rom => Split::Train,
            MotionKind::Turn => Split::Validation,
            MotionKind::Spin => Split::Test,
        }
    }
}

/// Largest playback speed factor of a built-in motion.
pub const MAX_SPEED: f32 = 10.0;

/// Root angular speed of the spin at full speed, rad/s.
pub const SPIN_RAD_PER_SEC: f32 = 4.0 * PI;
/// Ease-in/out time of walk, run and spin, seconds.
const RAMP_SECS: f32 = 0.6;
/// Gravity used for the jump's flight phase, m/s².
const GRAVITY: f32 = 9.81;

fn rx(a: f32) -> Quat {
    Quat::from_axis_angle(&Vec3::x_axis(), a)
}
fn ry(a: f32) -> Quat {
    Quat::from_axis_angle(&Vec3::y_axis(), a)
}
fn rz(a: f32) -> Quat {
    Quat::from_axis_angle(&Vec3::z_axis(), a)
}

/// The rotation's image under the reflection `x -> -x`.
fn mirror_rotation(q: &Quat) -> Quat {
    let c = q.coords;
    Quat::new_unchecked(nalgebra::Quaternion::new(c.w, c.x, -c.y, -c.z))
}

fn smoothstep(u: f32) -> f32 {
    let u = u.clamp(0.0, 1.0);
    u * u * (3.0 - 2.0 * u)
}

/// Ease-in/out envelope: 0 at both ends, 1 in the middle, C1 smooth.
fn envelope(t: f32, duration: f32) -> f32 {
    let r = RAMP_SECS.min(0.5 * duration);
    if r <= 0.0 {
        return 1.0;
    }
    smoothstep(t / r).min(smoothstep((duration - t) / r))
}

/// `∫_0^t envelope`, in closed form (the integral of smoothstep is `u³ - u⁴/2`).
fn envelope_integral(t: f32, duration: f32) -> f32 {
    let r = RAMP_SECS.min(0.5 * duration);
    if r <= 0.0 {
        return t.max(0.0);
    }
    let f = |u: f32| {
        let u = u.clamp(0.0, 1.0);
        u * u * u - 0.5 * u * u * u * u
    };
    let t = t.clamp(0.0, duration);
    if t <= r {
        r * f(t / r)
    } else if t <= duration - r {
        0.5 * r + (t - r)
    } else {
        0.5 * r + (duration - 2.0 * r) + r * (0.5 - f((duration - t) / r))
    }
}

/// Periodic Gaussian bump of width `w` centred at phase `c` (phases in cycles).
fn bump(p: f32, c: f32, w: f32) -> f32 {
    let d = (p - c + 0.5).rem_euclid(1.0) - 0.5;
    (-(d / w) * (d / w)).exp()
}

/// Cubic Hermite interpolation through `(time, value, slope)` keys, clamped at the ends.
fn hermite(keys: &[(f32, f32, f32)], t: f32) -> f32 {
    let (Some(first), Some(last)) = (keys.first(), keys.last()) else {
        return 0.0;
    };
    if t <= first.0 {
        return first.1;
    }
    if t >= last.0 {
        return last.1;
    }
    for w in keys.windows(2) {
        let ((t0, v0, s0), (t1, v1, s1)) = (w[0], w[1]);
        if t <= t1 && t1 > t0 {
            let dt = t1 - t0;
            let u = (t - t0) / dt;
            let (u2, u3) = (u * u, u * u * u);
            return (2.0 * u3 - 3.0 * u2 + 1.0) * v0
                + (u3 - 2.0 * u2 + u) * dt * s0
                + (-2.0 * u3 + 3.0 * u2) * v1
                + (u3 - u2) * dt * s1;
        }
    }
    last.1
}

/// Knee flexion (rad) that shortens the hip-ankle distance by `drop_m`.
fn leg_bend(drop_m: f32) -> f32 {
    if drop_m.is_nan() || drop_m <= 0.0 {
        return 0.0;
    }
    let p = rest_joint_positions();
    let thigh = (p[LEFT_LEG] - p[LEFT_UP_LEG]).norm();
    let shin = (p[LEFT_FOOT] - p[LEFT_LEG]).norm();
    let l = (thigh + shin - drop_m.max(0.0)).max(0.3);
    let c = (l * l - thigh * thigh - shin * shin) / (2.0 * thigh * shin);
    c.clamp(-1.0, 1.0).acos()
}

/// Local rotations and root translation under construction.
struct PoseBuilder {
    rotations: [Quat; JOINT_COUNT],
    root: Vec3,
}

impl PoseBuilder {
    fn new() -> Self {
        Self {
            rotations: [Quat::identity(); JOINT_COUNT],
            root: rest_joint_positions()[HIPS],
        }
    }

    /// Sets a left joint to `left` and its right counterpart to the mirror of `right`
    /// (the left-side rotation the right joint would have if it were on the left).
    fn pair(&mut self, left_joint: usize, left: Quat, right: Quat) {
        self.rotations[left_joint] = left;
        self.rotations[mirror_joint(left_joint)] = mirror_rotation(&right);
    }

    fn finish(self) -> Pose {
        Pose {
            rotations: self.rotations.to_vec(),
            root_translation: self.root,
        }
    }
}

/// Legs and arms of a gait for the left side at cycle phase `p` (right side: `p + 0.5`).
struct Gait {
    hip_flex: [f32; 3],
    knee_stance: f32,
    knee_swing: f32,
    arm_swing: f32,
    elbow: [f32; 2],
}

fn gait_side(g: &Gait, p: f32, e: f32) -> [Quat; 5] {
    let c = (TAU * p).cos();
    let hip = e * (g.hip_flex[0] + g.hip_flex[1] * c);
    let knee =
        e * (g.knee_stance * bump(p, 0.12, 0.08) + g.knee_swing * bump(p, g.hip_flex[2], 0.12));
    let ankle = 0.5 * (hip - knee) + e * 0.2 * bump(p, 0.55, 0.08);
    let arm = e * g.arm_swing * (TAU * (p + 0.5)).cos();
    let elbow = e * (g.elbow[0] + g.elbow[1] * (1.0 + (TAU * (p + 0.5)).cos()));
    [rx(-hip), rx(knee), rx(ankle), rx(-arm), rx(-elbow)]
}

fn apply_gait(b: &mut PoseBuilder, g: &Gait, phase: f32, e: f32) {
    let l = gait_side(g, phase, e);
    let r = gait_side(g, phase + 0.5, e);
    for (k, joint) in [LEFT_UP_LEG, LEFT_LEG, LEFT_FOOT, LEFT_ARM, LEFT_FORE_ARM]
        .into_iter()
        .enumerate()
    {
        b.pair(joint, l[k], r[k]);
    }
}

fn walk_or_run(t: f32, duration: f32, run: bool) -> Pose {
    let e = envelope(t, duration);
    let (period, speed) = if run { (0.72, 3.2) } else { (1.1, 1.25) };
    let gait = if run {
        Gait {
            hip_flex: [0.1, 0.5, 0.62],
            knee_stance: 0.45,
            knee_swing: 1.6,
            arm_swing: 0.45,
            elbow: [1.2, 0.08],
        }
    } else {
        Gait {
            hip_flex: [0.05, 0.33, 0.7],
            knee_stance: 0.18,
            knee_swing: 1.0,
            arm_swing: 0.28,
            elbow: [0.3, 0.06],
        }
    };
    let phase = t / period;
    let mut b = PoseBuilder::new();
    apply_gait(&mut b, &gait, phase, e);
    let twist = (TAU * phase).cos();
    b.rotations[HIPS] = ry(-e * 0.07 * twist);
    b.rotations[SPINE] = rx(e * if run { 0.15 } else { 0.04 });
    b.rotations[SPINE2] = ry(e * 0.10 * twist);
    let (bob, base) = if run { (0.035, 0.03) } else { (0.01, 0.01) };
    b.root += Vec3::new(
        e * 0.018 * (TAU * phase).sin(),
        -e * (base + bob * (2.0 * TAU * (phase - 0.12)).cos()),
        speed * envelope_integral(t, duration),
    );
    b.finish()
}

fn idle(t: f32) -> Pose {
    let breath = 0.5 * (1.0 - (TAU * t / 4.0).cos());
    let sway = 0.5 * (1.0 - (TAU * t / 6.0).cos());
    let look = (TAU * t / 7.0).sin() * (PI * t / 7.0).sin();
    let mut b = PoseBuilder::new();
    b.rotations[SPINE1] = rx(-0.02 * breath);
    b.rotations[SPINE2] = rx(-0.015 * breath);
    b.rotations[HIPS] = rz(-0.02 * sway);
    b.pair(LEFT_UP_LEG, rz(0.02 * sway), rz(-0.02 * sway));
    b.rotations[HEAD] = ry(0.15 * look);
    b.pair(LEFT_FORE_ARM, rx(-0.04 * breath), rx(-0.04 * breath));
    b.root.x += 0.015 * sway;
    b.finish()
}

fn jump(t: f32) -> Pose {
    const CYCLE: f32 = 1.8;
    const TAKEOFF: f32 = 0.70;
    const TAKEOFF_SPEED: f32 = 2.2;
    let flight = 2.0 * TAKEOFF_SPEED / GRAVITY;
    let height = TAKEOFF_SPEED * TAKEOFF_SPEED / (2.0 * GRAVITY);
    let land = TAKEOFF + flight;
    let tc = t.rem_euclid(CYCLE);
    let lift = hermite(
        &[
            (0.0, 0.0, 0.0),
            (0.45, -0.16, 0.0),
            (TAKEOFF, 0.0, TAKEOFF_SPEED),
            (TAKEOFF + 0.5 * flight, height, 0.0),
            (land, 0.0, -TAKEOFF_SPEED),
            (land + 0.22, -0.13, 0.0),
            (CYCLE, 0.0, 0.0),
        ],
        tc,
    );
    let airborne = tc > TAKEOFF && tc < land;
    let drop = if airborne { 0.0 } else { (-lift).max(0.0) };
    let knee = if airborne {
        0.5 * (PI * (tc - TAKEOFF) / flight).sin()
    } else {
        leg_bend(drop)
    };
    let lean = 1.5 * drop;
    let arm = hermite(
        &[
            (0.0, 0.0, 0.0),
            (0.45, 0.6, 0.0),
            (0.75, -1.1, 0.0),
            (land + 0.1, -0.3, 0.0),
            (CYCLE, 0.0, 0.0),
        ],
        tc,
    );
    let mut b = PoseBuilder::new();
    b.rotations[HIPS] = rx(lean);
    b.rotations[SPINE] = rx(-0.4 * lean);
    let thigh = rx(-(0.5 * knee + lean));
    b.pair(LEFT_UP_LEG, thigh, thigh);
    b.pair(LEFT_LEG, rx(knee), rx(knee));
    b.pair(LEFT_FOOT, rx(-0.5 * knee), rx(-0.5 * knee));
    b.pair(LEFT_ARM, rx(arm), rx(arm));
    let elbow = rx(-0.3 * (PI * tc / CYCLE).sin().powi(2));
    b.pair(LEFT_FORE_ARM, elbow, elbow);
    b.root.y += lift;
    b.finish()
}

/// Small alternating steps; `amount` in [0, 1] scales them, `hz` is steps per second per leg.
fn stepping(b: &mut PoseBuilder, t: f32, hz: f32, amount: f32) {
    let s = (TAU * hz * t).sin();
    let (left, right) = (s.max(0.0).powi(2) * amount, (-s).max(0.0).powi(2) * amount);
    let side = |lift: f32| [rx(-0.45 * lift), rx(0.9 * lift), rx(-0.45 * lift)];
    let (l, r) = (side(left), side(right));
    for (k, joint) in [LEFT_UP_LEG, LEFT_LEG, LEFT_FOOT].into_iter().enumerate() {
        b.pair(joint, l[k], r[k]);
    }
}

fn turn(t: f32) -> Pose {
    const HALF_PERIOD: f32 = 1.6;
    let yaw = 0.5 * PI * (1.0 - (PI * t / HALF_PERIOD).cos());
    let speed = (PI * t / HALF_PERIOD).sin();
    let mut b = PoseBuilder::new();
    stepping(&mut b, t, 1.25, speed * speed);
    b.rotations[HIPS] = ry(yaw);
    b.rotations[SPINE2] = ry(0.15 * speed);
    b.root.y -= 0.01 * speed * speed;
    b.finish()
}

fn spin(t: f32, duration: f32) -> Pose {
    let e = envelope(t, duration);
    let yaw = SPIN_RAD_PER_SEC * envelope_integral(t, duration);
    let mut b = PoseBuilder::new();
    stepping(&mut b, t, 2.0, 0.5 * e);
    b.rotations[HIPS] = ry(yaw);
    b.pair(LEFT_ARM, rz(ARM_DROP_RAD * e), rz(ARM_DROP_RAD * e));
    b.root.y -= 0.01 * e;
    b.finish()
}

/// Twirl keys: (time s, root yaw rate in turns per second, arm raise in [0, 1]); the yaw
/// rate passes through every speed of the spin in both directions, the arms are out at some
/// speeds and down at others. Starts and ends at rest.
const TWIRL_KEYS: [(f32, f32, f32); 10] = [
    (0.0, 0.0, 0.0),
    (0.8, 0.8, 0.6),
    (1.8, 2.6, 1.0),
    (2.6, 2.2, 0.3),
    (3.4, 0.0, 0.0),
    (4.2, -1.4, 0.8),
    (5.2, -2.4, 0.4),
    (6.0, -1.0, 1.0),
    (6.8, 0.6, 0.5),
    (7.6, 0.0, 0.0),
];

/// Root yaw (rad) and yaw rate (rad/s) of the twirl at `t` in `0..=7.6` s: the yaw is the
/// integral of the rate, which eases (smoothstep) from key to key, so the integral is closed
/// form per segment.
fn twirl_yaw(t: f32) -> (f32, f32) {
    let mut yaw = 0.0;
    for w in TWIRL_KEYS.windows(2) {
        let ((t0, r0, _), (t1, r1, _)) = (w[0], w[1]);
        let dt = t1 - t0;
        if dt <= 0.0 {
            continue;
        }
        // Rate on the segment: r0 + (r1 - r0) · s(u), s the smoothstep; ∫_0^u s = u³ - u⁴/2.
        let u = ((t - t0) / dt).clamp(0.0, 1.0);
        yaw += TAU * dt * (r0 * u + (r1 - r0) * (u * u * u - 0.5 * u * u * u * u));
        if t <= t1 {
            return (yaw, TAU * (r0 + (r1 - r0) * smoothstep(u)));
        }
    }
    (yaw, 0.0)
}

fn twirl(t: f32) -> Pose {
    // Longer takes repeat the cycle; it starts and ends at rest, so the yaw carries on.
    let cycle = TWIRL_KEYS[TWIRL_KEYS.len() - 1].0;
    let cycles = (t / cycle).floor();
    let t = t - cycles * cycle;
    let (yaw, rate) = twirl_yaw(t);
    let yaw = yaw + cycles * twirl_yaw(cycle).0;
    let arms = hermite(&TWIRL_KEYS.map(|(time, _, arms)| (time, arms, 0.0)), t);
    let amount = (rate.abs() / SPIN_RAD_PER_SEC).min(1.0);
    let mut b = PoseBuilder::new();
    stepping(&mut b, t, 2.0, 0.5 * amount);
    b.rotations[HIPS] = ry(yaw);
    b.rotations[SPINE2] = ry(-0.1 * rate / SPIN_RAD_PER_SEC);
    b.pair(LEFT_ARM, rz(ARM_DROP_RAD * arms), rz(ARM_DROP_RAD * arms));
    b.root.y -= 0.01 * amount;
    b.finish()
}

/// Range-of-motion keys: time (s), then the channels [`RomChannel`] names, in radians. Each
/// move takes 0.8-1 s and eases in and out (cubic, zero slope at every key); a repeated value
/// is a hold.
const ROM_KEYS: [(f32, [f32; 9]); 19] = {
    const A: f32 = ARM_DROP_RAD;
    [
        (0.0, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        (1.0, [A, A, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        (1.3, [A, A, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        (2.3, [A + 0.6, A + 0.6, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        (2.6, [A + 0.6, A + 0.6, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        (3.6, [0.0, 0.0, 1.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        (3.9, [0.0, 0.0, 1.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        (4.9, [0.5 * A, 0.5 * A, 0.0, 1.6, 0.0, 0.0, 0.0, 0.0, 0.0]),
        (5.2, [0.5 * A, 0.5 * A, 0.0, 1.6, 0.0, 0.0, 0.0, 0.0, 0.0]),
        (6.2, [A + 0.4, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        (7.2, [0.0, A + 0.4, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        (8.2, [0.0, 0.0, 0.0, 0.0, 0.45, 0.0, 0.0, 0.0, 0.0]),
        (9.0, [0.0, 0.0, 0.0, 0.0, 0.0, 0.3, 0.0, 0.0, 0.0]),
        (9.8, [0.0, 0.0, 0.0, 0.0, 0.0, -0.3, 0.0, 0.0, 0.0]),
        (10.6, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.6, 0.0, 0.0]),
        (11.4, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -0.6, 0.0, 0.0]),
        (12.2, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]),
        (13.0, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]),
        (13.8, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
    ]
};

/// The channels of [`ROM_KEYS`], in order.
#[derive(Clone, Copy)]
enum RomChannel {
    /// Left upper arm raised sideways from the A-pose (rad; [`ARM_DROP_RAD`] is horizontal).
    RaiseLeft,
    /// Right upper arm raised sideways.
    RaiseRight,
    /// Both upper arms swung forward.
    Forward,
    /// Both elbows bent.
    Elbow,
    /// Spine bent forward (over two joints).
    Bend,
    /// Spine leaned sideways.
    Lean,
    /// Spine twisted about the vertical.
    Twist,
    /// Left knee raised (1 = hip flexed 0.9 rad, knee 1.4 rad).
    KneeLeft,
    /// Right knee raised.
    KneeRight,
}

fn range_of_motion(t: f32) -> Pose {
    // Longer takes repeat the cycle, which starts and ends at rest.
    let t = t.rem_euclid(ROM_KEYS[ROM_KEYS.len() - 1].0);
    let channel = |c: RomChannel| hermite(&ROM_KEYS.map(|(time, v)| (time, v[c as usize], 0.0)), t);
    let arm = |raise: f32| rx(-channel(RomChannel::Forward)) * rz(raise);
    let elbow = rx(-channel(RomChannel::Elbow));
    let knee = |k: f32| [rx(-0.9 * k), rx(1.4 * k), rx(-0.5 * k)];
    let (bend, lean, twist) = (
        channel(RomChannel::Bend),
        channel(RomChannel::Lean),
        channel(RomChannel::Twist),
    );
    let mut b = PoseBuilder::new();
    b.pair(
        LEFT_ARM,
        arm(channel(RomChannel::RaiseLeft)),
        arm(channel(RomChannel::RaiseRight)),
    );
    b.pair(LEFT_FORE_ARM, elbow, elbow);
    let spine = rx(0.5 * bend) * rz(0.5 * lean) * ry(0.5 * twist);
    b.rotations[SPINE] = spine;
    b.rotations[SPINE1] = spine;
    let (l, r) = (
        knee(channel(RomChannel::KneeLeft)),
        knee(channel(RomChannel::KneeRight)),
    );
    for (k, joint) in [LEFT_UP_LEG, LEFT_LEG, LEFT_FOOT].into_iter().enumerate() {
        b.pair(joint, l[k], r[k]);
    }
    b.finish()
}

/// The pose of motion `kind` at `t_secs` into a take lasting `duration_secs`.
pub fn pose_at(kind: MotionKind, t_secs: f32, duration_secs: f32) -> Pose {
    let t = if t_secs.is_finite() {
        t_secs.max(0.0)
    } else {
        0.0
    };
    match kind {
        MotionKind::Idle => idle(t),
        MotionKind::Walk => walk_or_run(t, duration_secs, false),
        MotionKind::Run => walk_or_run(t, duration_secs, true),
        MotionKind::Jump => jump(t),
        MotionKind::Turn => turn(t),
        MotionKind::Spin => spin(t, duration_secs),
        MotionKind::Twirl => twirl(t),
        MotionKind::Rom => range_of_motion(t),
    }
}

/// Samples motion `kind` at `fps` frames per second (0 < fps <= 10000) for `duration_secs`
/// seconds (0..=3600); the motion is named after the kind.
pub fn motion(kind: MotionKind, fps: f32, duration_secs: f32) -> Result<Motion, SceneError> {
    motion_at_speed(kind, fps, duration_secs, 1.0)
}

/// Like [`motion`], played `speed` times as fast (0 < speed <= 10): the take of
/// `duration_secs · speed` seconds, time-scaled to last `duration_secs` (a spin at speed 0.5
/// turns once a second, easing in and out over 1.2 s).
pub fn motion_at_speed(
    kind: MotionKind,
    fps: f32,
    duration_secs: f32,
    speed: f32,
) -> Result<Motion, SceneError> {
    let invalid = |reason: String| SceneError::InvalidMotion {
        name: kind.name().into(),
        reason,
    };
    if !(fps.is_finite() && fps > 0.0 && fps <= 10_000.0) {
        return Err(invalid(format!(
            "frame rate {fps} is outside (0, 10000] frames per second"
        )));
    }
    if !(duration_secs.is_finite() && (0.0..=3600.0).contains(&duration_secs)) {
        return Err(invalid(format!(
            "duration {duration_secs} s is outside 0..=3600 s"
        )));
    }
    if !(speed.is_finite() && speed > 0.0 && speed <= MAX_SPEED) {
        return Err(invalid(format!(
            "speed {speed} is outside (0, {MAX_SPEED}]"
        )));
    }
    let frames = (duration_secs * fps + 1e-3).floor() as usize + 1;
    let poses = (0..frames)
        .map(|k| pose_at(kind, speed * k as f32 / fps, speed * duration_secs))
        .collect();
    Motion::new(kind.name(), fps, poses, JOINT_COUNT)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn envelope_integral_matches_numeric() {
        for duration in [0.5, 1.0, 5.0] {
            let mut acc = 0.0;
            let n = 20_000;
            for k in 0..n {
                let t = (k as f32 + 0.5) * duration / n as f32;
                acc += envelope(t, duration) * duration / n as f32;
                if k % 997 == 0 {
                    let exact = envelope_integral((k + 1) as f32 * duration / n as f32, duration);
                    assert!((acc - exact).abs() < 1e-3, "{acc} vs {exact} at {duration}");
                }
            }
        }
    }

    #[test]
    fn hermite_reproduces_ballistic_flight() {
        let v = 2.2;
        let f = 2.0 * v / GRAVITY;
        let keys = [
            (0.0, 0.0, v),
            (0.5 * f, v * v / (2.0 * GRAVITY), 0.0),
            (f, 0.0, -v),
        ];
        for k in 0..=10 {
            let t = k as f32 * f / 10.0;
            assert!((hermite(&keys, t) - (v * t - 0.5 * GRAVITY * t * t)).abs() < 1e-5);
        }
    }

    #[test]
    fn motions_start_at_rest_except_idle_offsets() {
        for kind in MotionKind::ALL {
            let pose = pose_at(kind, 0.0, 4.0);
            for q in &pose.rotations {
                assert!(q.angle() < 1e-5, "{kind:?}");
            }
            assert!(
                (pose.root_translation - Vec3::new(0.0, 0.95, 0.0)).norm() < 1e-5,
                "{kind:?}"
            );
        }
        assert!(MotionKind::from_name("walk") == Some(MotionKind::Walk));
        assert!(leg_bend(0.0) < 1e-3 && leg_bend(0.16) > 0.5);
    }

    #[test]
    fn rom_reaches_its_poses_slowly_and_repeats() {
        let cycle = ROM_KEYS[ROM_KEYS.len() - 1].0;
        let angle =
            |t: f32, joint: usize| pose_at(MotionKind::Rom, t, cycle).rotations[joint].angle();
        // Both arms above the horizontal at 2.3 s, one at a time at 6.2 s and 7.2 s.
        assert!((angle(2.3, LEFT_ARM) - (ARM_DROP_RAD + 0.6)).abs() < 1e-4);
        assert!((angle(2.3, RIGHT_ARM) - (ARM_DROP_RAD + 0.6)).abs() < 1e-4);
        assert!(angle(6.2, LEFT_ARM) > ARM_DROP_RAD && angle(6.2, RIGHT_ARM) < 1e-4);
        assert!(angle(7.2, RIGHT_ARM) > ARM_DROP_RAD && angle(7.2, LEFT_ARM) < 1e-4);
        // The elbows, the spine and each knee move in their turn.
        assert!((angle(4.9, LEFT_FORE_ARM) - 1.6).abs() < 1e-4);
        assert!(angle(8.2, SPINE) > 0.2 && angle(10.6, SPINE1) > 0.25);
        assert!(angle(12.2, LEFT_LEG) > 1.3 && angle(12.2, RIGHT_LEG) < 1e-4);
        assert!(angle(13.0, RIGHT_LEG) > 1.3 && angle(13.0, LEFT_LEG) < 1e-4);
        // Slow: no joint turns faster than 3 rad/s; the cycle closes at rest and repeats.
        let fps = 120.0;
        for k in 0..(2.0 * cycle * fps) as usize {
            let (a, b) = (k as f32 / fps, (k + 1) as f32 / fps);
            let (pa, pb) = (
                pose_at(MotionKind::Rom, a, 30.0),
                pose_at(MotionKind::Rom, b, 30.0),
            );
            for (qa, qb) in pa.rotations.iter().zip(&pb.rotations) {
                assert!(qa.angle_to(qb) * fps < 3.0, "at {a} s");
            }
        }
        for t in [0.0, 1.7, 5.0, 12.9] {
            let (p, q) = (
                pose_at(MotionKind::Rom, t, 30.0),
                pose_at(MotionKind::Rom, t + cycle, 30.0),
            );
            for (a, b) in p.rotations.iter().zip(&q.rotations) {
                assert!(a.angle_to(b) < 1e-4, "at {t} s");
            }
        }
    }
}
