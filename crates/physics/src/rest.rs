//! Rest-state quantities of a garment, computed once in `f64` on the CPU: vertex masses, edges
//! and rest lengths, per-triangle rest frames (inverse rest matrices), hinges with rest
//! dihedral angles and `l²/(8·Σ|cross|)` weights, pinning and collision masks.
//!
//! Degenerate elements never divide by zero: a triangle whose rest area is (relatively) zero
//! gets a zero inverse rest matrix and zero weight, a hinge touching such a triangle gets zero
//! weight, and the in-plane frame is built by projecting a world axis onto the triangle (no
//! rotation to +Z, so faces whose normal is exactly ±Z are ordinary).

use neural_cloth_core::geometry::{Topology, TriMesh, Vec3};
use neural_cloth_core::scene::Garment;

use super::{ClothModel, FabricParams, PhysicsError};

type V64 = nalgebra::Vector3<f64>;

/// Relative area below which a rest triangle counts as degenerate: `|cross| <= 1e-10 · l_max²`.
pub const DEGENERATE_RELATIVE_AREA: f64 = 1e-10;

/// Everything about a garment's rest state that the energies need, as plain arrays.
#[derive(Clone, Debug)]
pub struct GarmentRest {
    /// Rest (template) positions in metres.
    pub rest_positions: Vec<Vec3>,
    /// Lumped vertex masses in kg: density times a third of the incident triangle areas.
    pub mass_kg: Vec<f64>,
    /// Unique edges `[a, b]`.
    pub edges: Vec<[u32; 2]>,
    /// Rest edge lengths as the energies measure them, `sqrt(l² + edge_eps2_m2)`, in metres.
    pub edge_rest_m: Vec<f64>,
    /// Squared regulariser added under edge-length square roots (keeps gradients finite for
    /// coincident vertices), in m²: `(1e-6 · mean edge length)²`.
    pub edge_eps2_m2: f64,
    /// Triangles.
    pub faces: Vec<[u32; 3]>,
    /// Inverse rest matrices `[c00, c01, c10, c11]`: the deformation gradient's columns are
    /// `w_u = dx1·c00 + dx2·c10`, `w_v = dx1·c01 + dx2·c11`. Zero for degenerate triangles.
    pub face_inv_rest: Vec<[f64; 4]>,
    /// `|cross|` of each rest triangle (twice its area) in m², zero for degenerate triangles.
    pub face_area2_m2: Vec<f64>,
    /// Hinges `[edge0, edge1, opposite0, opposite1]`; the signed dihedral angle is that of the
    /// two faces' own normals about the edge `edge1 - edge0` (for consistently oriented meshes
    /// the convention of [`neural_cloth_core::geometry::topology::dihedral_angle`]).
    pub hinges: Vec<[u32; 4]>,
    /// Hinge weights `l̄² / (8 (|c̄_0| + |c̄_1|))` (dimensionless), zero for hinges touching a
    /// degenerate face.
    pub hinge_weight: Vec<f64>,
    /// Cosine of the rest dihedral angle.
    pub hinge_rest_cos: Vec<f64>,
    /// Sine of the rest dihedral angle.
    pub hinge_rest_sin: Vec<f64>,
    /// The two faces of each hinge (`faces[0]` holds the edge in the order of `hinges`).
    pub hinge_faces: Vec<[u32; 2]>,
    /// `1/|c̄_f|` per face (0 for degenerate ones): scales current face normals to ~unit length.
    pub face_normal_scale: Vec<f64>,
    /// Pinned vertices.
    pub pinned: Vec<u32>,
    /// Per vertex: does it collide with the body (false for the garment's `no_collide` list).
    pub collide: Vec<bool>,
    /// Total rest area in m².
    pub total_area_m2: f64,
    /// Total mass in kg.
    pub total_mass_kg: f64,
    /// Mean rest edge length in metres.
    pub mean_edge_m: f64,
}

impl GarmentRest {
    /// Rest state of a scene garment with the density of `fabric`.
    pub fn from_garment(garment: &Garment, fabric: &FabricParams) -> Result<Self, PhysicsError> {
        Self::new(
            &garment.mesh,
            &garment.topology,
            &garment.pinned,
            &garment.no_collide,
            fabric.density_kg_per_m2,
        )
    }

