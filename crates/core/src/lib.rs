//! The core layers of neural-cloth, each depending only on those before it: [`geometry`]
//! (meshes, topology, rotations, skinning, nearest-point trees), [`scene`] (avatars, garments,
//! motions, fabric and effects as plain data, the scene description) and [`io`] (importers,
//! retargeting, inspection and exporters).

pub mod geometry;
pub mod io;
pub mod scene;
