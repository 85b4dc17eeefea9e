//! The paper's bending and Baraff-Witkin stretch metrics exactly as its official code
//! (`hbertiche/NeuralClothSim`) computes them, beside our own ones in [`super::metrics`].
//!
//! # What the official code does
//!
//! **Bending** (`ncs/loss/losses.py`, `BendingLoss.__call__`, its `error`): for every entry of
//! `garment.face_adjacency` (`ncs/utils/mesh.py`, `faces_to_edges_and_adjacency`: *every pair*
//! of faces that share an undirected edge, so one pair per interior edge and all `k(k-1)/2`
//! pairs at a non-manifold edge of `k` faces) it takes the face normals of `face_normals`
//! (`ncs/utils/mesh.py`: `(x1 - x0) × (x2 - x1)` divided by `|·| + 1e-7`), the *unsigned*
//! angle `θ = atan2(|n0 × n1|, n0 · n1)` and the same `θ̄` on the rest mesh
//! (`ncs/model/cloth.py`, `Garment.face_dihedral` from `dihedral_angle_adjacent_faces`), and
//! reports `tf.reduce_mean(|θ - θ̄|)` over batch and pairs: a plain mean, no weights, no
//! skipped hinge. Radians.
//!
//! **Stretch** (`ncs/loss/losses.py`, `ClothLoss.__call__`, its `stretch_error`): the rest
//! frame comes from `Garment.make_continuum` (`ncs/model/cloth.py`): each face's rest normal
//! `n` is rotated onto `+Z` by the rotation vector `angle · axis`, `angle = arccos(n_z)`,
//! `axis = normalise(n_y, -n_x, 0)` (the minimal rotation), the rotated rest triangle's `x, y`
//! are its 2D coordinates, and `uv_matrices = inv([uv1 - uv0, uv2 - uv0])` (edges as columns).
//! Then `F = [x1 - x0, x2 - x0] · uv_matrices`, `w_u, w_v` its columns, `s = |w| - 1`, and
//! `stretch_error = mean_batch Σ_f Σ_{u,v} face_areas_f · |s| · 0.5 / total_area` where
//! `face_areas = |cross|` (*twice* the triangle area, `vertex_area` in `ncs/utils/mesh.py`)
//! and `total_area` the true total area (`Σ|cross|/2`). That is
//! `Σ_f |c_f| (|s_u| + |s_v|) / Σ_f |c_f|`: the area-weighted mean of the **sum**
//! `|s_u| + |s_v|`, i.e. about twice our [`ClothMetrics::stretch`](super::ClothMetrics),
//! which averages the two directions. Unitless.
//!
//! # Where we differ (on purpose)
//!
//! - Faces whose rest normal is exactly `±Z` give `axis = 0/0` in the official code, hence NaN
//!   rotations and a NaN metric. Here `+Z` uses the identity and `-Z` the rotation by `π` about
//!   `+X` (`(x, y, z) → (x, -y, -z)`), the limit of the official rotation as `n → -Z` with
//!   `n_x = 0, n_y > 0`.
//! - Rest normals are normalised exactly (the official `+1e-7` in the normalisation tilts the
//!   rotation slightly for small faces; its effect on lengths is of order `1e-7/|c|`).
//! - Rest faces that are degenerate (`GarmentRest::face_area2_m2 == 0`) are left out of the
//!   stretch (the official `np.linalg.inv` would fail on them; their official weight is ~0).
//! - In the bending, a zero normal (a collapsed face) gives `θ = 0` (`atan2(0, ±0)` could give
//!   `π` for a negative zero); no normal is ever normalised, `atan2` being scale-invariant.
//! - An empty list of face pairs (or of faces) gives 0 instead of the official NaN.
//!
//! Everything is plain `f64` arithmetic on positions read back to the CPU:
//! `O(B · (F + pairs))` time and no allocation proportional to the batch.

use std::borrow::Cow;

use neural_cloth_core::geometry::Vec3;

use super::{GarmentRest, PhysicsError};

type V64 = nalgebra::Vector3<f64>;

