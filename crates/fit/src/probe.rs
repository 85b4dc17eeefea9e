//! The avatar's body at its rest pose (or another pose) as the fitting sees it: signed
//! clearance of a point (nearest body vertex and its normal, as the collision term and the
//! paper's collision metric measure it), the body's bounds, its horizontal extent per height
//! band, and the measurements built on them (vertices inside the body, which way a garment's
//! faces turn).

use neural_cloth_core::geometry::{TriMesh, Vec3, safe_normalize};
use neural_cloth_core::scene::{Avatar, Pose};
use neural_cloth_physics::PosedBody;

use super::FitError;
use super::repose::Limbs;

/// Height of one horizontal band of [`BodyProbe`]'s per-height extents, metres.
const BIN_M: f32 = 0.01;

/// The avatar's rest-pose body, ready for clearance queries.
#[derive(Clone, Debug)]
pub struct BodyProbe {
    body: PosedBody,
    lo_m: Vec3,
    hi_m: Vec3,
    /// Per band of [`BIN_M`] from `lo_m.y`: `(x_min, x_max, z_min, z_max)` of the body
    /// vertices in it, metres (`None` when the band holds none).
    bands: Vec<Option<[f32; 4]>>,
    /// Heights of the crotch and the neck, metres, when the body has them.
    trunk_m: Option<(f32, f32)>,
    /// Height of the shoulders (the mean of the upper-arm joints), metres, when the avatar
    /// has two arms.
    shoulders_m: Option<f32>,
}

impl BodyProbe {
    /// The body of `avatar` at the rest pose of its skeleton.
    pub fn rest(avatar: &Avatar) -> Result<Self, FitError> {
        Self::posed(avatar, &avatar.skeleton.rest_pose())
    }

    /// The body of `avatar` at `pose`.
    pub fn posed(avatar: &Avatar, pose: &Pose) -> Result<Self, FitError> {
        let body = PosedBody::from_avatar(avatar, pose).map_err(|e| FitError::Body {
            avatar: avatar.name.clone(),
            reason: e.to_string(),
        })?;
        let Some((lo_m, hi_m)) = bounds_of(body.positions()) else {
            return Err(FitError::Body {
                avatar: avatar.name.clone(),
                reason: "the body has no vertices".into(),
            });
        };
        let count = (((hi_m.y - lo_m.y) / BIN_M).ceil() as usize).max(1);
        let mut bands: Vec<Option<[f32; 4]>> = vec![None; count];
        let mut centred = vec![false; count];
        let centre_x = 0.5 * (lo_m.x + hi_m.x);
        let near_centre_m = 0.01 * (hi_m.y - lo_m.y);
        for p in body.positions() {
            let k = (((p.y - lo_m.y) / BIN_M) as usize).min(count - 1);
            bands[k] = Some(match bands[k] {
                None => [p.x, p.x, p.z, p.z],
                Some([x0, x1, z0, z1]) => [x0.min(p.x), x1.max(p.x), z0.min(p.z), z1.max(p.z)],
            });
            centred[k] |= (p.x - centre_x).abs() < near_centre_m;
        }
        let trunk_m = trunk(&bands, &centred).map(|(c, n)| {
            (
                lo_m.y + (c as f32 + 0.5) * BIN_M,
                lo_m.y + (n as f32 + 0.5) * BIN_M,
            )
        });
        let shoulders_m = Limbs::arms(avatar).map(|arms| {
            let joints = avatar.skeleton.joint_positions(pose);
            let [left, right] = arms.joints();
            0.5 * (joints[left].y + joints[right].y)
        });
        Ok(Self {
            body,
            lo_m,
            hi_m,
            bands,
            trunk_m,
            shoulders_m,
        })
    }

    /// Heights of the crotch (where the legs join) and the neck (the narrowest band between
    /// the shoulders and the top of the head), metres; `None` for a body without them.
    pub fn trunk_m(&self) -> Option<(f32, f32)> {
        self.trunk_m
    }

    /// Height of the shoulders (the mean height of the upper-arm joints), metres; `None` for
    /// an avatar without two arms. A garment without openings for the arms is worn below
    /// them.
    pub fn shoulders_m(&self) -> Option<f32> {
        self.shoulders_m
    }

