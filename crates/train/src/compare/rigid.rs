//! How much of a difference between two garment sequences is a rigid motion of the whole
//! garment. A frictionless garment (the paper's losses and our simulator have no friction)
//! slides over the body: on a turning body the simulator's t-shirt lags by a few degrees, on a
//! run it slips back and forth. Such slip is history (how far the garment has slid so far),
//! where the network's output follows the skinned body by construction; splitting each
//! frame's difference into its best rigid motion (Kabsch: rotation and translation, least
//! squares over the vertices) and the remaining shape difference says which of the two a
//! model misses.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use neural_cloth_core::geometry::Vec3;

use super::super::TrainError;

/// The best rigid motion from one frame's vertices onto another's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidFit {
    /// Mean vertex distance left after the rigid motion (the shape difference), metres.
    pub residual_m: f64,
    /// Mean distance the rigid motion moves the vertices (the slip), metres.
    pub moved_m: f64,
}

/// The best rigid motion (rotation about the centroid, then translation) taking `from` onto
/// `to`, both the same vertices in the same order. `None` when the counts differ, a frame
/// is empty or holds a non-finite coordinate. Degenerate frames (all vertices on a line or a point) get the best motion the
/// SVD finds, which may not be unique; the residual is still the distance it leaves.
pub fn best_rigid_fit(from: &[Vec3], to: &[Vec3]) -> Option<RigidFit> {
    if from.len() != to.len() || from.is_empty() {
        return None;
    }
    let n = from.len() as f64;
    let f64v = |p: &Vec3| Vector3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z));
    let centre = |ps: &[Vec3]| ps.iter().map(f64v).sum::<Vector3<f64>>() / n;
    let (ca, cb) = (centre(from), centre(to));
    let mut h = Matrix3::<f64>::zeros();
    for (a, b) in from.iter().zip(to) {
        h += (f64v(a) - ca) * (f64v(b) - cb).transpose();
    }
    // A non-finite vertex (a diverged network or simulation) has no rigid fit; nalgebra's
    // 3x3 SVD would iterate on NaN without end.
    if !(h.iter().all(|v| v.is_finite()) && ca.iter().chain(cb.iter()).all(|v| v.is_finite())) {
        return None;
    }
    let svd = h.try_svd(true, true, f64::EPSILON, 1000)?;
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut d = Matrix3::identity();
    if (v_t.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let rotation = v_t.transpose() * d * u.transpose();
    let (mut residual, mut moved) = (0.0, 0.0);
    for (a, b) in from.iter().zip(to) {
        let aligned = rotation * (f64v(a) - ca) + cb;
        residual += (aligned - f64v(b)).norm();
        moved += (aligned - f64v(a)).norm();
    }
    Some(RigidFit {
        residual_m: residual / n,
        moved_m: moved / n,
    })
}

/// A comparison split into the rigid motion of the whole garment and the shape.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RigidSplit {
    /// Network to simulator after each frame's best rigid motion (the shape difference),
    /// mean over all frames, mm.
    pub shape_distance_mm: f64,
    /// The network's swing (its output at `w` against `w = 0`) that is a rigid motion of the
    /// whole garment: mean distance the best rigid motion moves the vertices, mm.
    pub network_slip_mm: f64,
    /// The network's swing left after that rigid motion (the swing of the shape), mm.
    pub network_shape_swing_mm: f64,
    /// The simulator's swing (against its quasi-static simulation) that is rigid slip, mm.
    pub simulator_slip_mm: f64,
    /// The simulator's swing left after that rigid motion, mm.
    pub simulator_shape_swing_mm: f64,
}

/// Mean over frames of `fit(reference[k] -> candidate[k])`, both parts in mm; `None` when a
/// frame has no fit (a non-finite coordinate).
pub(super) fn mean_fit(
    reference: &[Vec<Vec3>],
    candidate: &[Vec<Vec3>],
) -> Result<Option<(f64, f64)>, TrainError> {
    let sizes_differ = reference.len() != candidate.len()
        || reference.is_empty()
        || reference
            .iter()
            .zip(candidate)
            .any(|(r, c)| r.len() != c.len());
    if sizes_differ {
        return Err(TrainError::Data(format!(
            "rigid split of {} against {} frames of other sizes",
            candidate.len(),
            reference.len()
        )));
    }
    let (mut residual, mut moved) = (0.0, 0.0);
    for (r, c) in reference.iter().zip(candidate) {
        let Some(fit) = best_rigid_fit(r, c) else {
            return Ok(None);
        };
        residual += fit.residual_m;
        moved += fit.moved_m;
    }
    let n = reference.len() as f64;
    Ok(Some((1000.0 * residual / n, 1000.0 * moved / n)))
}

