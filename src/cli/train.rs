//! `neural-cloth train`: trains on a scene headless, with a progress bar and a final JSON
//! summary; `neural-cloth eval RUN`: the §4.2 metrics of a trained run on its test split.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::bail;
use indicatif::{ProgressBar, ProgressStyle};

use super::scene_args::{SceneArgs, scene_config_from_args, scene_from_args};
use super::train_flags::{apply_flags, descriptor_config};
use neural_cloth::model::RotationFrame;
use neural_cloth::scene::config::SceneConfig;
use neural_cloth::train::retention::{MAX_KEEP_NEWEST, Retention};

use neural_cloth::train::{
    BasisRowNorm, InertiaMode, RunDir, RunLocation, TrainConfig, TrainEvent, TrainSetup, Trainer,
    resume,
};

/// Arguments of `train`.
#[derive(clap::Args, Debug)]
pub struct TrainArgs {
    /// Scene file (TOML); default: the built-in scene.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Garment file (OBJ/glTF) replacing the scene's garment; needs --avatar.
    #[arg(long, requires = "avatar")]
    pub garment: Option<PathBuf>,
    /// Skinned avatar (glTF/GLB, or `mannequin` for the built-in one) replacing the scene's
    /// avatar; needs --garment.
    #[arg(long, requires = "garment")]
    pub avatar: Option<PathBuf>,
    /// Folder of BVH (or glTF) motions. Files sorted by name; of each ten the 9th is a test
    /// and the 10th a validation motion; with 3 to 9 files the last tests and the one before
    /// validates; with 2 the last tests.
    #[arg(long)]
    pub motions: Option<PathBuf>,
    /// Joint map (TOML: `[joints] AvatarJoint = "MotionJoint"`) overriding the automatic
    /// joint mapping of every motion file that has no map of its own.
    #[arg(long)]
    pub joint_map: Option<PathBuf>,
    /// Up axis of the avatar, garment and motion files: auto (detected from a skeleton or an
    /// OBJ's shape), y or z (turned Y up); a scene file's own `up` on a source wins.
    #[arg(long, default_value = "auto")]
    pub up: neural_cloth::io::UpAxis,
    /// Train for this many minutes.
    #[arg(long)]
    pub minutes: Option<f64>,
    /// Train for this many steps.
    #[arg(long)]
    pub steps: Option<u64>,
    /// Compute backend (default: cpu; a resumed run keeps its own).
    #[arg(long, value_enum)]
    pub backend: Option<Backend>,
    /// Output folder of the run (default: a new folder under ./runs).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Continue the run in this folder from its newest checkpoint, on the scene and with the
    /// settings it recorded (flags given again override the settings; a --scene that differs
    /// from the recorded one is refused).
    #[arg(long, conflicts_with = "out")]
    pub resume: Option<PathBuf>,
    /// Write a checkpoint every this many steps (default 200).
    #[arg(long)]
    pub checkpoint_every: Option<u64>,
    /// Keep this many of the newest checkpoints, 1..=1000 (default 3, or what the resumed run
    /// recorded); written to RUN/retention.json, which the app's Runs panel edits too
    #[arg(long)]
    pub keep_checkpoints: Option<usize>,
    /// Do not also keep the checkpoint with the lowest validation loss
    #[arg(long)]
    pub no_keep_best: bool,
    /// Validate every this many steps (default 50).
    #[arg(long)]
    pub validate_every: Option<u64>,
    /// Windows per batch.
    #[arg(long)]
    pub batch: Option<usize>,
    /// Temporal window in seconds, 0.05..=4 (default 1, or the run's own with --resume; the
    /// paper's 0.5 loses the skirt's lag behind a spin and lets the GRU's state drift on long
    /// runs: docs/TRAINING.md round 12).
    #[arg(long)]
    pub window: Option<f32>,
    /// Seconds of motion before each window over which the GRU runs without gradient to set
    /// the window's starting state, as inference carries it (0..=10, default 0; 1.5 ends the
    /// drift of long t-shirt runs but loses the skirt's lag on some seeds: docs/TRAINING.md
    /// round 11).
    #[arg(long, value_name = "SECS")]
    pub gru_burn_in: Option<f32>,
    /// Draw each step's burn-in length uniformly from none to --gru-burn-in (windows from a
    /// zero state and from a carried one alike).
    #[arg(long)]
    pub gru_burn_in_random: bool,
    /// Training frame rate in frames per second, 5..=240, replacing the scene's
    /// `training_fps` (default: the scene's, 30 in the built-in scene); a resumed run keeps
    /// the rate it was trained at.
    #[arg(long)]
    pub fps: Option<f32>,
    /// Random seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Adam learning rate (default 1e-3).
    #[arg(long)]
    pub learning_rate: Option<f64>,
    /// Learning-rate factor of the decoder basis, in (0, 1] (default 4/512 = 0.0078125; 1 = the official
    /// code's single rate, which kills flared garments: see docs/TRAINING.md).
    #[arg(long)]
    pub basis_lr_scale: Option<f64>,
    /// Learning-rate factor of the basis bias (the mean offset the warm start sets), in
    /// (0, 1] (default 1/16).
    #[arg(long)]
    pub basis_bias_lr_scale: Option<f64>,
    /// Gain of the basis initialisation (default 1 = glorot-normal).
    #[arg(long)]
    pub basis_init_gain: Option<f64>,
    /// Hidden widths of the static encoder, comma-separated (default `512,512,512`; the
    /// paper's `64,128,256` leaves the skirt's spin about 50 mm further from the simulator:
    /// docs/TRAINING.md rounds 10 and 12).
    #[arg(long, value_delimiter = ',')]
    pub static_hidden: Option<Vec<usize>>,
    /// Seconds the simulator drapes the garment on the rest pose before training (warm
    /// start; 0 = off, default 1.5).
    #[arg(long)]
    pub predrape_secs: Option<f32>,
    /// Train the basis without its learned mean offset (the official code's bias-free basis;
    /// also turns the warm start off).
    #[arg(long)]
    pub no_basis_bias: bool,
    /// Fraction of a bounded run over which the learning rate falls to --lr-final-factor of
    /// its value at the end (0..=1, default 0 = constant rate; 0.25 recommended for runs of
    /// 30 minutes and more: the t-shirt's held-out spin 15.2 mm from the simulator against
    /// 17.7 after 3771 steps, no change after 1656; docs/TRAINING.md round 28).
    #[arg(long)]
    pub lr_decay_fraction: Option<f64>,
    /// Learning-rate factor reached at the end of a bounded run, in (0, 1] (default 0.1).
    #[arg(long)]
    pub lr_final_factor: Option<f64>,
    /// Trailing frames of each window that get the per-frame loss (inertia and the static
    /// terms), 1..=16 (default 1, the paper's: the last frame only)
    #[arg(long)]
    pub loss_frames: Option<usize>,
    /// Steps over which the learning rate rises linearly to its value at the start (default 0)
    #[arg(long)]
    pub warmup_steps: Option<u64>,
    /// Stiffness scale of the training gradient filter `D (D + βK)⁻¹`, 0..=100 (0: off;
    /// default 0.01, or the run's own value with --resume; see docs/TRAINING.md)
    #[arg(long)]
    pub precondition: Option<f64>,
    /// Filter the moving windows' gradient only, still windows keeping the plain gradient
    /// (default true; false filters every window, round 8's default: docs/TRAINING.md
    /// rounds 8 and 12)
    #[arg(long, value_name = "BOOL", num_args = 0..=1, default_missing_value = "true")]
    pub precondition_moving_only: Option<bool>,
    /// Filter the dynamic terms' gradient only, the static terms keeping the plain gradient
    /// (default false; see docs/TRAINING.md round 8)
    #[arg(long, value_name = "BOOL", num_args = 0..=1, default_missing_value = "true")]
    pub precondition_dynamic_only: Option<bool>,
    /// Adam normalises each row of these decoder bases by one second moment shared over the
    /// garment's vertex coordinates, so a row moves along the physics gradient's shape instead
    /// of every coordinate by about the rate: off, dynamic (the dynamic basis) or both
    /// (default off; CPU backend only; see docs/TRAINING.md round 14)
    #[arg(long, value_enum)]
    pub basis_row_norm: Option<BasisRowNormArg>,
    /// Checkpoints hold an exponential moving average of the weights with this decay, in
    /// [0, 0.9999] (about the last 1 / (1 - decay) steps; default 0 = the last step's
    /// weights; CPU backend only; see docs/TRAINING.md round 16)
    #[arg(long, value_name = "DECAY")]
    pub weight_average: Option<f32>,
    /// Carry each moving window's filtered gradient forward in time over its loss frames,
    /// with this stiffness scale β' for the propagation's filter D (D + β'K)⁻¹, in [0, 100]
    /// (default 0 = off; needs --loss-frames above 1 to act; experimental: with 12 loss
    /// frames it shreds the t-shirt; see docs/TRAINING.md round 17)
    #[arg(long, value_name = "BETA")]
    pub propagate_history: Option<f64>,
    /// Hand each moving window's loss-frame gradient back to the two frames its physics step
    /// starts from (the least-squares residual's gradient), with this stiffness scale for the
    /// filter D (D + βK)⁻¹ it goes through, in [0, 100] (default 0 = off; experimental: no
    /// closer to the simulator on the t-shirt, docs/TRAINING.md round 18)
    #[arg(long, value_name = "BETA")]
    pub history_adjoint: Option<f64>,
    /// A diagnostic, not the method: fit the network directly to our simulator's frames of
    /// every training motion, the PC2 caches in DIR (a run's `reference/` folder, as
    /// `compare` writes it), to see how close the network can come to the simulator at all.
    /// Needs --still-fraction 0; turns the mirrored copies of the motions off (their frames
    /// are not simulated) (docs/TRAINING.md round 18)
    #[arg(long, value_name = "DIR")]
    pub fit_reference: Option<PathBuf>,
    /// With --fit-reference: also descend the physics loss at this weight (0-100; default 0,
    /// the fit alone), so the fitted network stays a garment physics accepts (a diagnostic;
    /// docs/TRAINING.md round 19)
    #[arg(long, value_name = "WEIGHT", requires = "fit_reference")]
    pub fit_physics: Option<f64>,
    /// Warm start: simulate every training motion once with our simulator (cached in the
    /// run's reference/ folder, where `compare` finds it) and, for this many steps at the
    /// start, fit the network to those frames alongside the paper's loss; then the paper's
    /// loss alone (default 0 = off; 150-400 steps put the t-shirt's spin in the swinging
    /// basin: docs/TRAINING.md rounds 21 and 22)
    #[arg(long, value_name = "STEPS", conflicts_with = "fit_reference")]
    pub warm_start_steps: Option<u64>,
    /// Train without the left/right mirrored copies of the motions (default: with them).
    /// With --warm-start-steps, the copies have no simulated frames and, trained by the
    /// paper's loss alone, pull the swing back (the spin alone: 9.1 mm from the simulator
    /// without them, 17.8 with them; docs/TRAINING.md round 22)
    #[arg(long)]
    pub no_mirror: bool,
    /// Train at least this many steps on the motions alone before their mirrored copies join
    /// (default 0; `--mirror-from` decides too). Learned one way first, the
    /// direction-dependent part of a motion (a skirt's twist) carries to the other: the skirt
    /// 88.8 / 101.0 mm (resumed) and 116.8 / 128.4 (from scratch) from the simulator on the
    /// spin / mirrored spin after 1100 + 1100 steps, 132.7 / 132.8 with the copies throughout
    /// (docs/TRAINING.md round 24)
    #[arg(long, value_name = "STEPS", conflicts_with = "no_mirror")]
    pub mirror_from_step: Option<u64>,
    /// The mirrored copies join once this fraction of the run's budget (`--steps` or
    /// `--minutes`) is spent; 0..1, default 0.5 (0: with them from the start). The skirt
    /// after 1702 steps: 93.8 / 92.0 mm from the simulator on the spin / mirrored spin with
    /// 0.5, 136.7 / 150.5 with 0; the t-shirt's held-out spin 2-9 mm closer after 2000 steps,
    /// within a millimetre after 1100 (docs/TRAINING.md round 25)
    #[arg(long, value_name = "FRACTION", conflicts_with = "no_mirror")]
    pub mirror_from: Option<f64>,
    /// Experimental: the warm start also fits the mirrored copies, to the mirror image of
    /// their motion's simulation when the garment and body are symmetric, else to their own
    /// simulation. Measured worse: the spin alone 26.8 mm from the simulator against 17.8
    /// without it (docs/TRAINING.md round 23)
    #[arg(long, requires = "warm_start_steps", conflicts_with = "no_mirror")]
    pub warm_start_mirror_frames: bool,
    /// How joint rotations enter the network's input: heading-free (default; the turning
    /// rate with its sign, every descriptor invariant to the heading) or the paper's
    /// (docs/TRAINING.md round 24). A resumed run keeps the frame it was trained with
    #[arg(long, value_name = "FRAME", conflicts_with = "resume")]
    pub rotation_frame: Option<RotationFrameArg>,
    /// L-BFGS iterations per frame of the warm start's simulation (10-1000; default 200)
    #[arg(long, value_name = "N", requires = "warm_start_steps")]
    pub warm_start_iterations: Option<usize>,
    /// Curriculum: the inertia target at the start of the run projects the network's own
    /// last velocity this much further (α in [0, 1]; default 0 = off), a negative damping
    /// that falls linearly to 0 over --momentum-boost-steps (experimental; docs/TRAINING.md
    /// round 20)
    #[arg(long, value_name = "ALPHA", requires = "momentum_boost_steps")]
    pub momentum_boost: Option<f64>,
    /// Steps over which --momentum-boost falls to 0
    #[arg(long, value_name = "STEPS")]
    pub momentum_boost_steps: Option<u64>,
    /// How the inertia term treats the network's two previous frames: `ours` (default: held
    /// constant, the paper's) or `snug` (gradients flow into them too, SNUG's; the paper's
    /// ablation, docs/REPORT.md 4.2; see docs/TRAINING.md round 17)
    #[arg(long, value_enum)]
    pub inertia: Option<InertiaArg>,
    /// Final stiffness scale of the gradient filter: with --steps, β moves geometrically from
    /// --precondition to it over the run (default: constant)
    #[arg(long)]
    pub precondition_final: Option<f64>,
    /// Only still windows train the static encoder (moving windows see its code detached;
    /// default: every window trains it; see docs/TRAINING.md).
    #[arg(long)]
    pub static_from_still: bool,
    /// Keep every training frame's posed body once built (steps about 3 % faster, memory that
    /// grows towards 0.8 GB on the default scene; default: each step builds its bodies and
    /// drops them).
    #[arg(long)]
    pub keep_posed_bodies: bool,
    /// Step each batch as two halves on two threads, their gradients summed (default true;
    /// false keeps the batch whole, the path before: docs/BENCHMARKS.md)
    #[arg(long, value_name = "BOOL", num_args = 0..=1, default_missing_value = "true")]
    pub split_batch: Option<bool>,
    /// Keep zero initial biases (no data-dependent centring of the layers).
    #[arg(long)]
    pub no_centre_init: bool,
    /// Fraction of each batch made of still windows (default 0.25; 0 = the paper's batches).
    #[arg(long)]
    pub still_fraction: Option<f32>,
    /// Scale each dynamic descriptor channel by its RMS over the training motions (off by
    /// default: measured harmful, see docs/TRAINING.md)
    #[arg(long)]
    pub scale_dynamic_input: bool,
    /// Give the dynamic code its own zero-initialised linear path to the offsets, true or
    /// false (default: the model's default; see docs/TRAINING.md)
    #[arg(long)]
    pub dynamic_basis: Option<bool>,
    /// Learning-rate factor of the dynamic basis, in (0, 1] (default 8/512)
    #[arg(long)]
    pub dynamic_basis_lr_scale: Option<f64>,
    /// Fraction of each batch given another sample's dynamic code, trained with the static
    /// losses only (the paper's motion augmentation, 0.2 there), 0..=0.9 (default 0)
    #[arg(long)]
    pub augmentation: Option<f32>,
    /// Train on a garment file even when it clearly does not fit the avatar (vertices inside
    /// the body, far from it, another size); without it such a garment is refused with the
    /// `neural-cloth fit` command that fixes it.
    #[arg(long)]
    pub skip_fit_check: bool,
    /// Dead units (percent of a layer) that trigger the revive remedy (default 75).
    #[arg(long)]
    pub dead_limit: Option<f64>,
}

