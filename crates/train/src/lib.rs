//! Train layer: the unsupervised trainer (paper §3.4, §4.1) on a named background thread.
//!
//! - [`Trainer::spawn`] prepares a run (data, model, physics, run directory) on the trainer
//!   thread and returns a [`TrainerHandle`] at once; the app and the CLI use exactly this API.
//! - [`config::TrainConfig`]: batch, window, optimiser, schedule (the frame rate is the
//!   scene's, [`Scene::training_fps`]).
//! - [`data`]: motions → descriptors, skinning matrices and windows.
//! - [`session::NeuralSession`]: one optimiser step, validation, checkpoints.
//! - [`run_dir`]: the run directory layout (resume, eval, bake); [`checkpoint`]: crash-safe
//!   checkpoint folders, their verification and the fallback to an older one; [`resume`]: the
//!   scene a run recorded; [`retention`]: which checkpoints are kept, disk use.
//! - [`handle`]: the thread loop, commands, events, divergence rollback.

pub mod adam;
pub mod alloc;
pub mod checkpoint;
pub mod compare;
pub mod config;
pub mod data;
pub mod eval;
pub mod filter;
pub mod fit_reference;
pub mod handle;
pub mod health;
pub mod losses;
pub mod metrics;
pub mod preflight;
pub mod resume;
pub mod retention;
pub mod run_dir;
pub mod session;
pub mod trained;
pub mod warm_start;
pub mod warm_start_mirror;
pub mod warm_start_sim;

pub use config::{BackendKind, BasisRowNorm, InertiaMode, TrainConfig};
pub use eval::{EvalReport, evaluate};
pub use handle::{
    LiveSetting, PrepareProgress, Preparing, RunSummary, TrainCommand, TrainEvent, TrainerHandle,
};
pub use metrics::{MetricHistory, MetricRecord};
pub use run_dir::{RunDir, RunMeta};
pub use trained::{TrainedModel, load_trained};

use std::path::{Path, PathBuf};
use std::sync::Arc;

use burn::tensor::{Device, DeviceKind};

use neural_cloth_core::scene::Scene;
use neural_cloth_core::scene::config::{SceneConfig, Split};
use neural_cloth_model::{ClothNetConfig, DescriptorConfig, EncoderKind, GarmentLbs};
use neural_cloth_physics::{Effects, FabricParams, PhysicsTerms};

use data::Dataset;

use handle::LoopConfig;
use run_dir::{avatar_fingerprint, garment_fingerprint, garment_skin_fingerprint};
use session::{NeuralSession, SessionParts};