/// Splits the network-to-simulator distance and both swings into rigid slip and shape;
/// `None` when a frame holds a non-finite coordinate (the distances say so already).
pub fn rigid_split(
    network: &[Vec<Vec3>],
    network_static: &[Vec<Vec3>],
    simulator: &[Vec<Vec3>],
    simulator_static: &[Vec<Vec3>],
) -> Result<Option<RigidSplit>, TrainError> {
    let parts = (
        mean_fit(simulator, network)?,
        mean_fit(network_static, network)?,
        mean_fit(simulator_static, simulator)?,
    );
    let (Some((shape_distance_mm, _)), Some(net), Some(sim)) = parts else {
        return Ok(None);
    };
    Ok(Some(RigidSplit {
        shape_distance_mm,
        network_slip_mm: net.1,
        network_shape_swing_mm: net.0,
        simulator_slip_mm: sim.1,
        simulator_shape_swing_mm: sim.0,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape() -> Vec<Vec3> {
        (0..40)
            .map(|i| {
                let t = i as f32 * 0.37;
                Vec3::new(0.2 * t.cos(), 0.05 * i as f32, 0.15 * t.sin())
            })
            .collect()
    }

    fn yaw(ps: &[Vec3], angle: f32, shift: Vec3) -> Vec<Vec3> {
        let (s, c) = angle.sin_cos();
        ps.iter()
            .map(|p| Vec3::new(c * p.x + s * p.z, p.y, -s * p.x + c * p.z) + shift)
            .collect()
    }

    #[test]
    fn a_rigidly_moved_garment_has_no_shape_difference() {
        let a = shape();
        let b = yaw(&a, 0.1, Vec3::new(0.01, -0.02, 0.005));
        let fit = best_rigid_fit(&a, &b).unwrap();
        assert!(fit.residual_m < 1e-6, "{fit:?}");
        let mean_moved = a
            .iter()
            .zip(&b)
            .map(|(p, q)| f64::from((p - q).norm()))
            .sum::<f64>()
            / a.len() as f64;
        assert!(
            (fit.moved_m - mean_moved).abs() < 1e-6,
            "{fit:?} {mean_moved}"
        );
    }

    #[test]
    fn a_deformed_garment_keeps_its_shape_difference_and_a_mirror_is_not_a_rotation() {
        let a = shape();
        // Stretch along x by 10 %: no rigid motion explains it.
        let b: Vec<Vec3> = a.iter().map(|p| Vec3::new(1.1 * p.x, p.y, p.z)).collect();
        let fit = best_rigid_fit(&a, &b).unwrap();
        assert!(fit.residual_m > 1e-3, "{fit:?}");
        // A reflection must not be fitted by a proper rotation with zero residual.
        let m: Vec<Vec3> = a.iter().map(|p| Vec3::new(-p.x, p.y, p.z)).collect();
        assert!(best_rigid_fit(&a, &m).unwrap().residual_m > 1e-3);
        // Degenerate and mismatched input: finite or refused, never NaN.
        let point = vec![Vec3::zeros(); 5];
        let fit = best_rigid_fit(&point, &point).unwrap();
        assert!(fit.residual_m.is_finite() && fit.moved_m.is_finite());
        assert!(best_rigid_fit(&a, &a[..3]).is_none());
        // Regression: a NaN vertex made nalgebra's 3x3 SVD loop for ever; now there is no fit.
        let mut broken = a.clone();
        broken[3].y = f32::NAN;
        assert!(best_rigid_fit(&a, &broken).is_none());
        broken[3].y = f32::INFINITY;
        assert!(best_rigid_fit(&broken, &a).is_none());
        assert!(best_rigid_fit(&[], &[]).is_none());
    }

    #[test]
    fn the_split_puts_slip_and_shape_where_they_belong() {
        let qs = vec![shape(); 3];
        // The "simulator" slips by a yaw; the "network" deforms in place.
        let sim: Vec<Vec<Vec3>> = qs.iter().map(|f| yaw(f, 0.08, Vec3::zeros())).collect();
        let net: Vec<Vec<Vec3>> = qs
            .iter()
            .map(|f| {
                f.iter()
                    .map(|p| p + Vec3::new(0.0, 0.0, 0.01 * p.y))
                    .collect()
            })
            .collect();
        let split = rigid_split(&net, &qs, &sim, &qs).unwrap().unwrap();
        assert!(split.simulator_shape_swing_mm < 1e-3, "{split:?}");
        assert!(split.simulator_slip_mm > 5.0, "{split:?}");
        assert!(split.network_shape_swing_mm > 1e-3, "{split:?}");
        assert!(rigid_split(&net, &qs, &sim, &qs[..2]).is_err());
        // A diverged network: no split, and no error (its distances already say NaN).
        let mut diverged = net.clone();
        diverged[1][0].x = f32::NAN;
        assert_eq!(rigid_split(&diverged, &qs, &sim, &qs).unwrap(), None);
    }
}
