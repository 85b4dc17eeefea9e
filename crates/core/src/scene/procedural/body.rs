//! The mannequin's proportions: joint positions of the A-pose rest skeleton and the body as a
//! smooth union of tapered capsules and ellipsoids (a signed distance field, metres).
//!
//! Only the character's left side (+X) and the centre line are described; the field is
//! evaluated at `(|x|, y, z)`, which makes the body exactly mirror symmetric about `x = 0`.

use crate::geometry::Vec3;

/// Number of joints of the mannequin skeleton.
pub const JOINT_COUNT: usize = 22;

/// Mixamo joint names in skeleton order (parents precede children).
pub const JOINT_NAMES: [&str; JOINT_COUNT] = [
    "Hips",
    "Spine",
    "Spine1",
    "Spine2",
    "Neck",
    "Head",
    "LeftShoulder",
    "LeftArm",
    "LeftForeArm",
    "LeftHand",
    "RightShoulder",
    "RightArm",
    "RightForeArm",
    "RightHand",
    "LeftUpLeg",
    "LeftLeg",
    "LeftFoot",
    "LeftToeBase",
    "RightUpLeg",
    "RightLeg",
    "RightFoot",
    "RightToeBase",
];

/// Parent of each joint (`None` for the root, `Hips`).
pub const JOINT_PARENTS: [Option<usize>; JOINT_COUNT] = [
    None,
    Some(0),
    Some(1),
    Some(2),
    Some(3),
    Some(4),
    Some(3),
    Some(6),
    Some(7),
    Some(8),
    Some(3),
    Some(10),
    Some(11),
    Some(12),
    Some(0),
    Some(14),
    Some(15),
    Some(16),
    Some(0),
    Some(18),
    Some(19),
    Some(20),
];

/// Joint indices used by the procedural motions and tests.
pub mod joint {
    /// Root joint.
    pub const HIPS: usize = 0;
    /// Lower spine.
    pub const SPINE: usize = 1;
    /// Middle spine.
    pub const SPINE1: usize = 2;
    /// Upper spine (chest).
    pub const SPINE2: usize = 3;
    /// Neck.
    pub const NECK: usize = 4;
    /// Head.
    pub const HEAD: usize = 5;
    /// Left clavicle.
    pub const LEFT_SHOULDER: usize = 6;
    /// Left upper arm (shoulder joint).
    pub const LEFT_ARM: usize = 7;
    /// Left forearm (elbow).
    pub const LEFT_FORE_ARM: usize = 8;
    /// Left hand (wrist).
    pub const LEFT_HAND: usize = 9;
    /// Right clavicle.
    pub const RIGHT_SHOULDER: usize = 10;
    /// Right upper arm.
    pub const RIGHT_ARM: usize = 11;
    /// Right forearm.
    pub const RIGHT_FORE_ARM: usize = 12;
    /// Right hand.
    pub const RIGHT_HAND: usize = 13;
    /// Left thigh (hip joint).
    pub const LEFT_UP_LEG: usize = 14;
    /// Left shin (knee).
    pub const LEFT_LEG: usize = 15;
    /// Left foot (ankle).
    pub const LEFT_FOOT: usize = 16;
    /// Left toes.
    pub const LEFT_TOE_BASE: usize = 17;
    /// Right thigh.
    pub const RIGHT_UP_LEG: usize = 18;
    /// Right shin.
    pub const RIGHT_LEG: usize = 19;
    /// Right foot.
    pub const RIGHT_FOOT: usize = 20;
    /// Right toes.
    pub const RIGHT_TOE_BASE: usize = 21;
}

/// Angle of the upper arms below the horizontal in the rest A-pose, in radians (42°).
pub const ARM_DROP_RAD: f32 = 42.0 * std::f32::consts::PI / 180.0;
/// Upper arm length in metres.
const UPPER_ARM_M: f32 = 0.28;
/// Forearm length in metres.
const FOREARM_M: f32 = 0.25;

/// Unit direction of the left arm in the A-pose (down and out, +X).
pub fn left_arm_dir() -> Vec3 {
    Vec3::new(ARM_DROP_RAD.cos(), -ARM_DROP_RAD.sin(), 0.0)
}

/// World position of the left shoulder joint (`LeftArm`) in the rest pose.
pub fn left_shoulder_pos() -> Vec3 {
    Vec3::new(0.17, 1.39, 0.0)
}

