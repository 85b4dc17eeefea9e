//! Loss variants the trainer needs beyond the physics layer's terms.

use burn::tensor::Tensor;

use crate::physics::PhysicsTerms;
use crate::physics::tensors::{norm2, per_sample};

/// SNUG-style inertia (paper §4.5 comparison): `m |x_t - (2x_{t-1} - x_{t-2})|² / (2Δt²)`
/// with gradients flowing into the past frames too (no stop-gradient), batch mean. `None`
/// when dynamics is off.
pub fn inertia_through_past(terms: &PhysicsTerms, x_t: &Tensor<3>, x_t1: &Tensor<3>, x_t2: &Tensor<3>, dt_secs: f32) -> Option<Tensor<1>> {
    if !terms.effects().dynamics {
        return None;
    }
    let projected = x_t1.clone().mul_scalar(2.0) - x_t2.clone();
    let dx2 = norm2(x_t.clone() - projected);
    let scale = 0.5 / (f64::from(dt_secs) * f64::from(dt_secs));
    Some(per_sample(dx2 * terms.tensors().mass.clone()).mul_scalar(scale).mean())
}