    /// Rest state of `mesh` with connectivity `topology`.
    pub fn new(
        mesh: &TriMesh,
        topology: &Topology,
        pinned: &[u32],
        no_collide: &[u32],
        density_kg_per_m2: f32,
    ) -> Result<Self, PhysicsError> {
        mesh.validate()
            .map_err(|e| PhysicsError::InvalidGarment(e.to_string()))?;
        let n = mesh.positions.len();
        if !(density_kg_per_m2.is_finite() && density_kg_per_m2 > 0.0) {
            return Err(PhysicsError::InvalidFabric {
                field: "density_kg_per_m2".into(),
                reason: format!("{density_kg_per_m2} is not positive"),
            });
        }
        let bad_index = |what: &str, list: &[u32]| -> Result<(), PhysicsError> {
            match list.iter().find(|&&i| i as usize >= n) {
                Some(i) => Err(PhysicsError::InvalidGarment(format!(
                    "{what} vertex {i} out of range ({n} vertices)"
                ))),
                None => Ok(()),
            }
        };
        bad_index("pinned", pinned)?;
        bad_index("no-collide", no_collide)?;
        let check_edges = topology.edges.iter().flatten().chain(
            topology
                .hinges
                .iter()
                .flat_map(|h| h.edge.iter().chain(&h.opposite)),
        );
        if let Some(i) = check_edges.copied().find(|&i| i as usize >= n) {
            return Err(PhysicsError::InvalidGarment(format!(
                "topology refers to vertex {i} of {n}"
            )));
        }
        let p: Vec<V64> = mesh.positions.iter().map(|v| v.cast::<f64>()).collect();

        // Triangles: |cross|, inverse rest matrices.
        let mut face_area2 = Vec::with_capacity(mesh.faces.len());
        let mut face_inv = Vec::with_capacity(mesh.faces.len());
        for face in &mesh.faces {
            let [a, b, c] = face.map(|i| p[i as usize]);
            let (area2, inv) = rest_frame(a, b, c);
            face_area2.push(area2);
            face_inv.push(inv);
        }
        let mut vertex_area = vec![0.0f64; n];
        for (face, &a2) in mesh.faces.iter().zip(&face_area2) {
            for &i in face {
                vertex_area[i as usize] += a2 / 6.0;
            }
        }
        let total_area_m2: f64 = face_area2.iter().sum::<f64>() / 2.0;
        let mass: Vec<f64> = vertex_area
            .iter()
            .map(|a| a * f64::from(density_kg_per_m2))
            .collect();

        // Edges.
        let lengths: Vec<f64> = topology
            .edges
            .iter()
            .map(|&[a, b]| (p[a as usize] - p[b as usize]).norm())
            .collect();
        let mean_edge = if lengths.is_empty() {
            0.0
        } else {
            lengths.iter().sum::<f64>() / lengths.len() as f64
        };
        let scale = if mean_edge > 0.0 { mean_edge } else { 1.0 };
        let edge_eps2 = (1e-6 * scale).powi(2);
        let edge_rest: Vec<f64> = lengths.iter().map(|l| (l * l + edge_eps2).sqrt()).collect();

        // Hinges, with the dihedral convention of the energy: the normals are the faces' own
        // `|cross|`-scaled normals, so a flipped face flips θ and θ̄ alike.
        let mut hinges = Vec::with_capacity(topology.hinges.len());
        let mut hinge_faces = Vec::with_capacity(topology.hinges.len());
        let (mut weight, mut rest_cos, mut rest_sin) = (vec![], vec![], vec![]);
        let unit_normal = |f: usize| -> Option<V64> {
            let [a, b, c] = mesh.faces.get(f)?.map(|i| p[i as usize]);
            let cross = (b - a).cross(&(c - a));
            (face_area2.get(f).copied().unwrap_or(0.0) > 0.0).then(|| cross / cross.norm())
        };
        for h in &topology.hinges {
            let [e0, e1] = h.edge;
            let [o0, o1] = h.opposite;
            if h.faces.iter().any(|&f| f as usize >= mesh.faces.len()) {
                return Err(PhysicsError::InvalidGarment(format!(
                    "hinge refers to face {:?} of {}",
                    h.faces,
                    mesh.faces.len()
                )));
            }
            hinges.push([e0, e1, o0, o1]);
            hinge_faces.push(h.faces);
            let edge = p[e1 as usize] - p[e0 as usize];
            let l = edge.norm();
            let (a0, a1) = (
                face_area2[h.faces[0] as usize],
                face_area2[h.faces[1] as usize],
            );
            match (
                unit_normal(h.faces[0] as usize),
                unit_normal(h.faces[1] as usize),
            ) {
                (Some(n0), Some(n1)) if l > 0.0 => {
                    let (s, c) = (n0.cross(&n1).dot(&edge) / l, n0.dot(&n1));
                    let r = (s * s + c * c).sqrt();
                    weight.push(l * l / (8.0 * (a0 + a1)));
                    rest_cos.push(if r > 0.0 { c / r } else { 1.0 });
                    rest_sin.push(if r > 0.0 { s / r } else { 0.0 });
                }
                _ => {
                    weight.push(0.0);
                    rest_cos.push(1.0);
                    rest_sin.push(0.0);
                }
            }
        }
        let face_normal_scale: Vec<f64> = face_area2
            .iter()
            .map(|&a| if a > 0.0 { 1.0 / a } else { 0.0 })
            .collect();
        let mut collide = vec![true; n];
        for &i in no_collide {
            collide[i as usize] = false;
        }
        let mut pinned = pinned.to_vec();
        pinned.sort_unstable();
        pinned.dedup();
        Ok(Self {
            rest_positions: mesh.positions.clone(),
            total_mass_kg: mass.iter().sum(),
            mass_kg: mass.clone(),
            edges: topology.edges.clone(),
            edge_rest_m: edge_rest,
            edge_eps2_m2: edge_eps2,
            faces: mesh.faces.clone(),
            face_inv_rest: face_inv,
            face_area2_m2: face_area2,
            hinges,
            hinge_faces,
            hinge_weight: weight,
            hinge_rest_cos: rest_cos,
            hinge_rest_sin: rest_sin,
            face_normal_scale,
            pinned,
            collide,
            total_area_m2,
            mean_edge_m: mean_edge,
        })
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.rest_positions.len()
    }

