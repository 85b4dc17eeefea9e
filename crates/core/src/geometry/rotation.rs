//! Rotation representations: the continuous 6D representation of Zhou et al. (2019),
//! quaternion slerp that takes the short way round, and checks for usable rotations.

use super::{Mat3, Quat, Vec3};

/// The 6D representation of a rotation: its first two columns, `[c0.x, c0.y, c0.z, c1.x,
/// c1.y, c1.z]`.
pub fn rotation_to_6d(r: &Mat3) -> [f32; 6] {
    [
        r[(0, 0)],
        r[(1, 0)],
        r[(2, 0)],
        r[(0, 1)],
        r[(1, 1)],
        r[(2, 1)],
    ]
}

/// Rebuilds a rotation matrix from a 6D vector by Gram-Schmidt. Returns `None` when the two
/// columns are (nearly) zero or parallel, so no zero vector is ever normalised.
pub fn mat3_from_6d(v: &[f32; 6]) -> Option<Mat3> {
    let a = Vec3::new(v[0], v[1], v[2]);
    let b = Vec3::new(v[3], v[4], v[5]);
    let c0 = super::mesh::safe_normalize(a)?;
    let c1 = super::mesh::safe_normalize(b - c0 * c0.dot(&b))?;
    let c2 = c0.cross(&c1);
    Some(Mat3::from_columns(&[c0, c1, c2]))
}

/// Spherical interpolation from `a` (t = 0) to `b` (t = 1) along the shorter arc.
pub fn slerp_unit(a: &Quat, b: &Quat, t: f32) -> Quat {
    let b = if a.coords.dot(&b.coords) < 0.0 {
        Quat::new_unchecked(-b.into_inner())
    } else {
        *b
    };
    // nalgebra's slerp falls back to nlerp when the quaternions are (anti)parallel. Its f32
    // result drifts off unit length for small angles (sqrt(1 - c^2) cancels), so renormalise.
    a.try_slerp(&b, t, 1e-6)
        .map(|q| Quat::new_normalize(q.into_inner()))
        .unwrap_or(*a)
}

/// Builds a unit quaternion from raw `[x, y, z, w]` components, normalising when the norm is
/// within `tolerance` of 1. Returns `None` for NaN/inf or a norm too far from 1 (or zero).
pub fn quat_from_xyzw(xyzw: [f32; 4], tolerance: f32) -> Option<Quat> {
    if !xyzw.iter().all(|c| c.is_finite()) {
        return None;
    }
    let q = nalgebra::Quaternion::new(xyzw[3], xyzw[0], xyzw[1], xyzw[2]);
    let n = q.norm();
    ((n - 1.0).abs() <= tolerance && n > 0.0).then(|| Quat::new_unchecked(q / n))
}

/// Angle in radians between two rotations (0..=π).
pub fn angle_between(a: &Quat, b: &Quat) -> f32 {
    let d = a.coords.dot(&b.coords).abs().min(1.0);
    2.0 * d.acos()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn six_d_round_trip() {
        let q = Quat::from_euler_angles(0.3, -1.2, 2.5);
        let r = q.to_rotation_matrix().into_inner();
        let back = mat3_from_6d(&rotation_to_6d(&r)).unwrap();
        assert!((back - r).norm() < 1e-5);
    }

    #[test]
    fn six_d_rejects_parallel_columns() {
        assert!(mat3_from_6d(&[1.0, 0.0, 0.0, 2.0, 0.0, 0.0]).is_none());
        assert!(mat3_from_6d(&[0.0; 6]).is_none());
    }

    #[test]
    fn slerp_takes_short_arc_and_hits_endpoints() {
        let a = Quat::from_axis_angle(&Vec3::y_axis(), 0.1);
        let b = Quat::from_axis_angle(&Vec3::y_axis(), 0.5);
        let neg_b = Quat::new_unchecked(-b.into_inner());
        let mid = slerp_unit(&a, &neg_b, 0.5);
        assert!(angle_between(&mid, &Quat::from_axis_angle(&Vec3::y_axis(), 0.3)) < 1e-5);
        assert!(angle_between(&slerp_unit(&a, &b, 1.0), &b) < 1e-5);
    }

    #[test]
    fn quaternion_validation() {
        assert!(quat_from_xyzw([0.0, 0.0, 0.0, 1.0], 1e-3).is_some());
        assert!(quat_from_xyzw([0.0, 0.0, 0.0, 1.0005], 1e-3).is_some());
        assert!(quat_from_xyzw([0.0, 0.0, 0.0, 2.0], 1e-3).is_none());
        assert!(quat_from_xyzw([f32::NAN, 0.0, 0.0, 1.0], 1e-3).is_none());
        assert!(quat_from_xyzw([0.0; 4], 1e-3).is_none());
    }
}