impl TrainArgs {
    /// The scene parts the flags name.
    fn scene_args(&self) -> SceneArgs<'_> {
        SceneArgs {
            scene: self.scene.as_deref(),
            avatar: self.avatar.as_deref(),
            garment: self.garment.as_deref(),
            motions: self.motions.as_deref(),
            joint_map: self.joint_map.as_deref(),
            up: self.up,
            training_fps: self.fps,
        }
    }
}

/// The bases whose Adam rows share one second moment, on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum BasisRowNormArg {
    /// Every value its own second moment (burn's Adam).
    Off,
    /// The dynamic basis.
    Dynamic,
    /// The shared basis and the dynamic basis.
    Both,
}

impl From<BasisRowNormArg> for BasisRowNorm {
    fn from(arg: BasisRowNormArg) -> Self {
        match arg {
            BasisRowNormArg::Off => Self::Off,
            BasisRowNormArg::Dynamic => Self::Dynamic,
            BasisRowNormArg::Both => Self::Both,
        }
    }
}

/// The inertia's treatment of the previous frames, on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum InertiaArg {
    /// The previous frames held constant (the paper's).
    Ours,
    /// Gradients flow into the previous frames too (SNUG's).
    Snug,
}

impl From<InertiaArg> for InertiaMode {
    fn from(arg: InertiaArg) -> Self {
        match arg {
            InertiaArg::Ours => Self::Ours,
            InertiaArg::Snug => Self::Snug,
        }
    }
}

