//! Mesh connectivity: unique edges, hinges (pairs of faces sharing an edge), vertex
//! neighbourhoods, and signed dihedral angles computed with `atan2`.

use std::collections::HashMap;

use super::{TriMesh, Vec3};

/// Two faces sharing the edge `edge`; `opposite[k]` is the vertex of `faces[k]` not on it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Hinge {
    /// Shared edge, ordered as it appears in `faces[0]`.
    pub edge: [u32; 2],
    /// The two adjacent faces.
    pub faces: [u32; 2],
    /// Vertex of each face opposite the shared edge.
    pub opposite: [u32; 2],
}

/// Connectivity derived once from a mesh's faces.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Topology {
    /// Unique undirected edges, each as `[min, max]`, in first-seen order.
    pub edges: Vec<[u32; 2]>,
    /// Interior edges with exactly two faces. Non-manifold edges contribute no hinge.
    pub hinges: Vec<Hinge>,
    /// Sorted, de-duplicated neighbour lists per vertex.
    pub neighbours: Vec<Vec<u32>>,
    /// Edges with a single face (open boundary).
    pub boundary_edges: Vec<[u32; 2]>,
}

impl Topology {
    /// Builds the connectivity of `mesh`. Degenerate faces (repeated vertices) are skipped.
    pub fn new(mesh: &TriMesh) -> Self {
        Self::from_faces(mesh.positions.len(), &mesh.faces)
    }

    /// Builds the connectivity of `vertex_count` vertices joined by `faces`.
    pub fn from_faces(vertex_count: usize, faces: &[[u32; 3]]) -> Self {
        // Per edge: (face, directed edge as it appears in the face, opposite vertex).
        type EdgeUse = (u32, [u32; 2], u32);
        let mut edge_faces: HashMap<[u32; 2], Vec<EdgeUse>> = HashMap::new();
        let mut edges = Vec::new();
        let mut neighbours = vec![Vec::new(); vertex_count];
        for (f, face) in faces.iter().enumerate() {
            if face[0] == face[1] || face[1] == face[2] || face[0] == face[2] {
                continue;
            }
            for k in 0..3 {
                let (a, b, c) = (face[k], face[(k + 1) % 3], face[(k + 2) % 3]);
                let key = [a.min(b), a.max(b)];
                let entry = edge_faces.entry(key).or_default();
                if entry.is_empty() {
                    edges.push(key);
                }
                entry.push((f as u32, [a, b], c));
                neighbours[a as usize].push(b);
                neighbours[b as usize].push(a);
            }
        }
        for n in &mut neighbours {
            n.sort_unstable();
            n.dedup();
        }
        let mut hinges = Vec::new();
        let mut boundary_edges = Vec::new();
        for key in &edges {
            match edge_faces[key].as_slice() {
                [(f0, e0, o0), (f1, _, o1)] => hinges.push(Hinge {
                    edge: *e0,
                    faces: [*f0, *f1],
                    opposite: [*o0, *o1],
                }),
                [_] => boundary_edges.push(*key),
                _ => {}
            }
        }
        Self {
            edges,
            hinges,
            neighbours,
            boundary_edges,
        }
    }

    /// Edge lengths of `positions` in metres.
    pub fn edge_lengths(&self, positions: &[Vec3]) -> Vec<f32> {
        self.edges
            .iter()
            .map(|&[a, b]| (positions[a as usize] - positions[b as usize]).norm())
            .collect()
    }

    /// Signed dihedral angle of every hinge in radians (0 for a flat hinge, ±π fully folded).
    pub fn dihedral_angles(&self, positions: &[Vec3]) -> Vec<f32> {
        self.hinges
            .iter()
            .map(|h| {
                let p = |i: u32| positions[i as usize];
                dihedral_angle(
                    p(h.edge[0]),
                    p(h.edge[1]),
                    p(h.opposite[0]),
                    p(h.opposite[1]),
                )
            })
            .collect()
    }
}

/// Signed angle between the normals of triangles `(e0, e1, o0)` and `(e1, e0, o1)`, from
/// `atan2(|n0 × n1| · sign, n0 · n1)`. Robust near 0 and ±π and finite for degenerate faces.
pub fn dihedral_angle(e0: Vec3, e1: Vec3, o0: Vec3, o1: Vec3) -> f32 {
    let edge = e1 - e0;
    let n0 = edge.cross(&(o0 - e0));
    let n1 = (o1 - e0).cross(&edge);
    let sin_part = n0.cross(&n1).dot(&edge);
    let len = edge.norm();
    let sin = if len > 0.0 { sin_part / len } else { 0.0 };
    let cos = n0.dot(&n1);
    sin.atan2(cos)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hinge_mesh(angle: f32) -> TriMesh {
        // Shared edge along X; first wing in +Y, second wing rotated by `angle` about X.
        let (s, c) = angle.sin_cos();
        TriMesh::new(
            vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.5, 1.0, 0.0),
                Vec3::new(0.5, -c, -s),
            ],
            vec![[0, 1, 2], [1, 0, 3]],
        )
        .unwrap()
    }

    #[test]
    fn edges_and_hinges_of_two_triangles() {
        let t = Topology::new(&hinge_mesh(0.0));
        assert_eq!(t.edges.len(), 5);
        assert_eq!(t.hinges.len(), 1);
        assert_eq!(t.boundary_edges.len(), 4);
        assert_eq!(t.hinges[0].opposite, [2, 3]);
        assert_eq!(t.neighbours[0], vec![1, 2, 3]);
    }

    #[test]
    fn dihedral_is_zero_when_flat_and_signed_when_bent() {
        let t = Topology::new(&hinge_mesh(0.0));
        assert!(t.dihedral_angles(&hinge_mesh(0.0).positions)[0].abs() < 1e-6);
        let a = t.dihedral_angles(&hinge_mesh(0.5).positions)[0];
        let b = t.dihedral_angles(&hinge_mesh(-0.5).positions)[0];
        assert!((a.abs() - 0.5).abs() < 1e-5, "{a}");
        assert!((a + b).abs() < 1e-5);
    }

    #[test]
    fn dihedral_near_fully_folded_is_finite() {
        let t = Topology::new(&hinge_mesh(0.0));
        for angle in [std::f32::consts::PI - 1e-4, -std::f32::consts::PI + 1e-4] {
            let d = t.dihedral_angles(&hinge_mesh(angle).positions)[0];
            assert!(d.is_finite() && d.abs() > 3.0, "{d}");
        }
        let collapsed = [Vec3::zeros(); 4];
        assert_eq!(t.dihedral_angles(&collapsed)[0], 0.0);
    }
}
