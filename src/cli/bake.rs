//! `neural-cloth bake RUN` (a trained model) and `neural-cloth simulate` (the reference
//! simulator): bake a motion into PC2, MDD, an OBJ sequence, USD or glTF, optionally in a
//! destination tool's convention (`--preset`), with a progress bar.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressStyle};

use neural_cloth::bake::{
    BakeFormat, BakeOptions, FrameSource, ModelSource, Preset, SimulatorSource, bake,
};
use neural_cloth::io::JointMap;
use neural_cloth::io::scene_loader::{MotionImport, load_motions};
use neural_cloth::io::{Units, UpAxis};
use neural_cloth::physics::GarmentRest;
use neural_cloth::physics::simulator::{SimOptions, Stepper};
use neural_cloth::scene::{Motion, Scene};
use neural_cloth::train::load_trained;

/// Output settings shared by `bake` and `simulate`.
#[derive(clap::Args, Debug)]
pub struct OutputArgs {
    /// Motion: a name from the scene, or a BVH/glTF file.
    #[arg(long)]
    pub motion: String,
    /// Joint map (TOML: `[joints] AvatarJoint = "MotionJoint"`) for a --motion file,
    /// overriding the automatic joint mapping.
    #[arg(long)]
    pub joint_map: Option<PathBuf>,
    /// Up axis of a --motion file: auto (detected from its rig), y or z (turned Y up).
    #[arg(long, default_value = "auto")]
    pub up: UpAxis,
    /// Output format.
    #[arg(long, value_parser = parse_format, default_value = "pc2")]
    pub format: BakeFormat,
    /// Output frame rate.
    #[arg(long, default_value_t = 30.0)]
    pub fps: f32,
    /// First output frame.
    #[arg(long, default_value_t = 0)]
    pub start: usize,
    /// Last output frame (exclusive); default: the end of the motion.
    #[arg(long)]
    pub end: Option<usize>,
    /// Output file (a folder for OBJ sequences); default: <motion>.<format> here.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write for a destination tool: blender, unreal, unity, maya or houdini (axis, units,
    /// handedness, frame numbering; see the README's export table). Default: Y up, metres,
    /// right-handed, frames from 0. Not for glTF.
    #[arg(long, value_parser = parse_preset)]
    pub preset: Option<Preset>,
    /// Also write the body (a second cache, the body mesh in glTF, a second mesh in USD).
    #[arg(long)]
    pub body: bool,
    /// Also write the unskinned rest-space garment shapes.
    #[arg(long)]
    pub rest: bool,
    /// Morph targets in the glTF export.
    #[arg(long, default_value_t = 16)]
    pub targets: usize,
}

fn parse_format(s: &str) -> Result<BakeFormat, String> {
    BakeFormat::parse(s).ok_or_else(|| format!("unknown format '{s}' (pc2, mdd, obj, gltf, usd)"))
}

fn parse_preset(s: &str) -> Result<Preset, String> {
    Preset::parse(s).map_err(|e| e.to_string())
}

/// Arguments of `bake`.
#[derive(clap::Args, Debug)]
pub struct BakeArgs {
    /// Run folder (or checkpoint folder) of a trained model.
    pub checkpoint: PathBuf,
    /// Dynamic weight w in [0, 2] (1 = as trained).
    #[arg(long, default_value_t = 1.0)]
    pub w: f32,
    /// Output settings.
    #[command(flatten)]
    pub output: OutputArgs,
}

/// Arguments of `simulate`.
#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// Scene file (TOML); default: the built-in scene.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// L-BFGS iterations per frame (the accuracy knob).
    #[arg(long, default_value_t = 40)]
    pub iterations: usize,
    /// Simulation steps per output frame.
    #[arg(long, default_value_t = 1)]
    pub substeps: usize,
    /// Seconds the first pose is held so the garment settles before the motion plays.
    #[arg(long, default_value_t = 0.5)]
    pub settle: f32,
    /// Output settings.
    #[command(flatten)]
    pub output: OutputArgs,
}

