//! Render layer: a wgpu renderer with our own WGSL shaders (`shaders/`), independent of egui.
//!
//! It draws a [`SceneFrame`] (posed body and garment with per-vertex normals, optional strain
//! heat-map colours, collision markers, ground grid, wireframe) seen by an [`OrbitCamera`]
//! into its own colour + depth [`RenderTarget`]. The app shows that texture in its viewport
//! (registered with egui as a native texture); [`offscreen`] renders the same way on a device of
//! its own and reads the image back for the CLI's `screenshot` and for tests.

pub mod camera;
pub mod frame;
pub mod gpu;
pub mod offscreen;
pub mod pipelines;
pub mod renderer;
pub mod target;

pub use camera::OrbitCamera;
pub use frame::{MeshFrame, SceneFrame, vertex_normals};
pub use gpu::{heat_color, vertex_values_from_edges};
pub use offscreen::{Offscreen, render_to_image, screenshot};
pub use renderer::{DrawOptions, Renderer};
pub use target::RenderTarget;

/// Errors of the render layer.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// No usable GPU adapter or device (no driver, no Vulkan/Metal/DX12/GL implementation).
    #[error(
        "no usable GPU adapter: {0} (on Linux without a GPU, install Mesa's lavapipe: mesa-vulkan-drivers)"
    )]
    NoAdapter(String),
    /// A mesh cannot be drawn.
    #[error("cannot draw mesh '{name}': {reason}")]
    InvalidMesh {
        /// Which mesh (body or garment).
        name: String,
        /// What is wrong.
        reason: String,
    },
    /// The target's format or sample count differs from the renderer's.
    #[error("render target is {found}, but the renderer was built for {expected}")]
    TargetMismatch {
        /// The renderer's format and sample count.
        expected: String,
        /// The target's format and sample count.
        found: String,
    },
    /// Reading the image back failed.
    #[error("image read-back failed: {0}")]
    Readback(String),
}
