//! Eq. 8 at a given frame: how far any garment frame (simulated or predicted by the network)
//! is from solving the implicit step, with the same energy code.

use serde::{Deserialize, Serialize};

use crate::PhysicsError;
use crate::collision::{BodyBatch, Contacts};
use crate::tensors::positions_tensor;
use neural_cloth_core::geometry::Vec3;

use super::{StepInput, Stepper};

// ---------------------------------------------------------------------------------------------
// Eq. 8 at a given frame (added for `report`): how far any garment frame — simulated or
// predicted by the network — is from solving the implicit step, with the same energy code.
// ---------------------------------------------------------------------------------------------

/// The implicit-integration objective (Eq. 8, divided by `Δt²`) evaluated at a given frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameResidual {
    /// Objective `L_inertia + E` at the frame, joules.
    pub objective_j: f64,
    /// Largest per-coordinate residual force (objective gradient) relative to the mean vertex
    /// weight `m̄·|g|`; 0 at an exact solution of the step.
    pub residual_max: f64,
    /// Root-mean-square per-vertex residual force relative to `m̄·|g|`.
    pub residual_rms: f64,
}

impl Stepper {
    /// Evaluates Eq. 8 at `x` as the step following `x_t1` (previous frame) and `x_t2` (the
    /// one before), with contacts queried at `x` and the pin targets of `input`. Does not
    /// change the stepper's state. Without `dynamics` the history is ignored (static solve).
    pub fn residual_at(
        &self,
        x_t2: &[Vec3],
        x_t1: &[Vec3],
        x: &[Vec3],
        input: &StepInput,
    ) -> Result<FrameResidual, PhysicsError> {
        let v = self.terms.rest().vertex_count();
        if [x_t2.len(), x_t1.len(), x.len()].iter().any(|&n| n != v) {
            return Err(PhysicsError::ShapeMismatch {
                what: "frames for the Eq. 8 residual".into(),
                expected: format!("{v} vertices"),
                found: format!("{}, {}, {}", x_t2.len(), x_t1.len(), x.len()),
            });
        }
        if [x_t2, x_t1, x]
            .iter()
            .any(|f| f.iter().any(|p| !p.iter().all(|c| c.is_finite())))
        {
            return Err(PhysicsError::NonFinite(
                "frames for the Eq. 8 residual".into(),
            ));
        }
        let (device, dtype) = (self.terms.device().clone(), self.terms.dtype());
        let upload = |f: &[Vec3]| positions_tensor(&[f], &device, dtype);
        let contacts = match (self.terms.effects().collision, &input.body) {
            (true, Some(b)) => {
                let flat: Vec<f32> = x.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
                Some(Contacts::query(
                    &BodyBatch::new(vec![b.clone()]),
                    &flat,
                    v,
                    &device,
                    dtype,
                )?)
            }
            (true, None) => return Err(PhysicsError::MissingBody),
            (false, _) => None,
        };
        let pin_target = match (&input.pin_targets, self.terms.tensors().pinned.is_some()) {
            (Some(t), true) => Some(positions_tensor(&[t.as_slice()], &device, dtype)?),
            _ => None,
        };
        let friction = match (&contacts, &input.body) {
            (Some(c), Some(now)) => {
                let before = input.body_before.as_ref().unwrap_or(now);
                self.terms.friction_contacts(
                    c,
                    &BodyBatch::new(vec![now.clone()]),
                    &BodyBatch::new(vec![before.clone()]),
                    &[],
                )?
            }
            _ => None,
        };
        let (value, _, grad) = self.objective(
            &upload(x)?,
            contacts.as_ref(),
            friction.as_ref(),
            &upload(x_t1)?,
            &upload(x_t2)?,
            pin_target.as_ref(),
            true,
        )?;
        let max = grad.iter().fold(0.0f64, |m, g| m.max(g.abs()));
        let sum_sq: f64 = grad.iter().map(|g| g * g).sum();
        let rms = (sum_sq / v.max(1) as f64).sqrt();
        Ok(FrameResidual {
            objective_j: value,
            residual_max: max / self.force_scale,
            residual_rms: rms / self.force_scale,
        })
    }
}
