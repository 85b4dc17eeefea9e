//! Avatars: a skeleton, a skinned body mesh and the motions that come with it.

use crate::geometry::{SkinWeights, TriMesh, Vec3, linear_blend_skin};

use super::skeleton::{Pose, Skeleton};
use super::{Motion, SceneError};

/// A skinned body: skeleton, bind-space mesh, skin weights and motions.
#[derive(Clone, Debug)]
pub struct Avatar {
    /// Display name (file stem or procedural name).
    pub name: String,
    /// The joint hierarchy.
    pub skeleton: Skeleton,
    /// Body mesh in bind space (the space the inverse bind matrices expect).
    pub bind_mesh: TriMesh,
    /// Skin weights of `bind_mesh`, indices into `skeleton`.
    pub skin: SkinWeights,
    /// The body in the skeleton's rest pose in world space (metres, Y up): `bind_mesh` skinned
    /// with [`Skeleton::rest_pose`].
    pub rest_mesh: TriMesh,
    /// Motions that come with the avatar (glTF animations, procedural or retargeted BVH).
    pub motions: Vec<Motion>,
}

impl Avatar {
    /// Assembles an avatar, validating joint counts and computing the rest mesh.
    pub fn new(
        name: impl Into<String>,
        skeleton: Skeleton,
        bind_mesh: TriMesh,
        skin: SkinWeights,
        motions: Vec<Motion>,
    ) -> Result<Self, SceneError> {
        let name = name.into();
        bind_mesh.validate().map_err(|e| SceneError::Mesh {
            what: format!("avatar '{name}' body"),
            source: e,
        })?;
        if skin.len() != bind_mesh.vertex_count() {
            return Err(SceneError::JointCountMismatch {
                what: format!("avatar '{name}' skin weights (one per vertex)"),
                expected: bind_mesh.vertex_count(),
                found: skin.len(),
            });
        }
        if let Some(j) = skin.max_joint()
            && j as usize >= skeleton.len()
        {
            return Err(SceneError::JointCountMismatch {
                what: format!(
                    "avatar '{name}' skin weights refer to joint {j}; joints in skeleton"
                ),
                expected: skeleton.len(),
                found: j as usize + 1,
            });
        }
        for m in &motions {
            if let Some(p) = m.frames.first()
                && p.rotations.len() != skeleton.len()
            {
                return Err(SceneError::JointCountMismatch {
                    what: format!("motion '{}' for avatar '{name}'", m.name),
                    expected: skeleton.len(),
                    found: p.rotations.len(),
                });
            }
        }
        let mut rest_mesh = bind_mesh.clone();
        rest_mesh.positions = linear_blend_skin(
            &bind_mesh.positions,
            &skin,
            &skeleton.skin_from_bind(&skeleton.rest_pose()),
        );
        rest_mesh.validate().map_err(|e| SceneError::Mesh {
            what: format!("avatar '{name}' rest pose"),
            source: e,
        })?;
        Ok(Self {
            name,
            skeleton,
            bind_mesh,
            skin,
            rest_mesh,
            motions,
        })
    }

    /// Body vertex positions in world space under `pose`.
    pub fn pose_vertices(&self, pose: &Pose) -> Vec<Vec3> {
        linear_blend_skin(
            &self.bind_mesh.positions,
            &self.skin,
            &self.skeleton.skin_from_bind(pose),
        )
    }

    /// Height of the rest mesh along Y in metres.
    pub fn height_m(&self) -> f32 {
        self.rest_mesh
            .bounds()
            .map(|(lo, hi)| hi.y - lo.y)
            .unwrap_or(0.0)
    }

    /// The motion called `name`.
    pub fn motion(&self, name: &str) -> Option<&Motion> {
        self.motions.iter().find(|m| m.name == name)
    }
}
