//! Builds the viewport's [`SceneFrame`] from the app state: the body posed by the current
//! motion time, the garment from the preview model at `w` (or skinned template), strain
//! heat-map colours and collision markers when those overlays are on.

use std::sync::Arc;

use neural_cloth_core::geometry::Vec3;
use neural_cloth_core::scene::{Avatar, Garment};
use neural_cloth_physics::collision::PosedBody;
use neural_cloth_render::{MeshFrame, SceneFrame, heat_color, vertex_values_from_edges};

use super::error::AppError;
use super::state::AppState;

/// Strain shown as full red in the heat-map (10 % elongation or compression).
pub const HEAT_MAX_STRAIN: f32 = 0.1;

/// Connectivity shared by every frame of one scene revision (so the renderer sees the same
/// `Arc`s and only rewrites positions).
#[derive(Clone, Debug, Default)]
pub struct TopologyCache {
    revision: u64,
    body_faces: Option<Arc<[[u32; 3]]>>,
    garment_faces: Option<Arc<[[u32; 3]]>>,
    garment_edges: Option<Arc<[[u32; 2]]>>,
    rest_lengths: Vec<f32>,
}

impl TopologyCache {
    fn refresh(&mut self, revision: u64, avatar: &Avatar, garment: Option<&Garment>) {
        if self.revision == revision && self.body_faces.is_some() {
            return;
        }
        self.revision = revision;
        self.body_faces = Some(avatar.bind_mesh.faces.clone().into());
        self.garment_faces = garment.map(|g| g.mesh.faces.clone().into());
        self.garment_edges = garment.map(|g| g.topology.edges.clone().into());
        self.rest_lengths = garment
            .map(|g| g.topology.edge_lengths(&g.mesh.positions))
            .unwrap_or_default();
    }
}

/// Relative length change of every edge, `|l / l_rest - 1|` (0 for degenerate rest edges).
pub fn edge_strains(edges: &[[u32; 2]], rest_lengths: &[f32], positions: &[Vec3]) -> Vec<f32> {
    edges
        .iter()
        .zip(rest_lengths)
        .map(
            |(&[a, b], &rest)| match (positions.get(a as usize), positions.get(b as usize)) {
                (Some(pa), Some(pb)) if rest > 1e-9 => ((pa - pb).norm() / rest - 1.0).abs(),
                _ => 0.0,
            },
        )
        .collect()
}

/// The frame the viewport shows for `state` now.
pub fn build_frame(state: &mut AppState) -> SceneFrame {
    let avatar = state.scene.avatar.clone();
    let garment = state.scene.garment.clone();
    let motion_index = state.playback.motion;
    let time = state.playback.time_secs;
    let pose = avatar
        .motions
        .get(motion_index)
        .map(|m| m.sample(time))
        .unwrap_or_else(|| avatar.skeleton.rest_pose());
    let mut cache = std::mem::take(&mut state.topology);
    cache.refresh(state.scene.revision, &avatar, garment.as_deref());
    let body_positions = avatar.pose_vertices(&pose);
    let body_faces = cache
        .body_faces
        .clone()
        .unwrap_or_else(|| Arc::from(Vec::new()));
    let mut frame = SceneFrame {
        body: None,
        garment: None,
        collision_points: Vec::new(),
        ground_y: avatar.rest_mesh.bounds().map(|(lo, _)| lo.y).unwrap_or(0.0),
    };
    if let (Some(g), Some(faces), Some(edges)) = (
        garment.as_ref(),
        cache.garment_faces.clone(),
        cache.garment_edges.clone(),
    ) {
        let predicted = match avatar.motions.get(motion_index) {
            Some(m) => state.preview.garment_positions(
                &avatar,
                g,
                motion_index,
                m,
                time,
                state.w,
                state.scene.config.training_fps,
                state.scene.config.effects.dynamics,
            ),
            None => None,
        };
        let positions = predicted.unwrap_or_else(|| g.pose_vertices(&avatar, &pose));
        let mut mesh = MeshFrame::new(positions, faces, edges.clone());
        if state.draw.heat_map {
            let strains = edge_strains(&edges, &cache.rest_lengths, &mesh.positions);
            let per_vertex = vertex_values_from_edges(mesh.positions.len(), &edges, &strains);
            mesh.colors = Some(
                per_vertex
                    .iter()
                    .map(|&s| heat_color(s, HEAT_MAX_STRAIN))
                    .collect(),
            );
        }
        if state.draw.collision_points {
            match PosedBody::new(body_positions.clone(), &body_faces) {
                Ok(body) => {
                    let skip: std::collections::HashSet<u32> =
                        g.no_collide.iter().copied().collect();
                    frame.collision_points = mesh
                        .positions
                        .iter()
                        .enumerate()
                        .filter(|(i, p)| {
                            !skip.contains(&(*i as u32)) && body.signed_distance(p) < 0.0
                        })
                        .map(|(_, p)| *p)
                        .collect();
                }
                Err(e) => state.preview.error = Some(AppError::CollisionQuery(e)),
            }
        }
        frame.garment = Some(mesh);
    }
    frame.body = Some(MeshFrame::new(
        body_positions,
        body_faces,
        Arc::from(Vec::new()),
    ));
    state.topology = cache;
    frame
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strains_are_relative_and_guarded() {
        let p = [
            Vec3::zeros(),
            Vec3::new(1.1, 0.0, 0.0),
            Vec3::new(0.0, 0.9, 0.0),
        ];
        let s = edge_strains(&[[0, 1], [0, 2], [1, 7], [0, 0]], &[1.0, 1.0, 1.0, 0.0], &p);
        assert!((s[0] - 0.1).abs() < 1e-6 && (s[1] - 0.1).abs() < 1e-6);
        assert_eq!(&s[2..], &[0.0, 0.0]);
    }
}
