//! Gravity potential, inertia (with the stop-gradient on the projected position) and pinning.

use burn::tensor::{Int, Tensor};

use crate::tensors::{RestTensors, gather, norm2, per_sample};

/// Gravity potential `-Σ m x·g` per sample, `[B]` joules.
pub fn gravity(x: &Tensor<3>, rt: &RestTensors) -> Tensor<1> {
    let height = (x.clone() * rt.gravity.clone()).sum_dim(2);
    per_sample(height * rt.mass.clone()).neg()
}

/// Inertia `Σ m |x_t - sg(2x_{t-1} - x_{t-2})|² / (2Δt²)` per sample, `[B]` joules.
///
/// The projection is detached: no gradient ever reaches `x_{t-1}` or `x_{t-2}`.
pub fn inertia(
    x_t: &Tensor<3>,
    x_t1: &Tensor<3>,
    x_t2: &Tensor<3>,
    rt: &RestTensors,
    dt_secs: f32,
) -> Tensor<1> {
    let projected = (x_t1.clone().mul_scalar(2.0) - x_t2.clone()).detach();
    let dx2 = norm2(x_t.clone() - projected);
    let scale = 0.5 / (f64::from(dt_secs) * f64::from(dt_secs));
    per_sample(dx2 * rt.mass.clone()).mul_scalar(scale)
}

/// Mass-weighted mean distance `Σ m |x_t - x_proj| / Σ m` per sample, `[B]` metres (the
/// inertia metric of the official code).
pub fn inertia_distance(
    x_t: &Tensor<3>,
    x_t1: &Tensor<3>,
    x_t2: &Tensor<3>,
    rt: &RestTensors,
    total_mass: f64,
) -> Tensor<1> {
    let projected = (x_t1.clone().mul_scalar(2.0) - x_t2.clone()).detach();
    let d = norm2(x_t.clone() - projected).sqrt();
    per_sample(d * rt.mass.clone()).div_scalar(total_mass.max(f64::MIN_POSITIVE))
}

/// Pinning `k Σ_{i pinned} |x_i - target_i|²` per sample, `[B]` joules; `target` is `[B, V, 3]`
/// (only its pinned rows are read).
pub fn pinning(x: &Tensor<3>, target: &Tensor<3>, pinned: &Tensor<1, Int>, k: f32) -> Tensor<1> {
    let d = gather(x, pinned) - gather(target, pinned).detach();
    per_sample(norm2(d)).mul_scalar(k)
}
