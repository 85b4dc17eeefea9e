//! Train layer: the unsupervised trainer (paper §3.4, §4.1) on a named background thread.
//!
//! - [`Trainer::spawn`] prepares a run (data, model, physics, run directory) on the trainer
//!   thread and returns a [`TrainerHandle`] at once; the app and the CLI use exactly this API.
//! - [`config::TrainConfig`]: batch, window, rate, optimiser, schedule.
//! - [`data`]: motions → descriptors, skinning matrices and windows.
//! - [`session::NeuralSession`]: one optimiser step, validation, checkpoints.
//! - [`run_dir`]: the run directory layout (resume, eval, bake).
//! - [`handle`]: the thread loop, commands, events, divergence rollback.

pub mod compare;
pub mod config;
pub mod data;
pub mod eval;
pub mod handle;
pub mod losses;
pub mod metrics;
pub mod preflight;
pub mod run_dir;
pub mod session;
pub mod trained;
pub mod warm_start;

pub use config::{BackendKind, InertiaMode, TrainConfig};
pub use eval::{EvalReport, evaluate};
pub use handle::{RunSummary, TrainCommand, TrainEvent, TrainerHandle};
pub use metrics::{MetricHistory, MetricRecord};
pub use run_dir::{RunDir, RunMeta};
pub use trained::{TrainedModel, load_trained};

use std::path::{Path, PathBuf};
use std::sync::Arc;

use burn::tensor::{Device, DeviceKind};

use crate::model::{ClothNetConfig, DescriptorConfig, EncoderKind, GarmentLbs};
use crate::physics::{FabricParams, PhysicsTerms};
use crate::scene::Scene;
use crate::scene::config::{SceneConfig, Split};

use data::Dataset;
use handle::LoopConfig;
use run_dir::garment_fingerprint;
use session::{NeuralSession, SessionParts};

