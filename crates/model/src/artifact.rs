//! A trained model as one value: the weights together with the settings needed to run them
//! (descriptor settings and the frame rate the network was trained at; the encoder kind is
//! part of the weights), as burn's own guide keeps a config beside its record. Every
//! inference engine of trained or snapshot weights is built here, so a model can never be run
//! at another rate or with other input joints than it was trained with.

use neural_cloth_core::scene::{Avatar, Garment};

use super::ModelError;
use super::descriptors::DescriptorConfig;
use super::inference::{InferenceEngine, InferenceOptions, InferenceScene};
use super::weights::InferenceWeights;

/// Weights of a cloth network with the settings they were trained with.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelArtifact {
    /// The weights in the inference layout (the encoder kind included).
    pub weights: InferenceWeights,
    /// Which joints feed the network and how gravity points.
    pub descriptors: DescriptorConfig,
    /// Frame rate the network was trained at, frames per second: poses are fed at this rate.
    pub fps: f32,
}

impl ModelArtifact {
    /// Weights trained with `descriptors` at `fps`.
    pub fn new(weights: InferenceWeights, descriptors: DescriptorConfig, fps: f32) -> Self {
        Self {
            weights,
            descriptors,
            fps,
        }
    }

    /// Whether `engine` takes poses as these weights need (same descriptor settings and frame
    /// rate), so that they can be swapped in with [`InferenceEngine::set_weights`].
    pub fn fits_engine(&self, engine: &InferenceEngine) -> bool {
        self.descriptors == *engine.descriptors() && self.fps.to_bits() == engine.fps().to_bits()
    }

    /// Runs these weights in `engine`: swapped in where the engine takes poses as they need
    /// ([`Self::fits_engine`]), otherwise a fresh engine with the same options replaces it
    /// (weights trained at another rate or with other descriptors).
    pub fn swap_into(
        &self,
        engine: &mut InferenceEngine,
        avatar: &Avatar,
        garment: &Garment,
    ) -> Result<(), ModelError> {
        if self.fits_engine(engine) {
            return engine.set_weights(self.weights.clone());
        }
        *engine = self.engine(avatar, garment, engine.options().clone())?;
        Ok(())
    }

    /// An engine running a copy of these weights for `garment` on `avatar`.
    pub fn engine(
        &self,
        avatar: &Avatar,
        garment: &Garment,
        options: InferenceOptions,
    ) -> Result<InferenceEngine, ModelError> {
        self.clone().into_engine(avatar, garment, options)
    }

    /// An engine for `garment` on `avatar` that takes the weights over (no copy).
    pub fn into_engine(
        self,
        avatar: &Avatar,
        garment: &Garment,
        options: InferenceOptions,
    ) -> Result<InferenceEngine, ModelError> {
        self.into_engine_for(InferenceScene::new(avatar, garment), options)
    }

    /// An engine for an explicit scene description that takes the weights over: the one place
    /// an engine is built from a model.
    pub fn into_engine_for(
        self,
        scene: InferenceScene<'_>,
        options: InferenceOptions,
    ) -> Result<InferenceEngine, ModelError> {
        InferenceEngine::new(self.weights, scene, &self.descriptors, self.fps, options)
    }
}
