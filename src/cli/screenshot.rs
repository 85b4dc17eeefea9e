//! `neural-cloth screenshot`: renders the viewport offscreen (the same renderer and path as the
//! app's viewport) and writes a PNG; with `--run` the garment comes from a trained model.

use std::path::PathBuf;

use anyhow::Context;

use neural_cloth::model::InferenceOptions;
use neural_cloth::render::frame::SceneFrame;
use neural_cloth::render::offscreen::screenshot;
use neural_cloth::render::renderer::DrawOptions;
use neural_cloth::train::load_trained;

/// Arguments of `screenshot`.
#[derive(clap::Args, Debug)]
pub struct ScreenshotArgs {
    /// Output PNG.
    #[arg(long, default_value = "screenshot.png")]
    pub out: PathBuf,
    /// Scene file (TOML); default: the built-in scene (ignored with --run).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// A trained run: the garment is the model's prediction.
    #[arg(long)]
    pub run: Option<PathBuf>,
    /// Motion name (default: the scene's first motion).
    #[arg(long)]
    pub motion: Option<String>,
    /// Time in the motion, seconds.
    #[arg(long, default_value_t = 0.0)]
    pub time: f32,
    /// Dynamic weight w in [0, 2] (with --run).
    #[arg(long, default_value_t = 1.0)]
    pub w: f32,
    /// Image width in pixels.
    #[arg(long, default_value_t = 960)]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 720)]
    pub height: u32,
    /// Overlay the garment's edges.
    #[arg(long)]
    pub wireframe: bool,
}

/// Runs `screenshot`.
pub fn run(args: ScreenshotArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        (0.0..=2.0).contains(&args.w),
        "w = {} is outside [0, 2]",
        args.w
    );
    anyhow::ensure!(
        (16..=8192).contains(&args.width) && (16..=8192).contains(&args.height),
        "image size must be 16..=8192 pixels a side"
    );
    let (scene, trained) = match &args.run {
        Some(run) => {
            let t = load_trained(run)?;
            (t.scene.clone(), Some(t))
        }
        None => (
            super::scene_args::scene_from_args(&super::scene_args::SceneArgs::file(
                args.scene.as_deref(),
            ))?
            .0,
            None,
        ),
    };
    let motion = match &args.motion {
        Some(name) => super::bake::find_motion(
            &scene,
            name,
            scene.training_fps,
            None,
            neural_cloth::io::UpAxis::Auto,
        )?,
        None => scene
            .motions
            .first()
            .map(|(m, _)| m.clone())
            .context("the scene has no motion")?,
    };
    let pose = motion.sample(args.time);
    let garment_positions = match &trained {
        Some(t) => {
            let mut engine = t.engine(InferenceOptions::default())?;
            let fps = engine.fps();
            let frames = (args.time.max(0.0) * fps).round() as usize;
            for k in 0..=frames {
                engine.step(&motion.sample(k as f32 / fps), args.w)?;
            }
            Some(engine.garment_positions().to_vec())
        }
        None => None,
    };
    let frame = SceneFrame::from_scene(
        &scene.avatar,
        &pose,
        Some(&scene.garment),
        garment_positions,
    );
    let options = DrawOptions {
        wireframe: args.wireframe,
        ..Default::default()
    };
    let image = screenshot(&frame, None, &options, [args.width, args.height])?;
    image
        .save(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    println!("wrote {}", args.out.display());
    Ok(())
}