    /// Lower and upper corners of the body's bounding box, metres.
    pub fn bounds_m(&self) -> (Vec3, Vec3) {
        (self.lo_m, self.hi_m)
    }

    /// Height of the body, metres.
    pub fn height_m(&self) -> f32 {
        self.hi_m.y - self.lo_m.y
    }

    /// The nearest body vertex to `q` and its unit normal, metres.
    pub fn nearest(&self, q: &Vec3) -> (Vec3, Vec3) {
        let i = self.body.nearest(q);
        (self.body.positions()[i], self.body.normals()[i])
    }

    /// Signed clearance of `q` from the body, metres: `n_b · (q - b)` for the nearest body
    /// vertex `b` and its normal `n_b` (negative inside).
    pub fn clearance_m(&self, q: &Vec3) -> f32 {
        self.body.signed_distance(q)
    }

    /// Centre `(x, z)` of the bounding box of the body vertices between heights `y_lo_m` and
    /// `y_hi_m`; `None` when no body vertex lies in that band.
    pub fn band_centre_xz(&self, y_lo_m: f32, y_hi_m: f32) -> Option<(f32, f32)> {
        let last = self.bands.len().checked_sub(1)?;
        let lo = ((y_lo_m - self.lo_m.y) / BIN_M).floor().max(0.0) as usize;
        let hi_f = ((y_hi_m - self.lo_m.y) / BIN_M).floor();
        if hi_f < 0.0 || lo > last {
            return None;
        }
        let hi = (hi_f as usize).min(last);
        let box_xz = self.bands[lo..=hi.max(lo)]
            .iter()
            .flatten()
            .copied()
            .reduce(|a, b| {
                [
                    a[0].min(b[0]),
                    a[1].max(b[1]),
                    a[2].min(b[2]),
                    a[3].max(b[3]),
                ]
            })?;
        Some((0.5 * (box_xz[0] + box_xz[1]), 0.5 * (box_xz[2] + box_xz[3])))
    }

    /// Number of `points` inside the body (clearance below zero).
    pub fn inside_count(&self, points: &[Vec3]) -> usize {
        points.iter().filter(|p| self.clearance_m(p) < 0.0).count()
    }

    /// Share of `points` outside the body's bounding box grown by `margin_m` on every side,
    /// in [0, 1] (0 for no points).
    pub fn outside_bounds_share(&self, points: &[Vec3], margin_m: f32) -> f32 {
        if points.is_empty() {
            return 0.0;
        }
        let (lo, hi) = (
            self.lo_m.add_scalar(-margin_m),
            self.hi_m.add_scalar(margin_m),
        );
        let outside = points
            .iter()
            .filter(|p| (0..3).any(|k| p[k] < lo[k] || p[k] > hi[k]))
            .count();
        outside as f32 / points.len() as f32
    }

    /// Share of the 36 sectors of 10° around the body's vertical axis that `points` cover,
    /// in [0, 1]: each point's azimuth is taken about the centre of the body band at its
    /// height (±5 cm). A garment worn around the body covers all of them; a sheet against
    /// it, half or less. Points beside no body band are left out.
    pub fn azimuth_coverage(&self, points: &[Vec3]) -> f32 {
        const SECTORS: usize = 36;
        let mut hit = [false; SECTORS];
        for p in points {
            let Some((cx, cz)) = self.band_centre_xz(p.y - 0.05, p.y + 0.05) else {
                continue;
            };
            let (dx, dz) = (p.x - cx, p.z - cz);
            if dx == 0.0 && dz == 0.0 {
                continue;
            }
            let turn = dz.atan2(dx) / std::f32::consts::TAU + 0.5;
            hit[((turn * SECTORS as f32) as usize).min(SECTORS - 1)] = true;
        }
        hit.iter().filter(|&&h| h).count() as f32 / SECTORS as f32
    }

