//! Garments: a template mesh in the avatar's rest pose with skin weights transferred from the
//! nearest body vertex and smoothed by Laplacian passes.

use crate::geometry::{KdTree, SkinWeights, Topology, TriMesh, Vec3, linear_blend_skin};

use super::skeleton::Pose;
use super::{Avatar, SceneError};

/// Options for building a garment from a template mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct GarmentOptions {
    /// Laplacian smoothing passes over the transferred weights; 0..=200, default 3 (use ~20-50
    /// for skirts and dresses so the cloth does not follow a single leg).
    pub smoothing_passes: usize,
    /// Largest allowed distance from a garment vertex to the nearest body vertex, in metres;
    /// farther means the garment does not belong to this avatar. Default 0.5.
    pub max_distance_m: f32,
}

impl Default for GarmentOptions {
    fn default() -> Self {
        Self {
            smoothing_passes: 3,
            max_distance_m: 0.5,
        }
    }
}

impl GarmentOptions {
    /// Smoothing passes of loose garments (a skirt should not follow a single leg).
    pub const LOOSE_SMOOTHING_PASSES: usize = 30;

    /// The options for a garment named `name`: [`Self::LOOSE_SMOOTHING_PASSES`] when the name
    /// says it is loose (contains "skirt", "dress", "gown" or "robe", any case), the defaults
    /// otherwise. The passes used end up in [`Garment::smoothing_passes`].
    pub fn for_name(name: &str) -> Self {
        let name = name.to_ascii_lowercase();
        let loose = ["skirt", "dress", "gown", "robe"]
            .iter()
            .any(|k| name.contains(k));
        Self {
            smoothing_passes: if loose {
                Self::LOOSE_SMOOTHING_PASSES
            } else {
                Self::default().smoothing_passes
            },
            ..Self::default()
        }
    }
}

/// A garment ready to be simulated on an avatar.
#[derive(Clone, Debug)]
pub struct Garment {
    /// Display name.
    pub name: String,
    /// Template in the avatar's rest pose, world space, metres.
    pub mesh: TriMesh,
    /// Connectivity of `mesh`.
    pub topology: Topology,
    /// Skin weights transferred from the body.
    pub skin: SkinWeights,
    /// Laplacian smoothing passes the skin weights were smoothed with
    /// ([`GarmentOptions::smoothing_passes`]): what a scene description must record to rebuild
    /// the same garment.
    pub smoothing_passes: usize,
    /// Vertices pinned to their skinned position (e.g. a waistband); may be empty.
    pub pinned: Vec<u32>,
    /// Vertices exempt from body collision (e.g. a collar inside the neck); may be empty.
    pub no_collide: Vec<u32>,
    /// Repairs made while building (removed faces, etc.), for display.
    pub warnings: Vec<String>,
}

impl Garment {
    /// Builds a garment for `avatar` from a template already in its rest pose.
    ///
    /// Degenerate and duplicate faces are removed (with a warning); non-manifold edges and a
    /// template far from the body are errors.
    pub fn new(
        name: impl Into<String>,
        mut mesh: TriMesh,
        avatar: &Avatar,
        options: &GarmentOptions,
    ) -> Result<Self, SceneError> {
        let name = name.into();
        mesh.validate().map_err(|e| SceneError::Mesh {
            what: format!("garment '{name}'"),
            source: e,
        })?;
        let mut warnings = Vec::new();
        let removed = mesh.remove_bad_faces();
        if removed > 0 {
            warnings.push(format!("removed {removed} degenerate or duplicate faces"));
        }
        let report = mesh.report();
        if !report.non_manifold_edges.is_empty() {
            return Err(SceneError::InvalidGarment {
                name,
                reason: format!(
                    "{} non-manifold edges (shared by more than two faces), first {:?}",
                    report.non_manifold_edges.len(),
                    report.non_manifold_edges[0]
                ),
            });
        }
        if mesh.faces.is_empty() {
            return Err(SceneError::InvalidGarment {
                name,
                reason: "no usable faces".into(),
            });
        }
        if report.unreferenced_vertices > 0 {
            warnings.push(format!(
                "{} vertices belong to no face",
                report.unreferenced_vertices
            ));
        }
        let topology = Topology::new(&mesh);
        let skin = transfer_skin_weights(
            &avatar.rest_mesh.positions,
            &avatar.skin,
            &mesh.positions,
            &topology,
            options,
            &name,
        )?;
        Ok(Self {
            name,
            mesh,
            topology,
            skin,
            smoothing_passes: options.smoothing_passes,
            pinned: Vec::new(),
            no_collide: Vec::new(),
            warnings,
        })
    }

