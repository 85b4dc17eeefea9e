//! Physics layer: fabric parameters, the cloth energies of paper §3.4 written once as
//! device-agnostic burn tensor code, the metrics of §4.2, and a reference simulator (the
//! paper's "standard simulation", Eq. 8) built on the same energies.
//!
//! - [`FabricParams`]: material model, stiffnesses, density, collision and gravity; presets.
//! - [`GarmentRest`]: rest state (masses, edges, rest frames, hinges) computed once in `f64`.
//! - [`PhysicsTerms`]: the rest state on a device; evaluates the enabled terms on `[B, V, 3]`
//!   batches and returns per-term scalars ([`LossTerms`]). Training, evaluation and the
//!   simulator all go through it.
//! - [`collision`]: posed bodies, the batched nearest-vertex query, the collision energy.
//! - [`precondition`]: the training's gradient filter `D (D + βK)⁻¹` ([`GradientFilter`]).
//! - [`metrics`]: strain, bending, collision %, gravity and inertia of any mesh sequence.
//! - [`simulator`]: frame-by-frame minimisation of `½(x - x̃)ᵀM(x - x̃) + Δt² E(x)` with
//!   L-BFGS ([`lbfgs`]) whose initial metric is a prefactored `M/Δt² + K` ([`sparse`]);
//!   [`simulator::simulate`] bakes a motion, [`simulator::Stepper`] steps one frame at a time.
//! - [`fused`]: the static energies again as host kernels computing energy and analytic
//!   gradient in one pass, handed to burn through a surrogate; [`PhysicsTerms`] uses them by
//!   default and keeps the tensor code as the reference.
//!
//! # Conventions
//! Metres, seconds, kilograms, Y up. Energies are joules, summed over the mesh for each batch
//! sample; losses are batch means of those sums (the official code's reduction). Triangle
//! stiffness terms are weighted by `|cross|` (twice the area) so that the paper's stiffness
//! magnitudes keep their meaning; see [`fabric`] for the exact formulas and their physical
//! equivalents. Hot-path tensors are `f32`; `f64` is used on the CPU for rest-state
//! precomputation, inside the fused kernels (which read `f32` positions and return `f32`
//! gradients) and, where the backend supports it, for reference checks.
//!
//! # Cost of each term (10K degrees of freedom)
//! Measured with `neural_cloth_lab::bench::cost::measure_term_costs` (`neural-cloth bench
//! --physics-only`, or `cargo test --release --test report measure_term_costs -- --ignored
//! --nocapture`), which times each
//! term as burn tensor code and as a fused kernel in the same run. On the flex CPU backend
//! (batch 16, ~9.8K DoF), as burn tensor code, relative to `Σx²` forward + backward: gravity,
//! inertia, pinning and the collision energy itself a few ×; membrane terms ≈ 100-250×;
//! bending ≈ 600-900×, almost all of it the overhead of many small autodiff operations. The
//! fused kernels cut the membrane terms about 5-10× and bending about 4-6×; the exact query on
//! a wide k-d tree ([`neural_cloth_core::geometry::WideKdTree`], seeded with the previous garment vertex's
//! answer) cuts the collision query about 10× against the first-found k-d tree and about 2.7×
//! against the bucketed tree it replaced (see the table for the read-back and upload).

pub mod collision;
pub mod energies;
pub mod fabric;
pub mod friction;
pub mod fused;
pub mod lbfgs;
pub mod metrics;
pub mod paper_metrics;
pub mod precondition;
pub mod rest;
pub mod shapes;
pub mod simulator;
pub mod sparse;
pub mod tensors;
pub mod terms;

pub use collision::{BodyBatch, Contacts, PosedBody};
pub use fabric::{ClothModel, FabricParams};
pub use friction::FrictionContacts;
pub use metrics::{ClothMetrics, StaticTerms};
/// The scene's effect set decides which terms are built and evaluated.
pub use neural_cloth_core::scene::config::Effects;
pub use precondition::GradientFilter;
pub use rest::GarmentRest;
pub use simulator::{FrameReport, SimOptions, Simulation, simulate};
pub use terms::{LossTerms, PhysicsTerms, Term};

/// Errors of the physics layer.
#[derive(Debug, thiserror::Error)]
pub enum PhysicsError {
    /// A fabric parameter is out of range or malformed.
    #[error("invalid fabric parameter '{field}': {reason}")]
    InvalidFabric {
        /// Offending field.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// The fabric parameters are invalid (an unknown preset, a value out of range).
    #[error(transparent)]
    Fabric(#[from] neural_cloth_core::scene::fabric::FabricError),
    /// The garment cannot be simulated.
    #[error("invalid garment: {0}")]
    InvalidGarment(String),
    /// The body cannot be used for collisions.
    #[error("invalid body: {0}")]
    InvalidBody(String),
    /// Collision is enabled but no posed body was given.
    #[error("collision is enabled but no posed body was given")]
    MissingBody,
    /// Tensor or array shapes disagree.
    #[error("{what}: expected {expected}, found {found}")]
    ShapeMismatch {
        /// What was checked.
        what: String,
        /// Expected shape.
        expected: String,
        /// Actual shape.
        found: String,
    },
    /// Invalid simulation options or inputs.
    #[error("invalid simulation setting: {0}")]
    InvalidOptions(String),
    /// A value became NaN or infinite.
    #[error("non-finite value in {0}")]
    NonFinite(String),
    /// Reading a tensor back failed.
    #[error("tensor backend: {0}")]
    Backend(String),
    /// The simulation was cancelled by the progress callback.
    #[error("simulation cancelled after {frames} frames")]
    Cancelled {
        /// Frames finished.
        frames: usize,
    },
    /// A scene-level error (posing, garment building).
    #[error(transparent)]
    Scene(#[from] neural_cloth_core::scene::SceneError),
}