    /// Which way the faces of `mesh` turn, in [-1, 1]: the area-weighted mean of the cosine
    /// between each face's normal and the normal of the body vertex nearest to its centre.
    /// A garment wound outward (as it should be) scores near 1; one mirrored in its file
    /// (the positions reflected, the faces not) near -1. 0 for a mesh without area.
    pub fn winding_score(&self, mesh: &TriMesh) -> f32 {
        let (mut sum, mut total) = (0.0f64, 0.0f64);
        for (f, cross) in mesh.face_cross().iter().enumerate() {
            let area = 0.5 * f64::from(cross.norm());
            let Some(n) = safe_normalize(*cross) else {
                continue;
            };
            let [a, b, c] = mesh.corners(f);
            let (_, body_n) = self.nearest(&((a + b + c) / 3.0));
            sum += area * f64::from(n.dot(&body_n));
            total += area;
        }
        if total > 0.0 {
            (sum / total) as f32
        } else {
            0.0
        }
    }
}

/// Band indices of the crotch and the neck: the crotch is the lowest band between 30 % and
/// 70 % of the height from which every band up to 70 % has body at the centre plane, give
/// or take 3 % of the height (below it, the legs leave a gap); the neck is the band of least
/// width between 75 % and 95 %.
fn trunk(bands: &[Option<[f32; 4]>], centred: &[bool]) -> Option<(usize, usize)> {
    let n = bands.len();
    let at = |share: f32| ((n as f32 * share) as usize).min(n.saturating_sub(1));
    let (lo, mid) = (at(0.3), at(0.7));
    // A coarse body has no vertex near the centre plane in every band: look a few bands up
    // and down.
    let reach = (0.03 * n as f32).ceil() as usize;
    let near = |k: usize| {
        centred[k.saturating_sub(reach)..(k + reach + 1).min(n)]
            .iter()
            .any(|&c| c)
    };
    let mut crotch = None;
    for k in (lo..=mid).rev() {
        if !near(k) {
            break;
        }
        crotch = Some(k);
    }
    let neck = (at(0.75)..=at(0.95))
        .filter_map(|k| bands[k].map(|b| (k, b[1] - b[0])))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(k, _)| k);
    crotch.zip(neck).filter(|(c, n)| c < n)
}

/// Bounds `(min, max)` of `points`; `None` when empty.
pub fn bounds_of(points: &[Vec3]) -> Option<(Vec3, Vec3)> {
    let first = *points.first()?;
    Some(
        points
            .iter()
            .fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p))),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use neural_cloth_core::scene::procedural::{GarmentKind, builtin_garment, mannequin};

    #[test]
    fn the_builtin_tshirt_is_outside_the_body_and_wound_outward() {
        let avatar = mannequin().unwrap();
        let probe = BodyProbe::rest(&avatar).unwrap();
        assert!(
            (1.5..2.0).contains(&probe.height_m()),
            "{}",
            probe.height_m()
        );
        let garment = builtin_garment(&avatar, GarmentKind::TShirt, 800, None).unwrap();
        let inside = probe.inside_count(&garment.mesh.positions);
        assert!(inside * 100 <= garment.vertex_count(), "{inside} inside");
        assert!(probe.winding_score(&garment.mesh) > 0.5);
        assert!(probe.azimuth_coverage(&garment.mesh.positions) > 0.9);
        let front: Vec<Vec3> = garment
            .mesh
            .positions
            .iter()
            .copied()
            .filter(|p| p.z > 0.05)
            .collect();
        assert!(probe.azimuth_coverage(&front) < 0.6);
        let mut mirrored = garment.mesh.clone();
        mirrored.map_positions(|p| Vec3::new(-p.x, p.y, p.z));
        assert!(probe.winding_score(&mirrored) < -0.5);
        assert_eq!(
            probe.outside_bounds_share(&garment.mesh.positions, 0.1),
            0.0
        );
        assert!(probe.outside_bounds_share(&garment.mesh.positions, -0.1) > 0.5);
        let (x, z) = probe.band_centre_xz(1.0, 1.3).unwrap();
        assert!(x.abs() < 0.01 && z.abs() < 0.1, "{x} {z}");
        assert!(probe.band_centre_xz(5.0, 6.0).is_none());
        let (crotch, neck) = probe.trunk_m().unwrap();
        assert!((0.7..0.95).contains(&crotch), "crotch at {crotch} m");
        assert!((1.4..1.6).contains(&neck), "neck at {neck} m");
    }
}