/// World positions of the joints in the rest A-pose (metres, Y up, facing +Z, left = +X).
/// Right-side joints are exact mirror images of the left-side ones.
pub fn rest_joint_positions() -> [Vec3; JOINT_COUNT] {
    let d = left_arm_dir();
    let shoulder = left_shoulder_pos();
    let elbow = shoulder + d * UPPER_ARM_M;
    let wrist = elbow + d * FOREARM_M;
    let left = [
        Vec3::new(0.035, 1.41, 0.0),
        shoulder,
        elbow,
        wrist,
        Vec3::new(0.092, 0.91, 0.0),
        Vec3::new(0.09, 0.50, 0.012),
        Vec3::new(0.09, 0.085, -0.02),
        Vec3::new(0.09, 0.025, 0.105),
    ];
    let m = |v: Vec3| Vec3::new(-v.x, v.y, v.z);
    [
        Vec3::new(0.0, 0.95, 0.0),
        Vec3::new(0.0, 1.05, 0.0),
        Vec3::new(0.0, 1.17, 0.0),
        Vec3::new(0.0, 1.30, 0.0),
        Vec3::new(0.0, 1.46, 0.0),
        Vec3::new(0.0, 1.56, 0.01),
        left[0],
        left[1],
        left[2],
        left[3],
        m(left[0]),
        m(left[1]),
        m(left[2]),
        m(left[3]),
        left[4],
        left[5],
        left[6],
        left[7],
        m(left[4]),
        m(left[5]),
        m(left[6]),
        m(left[7]),
    ]
}

/// Shape of one body part.
#[derive(Clone, Copy, Debug)]
pub enum Shape {
    /// Segment `a`-`b` swept by a sphere whose radius goes linearly from `ra` to `rb`.
    Capsule {
        /// Start point.
        a: Vec3,
        /// End point.
        b: Vec3,
        /// Radius at `a` in metres.
        ra: f32,
        /// Radius at `b` in metres.
        rb: f32,
    },
    /// Axis-aligned ellipsoid.
    Ellipsoid {
        /// Centre.
        centre: Vec3,
        /// Semi-axes in metres.
        radii: Vec3,
    },
}

