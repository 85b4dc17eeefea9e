//! What one viewport frame shows, on the CPU: posed body and garment meshes with normals,
//! optional per-vertex colours, collision markers and the ground height. The renderer uploads
//! it; the app and the CLI build it from scene data.

use std::sync::Arc;

use neural_cloth_core::geometry::{Vec3, safe_normalize};
use neural_cloth_core::scene::{Avatar, Garment, Pose};

/// A triangle mesh in one pose, ready to upload.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshFrame {
    /// Vertex positions, world space, metres.
    pub positions: Vec<Vec3>,
    /// Area-weighted unit vertex normals (same length as `positions`).
    pub normals: Vec<Vec3>,
    /// Triangles (shared between frames so the renderer can tell the topology is unchanged).
    pub faces: Arc<[[u32; 3]]>,
    /// Unique edges for the wireframe (shared like `faces`); may be empty.
    pub edges: Arc<[[u32; 2]]>,
    /// Optional per-vertex linear RGBA colours (heat-map), same length as `positions`.
    pub colors: Option<Vec<[f32; 4]>>,
}

impl MeshFrame {
    /// A mesh with normals computed from `positions` and `faces`.
    pub fn new(positions: Vec<Vec3>, faces: Arc<[[u32; 3]]>, edges: Arc<[[u32; 2]]>) -> Self {
        let normals = vertex_normals(&positions, &faces);
        Self {
            positions,
            normals,
            faces,
            edges,
            colors: None,
        }
    }

    /// Axis-aligned bounds of the finite positions, or `None` when there are none.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        bounds_of(&self.positions)
    }
}

/// Everything the renderer draws for one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SceneFrame {
    /// The posed avatar body, if any.
    pub body: Option<MeshFrame>,
    /// The posed garment, if any.
    pub garment: Option<MeshFrame>,
    /// Collision markers (e.g. garment vertices inside the body), world space, metres.
    pub collision_points: Vec<Vec3>,
    /// Height of the ground plane in metres (usually the lowest rest-pose body point).
    pub ground_y: f32,
}

impl SceneFrame {
    /// Builds a frame from an avatar in `pose` and, optionally, a garment whose posed
    /// positions are `garment_positions` (e.g. from the model); without positions the garment
    /// is shown skinned by `pose` (its template, no neural offsets).
    pub fn from_scene(
        avatar: &Avatar,
        pose: &Pose,
        garment: Option<&Garment>,
        garment_positions: Option<Vec<Vec3>>,
    ) -> Self {
        let body_faces: Arc<[[u32; 3]]> = avatar.bind_mesh.faces.clone().into();
        let body = MeshFrame::new(
            avatar.pose_vertices(pose),
            body_faces,
            Arc::from(Vec::new()),
        );
        let garment = garment.map(|g| {
            let positions = match garment_positions {
                Some(p) if p.len() == g.vertex_count() => p,
                _ => g.pose_vertices(avatar, pose),
            };
            MeshFrame::new(
                positions,
                g.mesh.faces.clone().into(),
                g.topology.edges.clone().into(),
            )
        });
        let ground_y = avatar.rest_mesh.bounds().map(|(lo, _)| lo.y).unwrap_or(0.0);
        Self {
            body: Some(body),
            garment,
            collision_points: Vec::new(),
            ground_y,
        }
    }

    /// Bounds of body and garment together.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let parts = [self.body.as_ref(), self.garment.as_ref()];
        parts
            .iter()
            .flatten()
            .filter_map(|m| m.bounds())
            .reduce(|(a, b), (c, d)| (a.inf(&c), b.sup(&d)))
    }
}

/// Axis-aligned bounds of the finite points in `points`.
pub fn bounds_of(points: &[Vec3]) -> Option<(Vec3, Vec3)> {
    points
        .iter()
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .fold(None, |acc, p| match acc {
            None => Some((*p, *p)),
            Some((lo, hi)) => Some((lo.inf(p), hi.sup(p))),
        })
}

/// Area-weighted unit vertex normals; faces with out-of-range indices are skipped and a vertex
/// whose faces cancel or are degenerate gets `+Y`.
pub fn vertex_normals(positions: &[Vec3], faces: &[[u32; 3]]) -> Vec<Vec3> {
    let mut normals = vec![Vec3::zeros(); positions.len()];
    for face in faces {
        let [Some(a), Some(b), Some(c)] = face.map(|i| positions.get(i as usize)) else {
            continue;
        };
        let cross = (b - a).cross(&(c - a));
        if !cross.iter().all(|v| v.is_finite()) {
            continue;
        }
        for &i in face {
            if let Some(n) = normals.get_mut(i as usize) {
                *n += cross;
            }
        }
    }
    normals
        .into_iter()
        .map(|n| safe_normalize(n).unwrap_or_else(Vec3::y))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normals_of_a_quad_and_a_bad_face() {
        let positions = vec![
            Vec3::zeros(),
            Vec3::x(),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::y(),
            Vec3::z(),
        ];
        let n = vertex_normals(&positions, &[[0, 1, 2], [0, 2, 3], [0, 1, 7]]);
        for normal in n.iter().take(4) {
            assert!((normal - Vec3::z()).norm() < 1e-6);
        }
        assert_eq!(n[4], Vec3::y());
    }

    #[test]
    fn bounds_skip_non_finite_points() {
        let b = bounds_of(&[
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(f32::NAN, 0.0, 0.0),
            Vec3::new(-1.0, 0.0, 5.0),
        ]);
        assert_eq!(
            b,
            Some((Vec3::new(-1.0, 0.0, 3.0), Vec3::new(1.0, 2.0, 5.0)))
        );
        assert_eq!(bounds_of(&[]), None);
    }
}