/// How joint rotations enter the descriptors, on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum RotationFrameArg {
    /// The root without its heading, rotation rates in each joint's own frame.
    HeadingFree,
    /// The paper's: the root's global rotation, 6D derivatives in the parent's frame.
    Paper,
}

impl From<RotationFrameArg> for RotationFrame {
    fn from(arg: RotationFrameArg) -> Self {
        match arg {
            RotationFrameArg::HeadingFree => Self::HeadingFree,
            RotationFrameArg::Paper => Self::Paper,
        }
    }
}

/// The backend choice on the command line.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Backend {
    /// burn's flex CPU backend.
    Cpu,
    /// burn-wgpu (a GPU).
    Wgpu,
}

/// The scene a resumed run recorded, at the rate the run trained at, and its training
/// settings; refused when a scene given on the command line differs from the recorded one,
/// or `--fps` from the run's rate.
fn resumed_scene(
    dir: &Path,
    args: &TrainArgs,
) -> anyhow::Result<(neural_cloth::scene::Scene, SceneConfig, TrainConfig)> {
    let run = RunDir::open(dir)?;
    let meta = run.meta()?;
    if let Some(fps) = args.fps
        && fps != meta.training_fps
    {
        bail!(
            "the run was trained at {} frames per second and goes on at that rate; leave \
             --fps {fps} out to resume it",
            meta.training_fps
        );
    }
    let scene_args = SceneArgs {
        training_fps: None,
        ..args.scene_args()
    };
    if args.scene.is_some() || scene_args.edits_scene() {
        // The rate is checked above: compare the rest of the scene at the run's rate.
        let mut recorded = resume::recorded_config(&run)?;
        recorded.training_fps = meta.training_fps;
        let (mut given, _) = scene_config_from_args(&scene_args)?;
        given.training_fps = meta.training_fps;
        if let Some(difference) = resume::scene_difference(&recorded, &given)? {
            bail!(
                "the given scene differs from the one the run was trained on ({difference}); \
                 leave --scene out to resume on the run's own scene: {}",
                resume::scene_path(&run).display()
            );
        }
    }
    let mut recorded = resume::recorded_scene(&run)?;
    for w in &recorded.warnings {
        eprintln!("warning: {w}");
    }
    // The rate the run trained at (a run trained with --fps before the rate had one home
    // recorded the scene's own in scene.toml).
    recorded.scene.training_fps = meta.training_fps;
    recorded.config.training_fps = meta.training_fps;
    Ok((recorded.scene, recorded.config, meta.train))
}

