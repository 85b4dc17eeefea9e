//! Fitting to reference frames: the diagnostic of [`crate::TrainConfig::fit_reference`] (the
//! whole run) and the warm start of [`crate::TrainConfig::warm_start_steps`] (its first
//! steps): loading the frames and the mass-weighted distance a step descends.

use std::ops::Range;

use burn::tensor::Tensor;

use super::{NeuralSession, stack_frames};
use crate::TrainError;
use crate::fit_reference::FitReference;

impl NeuralSession {
    /// Loads the frames of [`crate::TrainConfig::fit_reference`] (when set), so that a folder
    /// without them is refused before the first step.
    pub fn load_fit_reference(&mut self) -> Result<(), TrainError> {
        if let Some(dir) = &self.config.fit_reference {
            let v = self.garment.vertex_count();
            self.reference = Some(FitReference::load(
                dir,
                self.train.motions.iter().map(|m| m.name.as_str()),
                v,
            )?);
        }
        Ok(())
    }

    /// The training motions as prepared (resampled, with their mirrored copies).
    pub fn training_data(&self) -> &crate::data::Dataset {
        &self.train
    }

    /// Sets the simulated frames the warm start fits to ([`crate::warm_start_sim`]).
    pub fn set_warm_start_reference(&mut self, reference: FitReference) {
        self.reference = Some(reference);
    }

    /// True when this step fits to reference frames: the diagnostic fit (every step), or the
    /// warm start before [`crate::TrainConfig::warm_start_steps`].
    pub fn fitting(&self) -> bool {
        self.reference.is_some()
            && (self.config.fit_reference.is_some()
                || self.filter.steps_taken() < self.config.warm_start_steps)
    }

    /// Forgets the warm start's frames once its steps are done (they take the memory of the
    /// training motions' simulation).
    pub(super) fn end_warm_start(&mut self) {
        if self.config.fit_reference.is_none()
            && self.filter.steps_taken() >= self.config.warm_start_steps
        {
            self.reference = None;
        }
    }

    /// The mass-weighted squared distance `Σ m |x - x_sim|² / (2Δt²)` (batch mean) of the
    /// loss frames of `x_net` (`[B, K, V, 3]`) from the reference frames, over the windows
    /// `samples` whose motion has them (still and augmented windows have none).
    pub(super) fn reference_loss(
        &self,
        x_net: &Tensor<4>,
        batch: &crate::data::Batch,
        samples: Range<usize>,
    ) -> Result<Tensor<1>, TrainError> {
        let v = self.garment.vertex_count();
        let rows = batch.stacked_frames(2);
        let (target, mut mask) = match &self.reference {
            Some(r) => r.rows(&rows)?,
            None => return Err(TrainError::Data("reference frames not loaded".into())),
        };
        // Rows are frame-major: row `k·B + s` holds sample `s`.
        for (row, m) in mask.iter_mut().enumerate() {
            if !samples.contains(&(row % batch.size.max(1))) {
                *m = 0.0;
            }
        }
        let target = Tensor::<3>::from_data(
            burn::tensor::TensorData::new(target, [rows.len(), v, 3]),
            &self.device,
        );
        let mask = Tensor::<3>::from_data(
            burn::tensor::TensorData::new(mask, [rows.len(), 1, 1]),
            &self.device,
        );
        let x_t = stack_frames(x_net, 2, batch.predicted, batch.size);
        let dt = f64::from(self.dt_secs());
        let dx2 = neural_cloth_physics::tensors::norm2(x_t - target) * mask;
        Ok(
            neural_cloth_physics::tensors::per_sample(dx2 * self.terms.tensors().mass.clone())
                .mul_scalar(0.5 / (dt * dt) / batch.size.max(1) as f64)
                .sum(),
        )
    }
}
