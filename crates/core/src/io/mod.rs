//! I/O layer: importers for skinned glTF/GLB avatars, glTF and OBJ garment templates and BVH
//! motions (with retargeting onto an avatar skeleton), a human-readable `inspect` report, and
//! (elsewhere in this folder) the exporters.
//!
//! Every importer converts to metres (see [`Units`]), validates what enters (non-finite values,
//! non-unit rotations, out-of-range indices, truncated data) and returns a typed [`IoError`]
//! naming the file instead of panicking. Each loader also has a `*_from_bytes` form that takes
//! the bytes and the path they came from (used for names, relative resources and messages).

pub mod axes;
pub mod bvh;
mod bvh_parse;
pub mod bvh_write;
pub mod export;
pub mod facing;
mod gltf_accessor;
mod gltf_anim;
pub mod gltf_avatar;
mod gltf_body;
mod gltf_doc;
pub mod gltf_mesh;
mod gltf_skinless;
pub mod inspect;
mod inspect_contents;
pub mod joint_map;
pub mod joint_names;
pub mod joint_structure;
mod joint_tables;
pub mod obj;
pub mod retarget;
mod root_placement;
pub mod scene_loader;
pub mod units;

pub use axes::UpAxis;
pub use bvh::{Bvh, BvhChannel, BvhJoint, load_bvh};
pub use gltf_avatar::{load_avatar, load_avatar_from_bytes};
pub use gltf_body::{MeshUsage, MeshUse};
pub use gltf_mesh::{load_gltf_mesh, load_gltf_mesh_from_bytes};
pub use gltf_skinless::SkeletonSource;
pub use inspect::inspect;
pub use joint_map::{JointMap, JointMapping, map_joints};
pub use joint_names::canonical_joint_name;
pub use obj::{load_obj, load_obj_from_bytes};
pub use retarget::{RetargetOptions, SourceMotion, retarget, retarget_bvh};
pub use units::Units;

use std::path::{Path, PathBuf};

use crate::scene::SceneError;

/// Options shared by the importers.
#[derive(Clone, Debug, PartialEq)]
pub struct ImportOptions {
    /// Length unit of the file; [`Units::Auto`] (default) guesses from the model's size.
    pub units: Units,
    /// Rate at which animations are resampled, in frames per second; (0, 1000], default 30.
    pub fps: f32,
    /// Which axis of the file is up; [`UpAxis::Auto`] (default) detects it from the shape.
    /// Z-up files are turned Y up.
    pub up: UpAxis,
}

impl Default for ImportOptions {
    fn default() -> Self {
        Self {
            units: Units::Auto,
            fps: 30.0,
            up: UpAxis::Auto,
        }
    }
}

/// A loaded mesh (garment template or any other static mesh) and what the importer noticed.
#[derive(Clone, Debug)]
pub struct LoadedMesh {
    /// Display name (file stem).
    pub name: String,
    /// The mesh in metres, Y up; vertex order as in the file.
    pub mesh: crate::geometry::TriMesh,
    /// The unit the file was read in (never `Auto`).
    pub units: Units,
    /// The file's up axis, as given or detected (never `Auto`); the mesh is Y up.
    pub up: UpAxis,
    /// Non-fatal problems (dropped UVs, ignored elements, guessed units).
    pub warnings: Vec<String>,
}

/// A loaded avatar and what the importer noticed.
#[derive(Clone, Debug)]
pub struct LoadedAvatar {
    /// The avatar in metres, Y up, with its animations as motions.
    pub avatar: crate::scene::Avatar,
    /// The unit the file was read in (never `Auto`).
    pub units: Units,
    /// The file's up axis, as given or detected (never `Auto`); the avatar is Y up.
    pub up: UpAxis,
    /// Non-fatal problems (ignored channels, morph targets, zero-length bones, meshes left
    /// out of the body, ...).
    pub warnings: Vec<String>,
    /// Every mesh of the file and what became of it: skinned body part, rigid part of a joint,
    /// or ignored (and why).
    pub meshes: Vec<MeshUse>,
    /// Where the skeleton came from: the skins of skinned meshes or, in an avatar built only of
    /// rigid parts, the skin or node hierarchy they hang from.
    pub skeleton_source: SkeletonSource,
}

