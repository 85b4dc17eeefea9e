//! Differentiable cloth energies on batches of posed garments `[B, V, 3]`, device-agnostic burn
//! tensor code. Each function returns one value per sample (`[B]`, joules); the caller reduces.
//! Collision lives in [`crate::collision`] because it needs the body query.

pub mod bending;
pub mod external;
pub mod membrane;

pub use bending::{bending, dihedral_change};
pub use external::{gravity, inertia, inertia_distance, pinning};
pub use membrane::{
    baraff_witkin, deformation, edge_lengths, green_strain, mass_spring, stretch_and_shear, stvk,
};
