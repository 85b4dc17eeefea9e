//! The built-in mannequin: a 22-joint Mixamo-named skeleton in an A-pose, about 1.75 m tall
//! (Y up, facing +Z, feet at y = 0, the character's left at +X), with a smooth, closed,
//! mirror-symmetric body mesh skinned by distance to the body parts.

use crate::geometry::{Mat4, SkinWeights, Vec3};

use super::super::skeleton::{JointTransform, Skeleton};
use super::super::{Avatar, SceneError};
use super::body::{
    BodySdf, JOINT_COUNT, JOINT_NAMES, JOINT_PARENTS, mirror_joint, rest_joint_positions,
};
use super::surface::{self, SurfaceSpec};

/// Name of the built-in avatar.
pub const MANNEQUIN_NAME: &str = "mannequin";
/// Vertex budget of the body mesh.
pub const BODY_VERTICES: usize = 6000;
/// Softness of the skin-weight falloff in metres: a part `SKIN_FALLOFF_M` farther away than
/// the nearest part gets `1/e` of its weight.
const SKIN_FALLOFF_M: f32 = 0.01;
/// Laplacian smoothing passes over the body's skin weights.
const SKIN_SMOOTHING_PASSES: usize = 10;

/// The mannequin skeleton: identity rest rotations, the A-pose in the bone offsets, and
/// `joint_from_bind` the inverse of the rest world transforms.
pub fn skeleton() -> Result<Skeleton, SceneError> {
    let world = rest_joint_positions();
    let rest_local: Vec<JointTransform> = (0..JOINT_COUNT)
        .map(|j| JointTransform {
            translation: match JOINT_PARENTS[j] {
                Some(p) => world[j] - world[p],
                None => world[j],
            },
            ..Default::default()
        })
        .collect();
    let mut sk = Skeleton::new(
        JOINT_NAMES.iter().map(|s| s.to_string()).collect(),
        JOINT_PARENTS.to_vec(),
        rest_local,
        vec![Mat4::identity(); JOINT_COUNT],
        vec![Mat4::identity(); JOINT_COUNT],
    )?;
    let rest = sk.rest_pose();
    let mut inverse = Vec::with_capacity(JOINT_COUNT);
    for (j, m) in sk.world_from_joint(&rest).iter().enumerate() {
        let Some(inv) = m.try_inverse() else {
            return Err(SceneError::InvalidSkeleton(format!(
                "rest transform of joint {j} is singular"
            )));
        };
        inverse.push(inv);
    }
    sk.joint_from_bind = inverse;
    Ok(sk)
}

/// Skin weights of `positions` from the body parts: `exp(-(d - d_min) / falloff)` over the
/// parts' signed distances (left parts and their mirror images), then `smoothing_passes` of
/// uniform Laplacian averaging over `neighbours` (the mesh's vertex rings), so joints blend
/// over a few centimetres along the surface but not across to a neighbouring limb; four
/// largest influences, normalised.
pub fn skin_weights(
    body: &BodySdf,
    positions: &[Vec3],
    neighbours: &[Vec<u32>],
    smoothing_passes: usize,
) -> SkinWeights {
    let mut dense: Vec<Vec<(u16, f32)>> = positions
        .iter()
        .map(|p| {
            let mirrored = Vec3::new(-p.x, p.y, p.z);
            let mut list: Vec<(u16, f32)> = Vec::with_capacity(2 * body.parts.len());
            for part in &body.parts {
                let d = part.shape.distance(p);
                list.push((part.joint as u16, d));
                let m = mirror_joint(part.joint);
                if m != part.joint {
                    list.push((m as u16, part.shape.distance(&mirrored)));
                }
            }
            let nearest = list.iter().map(|e| e.1).fold(f32::INFINITY, f32::min);
            let mut merged: Vec<(u16, f32)> = Vec::new();
            for (j, d) in list {
                let w = (-(d - nearest) / SKIN_FALLOFF_M).exp();
                if w > 1e-4 {
                    match merged.iter_mut().find(|e| e.0 == j) {
                        Some(e) => e.1 += w,
                        None => merged.push((j, w)),
                    }
                }
            }
            let total: f32 = merged.iter().map(|e| e.1).sum();
            merged.iter_mut().for_each(|e| e.1 /= total.max(1e-12));
            merged
        })
        .collect();
    for _ in 0..smoothing_passes {
        dense = (0..dense.len())
            .map(|v| {
                let ring = neighbours.get(v).map(Vec::as_slice).unwrap_or(&[]);
                let mut acc = dense[v].clone();
                for &u in ring {
                    for &(j, w) in &dense[u as usize] {
                        match acc.iter_mut().find(|e| e.0 == j) {
                            Some(e) => e.1 += w,
                            None => acc.push((j, w)),
                        }
                    }
                }
                let n = 1.0 + ring.len() as f32;
                acc.iter_mut().for_each(|e| e.1 /= n);
                acc.retain(|e| e.1 > 1e-5);
                acc
            })
            .collect();
    }
    SkinWeights::from_influences(dense, 0).0
}

/// Builds the mannequin avatar (no motions attached; see `procedural::motions`).
pub fn mannequin() -> Result<Avatar, SceneError> {
    mannequin_with_vertices(BODY_VERTICES)
}

/// Builds the mannequin with about `vertices` body vertices (at least a few hundred).
pub fn mannequin_with_vertices(vertices: usize) -> Result<Avatar, SceneError> {
    let skeleton = skeleton()?;
    let body = BodySdf::mannequin();
    let field = |p: &Vec3| body.distance(p);
    let (lo, hi) = body.half_bounds(0.03);
    let spec = SurfaceSpec {
        field: &field,
        region: None,
        lo,
        hi,
        target_vertices: vertices.max(300),
        area_estimate_m2: 1.8,
    };
    let mesh = surface::build(&spec)
        .map_err(|reason| SceneError::InvalidSkeleton(format!("mannequin body: {reason}")))?;
    let topology = crate::geometry::Topology::new(&mesh);
    let skin = skin_weights(
        &body,
        &mesh.positions,
        &topology.neighbours,
        SKIN_SMOOTHING_PASSES,
    );
    Avatar::new(MANNEQUIN_NAME, skeleton, mesh, skin, Vec::new())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Topology;

    #[test]
    fn skeleton_rest_pose_skins_to_identity() {
        let sk = skeleton().unwrap();
        for m in sk.skin_from_bind(&sk.rest_pose()) {
            assert!((m - Mat4::identity()).norm() < 1e-6);
        }
        let heights = sk.joint_positions(&sk.rest_pose());
        assert!((heights[0].y - 0.95).abs() < 1e-6);
    }

    #[test]
    fn small_mannequin_is_closed_and_weighted() {
        let avatar = mannequin_with_vertices(1500).unwrap();
        let topo = Topology::new(&avatar.bind_mesh);
        assert!(topo.boundary_edges.is_empty());
        let n = avatar.bind_mesh.vertex_count();
        assert!((1200..=1800).contains(&n), "{n} vertices");
        for w in &avatar.skin.weights {
            assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        }
    }
}