    /// A constant, isotropic approximation `K` (`V x V`, lower-triangle triplets) of the
    /// Hessian of the in-plane energy of `fabric` near rest, in N/m: the linear-FEM (cotangent)
    /// Laplacian `2 k_eff Σ_f |c̄_f| g_i·g_j` for triangle models, `2k` springs for mass-spring.
    /// The reference simulator factors `M/Δt² + K` as its L-BFGS initial metric.
    pub fn membrane_stiffness_triplets(&self, fabric: &FabricParams) -> Vec<(usize, usize, f64)> {
        let mut out = Vec::new();
        let mut add = |a: u32, b: u32, v: f64| {
            let (a, b) = (a as usize, b as usize);
            if a == b {
                out.push((a, a, v));
            } else {
                out.extend([(a, a, v), (b, b, v), (a.max(b), a.min(b), -v)]);
            }
        };
        match fabric.cloth_model {
            ClothModel::MassSpring => {
                let k = 2.0 * f64::from(fabric.stretch_stiffness);
                for &[a, b] in &self.edges {
                    add(a, b, k);
                }
            }
            ClothModel::BaraffWitkin | ClothModel::Stvk => {
                let k_eff = match fabric.cloth_model {
                    ClothModel::Stvk => {
                        f64::from(fabric.lame_mu) + 0.5 * f64::from(fabric.lame_lambda)
                    }
                    _ => {
                        f64::from(fabric.stretch_stiffness)
                            + 0.5 * f64::from(fabric.shear_stiffness)
                    }
                };
                for ((face, inv), &a2) in self
                    .faces
                    .iter()
                    .zip(&self.face_inv_rest)
                    .zip(&self.face_area2_m2)
                {
                    let [c00, c01, c10, c11] = *inv;
                    let g = [[-(c00 + c10), -(c01 + c11)], [c00, c01], [c10, c11]];
                    // K_ij = 2 k a2 g_i·g_j = Σ_{i<j} w_ij (e_i - e_j)(e_i - e_j)ᵀ with w_ij = -K_ij,
                    // since every row of K sums to zero.
                    for (i, j) in [(0, 1), (1, 2), (0, 2)] {
                        let w = -2.0 * k_eff * a2 * (g[i][0] * g[j][0] + g[i][1] * g[j][1]);
                        add(face[i], face[j], w);
                    }
                }
            }
        }
        out
    }
}

