//! Loading a trained run for evaluation, baking and preview: the scene it was trained on, the
//! network with the newest checkpoint's weights, and those weights in the inference layout.

use std::path::Path;

use burn::module::Module;
use burn::tensor::Bytes;

use crate::io::scene_loader::load_scene;
use crate::model::{ClothNet, InferenceEngine, InferenceOptions, InferenceWeights};
use crate::scene::Scene;
use crate::scene::config::SceneConfig;

use super::run_dir::{RunDir, RunMeta, avatar_fingerprint, garment_fingerprint};
use super::{BackendKind, TrainError, device_for};

/// A trained model ready to evaluate or bake.
pub struct TrainedModel {
    /// The run's description.
    pub meta: RunMeta,
    /// The scene it was trained on (rebuilt from `scene.toml`).
    pub scene: Scene,
    /// The network on the CPU device (no autodiff).
    pub model: ClothNet,
    /// The same weights for the fast inference engine.
    pub weights: InferenceWeights,
    /// Step of the loaded checkpoint.
    pub step: u64,
    /// The run directory.
    pub run: RunDir,
}

impl TrainedModel {
    /// A fresh inference engine of these weights on the run's own scene, at the training rate
    /// with the run's descriptor settings, garment only (no body skinning).
    pub fn garment_engine(&self) -> Result<InferenceEngine, TrainError> {
        Ok(InferenceEngine::from_scene(
            self.weights.clone(),
            &self.scene.avatar,
            &self.scene.garment,
            &self.meta.descriptors,
            self.meta.train.fps,
            InferenceOptions {
                skin_body: false,
                ..Default::default()
            },
        )?)
    }

    /// The posed body of every frame of `motion` when the run collides with the body (the
    /// collision metric needs them), `None` otherwise.
    pub fn bodies_of(
        &self,
        motion: &crate::scene::Motion,
    ) -> Result<Option<Vec<std::sync::Arc<crate::physics::PosedBody>>>, TrainError> {
        if !self.meta.effects.collision {
            return Ok(None);
        }
        let bodies = motion
            .frames
            .iter()
            .map(|p| {
                crate::physics::PosedBody::from_avatar(&self.scene.avatar, p)
                    .map(std::sync::Arc::new)
            })
            .collect::<Result<_, _>>()?;
        Ok(Some(bodies))
    }
}

/// Loads the newest checkpoint of the run at `run_dir` (a run directory, or a checkpoint folder
/// inside one) with the scene it was trained on.
pub fn load_trained(run_dir: &Path) -> Result<TrainedModel, TrainError> {
    let root = if run_dir.join("run.json").is_file() {
        run_dir.to_path_buf()
    } else {
        // A checkpoint folder: RUN/checkpoints/step-N.
        run_dir
            .parent()
            .and_then(|p| p.parent())
            .map(Path::to_path_buf)
            .unwrap_or_else(|| run_dir.to_path_buf())
    };
    let run = RunDir::open(&root)?;
    let meta = run.meta()?;
    let scene_path = root.join("scene.toml");
    let config = SceneConfig::from_toml_str(&run.scene_toml()?)
        .map_err(|e| TrainError::Checkpoint(format!("{e}: {}", scene_path.display())))?;
    let scene = load_scene(&config, &root, &scene_path)?.scene;
    if garment_fingerprint(&scene.garment) != meta.garment_fingerprint {
        return Err(TrainError::Checkpoint(format!(
            "the garment changed since training: the scene's garment '{}' no longer matches \
             the one the run was trained on ('{}', {} vertices): {}",
            scene.garment.name,
            meta.garment_name,
            meta.garment_vertices,
            root.display()
        )));
    }
    if meta
        .avatar_fingerprint
        .is_some_and(|f| f != avatar_fingerprint(&scene.avatar))
    {
        return Err(TrainError::Checkpoint(format!(
            "the avatar changed since training: the scene's avatar '{}' no longer matches the \
             one the run was trained on (the garment is unchanged): {}",
            scene.avatar.name,
            root.display()
        )));
    }
    let step = run
        .latest_step()
        .ok_or_else(|| TrainError::Checkpoint(format!("no checkpoint in {}", root.display())))?;
    let (model_bytes, _, _) = run.read_checkpoint(step)?;
    let device = device_for(BackendKind::Cpu, false);
    let model = meta
        .model
        .init(meta.input_joints, meta.garment_vertices, &device)?;
    let record = burn::store::ModuleRecord::from_bytes(Bytes::from_bytes_vec(model_bytes))
        .map_err(|e| TrainError::Checkpoint(e.to_string()))?;
    let model = model
        .try_load_record(record)
        .map_err(|e| TrainError::Checkpoint(e.to_string()))?;
    let weights = InferenceWeights::from_module(&model)?;
    Ok(TrainedModel {
        meta,
        scene,
        model,
        weights,
        step,
        run,
    })
}
