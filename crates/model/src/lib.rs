//! Model layer: body motion descriptors (paper §3.2), the disentangled recurrent
//! encoder-decoder as a burn module (§3.3), tensor skinning of its output, and a plain-Rust
//! inference engine that replays the trained weights frame by frame without burn (§4.5).
//!
//! Data flow: [`descriptors`] turns poses into per-joint static (9-d) and dynamic (12-d)
//! descriptors; [`network::ClothNet`] maps them to rest-space garment offsets;
//! [`skinning::GarmentLbs`] adds the template and poses the garment with linear blend
//! skinning. [`weights::InferenceWeights`] copies a trained network into plain matrices and
//! [`inference::InferenceEngine`] runs it on raw poses with the GRU state carried over, on its
//! own [`compiled::CompiledNet`] copy (f32 or f16 storage, SIMD [`kernels`]).
//! [`artifact::ModelArtifact`] keeps weights with the settings they were trained with and is
//! where engines of a trained model are built.

pub mod activity;
pub mod artifact;
pub mod compiled;
pub mod descriptors;
pub mod gru;
pub mod gru_unroll;
pub mod heading;
pub mod inference;
pub mod kernels;
pub mod network;
pub mod network_config;
pub mod skinning;
pub mod weights;

pub use artifact::ModelArtifact;
pub use descriptors::{
    DYNAMIC_DIM, DescriptorConfig, DescriptorExtractor, DescriptorStream, Descriptors,
    RotationFrame, STATIC_DIM, dynamic_channel_rms,
};
pub use inference::{InferenceEngine, InferenceOptions};
pub use kernels::Precision;
pub use network::{ClothNet, ClothNetConfig, EncoderKind, RecurrentEncoder};
pub use skinning::{GarmentLbs, SkinMatrixBuilder};
pub use weights::InferenceWeights;

/// Errors of the model layer.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// Every joint of the skeleton was excluded from the network input.
    #[error("no input joints left after excluding the patterns {patterns:?} from {joints} joints")]
    NoInputJoints {
        /// The exclusion patterns in effect.
        patterns: Vec<String>,
        /// Number of joints in the skeleton.
        joints: usize,
    },
    /// A count (joints, vertices, values, layer widths) disagrees with what was expected.
    #[error("{what}: expected {expected}, found {found}")]
    ShapeMismatch {
        /// What was being checked.
        what: String,
        /// Expected count.
        expected: usize,
        /// Actual count.
        found: usize,
    },
    /// A pose, time step or weight contains NaN or infinity, or a rate is not positive.
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// The network configuration is unusable.
    #[error("invalid network configuration: {0}")]
    InvalidConfig(String),
    /// Reading weights back from a burn tensor failed.
    #[error("reading tensor '{what}' failed: {reason}")]
    TensorRead {
        /// Which parameter.
        what: String,
        /// The backend's explanation.
        reason: String,
    },
    /// A scene-layer operation (resampling a motion) failed.
    #[error(transparent)]
    Scene(#[from] neural_cloth_core::scene::SceneError),
    /// A worker thread pool could not be built.
    #[error("thread pool: {0}")]
    ThreadPool(String),
}
