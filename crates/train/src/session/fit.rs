//! Fitting to reference frames ([`crate::TrainConfig::fit_reference`], a diagnostic): loading the
//! frames and the mass-weighted distance a step descends instead of the physics loss.

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

    /// The mass-weighted squared distance `Σ m |x - x_sim|² / (2Δt²)` (batch mean) of the
    /// loss frames of `x_net` (`[B, K, V, 3]`) from the frames of
    /// [`crate::TrainConfig::fit_reference`] ([`Self::load_fit_reference`]).
    pub(super) fn reference_loss(
        &self,
        x_net: &Tensor<4>,
        batch: &crate::data::Batch,
    ) -> Result<Tensor<1>, TrainError> {
        let v = self.garment.vertex_count();
        let rows = batch.stacked_frames(2);
        let target = match &self.reference {
            Some(r) => r.rows(&rows)?,
            None => return Err(TrainError::Data("reference frames not loaded".into())),
        };
        let target = Tensor::<3>::from_data(
            burn::tensor::TensorData::new(target, [rows.len(), v, 3]),
            &self.device,
        );
        let x_t = stack_frames(x_net, 2, batch.predicted, batch.size);
        let dt = f64::from(self.dt_secs());
        let dx2 = neural_cloth_physics::tensors::norm2(x_t - target);
        Ok(
            neural_cloth_physics::tensors::per_sample(dx2 * self.terms.tensors().mass.clone())
                .mul_scalar(0.5 / (dt * dt) / batch.size.max(1) as f64)
                .sum(),
        )
    }
}
