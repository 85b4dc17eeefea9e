//! Which way a rig faces, from its rest pose: the horizontal direction from its ankles to its
//! toes. A motion whose rig faces another way than the avatar (a Z-up file made facing +Y
//! reads facing -Z once turned Y up; a rig built facing +X) would otherwise move the avatar's
//! limbs the wrong way round (walking backwards, swinging its legs sideways); retargeting
//! turns such a motion about the vertical to face as the avatar does ([`turn_to_avatar`]).

use super::joint_map::JointMapping;
use super::retarget::SourceMotion;
use crate::geometry::{Quat, Vec3};

/// Motions facing less than this far from the avatar (degrees) are left as they are (feet
/// splay, and rigs are not built exactly square).
const MIN_TURN_DEG: f32 = 45.0;

/// The horizontal unit direction from each `(ankle, toe)` pair's ankle to its toe in
/// `rest`, averaged; None when there is no such pair or the toes point nowhere sideways.
pub fn forward(rest: &[Vec3], pairs: &[(usize, usize)]) -> Option<Vec3> {
    let sum: Vec3 = pairs
        .iter()
        .filter_map(|&(a, t)| Some(rest.get(t)? - rest.get(a)?))
        .map(|d| Vec3::new(d.x, 0.0, d.z))
        .sum();
    let n = sum.norm();
    (n > 1e-6 && n.is_finite()).then(|| sum / n)
}

/// The turn about +Y that takes horizontal unit direction `from` to `to`, in radians
/// (positive: counter-clockwise seen from above).
pub fn yaw_between(from: &Vec3, to: &Vec3) -> f32 {
    let cross_y = from.z * to.x - from.x * to.z;
    let dot = from.x * to.x + from.z * to.z;
    cross_y.atan2(dot)
}

/// `source` turned about the vertical through the origin to face as the avatar does, with
/// the turn in degrees, when both rigs' toes tell which way they face (the avatar's rest
/// positions `avatar_rest`, its ankles and toes from `mapping`'s canonical names, the
/// motion's the joints they map to) and the two differ by more than 45 degrees; else None.
pub fn turn_to_avatar(
    source: &SourceMotion,
    avatar_rest: &[Vec3],
    mapping: &JointMapping,
) -> Option<(SourceMotion, f32)> {
    let avatar_joint = |name: &str| mapping.canonical.iter().position(|c| *c == Some(name));
    let mut avatar_pairs = Vec::new();
    let mut motion_pairs = Vec::new();
    for side in ["Left", "Right"] {
        let (Some(ankle), Some(toe)) = (
            avatar_joint(&format!("{side}Foot")),
            avatar_joint(&format!("{side}ToeBase")),
        ) else {
            continue;
        };
        avatar_pairs.push((ankle, toe));
        if let (Some(Some(a)), Some(Some(t))) = (mapping.source.get(ankle), mapping.source.get(toe))
        {
            motion_pairs.push((*a, *t));
        }
    }
    let motion_rest: Vec<Vec3> = source.rest.iter().map(|r| r.1).collect();
    let to = forward(avatar_rest, &avatar_pairs)?;
    let from = forward(&motion_rest, &motion_pairs)?;
    let yaw = yaw_between(&from, &to);
    if yaw.to_degrees().abs() <= MIN_TURN_DEG {
        return None;
    }
    let turn = Quat::from_scaled_axis(Vec3::y() * yaw);
    let turned = |w: &[(Quat, Vec3)]| w.iter().map(|(q, p)| (turn * q, turn * p)).collect();
    let mut out = source.clone();
    out.rest = turned(&source.rest);
    out.frames = source.frames.iter().map(|w| turned(w)).collect();
    Some((out, yaw.to_degrees()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn forward_and_yaw() {
        let rest = [
            Vec3::new(0.1, 0.1, 0.0),
            Vec3::new(0.1, 0.0, 0.1),
            Vec3::new(-0.1, 0.1, 0.0),
            Vec3::new(-0.1, 0.0, 0.12),
        ];
        let f = forward(&rest, &[(0, 1), (2, 3)]).unwrap();
        assert!((f - Vec3::z()).norm() < 1e-6);
        assert!(forward(&rest, &[]).is_none());
        let yaw = yaw_between(&Vec3::z(), &Vec3::x());
        assert!((yaw - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
        let turned = Quat::from_scaled_axis(Vec3::y() * yaw) * Vec3::z();
        assert!((turned - Vec3::x()).norm() < 1e-6);
        assert!((yaw_between(&Vec3::z(), &-Vec3::z()).abs() - std::f32::consts::PI).abs() < 1e-6);
    }
}
