//! Indexed triangle meshes with per-vertex areas and normals, plus validation.

use super::Vec3;

/// Errors raised when a mesh is structurally unusable.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MeshError {
    /// The mesh has no vertices or no faces.
    #[error("mesh is empty ({vertices} vertices, {faces} faces)")]
    Empty {
        /// Number of vertices.
        vertices: usize,
        /// Number of faces.
        faces: usize,
    },
    /// A face refers to a vertex that does not exist.
    #[error("face {face} refers to vertex {index}, but the mesh has {vertices} vertices")]
    IndexOutOfRange {
        /// Face index.
        face: usize,
        /// Offending vertex index.
        index: u32,
        /// Number of vertices.
        vertices: usize,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate")]
    NonFinite {
        /// Vertex index.
        vertex: usize,
    },
}

/// An indexed triangle mesh. Positions are in metres unless a caller says otherwise.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles as counter-clockwise vertex index triples.
    pub faces: Vec<[u32; 3]>,
    /// Optional per-vertex texture coordinates (same length as `positions`).
    pub uvs: Option<Vec<[f32; 2]>>,
}

/// What [`TriMesh::report`] found wrong (or suspicious) about a mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshReport {
    /// Faces whose area is below `1e-12 m²` or which repeat a vertex.
    pub degenerate_faces: Vec<usize>,
    /// Faces that repeat another face's vertex set (the later one is listed).
    pub duplicate_faces: Vec<usize>,
    /// Edges shared by more than two faces.
    pub non_manifold_edges: Vec<[u32; 2]>,
    /// Vertices referenced by no face.
    pub unreferenced_vertices: usize,
}

impl MeshReport {
    /// True when nothing was found.
    pub fn is_clean(&self) -> bool {
        self.degenerate_faces.is_empty()
            && self.duplicate_faces.is_empty()
            && self.non_manifold_edges.is_empty()
            && self.unreferenced_vertices == 0
    }
}

/// Area below which a triangle counts as degenerate, in m².
pub const DEGENERATE_AREA_M2: f32 = 1e-12;

impl TriMesh {
    /// Builds a mesh and checks indices and finiteness.
    pub fn new(positions: Vec<Vec3>, faces: Vec<[u32; 3]>) -> Result<Self, MeshError> {
        let mesh = Self {
            positions,
            faces,
            uvs: None,
        };
        mesh.validate()?;
        Ok(mesh)
    }

    /// Checks that the mesh is non-empty, indices are in range and coordinates are finite.
    pub fn validate(&self) -> Result<(), MeshError> {
        if self.positions.is_empty() || self.faces.is_empty() {
            return Err(MeshError::Empty {
                vertices: self.positions.len(),
                faces: self.faces.len(),
            });
        }
        let n = self.positions.len();
        for (f, face) in self.faces.iter().enumerate() {
            for &i in face {
                if i as usize >= n {
                    return Err(MeshError::IndexOutOfRange {
                        face: f,
                        index: i,
                        vertices: n,
                    });
                }
            }
        }
        if let Some(v) = self
            .positions
            .iter()
            .position(|p| !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()))
        {
            return Err(MeshError::NonFinite { vertex: v });
        }
        Ok(())
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Corner positions of face `f`.
    pub fn corners(&self, f: usize) -> [Vec3; 3] {
        let [a, b, c] = self.faces[f];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Un-normalised face normals: `(b - a) × (c - a)`, whose length is twice the area.
    pub fn face_cross(&self) -> Vec<Vec3> {
        (0..self.faces.len())
            .map(|f| {
                let [a, b, c] = self.corners(f);
                (b - a).cross(&(c - a))
            })
            .collect()
    }

    /// Face areas in m².
    pub fn face_areas(&self) -> Vec<f32> {
        self.face_cross().iter().map(|c| 0.5 * c.norm()).collect()
    }

    /// Per-vertex areas: a third of the area of every incident face (lumped mass), in m².
    pub fn vertex_areas(&self) -> Vec<f32> {
        let mut areas = vec![0.0; self.positions.len()];
        for (face, area) in self.faces.iter().zip(self.face_areas()) {
            for &i in face {
                areas[i as usize] += area / 3.0;
            }
        }
        areas
    }

    /// Area-weighted vertex normals. A vertex whose incident faces cancel or are degenerate
    /// gets `+Y` rather than a NaN.
    pub fn vertex_normals(&self) -> Vec<Vec3> {
        let mut normals = vec![Vec3::zeros(); self.positions.len()];
        for (face, cross) in self.faces.iter().zip(self.face_cross()) {
            for &i in face {
                normals[i as usize] += cross;
            }
        }
        normals
            .into_iter()
            .map(|n| safe_normalize(n).unwrap_or_else(Vec3::y))
            .collect()
    }

    /// Axis-aligned bounds `(min, max)`; `None` for an empty mesh.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .iter()
                .fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p))),
        )
    }

    /// Applies `f` to every position.
    pub fn map_positions(&mut self, f: impl Fn(Vec3) -> Vec3) {
        for p in &mut self.positions {
            *p = f(*p);
        }
    }

    /// Finds degenerate, duplicated and non-manifold elements.
    pub fn report(&self) -> MeshReport {
        let mut report = MeshReport::default();
        let areas = self.face_areas();
        let mut seen = std::collections::HashSet::new();
        for (f, face) in self.faces.iter().enumerate() {
            let repeats = face[0] == face[1] || face[1] == face[2] || face[0] == face[2];
            // NaN areas count as degenerate.
            let usable = areas[f] > DEGENERATE_AREA_M2;
            if repeats || !usable {
                report.degenerate_faces.push(f);
            }
            let mut key = *face;
            key.sort_unstable();
            if !seen.insert(key) {
                report.duplicate_faces.push(f);
            }
        }
        let mut edge_count: std::collections::HashMap<[u32; 2], u32> = Default::default();
        for face in &self.faces {
            for k in 0..3 {
                let (a, b) = (face[k], face[(k + 1) % 3]);
                if a != b {
                    *edge_count.entry([a.min(b), a.max(b)]).or_default() += 1;
                }
            }
        }
        report.non_manifold_edges = edge_count
            .into_iter()
            .filter(|&(_, c)| c > 2)
            .map(|(e, _)| e)
            .collect();
        report.non_manifold_edges.sort_unstable();
        let mut used = vec![false; self.positions.len()];
        for face in &self.faces {
            for &i in face {
                if let Some(u) = used.get_mut(i as usize) {
                    *u = true;
                }
            }
        }
        report.unreferenced_vertices = used.iter().filter(|&&u| !u).count();
        report
    }

    /// Removes degenerate and duplicate faces (a safe repair: vertex order is kept).
    /// Returns how many faces were removed.
    pub fn remove_bad_faces(&mut self) -> usize {
        let report = self.report();
        let mut drop = vec![false; self.faces.len()];
        for &f in report
            .degenerate_faces
            .iter()
            .chain(&report.duplicate_faces)
        {
            drop[f] = true;
        }
        let before = self.faces.len();
        let mut k = 0;
        self.faces.retain(|_| {
            let keep = !drop[k];
            k += 1;
            keep
        });
        before - self.faces.len()
    }
}