/// Runs `train`.
pub fn run(args: TrainArgs) -> anyhow::Result<()> {
    let (scene, scene_config, mut train) = match &args.resume {
        Some(dir) => resumed_scene(dir, &args)?,
        None => {
            let (scene, config) = scene_from_args(&args.scene_args())?;
            (scene, config, TrainConfig::default())
        }
    };
    let model = apply_flags(&args, &mut train);
    model.validate()?;
    // A resumed run goes on to the limits it recorded unless new ones are given.
    if args.resume.is_none() || args.steps.is_some() || args.minutes.is_some() {
        train.max_steps = args.steps;
        train.max_minutes = args.minutes;
    }
    if train.max_steps.is_none() && train.max_minutes.is_none() {
        train.max_minutes = Some(10.0);
        eprintln!("no --minutes or --steps given: training for 10 minutes");
    }
    let (keep_checkpoints, no_keep_best) = (args.keep_checkpoints, args.no_keep_best);
    if let Some(n) = keep_checkpoints
        && !(1..=MAX_KEEP_NEWEST).contains(&n)
    {
        bail!("--keep-checkpoints {n} is outside 1..={MAX_KEEP_NEWEST}");
    }
    let descriptors = descriptor_config(&args);
    let location = match (args.resume, args.out) {
        (Some(dir), _) => RunLocation::Resume(dir),
        (None, Some(dir)) => RunLocation::At(dir),
        (None, None) => RunLocation::NewUnder(PathBuf::from("runs")),
    };
    let setup = TrainSetup {
        scene,
        scene_config,
        train: train.clone(),
        model,
        descriptors,
        location,
    };
    let handle = Trainer::spawn(setup, None)?;
    let bar = match train.max_steps {
        Some(n) => ProgressBar::new(n),
        None => ProgressBar::new((train.max_minutes.unwrap_or(1.0) * 60.0).ceil() as u64),
    };
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    // Without a terminal the bar is hidden and so are its lines: log them to stderr instead.
    let say = |line: String| {
        if bar.is_hidden() {
            eprintln!("{line}");
        } else {
            bar.println(line);
        }
    };
    let by_steps = train.max_steps.is_some();
    let mut steps_per_sec = 0.0;
    let mut last = (0u64, 0.0f64);
    let mut last_stage = String::new();
    loop {
        let Some(event) = handle.recv_timeout(Duration::from_millis(200)) else {
            bar.tick();
            continue;
        };
        match event {
            TrainEvent::Started { run_dir, step } => {
                say(format!(
                    "run folder: {} (from step {step})",
                    run_dir.display()
                ));
                if let Some(line) = apply_retention(&run_dir, keep_checkpoints, no_keep_best) {
                    say(line);
                }
            }
            TrainEvent::Step(r) => {
                if r.wall_secs > last.1 + 1.0 {
                    steps_per_sec = (r.step - last.0) as f64 / (r.wall_secs - last.1);
                    last = (r.step, r.wall_secs);
                }
                bar.set_position(if by_steps { r.step } else { r.wall_secs as u64 });
                bar.set_message(format!(
                    "step {} | {:.1} steps/s | loss {:.4} strain {:.4} bend {:.3} coll {:.1}% grav {:.4} inert {:.5}",
                    r.step, steps_per_sec, r.loss, r.strain, r.bending, r.collision_pct, r.gravity, r.inertia
                ));
            }
            TrainEvent::Validation(r) => say(format!(
                "validation @ {}: loss {:.4} strain {:.4} bending {:.3} collision {:.2}% gravity {:.4} inertia {:.5} slip {:.2} mm dead units {:.0}%",
                r.step,
                r.loss,
                r.strain,
                r.bending,
                r.collision_pct,
                r.gravity,
                r.inertia,
                r.slip_mm,
                r.dead_units_pct
            )),
            TrainEvent::Preparing(p) => {
                bar.set_message(format!("{:.0} %", 100.0 * p.fraction()));
                if p.stage != last_stage {
                    say(p.stage.clone());
                    last_stage = p.stage;
                }
            }
            TrainEvent::Warning(w) => say(format!("warning: {w}")),
            TrainEvent::Note(n) => say(format!("note: {n}")),
            TrainEvent::Stalled {
                step,
                reason,
                remedy,
            } => say(format!(
                "warning: training stalled at step {step}: {reason}; {remedy}"
            )),
            TrainEvent::RolledBack {
                diverged_at,
                restored_step,
                learning_rate,
            } => say(format!(
                "diverged at step {diverged_at}: rolled back to step {restored_step}, learning rate now {learning_rate:e}"
            )),
            TrainEvent::Checkpoint { .. }
            | TrainEvent::Snapshot { .. }
            | TrainEvent::Paused
            | TrainEvent::Resumed
            | TrainEvent::Applied(_)
            | TrainEvent::Rejected { .. } => {}
            TrainEvent::Finished(result) => {
                bar.finish_and_clear();
                let summary = result.map_err(|e| anyhow::anyhow!(e.to_string()))?;
                println!("{}", serde_json::to_string_pretty(&summary)?);
                if let Some(warning) = summary.health_warning() {
                    eprintln!("warning: {warning}");
                }
                break;
            }
        }
    }
    handle.join();
    Ok(())
}

/// Writes the checkpoint retention the flags ask for into the run folder `run_dir` (the
/// trainer reads it at every prune; flags not given keep what the run has). A line to print:
/// the policy set, or why it could not be.
fn apply_retention(run_dir: &Path, keep: Option<usize>, no_keep_best: bool) -> Option<String> {
    if keep.is_none() && !no_keep_best {
        return None;
    }
    let result = RunDir::open(run_dir).and_then(|run| {
        let current = run.retention()?;
        let wanted = Retention {
            keep_newest: keep.unwrap_or(current.keep_newest),
            keep_best: current.keep_best && !no_keep_best,
        };
        run.set_retention(wanted)?;
        Ok(wanted)
    });
    Some(match result {
        Ok(r) => format!(
            "keeping the newest {} checkpoint(s){}",
            r.keep_newest,
            if r.keep_best {
                " and the best by validation"
            } else {
                ""
            }
        ),
        Err(e) => format!("warning: checkpoint retention not set: {e}"),
    })
}
