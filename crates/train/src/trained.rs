//! Loading a trained run for evaluation, baking and preview: the scene it was trained on, the
//! network with the newest checkpoint's weights, and those weights in the inference layout.

use std::path::Path;

use burn::module::Module;
use burn::tensor::Bytes;

use neural_cloth_core::scene::{Avatar, Garment, Scene};
use neural_cloth_model::{
    ClothNet, InferenceEngine, InferenceOptions, InferenceWeights, ModelArtifact,
};

use super::checkpoint::MODEL_FILE;
use super::resume::recorded_scene;
use super::run_dir::{
    RunDir, RunMeta, avatar_fingerprint, garment_fingerprint, garment_skin_fingerprint,
};
use super::{BackendKind, TrainError, device_for};

/// A trained model ready to evaluate or bake.
pub struct TrainedModel {
    /// The run's description.
    pub meta: RunMeta,
    /// The scene it was trained on (rebuilt from `scene.toml`), at the rate the run trained at
    /// ([`RunMeta::training_fps`]; a run trained with `train --fps` before issue 14 recorded
    /// the scene's own rate in `scene.toml`).
    pub scene: Scene,
    /// The network on the CPU device (no autodiff).
    pub model: ClothNet,
    /// The same weights for the fast inference engine, with the run's descriptor settings and
    /// training frame rate.
    pub artifact: ModelArtifact,
    /// Step of the loaded checkpoint.
    pub step: u64,
    /// The run directory.
    pub run: RunDir,
    /// Problems met while loading (a damaged newer checkpoint skipped, scene warnings); the
    /// CLI prints them, the app shows them.
    pub warnings: Vec<String>,
}

impl TrainedModel {
    /// A fresh inference engine of the trained model on the run's own scene (at the training
    /// rate with the run's descriptor settings).
    pub fn engine(&self, options: InferenceOptions) -> Result<InferenceEngine, TrainError> {
        Ok(self
            .artifact
            .engine(&self.scene.avatar, &self.scene.garment, options)?)
    }

    /// [`Self::engine`] for the garment only (no body skinning).
    pub fn garment_engine(&self) -> Result<InferenceEngine, TrainError> {
        self.engine(InferenceOptions {
            skin_body: false,
            ..Default::default()
        })
    }

    /// The posed body of every frame of `motion` when the run collides with the body (the
    /// collision metric needs them), `None` otherwise.
    pub fn bodies_of(
        &self,
        motion: &neural_cloth_core::scene::Motion,
    ) -> Result<Option<Vec<std::sync::Arc<neural_cloth_physics::PosedBody>>>, TrainError> {
        if !self.scene.effects.collision {
            return Ok(None);
        }
        let bodies = motion
            .frames
            .iter()
            .map(|p| {
                neural_cloth_physics::PosedBody::from_avatar(&self.scene.avatar, p)
                    .map(std::sync::Arc::new)
            })
            .collect::<Result<_, _>>()?;
        Ok(Some(bodies))
    }
}

/// Loads a trained model with the scene it was trained on: the newest checkpoint of the run
/// at `run_dir`, or, when `run_dir` is a checkpoint folder inside a run
/// (`RUN/checkpoints/step-N`), exactly that checkpoint. A damaged newest checkpoint falls
/// back to the previous complete one ([`TrainedModel::warnings`] says so); a run of which no
/// checkpoint loads, or a named checkpoint that does not load, is an error naming the file.
pub fn load_trained(run_dir: &Path) -> Result<TrainedModel, TrainError> {
    // A checkpoint folder RUN/checkpoints/step-N names its step; any other folder is opened
    // as a run (and refused with the run folder's own message when it is not one).
    let checkpoint = if run_dir.join("run.json").is_file() {
        None
    } else {
        let in_checkpoints = run_dir
            .parent()
            .and_then(Path::file_name)
            .is_some_and(|name| name == "checkpoints");
        run_dir
            .file_name()
            .and_then(|n| crate::checkpoint::step_of(&n.to_string_lossy()))
            .filter(|_| in_checkpoints)
            .zip(run_dir.parent().and_then(Path::parent))
    };
    let (root, named_step) = match checkpoint {
        Some((step, root)) => (root.to_path_buf(), Some(step)),
        None => (run_dir.to_path_buf(), None),
    };
    let run = RunDir::open(&root)?;
    let meta = run.meta()?;
    let recorded = recorded_scene(&run)?;
    let mut scene = recorded.scene;
    scene.training_fps = meta.training_fps;
    refuse_changed_scene(&meta, &scene, &root)?;
    let device = device_for(BackendKind::Cpu, false);
    let loaded = match named_step {
        Some(step) => crate::checkpoint::Loaded {
            step,
            value: load_model(&run, &meta, step, &device)?,
            warnings: Vec::new(),
        },
        None => run
            .newest_loadable(|step| load_model(&run, &meta, step, &device))?
            .ok_or_else(|| {
                TrainError::Checkpoint(format!("no checkpoint in {}", root.display()))
            })?,
    };
    let (model, weights) = loaded.value;
    let mut warnings = recorded.warnings;
    warnings.extend(loaded.warnings);
    Ok(TrainedModel {
        scene,
        artifact: ModelArtifact::new(weights, meta.descriptors.clone(), meta.training_fps),
        meta,
        model,
        step: loaded.step,
        run,
        warnings,
    })
}