/// The motion named `spec` in the scene, or loaded from the file `spec` (up axis `up`,
/// retargeted with `joint_map`).
pub fn find_motion(
    scene: &Scene,
    spec: &str,
    fps: f32,
    joint_map: Option<&Path>,
    up: UpAxis,
) -> anyhow::Result<Motion> {
    if let Some((m, _)) = scene.motions.iter().find(|(m, _)| m.name == spec) {
        return Ok(m.clone());
    }
    let path = Path::new(spec);
    if path.is_file() {
        let mut warnings = Vec::new();
        let joint_map = joint_map.map(JointMap::load).transpose()?;
        let how = MotionImport {
            units: Units::Auto,
            up,
            fps,
            only: None,
            joint_map: joint_map.as_ref(),
        };
        let mut motions = load_motions(path, &scene.avatar, &how, &mut warnings)?;
        for w in warnings {
            eprintln!("warning: {w}");
        }
        return motions.drain(..).next().context("the file holds no motion");
    }
    let names: Vec<&str> = scene.motions.iter().map(|(m, _)| m.name.as_str()).collect();
    bail!(
        "unknown motion '{spec}' (the scene has: {}; or give a BVH/glTF file)",
        names.join(", ")
    )
}

fn options(out: &OutputArgs, motion: &Motion, w: f32) -> BakeOptions {
    let default_out = match out.format {
        BakeFormat::Obj => PathBuf::from(format!("{}-obj", motion.name)),
        f => PathBuf::from(format!("{}.{}", motion.name, f.extension())),
    };
    BakeOptions {
        format: out.format,
        out: out.out.clone().unwrap_or(default_out),
        fps: out.fps,
        start_frame: out.start,
        end_frame: out.end,
        w,
        include_body: out.body,
        rest_shapes: out.rest,
        morph_targets: out.targets,
        preset: out.preset,
    }
}

fn run_bake(
    scene: &Scene,
    motion: &Motion,
    source: &mut dyn FrameSource,
    options: &BakeOptions,
) -> anyhow::Result<()> {
    let bar = ProgressBar::new(0);
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:30} {pos}/{len} frames {per_sec}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let report = bake(
        &scene.avatar,
        &scene.garment,
        motion,
        source,
        options,
        &mut |done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
            true
        },
    )?;
    bar.finish_and_clear();
    println!("{}", serde_json::to_string_pretty(&report)?);
    Ok(())
}

/// Runs `bake`.
pub fn run(args: BakeArgs) -> anyhow::Result<()> {
    let trained = load_trained(&args.checkpoint)?;
    for w in &trained.warnings {
        eprintln!("warning: {w}");
    }
    let fps = trained.meta.training_fps;
    let motion = find_motion(
        &trained.scene,
        &args.output.motion,
        fps,
        args.output.joint_map.as_deref(),
        args.output.up,
    )?;
    let options = options(&args.output, &motion, args.w);
    neural_cloth::bake::check_options(&options)?;
    let mut source = ModelSource::new(trained.garment_engine()?);
    run_bake(&trained.scene, &motion, &mut source, &options)
}

/// Runs `simulate`.
pub fn simulate(args: SimulateArgs) -> anyhow::Result<()> {
    let (scene, _) = super::scene_args::scene_from_args(&super::scene_args::SceneArgs::file(
        args.scene.as_deref(),
    ))?;
    let fabric = scene.fabric.clone();
    let fps = args.output.fps;
    let motion = find_motion(
        &scene,
        &args.output.motion,
        fps,
        args.output.joint_map.as_deref(),
        args.output.up,
    )?;
    let options = options(&args.output, &motion, 1.0);
    neural_cloth::bake::check_options(&options)?;
    let sim = SimOptions {
        iterations_per_step: args.iterations,
        substeps: args.substeps,
        ..Default::default()
    };
    let step_fps = fps * args.substeps.max(1) as f32;
    let rest = std::sync::Arc::new(GarmentRest::from_garment(&scene.garment, &fabric)?);
    let first = motion.sample(0.0);
    let initial = scene.garment.pose_vertices(&scene.avatar, &first);
    let device = neural_cloth::train::device_for(neural_cloth::train::BackendKind::Cpu, false);
    let stepper = Stepper::new(
        rest,
        &fabric,
        &scene.effects,
        &initial,
        1.0 / step_fps,
        &sim,
        &device,
    )?;
    let mut source = SimulatorSource::new(
        stepper,
        &scene.avatar,
        &scene.garment,
        step_fps,
        scene.effects.collision,
    );
    // Let the garment settle on the first pose before the motion starts.
    for _ in 0..(args.settle.max(0.0) * step_fps).round() as usize {
        source.step(&first, 1.0)?;
    }
    run_bake(&scene, &motion, &mut source, &BakeOptions { ..options })
}