/// Errors of the train layer.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// A setting is out of range.
    #[error(transparent)]
    Config(#[from] config::ConfigError),
    /// The model layer refused.
    #[error(transparent)]
    Model(#[from] crate::model::ModelError),
    /// The physics layer refused.
    #[error(transparent)]
    Physics(#[from] crate::physics::PhysicsError),
    /// Loading a scene failed.
    #[error(transparent)]
    Io(#[from] crate::io::IoError),
    /// Writing a file failed.
    #[error(transparent)]
    Export(#[from] crate::io::export::ExportError),
    /// The data cannot be trained on.
    #[error("training data: {0}")]
    Data(String),
    /// A checkpoint or run directory is unusable.
    #[error("checkpoint: {0}")]
    Checkpoint(String),
    /// The file system refused.
    #[error("{source}: {}", path.display())]
    File {
        /// The OS error.
        #[source]
        source: std::io::Error,
        /// The path concerned.
        path: PathBuf,
    },
}

impl TrainError {
    /// Wraps an I/O error with its path.
    pub fn io(source: std::io::Error, path: &Path) -> Self {
        Self::File {
            source,
            path: path.to_path_buf(),
        }
    }
}

/// Where a run writes.
#[derive(Clone, Debug)]
pub enum RunLocation {
    /// A new timestamped run folder under this parent.
    NewUnder(PathBuf),
    /// This exact (new or empty) folder.
    At(PathBuf),
    /// Continue the run in this folder from its newest checkpoint.
    Resume(PathBuf),
}

/// Everything a run needs.
pub struct TrainSetup {
    /// The loaded scene.
    pub scene: Scene,
    /// Its description, saved with the run (file paths should be absolute).
    pub scene_config: SceneConfig,
    /// Training settings.
    pub train: TrainConfig,
    /// Network architecture (the encoder becomes static-only when the scene has no dynamics).
    pub model: ClothNetConfig,
    /// Descriptor settings.
    pub descriptors: DescriptorConfig,
    /// Fabric; `None` reads the scene's fabric table.
    pub fabric: Option<FabricParams>,
    /// Run folder.
    pub location: RunLocation,
}

/// L-BFGS iterations per step of the warm-start drape simulation.
pub const PREDRAPE_ITERATIONS: usize = 100;

/// Starts training runs.
pub struct Trainer;

impl Trainer {
    /// Starts a run on the named thread `neural-cloth-trainer`. Preparation (data, model) runs
    /// on that thread too, so this returns at once; a failed preparation arrives as
    /// `TrainEvent::Finished(Err(..))`. `notify` is called after each event.
    pub fn spawn(
        setup: TrainSetup,
        notify: Option<Arc<dyn Fn() + Send + Sync>>,
    ) -> Result<TrainerHandle, TrainError> {
        setup.train.validate()?;
        TrainerHandle::spawn_with(move || prepare(setup).map_err(|e| e.to_string()), notify)
            .map_err(|e| TrainError::io(e, Path::new("trainer thread")))
    }
}

/// The compute device of `backend`, with autodiff when `autodiff`.
pub fn device_for(backend: BackendKind, autodiff: bool) -> Device {
    let device = match backend {
        BackendKind::Cpu => Device::flex(),
        BackendKind::Wgpu => Device::wgpu(DeviceKind::DefaultDevice),
    };
    if autodiff { device.autodiff() } else { device }
}

/// Builds the session and loop settings of `setup` (synchronously; used by [`Trainer::spawn`]
/// on the trainer thread and by tests).
pub fn prepare(setup: TrainSetup) -> Result<(NeuralSession, LoopConfig), TrainError> {
    let TrainSetup {
        scene,
        scene_config,
        train,
        mut model,
        descriptors,
        fabric,
        location,
    } = setup;
    train.validate()?;
    let fabric = match fabric {
        Some(f) => f,
        None => FabricParams::from_table(&scene.fabric)?,
    };
    fabric.validate()?;
    if !scene.effects.dynamics {
        model.encoder = EncoderKind::StaticOnly;
    }
    let device = device_for(train.backend, true);
    device.seed(train.seed);
    let avatar = Arc::new(scene.avatar);
    let garment = Arc::new(scene.garment);
    let train_data = Dataset::new(
        &avatar,
        &scene.motions,
        Split::Train,
        train.fps,
        &descriptors,
        train.mirror_poses,
    )?;
    if train_data.is_empty() {
        return Err(TrainError::Data("no motion in the train split".into()));
    }
    let validation = Dataset::new(
        &avatar,
        &scene.motions,
        Split::Validation,
        train.fps,
        &descriptors,
        false,
    )?;
    let (run, resume) = match &location {
        RunLocation::NewUnder(parent) => (RunDir::fresh_under(parent)?, false),
        RunLocation::At(dir) => (RunDir::create(dir)?, false),
        RunLocation::Resume(dir) => (RunDir::open(dir)?, true),
    };
    let fingerprint = garment_fingerprint(&garment);
    if resume {
        let meta = run.meta()?;
        if meta.garment_fingerprint != fingerprint
            || meta.garment_vertices != garment.vertex_count()
        {
            return Err(TrainError::Checkpoint(format!(
                "the run was trained on garment '{}' ({} vertices), not on '{}' ({} vertices): {}",
                meta.garment_name,
                meta.garment_vertices,
                garment.name,
                garment.vertex_count(),
                run.root.display()
            )));
        }
        model = meta.model;
    }
    let warnings = preflight::preflight_warnings(&avatar, &garment, &fabric);
    let mut net = model.init(train_data.input_joints, garment.vertex_count(), &device)?;
    if !resume && train.predrape_secs > 0.0 && model.basis_bias {
        let drape = warm_start::simulated_drape(
            &avatar,
            &garment,
            &fabric,
            &scene.effects,
            train.predrape_secs,
            train.fps,
            PREDRAPE_ITERATIONS,
        )?;
        warm_start::set_basis_bias_to_drape(&mut net, &garment, &drape, &device)?;
    }
    let terms = PhysicsTerms::new(&garment, &fabric, &scene.effects, &device)?;
    let lbs = GarmentLbs::from_garment(&garment, avatar.skeleton.len(), &device)?;
    if !resume {
        let meta = RunMeta {
            version: 1,
            train: train.clone(),
            model: model.clone(),
            descriptors: descriptors.clone(),
            fabric: fabric.clone(),
            effects: scene.effects,
            input_joints: train_data.input_joints,
            garment_vertices: garment.vertex_count(),
            garment_fingerprint: fingerprint,
            garment_name: garment.name.clone(),
            avatar_fingerprint: Some(run_dir::avatar_fingerprint(&avatar)),
        };
        let scene_toml = scene_config
            .to_toml_string()
            .map_err(|e| TrainError::Checkpoint(e.to_string()))?;
        run.write_meta(&meta, &scene_toml)?;
    }
    let run_root = run.root.clone();
    let mut session = NeuralSession::new(SessionParts {
        device,
        model: net,
        config: train.clone(),
        terms,
        lbs,
        avatar,
        garment,
        train: train_data,
        validation,
        run,
        init_std: model.init_std,
    });
    if !resume && train.centre_init {
        session.centre_biases()?;
    }
    let mut history = MetricHistory::default();
    let mut start_step = 0;
    if resume && let Some(step) = session.run_dir().latest_step() {
        let state = session.load_checkpoint(step)?;
        start_step = state.step;
        history = session.run_dir().history();
        history.truncate_after(start_step);
    }
    let loop_config = LoopConfig {
        run_dir: run_root,
        start_step,
        history,
        max_steps: train.max_steps,
        max_secs: train.max_minutes.map(|m| m * 60.0),
        validate_every: train.validate_every,
        snapshot_every: train.snapshot_every,
        checkpoint_every: train.checkpoint_every,
        max_rollbacks: 8,
        dead_limit_pct: train.dead_limit_pct,
        warnings,
    };
    Ok((session, loop_config))
}