    /// Garment vertices skinned by `pose` of `avatar` (no neural offsets).
    pub fn pose_vertices(&self, avatar: &Avatar, pose: &Pose) -> Vec<Vec3> {
        self.pose_with_offsets(avatar, pose, None)
    }

    /// Template plus optional rest-space `offsets`, skinned by `pose`.
    pub fn pose_with_offsets(
        &self,
        avatar: &Avatar,
        pose: &Pose,
        offsets: Option<&[Vec3]>,
    ) -> Vec<Vec3> {
        let rest: Vec<Vec3> = match offsets {
            Some(o) => self
                .mesh
                .positions
                .iter()
                .zip(o)
                .map(|(p, d)| p + d)
                .collect(),
            None => self.mesh.positions.clone(),
        };
        // The template lives in world rest space, so skin with world_from_joint * rest_from_world.
        let sk = &avatar.skeleton;
        let rest_world = sk.world_from_joint(&sk.rest_pose());
        let posed = sk.world_from_joint(pose);
        let mats: Vec<_> = posed
            .iter()
            .zip(&rest_world)
            .map(|(p, r)| {
                p * r
                    .try_inverse()
                    .unwrap_or_else(crate::geometry::Mat4::identity)
            })
            .collect();
        linear_blend_skin(&rest, &self.skin, &mats)
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.mesh.vertex_count()
    }
}

/// Transfers skin weights from the nearest body vertex, then smooths them with `passes` of
/// uniform Laplacian averaging over the garment's edges, keeping 4 influences renormalised.
pub fn transfer_skin_weights(
    body_positions: &[Vec3],
    body_skin: &SkinWeights,
    garment_positions: &[Vec3],
    topology: &Topology,
    options: &GarmentOptions,
    name: &str,
) -> Result<SkinWeights, SceneError> {
    let tree = KdTree::new(body_positions);
    let mut dense: Vec<Vec<(u16, f32)>> = Vec::with_capacity(garment_positions.len());
    let mut farthest = 0.0f32;
    for p in garment_positions {
        let Some((i, d2)) = tree.nearest(p) else {
            return Err(SceneError::InvalidGarment {
                name: name.into(),
                reason: "avatar has no vertices".into(),
            });
        };
        farthest = farthest.max(d2.sqrt());
        let i = i as usize;
        dense.push(
            body_skin.joints[i]
                .iter()
                .copied()
                .zip(body_skin.weights[i].iter().copied())
                .filter(|(_, w)| *w > 0.0)
                .collect(),
        );
    }
    // A NaN distance fails the check too.
    let within = farthest <= options.max_distance_m;
    if !within {
        return Err(SceneError::GarmentFarFromBody {
            name: name.into(),
            farthest_m: farthest,
            limit_m: options.max_distance_m,
        });
    }
    for _ in 0..options.smoothing_passes {
        let next: Vec<Vec<(u16, f32)>> = (0..dense.len())
            .map(|v| {
                let mut acc: Vec<(u16, f32)> = dense[v].clone();
                let nbrs = &topology.neighbours[v];
                for &n in nbrs {
                    for &(j, w) in &dense[n as usize] {
                        match acc.iter_mut().find(|(k, _)| *k == j) {
                            Some(e) => e.1 += w,
                            None => acc.push((j, w)),
                        }
                    }
                }
                let total = 1.0 + nbrs.len() as f32;
                acc.iter_mut().for_each(|e| e.1 /= total);
                acc
            })
            .collect();
        dense = next;
    }
    Ok(SkinWeights::from_influences(dense, 0).0)
}