/// Held while the process's device random generator is seeded and drawn from (a run's
/// initial weights, revived units), so that the draws of one run are not interleaved with
/// another's on another thread. Poisoning is ignored: the guard protects no data.
pub fn device_rng_lock() -> std::sync::MutexGuard<'static, ()> {
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    LOCK.lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Errors of the train layer.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// A setting is out of range.
    #[error(transparent)]
    Config(#[from] config::ConfigError),
    /// The model layer refused.
    #[error(transparent)]
    Model(#[from] neural_cloth_model::ModelError),
    /// The physics layer refused.
    #[error(transparent)]
    Physics(#[from] neural_cloth_physics::PhysicsError),
    /// Loading a scene failed.
    #[error(transparent)]
    Io(#[from] neural_cloth_core::io::IoError),
    /// Writing a file failed.
    #[error(transparent)]
    Export(#[from] neural_cloth_core::io::export::ExportError),
    /// The data cannot be trained on.
    #[error("training data: {0}")]
    Data(String),
    /// The garment file does not fit the avatar (the message says what to do).
    #[error("{0}")]
    GarmentFit(String),
    /// Checking the garment's fit failed.
    #[error(transparent)]
    Fit(#[from] neural_cloth_fit::FitError),
    /// A checkpoint or run directory is unusable.
    #[error("checkpoint: {0}")]
    Checkpoint(String),
    /// A resumed run would go on at another training rate than it was trained at.
    #[error(
        "the run was trained at {run_fps} frames per second, the scene is at {scene_fps}; a run goes on at its own rate: {}",
        path.display()
    )]
    RateChanged {
        /// The rate the run recorded, frames per second.
        run_fps: f32,
        /// The rate of the scene given, frames per second.
        scene_fps: f32,
        /// The run folder.
        path: PathBuf,
    },
    /// A file of a run folder is damaged, truncated or unreadable.
    #[error("{reason}: {}", path.display())]
    Corrupt {
        /// What is wrong.
        reason: String,
        /// The file concerned.
        path: PathBuf,
    },
    /// A checkpoint file could not be written (the reason without the temporary it was
    /// written to).
    #[error("{reason}: {}", path.display())]
    WriteFile {
        /// What failed.
        reason: String,
        /// The file's final path.
        path: PathBuf,
    },
    /// The file system refused.
    #[error("{source}: {}", path.display())]
    File {
        /// The OS error.
        #[source]
        source: std::io::Error,
        /// The path concerned.
        path: PathBuf,
    },
    /// The network or optimiser state could not be turned into bytes.
    #[error(transparent)]
    Record(#[from] burn::store::RecordError),
    /// The fused optimiser refused (a parameter it cannot update, or a saved state of another
    /// network).
    #[error(transparent)]
    Optimiser(#[from] adam::AdamError),
    /// The motions hold no window to validate on.
    #[error("no validation frames")]
    NoValidationFrames,
    /// A rollback found no checkpoint to go back to.
    #[error("no checkpoint written yet")]
    NoCheckpointYet,
    /// Training diverged more often than allowed.
    #[error("training diverged {rollbacks} times; last at step {step}")]
    Diverged {
        /// Rollbacks so far, this one included.
        rollbacks: u32,
        /// Step of the last divergence.
        step: u64,
    },
    /// Training diverged and going back to the last checkpoint failed.
    #[error("diverged at step {step} and could not roll back: {source}")]
    RollbackFailed {
        /// Step of the divergence.
        step: u64,
        /// Why the rollback failed.
        #[source]
        source: Box<TrainError>,
    },
    /// The checkpoint at the end of the run could not be written.
    #[error("the final checkpoint (step {step}) could not be written: {source}")]
    FinalCheckpoint {
        /// Step of the checkpoint.
        step: u64,
        /// Why it could not be written.
        #[source]
        source: Box<TrainError>,
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
    /// The loaded scene; the run trains at its [`Scene::training_fps`] (a resumed run's scene
    /// must have the rate the run recorded).
    pub scene: Scene,
    /// Its description, saved with the run (file paths should be absolute).
    pub scene_config: SceneConfig,
    /// Training settings (without the frame rate: the scene's).
    pub train: TrainConfig,
    /// Network architecture (the encoder becomes static-only when the scene has no dynamics).
    pub model: ClothNetConfig,
    /// Descriptor settings.
    pub descriptors: DescriptorConfig,
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
        setup.train.validate(setup.scene.training_fps)?;
        TrainerHandle::spawn_with(move |progress| prepare_with(setup, progress), notify)
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
/// on the trainer thread and by tests). Resuming takes the model, descriptors and fabric the
/// run recorded and continues from its newest checkpoint that loads (older ones are tried
/// when the newest is damaged, with a warning); a run with checkpoints of which none loads is
/// an error, never a fresh start.
pub fn prepare(setup: TrainSetup) -> Result<(NeuralSession, LoopConfig), TrainError> {
    prepare_with(setup, &mut |_| true)
}

/// [`prepare`], reporting the long work before the first step (the warm start's simulation)
/// to `progress`, which cancels it by returning false.
pub fn prepare_with(
    setup: TrainSetup,
    progress: PrepareProgress<'_>,
) -> Result<(NeuralSession, LoopConfig), TrainError> {
    alloc::keep_freed_buffers();
    let TrainSetup {
        scene,
        scene_config,
        train,
        model,
        descriptors,
        location,
    } = setup;
    let fps = scene.training_fps;
    train.validate(fps)?;
    let Settings {
        resumed,
        mut model,
        descriptors,
        fabric,
    } = settings(&scene, &location, model, descriptors)?;
    // A new run scales the dynamic encoder's input to order one (see
    // `ClothNetConfig::dynamic_input_scale`); a resumed run keeps what it recorded.
    if resumed.is_none()
        && model.encoder == EncoderKind::Disentangled
        && model.normalise_dynamic_input
        && model.dynamic_input_scale.is_empty()
    {
        model.dynamic_input_scale =
            data::dynamic_scale_of(&scene.avatar, &scene.motions, fps, &descriptors)?;
    }
    let device = device_for(train.backend, true);
    let avatar = Arc::new(scene.avatar);
    let garment = Arc::new(scene.garment);
    let (train_data, validation) = datasets(&avatar, &scene.motions, &train, fps, &descriptors)?;
    let (run, resume) = match (resumed, &location) {
        (Some((run, _)), _) => (run, true),
        (None, RunLocation::NewUnder(parent)) => (RunDir::fresh_under(parent)?, false),
        (None, RunLocation::At(dir) | RunLocation::Resume(dir)) => (RunDir::create(dir)?, false),
    };
    let mut warnings = if resume { run.recover() } else { Vec::new() };
    // A resumed run that never wrote a checkpoint starts over, initialised like a new one.
    let has_checkpoint =
        resume && (!run.checkpoint_steps().is_empty() || run.latest_json_step().is_some());
    if !resume && train.fit_check {
        refuse_misfit(&avatar, &garment, &scene_config)?;
    }
    warnings.extend(preflight::preflight_warnings(&avatar, &garment, &fabric));
    let mut net = {
        // The device's random generator is the process's: seeding it and drawing the initial
        // weights form one step, so that runs prepared at the same time on other threads
        // (tests, the app beside a command) neither change nor take this run's weights.
        let _rng = device_rng_lock();
        device.seed(train.seed);
        model.init(train_data.input_joints, garment.vertex_count(), &device)?
    };
    if !has_checkpoint && train.predrape_secs > 0.0 && model.basis_bias {
        let drape = warm_start::simulated_drape(
            &avatar,
            &garment,
            &fabric,
            &scene.effects,
            train.predrape_secs,
            fps,
            PREDRAPE_ITERATIONS,
        )?;
        warm_start::set_basis_bias_to_drape(&mut net, &garment, &drape, &device)?;
    }
    let terms = PhysicsTerms::new(&garment, &fabric, &scene.effects, &device)?
        .with_fused(train.fused_physics);
    let lbs = GarmentLbs::from_garment(&garment, avatar.skeleton.len(), &device)?;
    if !resume {
        let meta = RunMeta {
            version: run_dir::RUN_VERSION,
            train: train.clone(),
            training_fps: fps,
            model: model.clone(),
            descriptors: descriptors.clone(),
            input_joints: train_data.input_joints,
            garment_vertices: garment.vertex_count(),
            garment_fingerprint: garment_fingerprint(&garment),
            garment_name: garment.name.clone(),
            avatar_fingerprint: Some(avatar_fingerprint(&avatar)),
            garment_skin_fingerprint: Some(garment_skin_fingerprint(&garment)),
        };
        // scene.toml records the rate, fabric and effects the run trains with (one fact, one
        // home: run.json keeps no copies).
        let recorded = SceneConfig {
            training_fps: fps,
            fabric: fabric.clone(),
            effects: scene.effects,
            ..scene_config.clone()
        };
        write_meta(&run, &meta, &recorded)?;
    }
    let run_root = run.root.clone();
    let mut session = NeuralSession::new(SessionParts {
        device,
        model: net,
        config: train.clone(),
        fps,
        descriptors: descriptors.clone(),
        terms,
        lbs,
        avatar: avatar.clone(),
        garment: garment.clone(),
        train: train_data,
        validation,
        run,
        init_std: model.init_std,
    });
    if !has_checkpoint && train.centre_init {
        session.centre_biases()?;
    }
    session.load_fit_reference()?;
    let (start_step, history) = if has_checkpoint {
        resume_state(&mut session, &mut warnings)?
    } else {
        (0, MetricHistory::default())
    };
    if start_step < train.warm_start_steps {
        let sim_scene = compare::SimulatedScene {
            avatar: &avatar,
            garment: &garment,
            fabric: &fabric,
            effects: scene.effects,
        };
        let warm = warm_start_sim::warm_start_reference(
            sim_scene,
            &run_root,
            &scene.motions,
            session.training_data(),
            fps,
            &train,
            progress,
        )?;
        let mirrors = match (warm.reflected, &warm.not_reflected) {
            (0, None) => String::new(),
            (n, None) => format!("; {n} mirrored copies reflected, the scene being symmetric"),
            (_, Some(why)) => format!("; mirrored copies simulated: {why}"),
        };
        progress(Preparing {
            stage: format!(
                "warm start: steps {start_step}..{} also fit our simulator's frames of the \
                 training motions ({} simulated now in {:.0} s, {} read from the run's \
                 cache{mirrors})",
                train.warm_start_steps, warm.simulated, warm.simulate_secs, warm.cached
            ),
            done: 1,
            total: 1,
        });
        session.set_warm_start_reference(warm.reference);
    }
    let loop_config = loop_config(&train, run_root, start_step, history, warnings);
    Ok((session, loop_config))
}

/// Refuses a garment file that clearly does not fit the avatar ([`preflight::fit_refusal`]);
/// built-in garments pass.
fn refuse_misfit(
    avatar: &neural_cloth_core::scene::Avatar,
    garment: &neural_cloth_core::scene::Garment,
    scene_config: &SceneConfig,
) -> Result<(), TrainError> {
    use neural_cloth_core::scene::config::{AvatarSource, GarmentSource};
    let GarmentSource::File { path, .. } = &scene_config.garment else {
        return Ok(());
    };
    let avatar_file = match &scene_config.avatar {
        AvatarSource::File { path, .. } => Some(path.as_path()),
        AvatarSource::Builtin { .. } => None,
    };
    match preflight::fit_refusal(avatar, avatar_file, garment, path)? {
        Some(why) => Err(TrainError::GarmentFit(why)),
        None => Ok(()),
    }
}

/// The model, descriptor and fabric settings of a run: for a resumed run the ones it recorded
/// (model and descriptors in `run.json`, the fabric in its scene), otherwise the given ones
/// and the scene's fabric.
struct Settings {
    resumed: Option<(RunDir, RunMeta)>,
    model: ClothNetConfig,
    descriptors: DescriptorConfig,
    fabric: FabricParams,
}

/// Resolves the [`Settings`] of a setup; refuses a new run over an existing one and a resume
/// on another garment or avatar.
fn settings(
    scene: &Scene,
    location: &RunLocation,
    mut model: ClothNetConfig,
    mut descriptors: DescriptorConfig,
) -> Result<Settings, TrainError> {
    let (resumed, recorded_fabric) = match location {
        RunLocation::Resume(dir) => {
            let (run, meta, fabric) = open_for_resume(dir, scene)?;
            (Some((run, meta)), Some(fabric))
        }
        RunLocation::At(dir) => {
            refuse_existing_run(dir)?;
            (None, None)
        }
        RunLocation::NewUnder(_) => (None, None),
    };
    if let Some((_, meta)) = &resumed {
        model = meta.model.clone();
        descriptors = meta.descriptors.clone();
    }
    let fabric = recorded_fabric.unwrap_or_else(|| scene.fabric.clone());
    fabric
        .validate()
        .map_err(neural_cloth_physics::PhysicsError::from)?;
    if !scene.effects.dynamics {
        model.encoder = EncoderKind::StaticOnly;
    }
    Ok(Settings {
        resumed,
        model,
        descriptors,
        fabric,
    })
}

/// Writes the description and the scene of a new run.
fn write_meta(run: &RunDir, meta: &RunMeta, scene: &SceneConfig) -> Result<(), TrainError> {
    let scene_toml = scene
        .to_toml_string()
        .map_err(|e| TrainError::Checkpoint(e.to_string()))?;
    run.write_meta(meta, &scene_toml)
}

/// The loop settings of a run that starts at `start_step` with `history`.
fn loop_config(
    train: &TrainConfig,
    run_dir: PathBuf,
    start_step: u64,
    history: MetricHistory,
    warnings: Vec<String>,
) -> LoopConfig {
    LoopConfig {
        run_dir,
        start_step,
        history,
        max_steps: train.max_steps,
        max_secs: train.max_minutes.map(|m| m * 60.0),
        validate_every: train.validate_every,
        snapshot_every: train.snapshot_every,
        checkpoint_every: train.checkpoint_every,
        max_rollbacks: 8,
        dead_limit_pct: train.dead_limit_pct,
        lr_decay: (train.lr_decay_fraction, train.lr_final_factor),
        warmup_steps: train.warmup_steps,
        warnings,
    }
}

/// The training and validation data of `motions`, resampled to `fps`.
fn datasets(
    avatar: &neural_cloth_core::scene::Avatar,
    motions: &[(neural_cloth_core::scene::Motion, Split)],
    train: &TrainConfig,
    fps: f32,
    descriptors: &DescriptorConfig,
) -> Result<(Dataset, Dataset), TrainError> {
    let train_data = Dataset::new(
        avatar,
        motions,
        Split::Train,
        fps,
        descriptors,
        train.mirror_poses,
    )?;
    if train_data.is_empty() {
        return Err(TrainError::Data("no motion in the train split".into()));
    }
    let validation = Dataset::new(avatar, motions, Split::Validation, fps, descriptors, false)?;
    Ok((train_data, validation))
}

/// Refuses to start a new run in a folder that already holds one (it would be overwritten).
fn refuse_existing_run(dir: &Path) -> Result<(), TrainError> {
    if dir.join("run.json").exists() {
        return Err(TrainError::Checkpoint(format!(
            "the folder already holds a run; resume it or choose another folder: {}",
            dir.display()
        )));
    }
    Ok(())
}

/// The run at `dir`, its description and the fabric its scene recorded; refused when `scene`
/// has another garment, avatar, training rate or effects.
fn open_for_resume(
    dir: &Path,
    scene: &Scene,
) -> Result<(RunDir, RunMeta, FabricParams), TrainError> {
    let run = RunDir::open(dir)?;
    let meta = run.meta()?;
    if meta.training_fps != scene.training_fps {
        return Err(TrainError::RateChanged {
            run_fps: meta.training_fps,
            scene_fps: scene.training_fps,
            path: run.root.clone(),
        });
    }
    let garment = &scene.garment;
    if meta.garment_fingerprint != garment_fingerprint(garment)
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
    if meta
        .avatar_fingerprint
        .is_some_and(|f| f != avatar_fingerprint(&scene.avatar))
    {
        return Err(TrainError::Checkpoint(format!(
            "the run was trained on another avatar than '{}': {}",
            scene.avatar.name,
            run.root.display()
        )));
    }
    if meta
        .garment_skin_fingerprint
        .is_some_and(|f| f != garment_skin_fingerprint(garment))
    {
        return Err(TrainError::Checkpoint(format!(
            "the run was trained on garment '{}' with other skin weights (smoothing passes) \
             than the scene's ({} passes): {}",
            meta.garment_name,
            garment.smoothing_passes,
            run.root.display()
        )));
    }
    // The effects' one home is the run's scene.toml: a resume goes on with the same ones.
    let recorded = resume::recorded_config(&run)?;
    if recorded.effects != scene.effects {
        let changed: Vec<String> = effect_flags(&recorded.effects)
            .into_iter()
            .zip(effect_flags(&scene.effects))
            .filter(|(a, b)| a.1 != b.1)
            .map(|((name, was), _)| format!("{name} {}", if was { "on" } else { "off" }))
            .collect();
        return Err(TrainError::Checkpoint(format!(
            "the run was trained with other effects than the scene's ({} in the run): {}",
            changed.join(", "),
            run.root.display()
        )));
    }
    Ok((run, meta, recorded.fabric))
}

/// Loads the newest checkpoint of the session's run that loads and the metric history up to
/// it; what had to be skipped is added to `warnings`.
fn resume_state(
    session: &mut NeuralSession,
    warnings: &mut Vec<String>,
) -> Result<(u64, MetricHistory), TrainError> {
    let run = session.run_dir().clone();
    let loaded = run
        .newest_loadable(|step| session.load_checkpoint(step))?
        .ok_or_else(|| {
            TrainError::Checkpoint(format!("no checkpoint to resume: {}", run.root.display()))
        })?;
    warnings.extend(loaded.warnings);
    let step = loaded.value.step;
    let mut history = match run.try_history() {
        Ok(h) => h,
        Err(e) => {
            warnings.push(format!("the metric history starts over: {e}"));
            return Ok((step, MetricHistory::default()));
        }
    };
    history.truncate_after(step);
    if history.last_step() < step {
        warnings.push(format!(
            "the metric history ends at step {}, before the checkpoint's step {step}: the curves \
             have a gap: {}",
            history.last_step(),
            run.root.join("metrics.json").display()
        ));
    }
    Ok((step, history))
}

/// Each effect's name and whether it is on.
fn effect_flags(effects: &Effects) -> [(&'static str, bool); 6] {
    [
        ("gravity", effects.gravity),
        ("bending", effects.bending),
        ("collision", effects.collision),
        ("dynamics", effects.dynamics),
        ("pinning", effects.pinning),
        ("friction", effects.friction),
    ]
}