/// The two official metrics of one batch, averaged over the batch.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PaperMetrics {
    /// Mean `|θ - θ̄|` of the unsigned angle between the normals of every pair of faces
    /// sharing an edge, radians.
    pub bending_rad: f64,
    /// `Σ_f |c_f| (| |w_u| - 1 | + | |w_v| - 1 |) / Σ_f |c_f|` with the official rest frames
    /// (rest normal rotated onto `+Z`), unitless.
    pub stretch: f64,
}

/// The official face normal `(x1 - x0) × (x2 - x1)`, unnormalised (length `|cross|`).
pub fn face_normal(p: [V64; 3]) -> V64 {
    (p[1] - p[0]).cross(&(p[2] - p[1]))
}

/// The unsigned angle `atan2(|n0 × n1|, n0 · n1)` between two (not necessarily unit) normals,
/// in `[0, π]`; 0 when both the sine and cosine vanish (a zero normal).
pub fn unsigned_angle(n0: &V64, n1: &V64) -> f64 {
    let (sin, cos) = (n0.cross(n1).norm(), n0.dot(n1));
    if sin == 0.0 && cos == 0.0 {
        0.0
    } else {
        sin.atan2(cos)
    }
}

/// The first two rows of the official rest rotation of a face with unit normal `n`: the
/// minimal rotation taking `n` to `+Z` (Rodrigues with axis `(n_y, -n_x, 0)/s`, `cos = n_z`,
/// `sin = s = √(n_x² + n_y²)`); for `s = 0`, the identity (`+Z`) or `diag(1, -1, -1)` (`-Z`).
pub fn rotation_to_z_rows(n: &V64) -> [V64; 2] {
    let s2 = n.x * n.x + n.y * n.y;
    if s2 > 0.0 {
        let s = s2.sqrt();
        let (a, b, c) = (n.y / s, -n.x / s, n.z);
        [
            V64::new(c + (1.0 - c) * a * a, (1.0 - c) * a * b, -n.x),
            V64::new((1.0 - c) * a * b, c + (1.0 - c) * b * b, -n.y),
        ]
    } else if n.z >= 0.0 {
        [V64::x(), V64::y()]
    } else {
        [V64::x(), -V64::y()]
    }
}

/// The official rest frame of the rest triangle `p`: `(|cross|, [c00, c01, c10, c11])` with
/// `[[c00, c01], [c10, c11]] = inv([uv1 - uv0, uv2 - uv0])`, so that
/// `w_u = dx1·c00 + dx2·c10` and `w_v = dx1·c01 + dx2·c11`. `None` for a zero or non-finite
/// normal or a singular 2D matrix.
pub fn official_rest_frame(p: [V64; 3]) -> Option<(f64, [f64; 4])> {
    let normal = face_normal(p);
    let area2 = normal.norm();
    if !(area2 > 0.0 && area2.is_finite()) {
        return None;
    }
    let [ru, rv] = rotation_to_z_rows(&(normal / area2));
    let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
    let (m00, m01, m10, m11) = (ru.dot(&e1), ru.dot(&e2), rv.dot(&e1), rv.dot(&e2));
    let det = m00 * m11 - m01 * m10;
    if !(det != 0.0 && det.is_finite()) {
        return None;
    }
    Some((area2, [m11 / det, -m01 / det, -m10 / det, m00 / det]))
}

/// The official face adjacency of `faces`: every pair of faces sharing an undirected edge
/// (`faces_to_edges_and_adjacency`), in edge order.
pub fn official_face_pairs(faces: &[[u32; 3]]) -> Vec<[u32; 2]> {
    let mut uses: Vec<([u32; 2], u32)> = Vec::with_capacity(3 * faces.len());
    for (f, t) in faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            uses.push(([a.min(b), a.max(b)], f as u32));
        }
    }
    uses.sort_unstable();
    let mut pairs = Vec::new();
    for group in uses.chunk_by(|a, b| a.0 == b.0) {
        for (i, (_, fi)) in group.iter().enumerate() {
            for (_, fj) in &group[i + 1..] {
                pairs.push([*fi, *fj]);
            }
        }
    }
    pairs
}