/// Refuses a recorded scene that no longer rebuilds what the run was trained on: another
/// garment, another avatar, or the garment with other skin weights (smoothing passes).
fn refuse_changed_scene(meta: &RunMeta, scene: &Scene, root: &Path) -> Result<(), TrainError> {
    refuse_changed_parts(meta, &scene.avatar, &scene.garment, root)
}

/// Refuses an avatar and garment that are not those the run at `root` was trained on (see
/// [`RunMeta`]'s fingerprints): another garment, another avatar, or the garment with other
/// skin weights. The app checks a project's own parts with it before showing a run's weights
/// on them.
pub fn refuse_changed_parts(
    meta: &RunMeta,
    avatar: &Avatar,
    garment: &Garment,
    root: &Path,
) -> Result<(), TrainError> {
    if garment_fingerprint(garment) != meta.garment_fingerprint {
        return Err(TrainError::Checkpoint(format!(
            "the garment changed since training: the scene's garment '{}' no longer matches \
             the one the run was trained on ('{}', {} vertices): {}",
            garment.name,
            meta.garment_name,
            meta.garment_vertices,
            root.display()
        )));
    }
    if meta
        .avatar_fingerprint
        .is_some_and(|f| f != avatar_fingerprint(avatar))
    {
        return Err(TrainError::Checkpoint(format!(
            "the avatar changed since training: the scene's avatar '{}' no longer matches the \
             one the run was trained on (the garment is unchanged): {}",
            avatar.name,
            root.display()
        )));
    }
    if meta
        .garment_skin_fingerprint
        .is_some_and(|f| f != garment_skin_fingerprint(garment))
    {
        return Err(TrainError::Checkpoint(format!(
            "the garment's skin weights changed since training: the scene rebuilds '{}' with \
             {} smoothing passes, not with the weights the run was trained on: {}",
            garment.name,
            garment.smoothing_passes,
            root.display()
        )));
    }
    Ok(())
}

/// The network of checkpoint `step`, and its weights in the inference layout.
fn load_model(
    run: &RunDir,
    meta: &RunMeta,
    step: u64,
    device: &burn::tensor::Device,
) -> Result<(ClothNet, InferenceWeights), TrainError> {
    run.read_state(step)?;
    let path = run.checkpoint_path(step).join(MODEL_FILE);
    let bytes = run.read_checkpoint_file(step, MODEL_FILE)?;
    let damaged = |e: String| TrainError::Corrupt {
        reason: format!("the network cannot be read from the checkpoint ({e})"),
        path: path.clone(),
    };
    let model = meta
        .model
        .init(meta.input_joints, meta.garment_vertices, device)?;
    let record = burn::store::ModuleRecord::from_bytes(Bytes::from_bytes_vec(bytes))
        .map_err(|e| damaged(e.to_string()))?;
    let model = model
        .try_load_record(record)
        .map_err(|e| damaged(e.to_string()))?;
    let weights = InferenceWeights::from_module(&model)?;
    weights
        .validate()
        .map_err(|e| damaged(format!("invalid weights: {e}")))?;
    Ok((model, weights))
}
