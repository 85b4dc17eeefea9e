//! Fabric parameters, as the physics layer evaluates them. The type lives in the scene layer
//! ([`neural_cloth_core::scene::fabric`], where scene descriptions carry it as plain data); see its docs for
//! the stiffness convention every energy here uses (triangle terms weighted by `|cross|`,
//! twice the area) and the physical meaning of each parameter.

pub use neural_cloth_core::scene::fabric::{ClothModel, FabricError, FabricParams, PRESET_NAMES};
