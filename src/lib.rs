//! neural-cloth: unsupervised neural cloth simulation (Bertiche, Madadi and Escalera, "Neural
//! Cloth Simulation", ACM TOG 2022) as a desktop authoring tool.
//!
//! Layers, each depending only on those above it in this list: [`geometry`], [`scene`],
//! [`io`], `physics`, [`fit`], `model`, `train`, `render`, `app`.

pub mod app;
pub mod bake;
pub mod bench;
pub mod fit;
pub mod geometry;
pub mod io;
pub mod model;
pub mod physics;
pub mod render;
pub mod report;
pub mod scene;
pub mod train;