impl Shape {
    /// Approximate signed distance from `p` (negative inside), in metres.
    pub fn distance(&self, p: &Vec3) -> f32 {
        match *self {
            Shape::Capsule { a, b, ra, rb } => {
                let ab = b - a;
                let len2 = ab.norm_squared();
                let t = if len2 > 0.0 {
                    ((p - a).dot(&ab) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (p - (a + ab * t)).norm() - (ra + (rb - ra) * t)
            }
            Shape::Ellipsoid { centre, radii } => {
                let q = p - centre;
                let k0 = q.component_div(&radii).norm();
                let k1 = q.component_div(&radii.component_mul(&radii)).norm();
                if k1 > 1e-12 {
                    k0 * (k0 - 1.0) / k1
                } else {
                    -radii.min()
                }
            }
        }
    }
}

/// One body part: a shape bound to a joint, blended into the body with radius `blend_m`.
#[derive(Clone, Copy, Debug)]
pub struct Part {
    /// The part's shape (left side or centre line).
    pub shape: Shape,
    /// Joint that moves this part (left-side or centre joint index).
    pub joint: usize,
    /// Smooth-union blend radius in metres (0 = hard union).
    pub blend_m: f32,
}

/// The body as a smooth union of parts; evaluated at `(|x|, y, z)`.
#[derive(Clone, Debug)]
pub struct BodySdf {
    /// Centre-line and left-side parts, in blend order.
    pub parts: Vec<Part>,
}

/// Polynomial smooth minimum with blend radius `k` (equals `min` when `k <= 0`).
pub fn smin(a: f32, b: f32, k: f32) -> f32 {
    if k <= 0.0 {
        return a.min(b);
    }
    let h = (0.5 + 0.5 * (b - a) / k).clamp(0.0, 1.0);
    b + (a - b) * h - k * h * (1.0 - h)
}

impl BodySdf {
    /// The mannequin's body.
    pub fn mannequin() -> Self {
        use joint::*;
        let j = rest_joint_positions();
        let d = left_arm_dir();
        let cap = |a: Vec3, b: Vec3, ra: f32, rb: f32| Shape::Capsule { a, b, ra, rb };
        let ell = |c: [f32; 3], r: [f32; 3]| Shape::Ellipsoid {
            centre: Vec3::new(c[0], c[1], c[2]),
            radii: Vec3::new(r[0], r[1], r[2]),
        };
        let part = |shape, joint, blend_m| Part {
            shape,
            joint,
            blend_m,
        };
        let parts = vec![
            part(ell([0.0, 0.93, -0.005], [0.165, 0.11, 0.115]), HIPS, 0.0),
            part(ell([0.0, 1.08, 0.005], [0.14, 0.12, 0.10]), SPINE, 0.06),
            part(ell([0.0, 1.20, 0.005], [0.15, 0.12, 0.105]), SPINE1, 0.06),
            part(ell([0.0, 1.32, 0.0], [0.165, 0.12, 0.11]), SPINE2, 0.06),
            part(
                cap(
                    Vec3::new(0.0, 1.40, -0.01),
                    Vec3::new(0.0, 1.56, 0.005),
                    0.056,
                    0.052,
                ),
                NECK,
                0.03,
            ),
            part(ell([0.0, 1.65, 0.015], [0.08, 0.105, 0.095]), HEAD, 0.03),
            part(
                cap(Vec3::new(0.03, 1.415, -0.01), j[LEFT_ARM], 0.062, 0.054),
                LEFT_SHOULDER,
                0.04,
            ),
            part(
                cap(j[LEFT_ARM], j[LEFT_FORE_ARM], 0.05, 0.04),
                LEFT_ARM,
                0.025,
            ),
            part(
                cap(j[LEFT_FORE_ARM], j[LEFT_HAND], 0.039, 0.029),
                LEFT_FORE_ARM,
                0.015,
            ),
            part(
                cap(
                    j[LEFT_HAND] + d * 0.03,
                    j[LEFT_HAND] + d * 0.15,
                    0.03,
                    0.024,
                ),
                LEFT_HAND,
                0.015,
            ),
            part(
                cap(j[LEFT_UP_LEG], j[LEFT_LEG], 0.078, 0.054),
                LEFT_UP_LEG,
                0.04,
            ),
            part(cap(j[LEFT_LEG], j[LEFT_FOOT], 0.052, 0.036), LEFT_LEG, 0.02),
            part(
                cap(
                    Vec3::new(0.09, 0.04, -0.045),
                    Vec3::new(0.09, 0.036, 0.1),
                    0.04,
                    0.036,
                ),
                LEFT_FOOT,
                0.02,
            ),
            part(
                cap(
                    Vec3::new(0.09, 0.03, 0.1),
                    Vec3::new(0.09, 0.028, 0.175),
                    0.03,
                    0.028,
                ),
                LEFT_TOE_BASE,
                0.01,
            ),
        ];
        Self { parts }
    }

    /// Signed distance to the body surface at `p` (negative inside), metres.
    pub fn distance(&self, p: &Vec3) -> f32 {
        let q = Vec3::new(p.x.abs(), p.y, p.z);
        self.parts.iter().fold(f32::INFINITY, |acc, part| {
            let d = part.shape.distance(&q);
            if acc.is_finite() {
                smin(acc, d, part.blend_m)
            } else {
                d
            }
        })
    }

    /// Axis-aligned bounds of the left half (`x >= 0`) of the body, padded by `pad_m`.
    pub fn half_bounds(&self, pad_m: f32) -> (Vec3, Vec3) {
        let mut lo = Vec3::repeat(f32::INFINITY);
        let mut hi = Vec3::repeat(f32::NEG_INFINITY);
        for part in &self.parts {
            let (a, b) = match part.shape {
                Shape::Capsule { a, b, ra, rb } => {
                    let r = ra.max(rb);
                    (a.inf(&b) - Vec3::repeat(r), a.sup(&b) + Vec3::repeat(r))
                }
                Shape::Ellipsoid { centre, radii } => (centre - radii, centre + radii),
            };
            lo = lo.inf(&a);
            hi = hi.sup(&b);
        }
        lo.x = 0.0;
        (lo - Vec3::new(0.0, pad_m, pad_m), hi + Vec3::repeat(pad_m))
    }
}

/// The mirror image of a left-side joint index (centre joints map to themselves).
pub fn mirror_joint(j: usize) -> usize {
    match j {
        6..=9 => j + 4,
        10..=13 => j - 4,
        14..=17 => j + 4,
        18..=21 => j - 4,
        _ => j,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn joints_mirror_and_parents_precede() {
        let p = rest_joint_positions();
        for j in 0..JOINT_COUNT {
            let m = mirror_joint(j);
            assert_eq!(
                p[m],
                Vec3::new(-p[j].x, p[j].y, p[j].z),
                "{}",
                JOINT_NAMES[j]
            );
            if let Some(parent) = JOINT_PARENTS[j] {
                assert!(parent < j);
            }
            let expected = JOINT_NAMES[j]
                .replace("Left", "#")
                .replace("Right", "Left")
                .replace('#', "Right");
            assert_eq!(JOINT_NAMES[m], expected);
        }
    }

    #[test]
    fn body_is_symmetric_and_has_expected_extent() {
        let body = BodySdf::mannequin();
        assert!(body.distance(&Vec3::new(0.0, 1.1, 0.0)) < -0.05);
        assert!(body.distance(&Vec3::new(0.0, 1.1, 0.5)) > 0.3);
        let p = Vec3::new(0.3, 1.3, 0.02);
        assert_eq!(
            body.distance(&p),
            body.distance(&Vec3::new(-0.3, 1.3, 0.02))
        );
        // Feet reach the floor and the head reaches about 1.75 m.
        assert!(body.distance(&Vec3::new(0.09, 0.002, 0.05)) < 0.0);
        assert!(body.distance(&Vec3::new(0.0, 1.745, 0.015)) < 0.0);
        assert!(body.distance(&Vec3::new(0.0, 1.765, 0.015)) > 0.0);
    }

    #[test]
    fn smooth_min_is_below_min_and_matches_far_away() {
        assert!(smin(0.1, 0.1, 0.05) < 0.1);
        assert_eq!(smin(0.0, 1.0, 0.05), 0.0);
        assert_eq!(smin(0.3, 0.2, 0.0), 0.2);
    }
}
