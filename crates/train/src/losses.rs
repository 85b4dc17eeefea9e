//! Loss variants the trainer needs beyond the physics layer's terms.

use burn::tensor::Tensor;

use neural_cloth_core::scene::Avatar;
use neural_cloth_physics::tensors::{norm2, per_sample};
use neural_cloth_physics::{BodyBatch, Contacts, FrictionContacts, PhysicsTerms};

use super::TrainError;
use super::data::{Batch, Dataset};

/// The friction inputs of a training or validation batch: `contacts` were queried for the
/// loss frames `2..K` of `batch`, stacked frame by frame; the step of each row starts at the
/// frame before (a still window's body does not move). Rows of samples `kept..` of each frame
/// (augmented samples, whose previous frame is not their own) get no friction. Built whatever
/// the friction effect (the slip metric reads it); None without dynamics.
pub fn friction_contacts(
    terms: &PhysicsTerms,
    data: &Dataset,
    avatar: &Avatar,
    batch: &Batch,
    contacts: &Contacts,
    kept: usize,
) -> Result<Option<FrictionContacts>, TrainError> {
    if !terms.effects().dynamics {
        return Ok(None);
    }
    let bodies = |frames: Vec<(usize, usize)>| -> Result<BodyBatch, TrainError> {
        Ok(BodyBatch::new(data.bodies(avatar, &frames)?))
    };
    let now = batch.stacked_frames(2);
    let mut before = batch.stacked_frames(1);
    before.truncate(now.len());
    let b = batch.size.max(1);
    let active: Vec<bool> = (0..now.len()).map(|row| row % b < kept).collect();
    Ok(Some(FrictionContacts::new(
        contacts,
        &bodies(now)?,
        &bodies(before)?,
        &active,
        terms.rest(),
        terms.fabric(),
    )?))
}

/// SNUG-style inertia (paper §4.5 comparison): `m |x_t - (2x_{t-1} - x_{t-2})|² / (2Δt²)`
/// with gradients flowing into the past frames too (no stop-gradient), batch mean. `None`
/// when dynamics is off.
pub fn inertia_through_past(
    terms: &PhysicsTerms,
    x_t: &Tensor<3>,
    x_t1: &Tensor<3>,
    x_t2: &Tensor<3>,
    dt_secs: f32,
) -> Option<Tensor<1>> {
    if !terms.effects().dynamics {
        return None;
    }
    let projected = x_t1.clone().mul_scalar(2.0) - x_t2.clone();
    let dx2 = norm2(x_t.clone() - projected);
    let scale = 0.5 / (f64::from(dt_secs) * f64::from(dt_secs));
    Some(
        per_sample(dx2 * terms.tensors().mass.clone())
            .mul_scalar(scale)
            .mean(),
    )
}

/// The frame before last that makes the plain inertia projection `2x_{t-1} - x_{t-2}'` the
/// boosted one `x_{t-1} + (1 + α)(x_{t-1} - x_{t-2})` ([`crate::TrainConfig::momentum_boost`]):
/// `x_{t-2}' = (1 + α) x_{t-2} - α x_{t-1}`; `x_t2` itself when `alpha` is 0.
pub fn boosted_history(x_t1: &Tensor<3>, x_t2: Tensor<3>, alpha: f64) -> Tensor<3> {
    if alpha == 0.0 {
        return x_t2;
    }
    x_t2.mul_scalar(1.0 + alpha) - x_t1.clone().mul_scalar(alpha)
}

/// Skins rest positions `[B, T, V, 3]` with per-vertex blended 3x4 matrices `[B, T, V, 12]`
/// (row-major): `x_r = Σ_c M_{r c} p_c + M_{r 3}`. Element-wise only, so its backward pass is
/// element-wise too.
pub fn skin_blended(rest: Tensor<4>, blended: Tensor<4>) -> Tensor<4> {
    let [b, t, v, _] = rest.dims();
    let m: Tensor<5> = blended.reshape([b, t, v, 3, 4]);
    let linear = m.clone().narrow(4, 0, 3);
    let translation: Tensor<4> = m.narrow(4, 3, 1).reshape([b, t, v, 3]);
    let p: Tensor<5> = rest.reshape([b, t, v, 1, 3]);
    let rotated: Tensor<4> = (linear * p).sum_dim(4).reshape([b, t, v, 3]);
    rotated + translation
}