/// Errors of the I/O layer. The offending file's path always comes last in the message.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// The file could not be read (or a resource it refers to).
    #[error("cannot read file ({source}): {}", path.display())]
    Read {
        /// The underlying error.
        #[source]
        source: std::io::Error,
        /// The file.
        path: PathBuf,
    },
    /// The file extension names no supported format.
    #[error(
        "unsupported file type '{extension}' (expected glb, gltf, obj or bvh): {}",
        path.display()
    )]
    UnsupportedFormat {
        /// The extension found (may be empty).
        extension: String,
        /// The file.
        path: PathBuf,
    },
    /// The bytes are not a glTF/GLB file at all.
    #[error("not a glTF file: {reason}: {}", path.display())]
    NotGltf {
        /// Why.
        reason: String,
        /// The file.
        path: PathBuf,
    },
    /// The file ends before its declared data does.
    #[error("truncated file: {what}: {}", path.display())]
    Truncated {
        /// What is missing.
        what: String,
        /// The file.
        path: PathBuf,
    },
    /// A structurally invalid glTF (bad references, out-of-range accessors, wrong types).
    #[error("invalid glTF: {reason}: {}", path.display())]
    InvalidGltf {
        /// What is wrong.
        reason: String,
        /// The file.
        path: PathBuf,
    },
    /// A glTF file was loaded as an avatar but no mesh is skinned and its meshes hang from no
    /// skeleton (it is not an avatar of rigid parts either).
    #[error(
        "glTF without a skin (no node has both a mesh and a skin) and not an avatar of rigid \
         parts ({why}): {}",
        path.display()
    )]
    NoSkin {
        /// Why its meshes do not make an avatar of rigid parts.
        why: String,
        /// The file.
        path: PathBuf,
    },
    /// The file has no usable triangle mesh.
    #[error("no triangle mesh found: {}", path.display())]
    NoMesh {
        /// The file.
        path: PathBuf,
    },
    /// A syntax error in a text format (OBJ, BVH), with its 1-based line number.
    #[error("{format} syntax error at line {line}: {reason}: {}", path.display())]
    Syntax {
        /// "OBJ" or "BVH".
        format: &'static str,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
        /// The file.
        path: PathBuf,
    },
    /// A NaN or infinite number where data enters.
    #[error("non-finite value in {what}: {}", path.display())]
    NonFinite {
        /// Where.
        what: String,
        /// The file.
        path: PathBuf,
    },
    /// A rotation whose quaternion norm is too far from 1.
    #[error("rotation is not a unit quaternion in {what} (norm {norm}): {}", path.display())]
    NonUnitRotation {
        /// Where.
        what: String,
        /// The norm found.
        norm: f32,
        /// The file.
        path: PathBuf,
    },
    /// Two counts that must agree do not (joints, weights, frames).
    #[error("{what}: expected {expected}, found {found}: {}", path.display())]
    JointCountMismatch {
        /// What was checked.
        what: String,
        /// Expected count.
        expected: usize,
        /// Count found.
        found: usize,
        /// The file.
        path: PathBuf,
    },
    /// Retargeting could not map the avatar's essential joints to the motion's joints.
    #[error(
        "cannot map avatar joints {joints:?} to joints of the motion (closest motion joints: \
         {closest}{note}; give them in a joint map, --joint-map): {}",
        path.display()
    )]
    UnmappedJoints {
        /// Avatar joints left without a motion joint.
        joints: Vec<String>,
        /// For each of them, the closest unused joint names of the motion.
        closest: String,
        /// Why mapping by structure did not help (`"; by structure: ..."`), or empty.
        note: String,
        /// The motion file.
        path: PathBuf,
    },
    /// A user joint map that cannot be read or names joints that do not exist.
    #[error("joint map: {reason}: {}", path.display())]
    JointMap {
        /// What is wrong.
        reason: String,
        /// The joint map file.
        path: PathBuf,
    },
    /// Something valid but not supported by this importer.
    #[error("unsupported: {what}: {}", path.display())]
    Unsupported {
        /// What.
        what: String,
        /// The file.
        path: PathBuf,
    },
    /// The imported data failed a scene-layer check.
    #[error("{source}: {}", path.display())]
    Scene {
        /// The scene error.
        #[source]
        source: SceneError,
        /// The file.
        path: PathBuf,
    },
}

impl IoError {
    /// The file this error is about.
    pub fn path(&self) -> &Path {
        match self {
            Self::Read { path, .. }
            | Self::UnsupportedFormat { path, .. }
            | Self::NotGltf { path, .. }
            | Self::Truncated { path, .. }
            | Self::InvalidGltf { path, .. }
            | Self::NoSkin { path, .. }
            | Self::NoMesh { path }
            | Self::Syntax { path, .. }
            | Self::NonFinite { path, .. }
            | Self::NonUnitRotation { path, .. }
            | Self::JointCountMismatch { path, .. }
            | Self::UnmappedJoints { path, .. }
            | Self::JointMap { path, .. }
            | Self::Unsupported { path, .. }
            | Self::Scene { path, .. } => path,
        }
    }
}

/// Reads a whole file, mapping the error to [`IoError::Read`].
pub(crate) fn read_bytes(path: &Path) -> Result<Vec<u8>, IoError> {
    std::fs::read(path).map_err(|source| IoError::Read {
        source,
        path: path.to_path_buf(),
    })
}

/// The display name of a file: its stem, or the whole path when it has none.
pub(crate) fn file_stem(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string())
}

/// Checks a frame rate option: finite and in (0, 1000].
pub(crate) fn check_fps(fps: f32, path: &Path) -> Result<f32, IoError> {
    if fps.is_finite() && fps > 0.0 && fps <= 1000.0 {
        Ok(fps)
    } else {
        Err(IoError::Unsupported {
            what: format!("frame rate {fps} (must be in (0, 1000] fps)"),
            path: path.to_path_buf(),
        })
    }
}
