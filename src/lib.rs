//! neural-cloth: unsupervised neural cloth simulation (Bertiche, Madadi and Escalera, "Neural
//! Cloth Simulation", ACM TOG 2022) as a desktop authoring tool.
//!
//! The layers are crates (see ARCHITECTURE.md), each depending only on those before it:
//! `neural-cloth-core` ([`geometry`], [`scene`], [`io`]), `neural-cloth-physics`
//! ([`physics`]), `neural-cloth-fit` ([`fit`]), `neural-cloth-model` ([`model`]),
//! `neural-cloth-train` ([`train`]), `neural-cloth-bake` ([`bake`]), `neural-cloth-render`
//! ([`render`]), `neural-cloth-lab` ([`bench`], [`report`]) and `neural-cloth-app` ([`app`]).
//! This crate re-exports them under those module names for the command line and the
//! integration tests.

pub use neural_cloth_app as app;
pub use neural_cloth_bake as bake;
pub use neural_cloth_core::{geometry, io, scene};
pub use neural_cloth_fit as fit;
pub use neural_cloth_lab::{bench, report};
pub use neural_cloth_model as model;
pub use neural_cloth_physics as physics;
pub use neural_cloth_render as render;
pub use neural_cloth_train as train;