/// `(|cross|, inverse rest matrix)` of a triangle in a frame whose first axis is the world Y axis
/// projected onto the triangle (world Z when the triangle is nearly horizontal).
fn rest_frame(a: V64, b: V64, c: V64) -> (f64, [f64; 4]) {
    let (e1, e2) = (b - a, c - a);
    let cross = e1.cross(&e2);
    let area2 = cross.norm();
    let lmax2 = e1
        .norm_squared()
        .max(e2.norm_squared())
        .max((c - b).norm_squared());
    if !(area2.is_finite() && lmax2 > 0.0 && area2 > DEGENERATE_RELATIVE_AREA * lmax2) {
        return (0.0, [0.0; 4]);
    }
    let n = cross / area2;
    let project = |axis: V64| axis - n * n.dot(&axis);
    let mut u = project(V64::y());
    if u.norm_squared() < 0.25 {
        u = project(V64::z());
    }
    let u = u / u.norm();
    let v = n.cross(&u);
    let (a1, b1, a2, b2) = (e1.dot(&u), e1.dot(&v), e2.dot(&u), e2.dot(&v));
    let det = a1 * b2 - a2 * b1;
    if !(det.abs() > 0.0 && det.is_finite()) {
        return (0.0, [0.0; 4]);
    }
    let inv = [b2 / det, -a2 / det, -b1 / det, a1 / det];
    (area2, inv)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(n: usize) -> TriMesh {
        let mut positions = Vec::new();
        let mut faces = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                positions.push(Vec3::new(i as f32 / n as f32, 0.0, j as f32 / n as f32));
            }
        }
        for j in 0..n {
            for i in 0..n {
                let v = (j * (n + 1) + i) as u32;
                let w = v + n as u32 + 1;
                faces.push([v, w, v + 1]);
                faces.push([v + 1, w, w + 1]);
            }
        }
        TriMesh::new(positions, faces).unwrap()
    }

    #[test]
    fn masses_and_frames_of_a_flat_square() {
        let mesh = square(4);
        let topo = Topology::new(&mesh);
        let rest = GarmentRest::new(&mesh, &topo, &[], &[3], 0.2).unwrap();
        assert!((rest.total_area_m2 - 1.0).abs() < 1e-9);
        assert!((rest.total_mass_kg - 0.2).abs() < 1e-6);
        assert!(!rest.collide[3] && rest.collide[4]);
        // Horizontal faces (normal ±Y) use the Z fallback; frames are orthonormal: w_u, w_v unit.
        for (face, inv) in mesh.faces.iter().zip(&rest.face_inv_rest) {
            let [a, b, c] = face.map(|i| mesh.positions[i as usize]);
            let (d1, d2) = (b - a, c - a);
            let inv = inv.map(|c| c as f32);
            let wu = d1 * inv[0] + d2 * inv[2];
            let wv = d1 * inv[1] + d2 * inv[3];
            assert!(
                (wu.norm() - 1.0).abs() < 1e-5
                    && (wv.norm() - 1.0).abs() < 1e-5
                    && wu.dot(&wv).abs() < 1e-5
            );
        }
        assert!(rest.hinge_weight.iter().all(|w| *w > 0.0));
        assert!(rest.hinge_rest_sin.iter().all(|s| s.abs() < 1e-6));
    }

    #[test]
    fn degenerate_triangles_get_zero_weight_and_finite_frames() {
        // Face 0 is collinear, face 2 has two coincident vertices; both hinges touch one of them.
        let z = Vec3::new(0.0, 0.0, 1.0);
        let mesh = TriMesh::new(
            vec![Vec3::zeros(), Vec3::x(), Vec3::x() * 2.0, z, z],
            vec![[0, 1, 2], [1, 0, 3], [3, 1, 4]],
        )
        .unwrap();
        let topo = Topology::new(&mesh);
        let rest = GarmentRest::new(&mesh, &topo, &[0], &[], 0.15).unwrap();
        assert_eq!(rest.face_area2_m2[0], 0.0);
        assert_eq!(rest.face_area2_m2[2], 0.0);
        assert_eq!(rest.face_inv_rest[0], [0.0; 4]);
        assert!(rest.face_area2_m2[1] > 0.0);
        assert!(rest.face_inv_rest.iter().flatten().all(|v| v.is_finite()));
        assert_eq!(rest.hinges.len(), 2);
        assert!(rest.hinge_weight.iter().all(|w| *w == 0.0));
        assert!(rest.edge_rest_m.iter().all(|l| *l > 0.0));
        assert!(GarmentRest::new(&mesh, &topo, &[9], &[], 0.15).is_err());
    }

    #[test]
    fn z_normal_faces_have_a_frame() {
        for sign in [1.0f32, -1.0] {
            let mesh = TriMesh::new(
                vec![Vec3::zeros(), Vec3::x(), Vec3::new(0.0, sign, 0.0)],
                vec![[0, 1, 2]],
            )
            .unwrap();
            let rest = GarmentRest::new(&mesh, &Topology::new(&mesh), &[], &[], 0.15).unwrap();
            assert!((rest.face_area2_m2[0] - 1.0).abs() < 1e-6);
            assert!(
                rest.face_inv_rest[0].iter().all(|v| v.is_finite())
                    && rest.face_inv_rest[0] != [0.0; 4]
            );
        }
    }
}
