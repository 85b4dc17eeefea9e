//! Scene layer: avatars (skeleton, rest mesh, skin weights), garments (template and
//! transferred skin weights), motions (poses, resampling, mirroring), procedural defaults,
//! fabric parameters (plain data) and the scene configuration.

pub mod avatar;
pub mod garment;
pub mod motion;
pub mod skeleton;
pub mod up_axis;

pub use avatar::Avatar;
pub use garment::{Garment, GarmentOptions};
pub use motion::{MIRRORED_NAME_SUFFIX, Motion};
pub use skeleton::{JointTransform, Pose, Skeleton};
pub use up_axis::UpAxis;

use crate::geometry::MeshError;

/// Errors of the scene layer.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The joint hierarchy is inconsistent.
    #[error("invalid skeleton: {0}")]
    InvalidSkeleton(String),
    /// A motion has unusable data.
    #[error("invalid motion '{name}': {reason}")]
    InvalidMotion {
        /// Motion name.
        name: String,
        /// What is wrong.
        reason: String,
    },
    /// Two things that must agree on a count do not.
    #[error("{what}: expected {expected}, found {found}")]
    JointCountMismatch {
        /// What was being checked.
        what: String,
        /// Expected count.
        expected: usize,
        /// Actual count.
        found: usize,
    },
    /// A garment cannot be used.
    #[error("invalid garment '{name}': {reason}")]
    InvalidGarment {
        /// Garment name.
        name: String,
        /// What is wrong.
        reason: String,
    },
    /// A garment vertex is farther from the body than skin weights can be taken over: the
    /// garment is placed for another body, in other units or away from this one.
    #[error(
        "invalid garment '{name}': a vertex is {farthest_m:.3} m from the body (limit \
         {limit_m:.3} m): is the garment in the avatar's rest pose and units?"
    )]
    GarmentFarFromBody {
        /// Garment name.
        name: String,
        /// Distance of its farthest vertex from the nearest body vertex, metres.
        farthest_m: f32,
        /// The limit ([`GarmentOptions::max_distance_m`]), metres.
        limit_m: f32,
    },
    /// A mesh failed validation.
    #[error("{what}: {source}")]
    Mesh {
        /// Which mesh.
        what: String,
        /// The mesh error.
        #[source]
        source: MeshError,
    },
}

pub mod config;
pub mod fabric;
pub mod procedural;

pub use config::{Effects, SceneConfig, Split};
pub use fabric::FabricParams;

/// A complete scene, built from a [`SceneConfig`] (by `io::scene_loader`): avatar, garment,
/// motions with their data splits, the declared physical effects, the fabric and the training
/// frame rate.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Display name.
    pub name: String,
    /// The body.
    pub avatar: Avatar,
    /// The garment, in the avatar's rest pose.
    pub garment: Garment,
    /// Motions for the avatar's skeleton, each with its split.
    pub motions: Vec<(Motion, Split)>,
    /// Effects to build and evaluate.
    pub effects: Effects,
    /// Fabric parameters.
    pub fabric: FabricParams,
    /// Frame rate motions are resampled to for training, frames per second (> 0).
    pub training_fps: f32,
}

impl Scene {
    /// Assembles a scene, checking that every motion fits the avatar's skeleton and that the
    /// training rate is positive.
    pub fn new(
        name: String,
        avatar: Avatar,
        garment: Garment,
        motions: Vec<(Motion, Split)>,
        effects: Effects,
        fabric: FabricParams,
        training_fps: f32,
    ) -> Result<Self, SceneError> {
        if !(training_fps.is_finite() && training_fps > 0.0) {
            return Err(SceneError::InvalidMotion {
                name: name.clone(),
                reason: format!("training rate {training_fps} frames per second is not positive"),
            });
        }
        for (m, _) in &motions {
            if let Some(found) = m
                .frames
                .iter()
                .map(|p| p.rotations.len())
                .find(|&n| n != avatar.skeleton.len())
            {
                return Err(SceneError::JointCountMismatch {
                    what: format!("motion '{}' for avatar '{}'", m.name, avatar.name),
                    expected: avatar.skeleton.len(),
                    found,
                });
            }
        }
        Ok(Self {
            name,
            avatar,
            garment,
            motions,
            effects,
            fabric,
            training_fps,
        })
    }

    /// The motions in `split`.
    pub fn motions_in(&self, split: Split) -> impl Iterator<Item = &Motion> {
        self.motions
            .iter()
            .filter(move |(_, s)| *s == split)
            .map(|(m, _)| m)
    }
}