/// The official face pairs of `rest`: its own hinges when the mesh is manifold (every face has
/// three distinct vertices and `3F = E + H`, i.e. no edge has more than two faces), otherwise
/// [`official_face_pairs`].
pub fn face_pairs(rest: &GarmentRest) -> Cow<'_, [[u32; 2]]> {
    let proper = rest
        .faces
        .iter()
        .all(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
    if proper && 3 * rest.faces.len() == rest.edges.len() + rest.hinge_faces.len() {
        Cow::Borrowed(&rest.hinge_faces)
    } else {
        Cow::Owned(official_face_pairs(&rest.faces))
    }
}

/// The official bending and stretch metrics of `batch` samples of positions `x` (flat
/// `[B, V, 3]`, metres), averaged over the batch.
pub fn paper_metrics(
    rest: &GarmentRest,
    x: &[f32],
    batch: usize,
) -> Result<PaperMetrics, PhysicsError> {
    let v = rest.vertex_count();
    if x.len() != batch * v * 3 {
        return Err(PhysicsError::ShapeMismatch {
            what: "positions for the paper metrics".into(),
            expected: format!("{batch} x {v} x 3 values"),
            found: x.len().to_string(),
        });
    }
    if batch == 0 {
        return Ok(PaperMetrics::default());
    }
    let at = |b: usize, i: u32| -> V64 {
        let k = (b * v + i as usize) * 3;
        V64::new(f64::from(x[k]), f64::from(x[k + 1]), f64::from(x[k + 2]))
    };
    let rest_at = |i: u32| -> V64 { rest.rest_positions[i as usize].cast::<f64>() };
    // Faces or pairs referring past the vertex list cannot come from a valid `GarmentRest`.
    let bad = |i: u32| i as usize >= v;
    if rest.faces.iter().flatten().any(|&i| bad(i)) {
        return Err(PhysicsError::InvalidGarment(
            "face index out of range in the paper metrics".into(),
        ));
    }

    let mut stretch_sum = 0.0;
    let mut weight_sum = 0.0;
    for (f, face) in rest.faces.iter().enumerate() {
        if !rest.face_area2_m2.get(f).is_some_and(|&a| a > 0.0) {
            continue;
        }
        let Some((area2, [c00, c01, c10, c11])) = official_rest_frame(face.map(rest_at)) else {
            continue;
        };
        weight_sum += area2;
        for b in 0..batch {
            let [x0, x1, x2] = face.map(|i| at(b, i));
            let (d1, d2) = (x1 - x0, x2 - x0);
            let wu = d1 * c00 + d2 * c10;
            let wv = d1 * c01 + d2 * c11;
            stretch_sum += area2 * ((wu.norm() - 1.0).abs() + (wv.norm() - 1.0).abs());
        }
    }

    let pairs = face_pairs(rest);
    let nf = rest.faces.len();
    let mut bending_sum = 0.0;
    for &[f0, f1] in pairs.iter() {
        let (Some(t0), Some(t1)) = (rest.faces.get(f0 as usize), rest.faces.get(f1 as usize))
        else {
            return Err(PhysicsError::InvalidGarment(format!(
                "face pair [{f0}, {f1}] out of range ({nf} faces) in the paper metrics"
            )));
        };
        let rest_angle =
            unsigned_angle(&face_normal(t0.map(rest_at)), &face_normal(t1.map(rest_at)));
        for b in 0..batch {
            let n0 = face_normal(t0.map(|i| at(b, i)));
            let n1 = face_normal(t1.map(|i| at(b, i)));
            bending_sum += (unsigned_angle(&n0, &n1) - rest_angle).abs();
        }
    }

    let samples = batch as f64;
    Ok(PaperMetrics {
        bending_rad: if pairs.is_empty() {
            0.0
        } else {
            bending_sum / (pairs.len() as f64 * samples)
        },
        stretch: if weight_sum > 0.0 {
            stretch_sum / (weight_sum * samples)
        } else {
            0.0
        },
    })
}