/// Normalises `v`, or returns `None` when its length is zero, tiny or not finite.
pub fn safe_normalize(v: Vec3) -> Option<Vec3> {
    let n = v.norm();
    (n > 1e-20 && n.is_finite()).then(|| v / n)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> TriMesh {
        TriMesh::new(
            vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        )
        .unwrap()
    }

    #[test]
    fn areas_sum_to_surface_area() {
        let m = quad();
        let total: f32 = m.vertex_areas().iter().sum();
        assert!((total - 1.0).abs() < 1e-6);
        assert!((m.face_areas()[0] - 0.5).abs() < 1e-6);
    }

    #[test]
    fn normals_point_along_z_for_ccw_quad() {
        for n in quad().vertex_normals() {
            assert!((n - Vec3::z()).norm() < 1e-6);
        }
    }

    #[test]
    fn degenerate_vertex_normal_is_finite() {
        let m = TriMesh::new(vec![Vec3::zeros(); 3], vec![[0, 1, 2]]).unwrap();
        assert!(
            m.vertex_normals()
                .iter()
                .all(|n| n.iter().all(|c| c.is_finite()))
        );
        assert_eq!(m.report().degenerate_faces, vec![0]);
    }

    #[test]
    fn rejects_bad_index_and_nan() {
        let err = TriMesh::new(vec![Vec3::zeros(); 3], vec![[0, 1, 3]]).unwrap_err();
        assert!(matches!(err, MeshError::IndexOutOfRange { index: 3, .. }));
        let err = TriMesh::new(
            vec![Vec3::zeros(), Vec3::x(), Vec3::new(f32::NAN, 0.0, 0.0)],
            vec![[0, 1, 2]],
        )
        .unwrap_err();
        assert_eq!(err, MeshError::NonFinite { vertex: 2 });
    }

    #[test]
    fn report_finds_duplicates_and_non_manifold_edges() {
        let mut m = quad();
        m.positions.push(Vec3::new(0.5, 0.5, 1.0));
        m.faces.push([2, 0, 1]); // duplicate of face 0
        m.faces.push([0, 2, 4]); // third face on edge 0-2
        let r = m.report();
        assert_eq!(r.duplicate_faces, vec![2]);
        assert!(r.non_manifold_edges.contains(&[0, 2]));
        assert_eq!(m.remove_bad_faces(), 1);
        assert_eq!(m.faces.len(), 3);
    }
}
