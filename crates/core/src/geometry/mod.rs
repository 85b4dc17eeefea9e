//! Geometry layer: triangle meshes and their topology, areas, normals, dihedral angles,
//! rotation representations (6D, slerp) and linear blend skinning.
//!
//! Everything here is plain `f32` CPU code with no knowledge of scenes, files or learning;
//! the upper layers (`scene`, `io`, `physics`, `model`) build on it.

pub mod bucket_kdtree;
pub mod kdtree;
pub mod mesh;
pub mod rotation;
pub mod skinning;
pub mod topology;
pub mod wide_kdtree;

pub use bucket_kdtree::BucketKdTree;
pub use kdtree::KdTree;
pub use mesh::{MeshError, MeshReport, TriMesh, safe_normalize};
pub use rotation::{mat3_from_6d, rotation_to_6d, slerp_unit};
pub use skinning::{SkinWeights, linear_blend_skin, linear_blend_skin_into};
pub use topology::{Hinge, Topology};
pub use wide_kdtree::WideKdTree;

/// Single-precision 3-vector used for positions and directions.
pub type Vec3 = nalgebra::Vector3<f32>;
/// Unit quaternion used for joint rotations.
pub type Quat = nalgebra::UnitQuaternion<f32>;
/// 3x3 matrix (rotations, frames).
pub type Mat3 = nalgebra::Matrix3<f32>;
/// 4x4 affine matrix named by its spaces, e.g. `world_from_joint`.
pub type Mat4 = nalgebra::Matrix4<f32>;