/// [`paper_metrics`] of one frame of positions.
pub fn paper_metrics_of_frame(
    rest: &GarmentRest,
    frame: &[Vec3],
) -> Result<PaperMetrics, PhysicsError> {
    let flat: Vec<f32> = frame.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    paper_metrics(rest, &flat, 1)
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use nalgebra::{Rotation3, Unit};

    use super::*;
    use neural_cloth_core::geometry::{Topology, TriMesh};

    fn rest_of(mesh: &TriMesh) -> GarmentRest {
        GarmentRest::new(mesh, &Topology::new(mesh), &[], &[], 0.15).unwrap()
    }

    fn mesh(positions: Vec<Vec3>, faces: Vec<[u32; 3]>) -> TriMesh {
        TriMesh {
            positions,
            faces,
            uvs: None,
        }
    }

    /// Unit square `0 (0,0,0), 1 (1,0,0), 2 (1,1,0), 3 (0,1,0)` split along the diagonal 0-2,
    /// with vertex 3 rotated by `phi` about that diagonal.
    fn folded_square(phi: f64) -> Vec<Vec3> {
        let axis = Unit::new_normalize(V64::new(1.0, 1.0, 0.0));
        let p3 = Rotation3::from_axis_angle(&axis, phi) * V64::new(0.0, 1.0, 0.0);
        vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            p3.cast::<f32>(),
        ]
    }

    const SQUARE_FACES: [[u32; 3]; 2] = [[0, 1, 2], [0, 2, 3]];

    #[test]
    fn folded_square_bending_is_the_unsigned_fold_angle() {
        let rest = rest_of(&mesh(folded_square(0.0), SQUARE_FACES.to_vec()));
        assert_eq!(face_pairs(&rest).len(), 1);
        let at_rest = paper_metrics_of_frame(&rest, &rest.rest_positions).unwrap();
        assert_eq!(at_rest.bending_rad, 0.0);
        assert!(at_rest.stretch < 1e-12, "{at_rest:?}");
        for phi in [0.3, -0.3, 1.2, -1.2, 2.5] {
            let m = paper_metrics_of_frame(&rest, &folded_square(phi)).unwrap();
            assert!((m.bending_rad - f64::abs(phi)).abs() < 1e-6, "{phi}: {m:?}");
            // Folding is rigid per triangle: no stretch.
            assert!(m.stretch < 1e-6, "{phi}: {m:?}");
        }
        // Rest folded by +0.4, current by -0.4: unsigned angles agree, the error is 0.
        let rest = rest_of(&mesh(folded_square(0.4), SQUARE_FACES.to_vec()));
        let m = paper_metrics_of_frame(&rest, &folded_square(-0.4)).unwrap();
        assert!(m.bending_rad < 1e-6, "{m:?}");
        let m = paper_metrics_of_frame(&rest, &folded_square(1.0)).unwrap();
        assert!((m.bending_rad - 0.6).abs() < 1e-6, "{m:?}");
    }

    #[test]
    fn rest_frame_is_the_official_rotation_to_plus_z() {
        // A tilted triangle: compare with nalgebra's axis-angle rotation (scipy's from_rotvec).
        let p = [
            V64::new(0.1, -0.2, 0.3),
            V64::new(0.5, 0.1, 0.0),
            V64::new(-0.1, 0.4, 0.6),
        ];
        let n = face_normal(p).normalize();
        let axis = Unit::new_normalize(V64::new(n.y, -n.x, 0.0));
        let rot = Rotation3::from_axis_angle(&axis, n.z.acos());
        assert!((rot * n - V64::z()).norm() < 1e-12);
        let q = p.map(|v| rot * v);
        assert!((q[0].z - q[1].z).abs() < 1e-12 && (q[0].z - q[2].z).abs() < 1e-12);
        let m = nalgebra::Matrix2::new(
            q[1].x - q[0].x,
            q[2].x - q[0].x,
            q[1].y - q[0].y,
            q[2].y - q[0].y,
        );
        let inv = m.try_inverse().unwrap();
        let (area2, c) = official_rest_frame(p).unwrap();
        assert!((area2 - (p[1] - p[0]).cross(&(p[2] - p[0])).norm()).abs() < 1e-12);
        let want = [inv[(0, 0)], inv[(0, 1)], inv[(1, 0)], inv[(1, 1)]];
        for (a, b) in c.iter().zip(want) {
            assert!((a - b).abs() < 1e-9, "{c:?} vs {want:?}");
        }
        // The rotation rows are those of nalgebra's matrix.
        let [ru, rv] = rotation_to_z_rows(&n);
        let r = rot.matrix();
        assert!((ru - V64::new(r[(0, 0)], r[(0, 1)], r[(0, 2)])).norm() < 1e-12);
        assert!((rv - V64::new(r[(1, 0)], r[(1, 1)], r[(1, 2)])).norm() < 1e-12);
    }

    #[test]
    fn normals_exactly_plus_and_minus_z_work() {
        let pos = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ];
        for faces in [vec![[0, 1, 2]], vec![[0, 2, 1]]] {
            let up = faces[0] == [0, 1, 2];
            let rest = rest_of(&mesh(pos.clone(), faces));
            let m = paper_metrics_of_frame(&rest, &pos).unwrap();
            assert!(m.stretch.is_finite() && m.stretch < 1e-12, "{up}: {m:?}");
            assert_eq!(m.bending_rad, 0.0);
            // Stretch along x by 10 %: u is x for both, so |w_u| = 1.1, |w_v| = 1.
            let stretched: Vec<Vec3> = pos.iter().map(|p| Vec3::new(p.x * 1.1, p.y, p.z)).collect();
            let m = paper_metrics_of_frame(&rest, &stretched).unwrap();
            assert!((m.stretch - 0.1).abs() < 1e-6, "{up}: {m:?}");
        }
        // The -Z frame is the limit of the official rotation for n → -Z with n_x = 0, n_y > 0.
        let exact = rotation_to_z_rows(&V64::new(0.0, 0.0, -1.0));
        let near = rotation_to_z_rows(&V64::new(0.0, 1e-9, -1.0).normalize());
        assert!((exact[0] - near[0]).norm() < 1e-8 && (exact[1] - near[1]).norm() < 1e-8);
        let near_up = rotation_to_z_rows(&V64::new(3e-10, 1e-9, 1.0).normalize());
        assert!((near_up[0] - V64::x()).norm() < 1e-8 && (near_up[1] - V64::y()).norm() < 1e-8);
    }

    #[test]
    fn uniform_and_directional_stretch_match_the_closed_form() {
        let sheet = crate::shapes::sheet(
            3,
            2,
            Vec3::new(0.1, 0.2, 0.3),
            Vec3::new(0.4, 0.3, 0.1),
            Vec3::new(-0.1, 0.2, 0.5),
        );
        let rest = rest_of(&sheet);
        let e = 0.1;
        // Uniform scaling by (1+e): |w_u| = |w_v| = 1+e, official stretch = 2e.
        let scaled: Vec<Vec3> = sheet
            .positions
            .iter()
            .map(|p| p * (1.0 + e as f32))
            .collect();
        let m = paper_metrics_of_frame(&rest, &scaled).unwrap();
        assert!((m.stretch - 2.0 * e).abs() < 1e-6, "{m:?}");
        // Stretch by (1+e) along the official u axis: |w_u| = 1+e, |w_v| = 1, stretch = e;
        // along the diagonal of (u, v): |w_u| = |w_v| = √(1 + e + e²/2).
        let n = face_normal(sheet.faces[0].map(|i| sheet.positions[i as usize].cast::<f64>()))
            .normalize();
        let [ru, rv] = rotation_to_z_rows(&n);
        let along = |d: V64| -> Vec<Vec3> {
            sheet
                .positions
                .iter()
                .map(|p| {
                    let p = p.cast::<f64>();
                    (p + d * (e * d.dot(&p))).cast::<f32>()
                })
                .collect()
        };
        let m = paper_metrics_of_frame(&rest, &along(ru)).unwrap();
        assert!((m.stretch - e).abs() < 1e-6, "{m:?}");
        let m = paper_metrics_of_frame(&rest, &along((ru + rv) / 2f64.sqrt())).unwrap();
        let want = 2.0 * ((1.0 + e + e * e / 2.0).sqrt() - 1.0);
        assert!((m.stretch - want).abs() < 1e-6, "{m:?} vs {want}");
        assert!((want - e).abs() > 2e-3);
    }

    #[test]
    fn face_pairs_match_the_official_adjacency() {
        let sheet = crate::shapes::sheet(3, 3, Vec3::zeros(), Vec3::x(), Vec3::new(0.0, 0.2, 1.0));
        let rest = rest_of(&sheet);
        let norm = |mut v: Vec<[u32; 2]>| {
            for p in &mut v {
                p.sort_unstable();
            }
            v.sort_unstable();
            v
        };
        assert!(matches!(face_pairs(&rest), Cow::Borrowed(_)));
        let official = official_face_pairs(&rest.faces);
        assert_eq!(official.len(), 3 * 3 * 3 - 2 * 3);
        assert_eq!(norm(face_pairs(&rest).into_owned()), norm(official));
        // Three faces on the edge 0-1: three pairs, all counted (no hinge of ours there).
        let fan = mesh(
            vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.5, 1.0, 0.0),
                Vec3::new(0.5, 0.0, 1.0),
                Vec3::new(0.5, -1.0, 0.2),
            ],
            vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
        );
        let rest = rest_of(&fan);
        assert!(rest.hinge_faces.is_empty());
        assert_eq!(
            norm(face_pairs(&rest).into_owned()),
            vec![[0, 1], [0, 2], [1, 2]]
        );
        // Move vertex 2 next to vertex 3: pairs (0,1) and (0,2) change, (1,2) does not; the
        // metric is the plain mean of the three changes of unsigned angle.
        let mut x = fan.positions.clone();
        x[2] = Vec3::new(0.5, 0.0, 1.0) * 0.999 + Vec3::new(0.0, 0.001, 0.0);
        let rest_n =
            |p: &[Vec3], f: usize| face_normal(fan.faces[f].map(|i| p[i as usize].cast::<f64>()));
        let pair = |p: &[Vec3], a: usize, b: usize| unsigned_angle(&rest_n(p, a), &rest_n(p, b));
        let want = [(0, 1), (0, 2), (1, 2)]
            .iter()
            .map(|&(a, b)| (pair(&x, a, b) - pair(&fan.positions, a, b)).abs())
            .sum::<f64>()
            / 3.0;
        let m = paper_metrics_of_frame(&rest, &x).unwrap();
        assert!(
            (m.bending_rad - want).abs() < 1e-6 && want > 0.5,
            "{m:?} vs {want}"
        );
    }

    #[test]
    fn degenerate_faces_and_shapes_are_guarded() {
        let pos = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
        ];
        // A zero-area face (0, 1, 3 collinear) beside a proper one.
        let rest = rest_of(&mesh(pos.clone(), vec![[0, 1, 2], [0, 3, 1]]));
        let m = paper_metrics_of_frame(&rest, &pos).unwrap();
        assert!(m.stretch.is_finite() && m.bending_rad.is_finite(), "{m:?}");
        assert_eq!(m.bending_rad, 0.0);
        let collapsed = vec![Vec3::zeros(); 4];
        let m = paper_metrics_of_frame(&rest, &collapsed).unwrap();
        assert!(m.stretch.is_finite() && m.bending_rad.is_finite(), "{m:?}");
        // |w| = 0 for the proper face: stretch 2 (|0 - 1| twice).
        assert!((m.stretch - 2.0).abs() < 1e-12, "{m:?}");
        assert!(matches!(
            paper_metrics(&rest, &[0.0; 9], 1),
            Err(PhysicsError::ShapeMismatch { .. })
        ));
        assert_eq!(
            paper_metrics(&rest, &[], 0).unwrap(),
            PaperMetrics::default()
        );
        assert!((unsigned_angle(&V64::zeros(), &-V64::x())).abs() < 1e-300);
        assert!((unsigned_angle(&V64::x(), &-V64::x()) - PI).abs() < 1e-15);
    }
}
