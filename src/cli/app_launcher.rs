//! Connects the app's training panel to the real trainer (`train::Trainer`); the app's
//! export is [`neural_cloth::app::export::ModelExporter`].

use std::sync::Arc;

use neural_cloth::app::{AppError, TrainerLauncher, TrainingRequest};
use neural_cloth::model::{ClothNetConfig, DescriptorConfig};
use neural_cloth::train::{RunLocation, TrainSetup, Trainer, TrainerHandle};

/// Starts real training runs for the app.
pub struct RealLauncher;

impl TrainerLauncher for RealLauncher {
    fn launch(
        &mut self,
        request: TrainingRequest,
        notify: Arc<dyn Fn() + Send + Sync>,
    ) -> Result<TrainerHandle, AppError> {
        let scene = (*request.scene).clone();
        // The run stores the app's scene description so it can be evaluated and baked later; a
        // scene that no longer matches it is refused at load time (garment fingerprint).
        let setup = TrainSetup {
            scene,
            scene_config: request.scene_config,
            train: request.config,
            model: ClothNetConfig::default(),
            descriptors: DescriptorConfig::default(),
            location: RunLocation::NewUnder(request.run_dir),
        };
        Ok(Trainer::spawn(setup, Some(notify))?)
    }
}
