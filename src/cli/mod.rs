//! Argument parsing and dispatch of the subcommands. Each subcommand lives in its own file
//! and calls into the library; this layer only parses, reports progress and prints.

mod app_launcher;
mod bake;
mod bench;
mod compare;
mod eval;
mod fit;
pub mod headless;
mod inspect;
mod report;
mod scene_args;
mod screenshot;
mod soak;
mod train;
mod train_flags;

use std::path::PathBuf;

use clap::{Parser, Subcommand};

/// Neural cloth simulation: train a garment model on a moving avatar without simulated data.
#[derive(Parser, Debug)]
#[command(name = "neural-cloth", version, about, long_about = None)]
pub struct Cli {
    /// What to do; without a subcommand the app opens on the default scene.
    #[command(subcommand)]
    pub command: Option<Command>,
    /// Project file (TOML) to open in the app.
    #[arg(long, global = false)]
    pub project: Option<PathBuf>,
}

/// The subcommands.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// Print what a glTF/GLB, OBJ or BVH file holds (joints, vertices, animations, units).
    Inspect {
        /// The file to read.
        file: PathBuf,
        /// Also print how the file's motion would map onto this avatar's joints (a glTF/GLB
        /// file, or `mannequin` for the built-in one).
        #[arg(long)]
        avatar: Option<PathBuf>,
        /// Joint map (TOML: `[joints] AvatarJoint = "MotionJoint"`) overriding the automatic
        /// mapping; needs --avatar.
        #[arg(long)]
        joint_map: Option<PathBuf>,
        /// Up axis of FILE: auto (detected from its skeleton, or an OBJ mesh's shape), y or z.
        #[arg(long, default_value = "auto")]
        up: neural_cloth::io::UpAxis,
    },
    /// Fit a garment made for another body, in other units or placed elsewhere onto the
    /// avatar's rest pose, relaxed by the simulator; writes an OBJ to train on.
    Fit(fit::FitArgs),
    /// Train a model on a scene headless (default: the built-in scene).
    Train(Box<train::TrainArgs>),
    /// Print the §4.2 metrics of a trained model on its scene's test split.
    Eval(eval::EvalArgs),
    /// Bake a motion with a trained model into PC2, MDD, OBJ sequence, USD or glTF.
    Bake(bake::BakeArgs),
    /// Bake a motion with the reference simulator (the paper's Eq. 8 baseline).
    Simulate(bake::SimulateArgs),
    /// Check a trained run against the reference simulator on the same motion.
    Compare(compare::CompareArgs),
    /// Measure inference fps (10K/250K DoF), the bandwidth floor, training and physics costs.
    Bench(bench::BenchArgs),
    /// Measure what accuracy costs in time and reproduce the paper's claims; writes docs/REPORT.md.
    Report(report::ReportArgs),
    /// Render the viewport offscreen to a PNG (works without a display).
    Screenshot(screenshot::ScreenshotArgs),
    /// Train with preview inference and periodic bakes alongside, logging memory, file
    /// descriptors and threads every minute (a long-run leak check).
    Soak(soak::SoakArgs),
}

/// Runs the parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        None => {
            // Leave one core to the UI: training (burn's flex kernels, collision queries) runs on
            // rayon's global pool, and the viewport must keep drawing while it trains.
            let cores = std::thread::available_parallelism()
                .map(|n| n.get())
                .unwrap_or(1);
            let _ = rayon::ThreadPoolBuilder::new()
                .num_threads(cores.saturating_sub(1).max(1))
                .build_global();
            neural_cloth::app::run_app(neural_cloth::app::AppOptions {
                project: cli.project,
                launcher: Some(Box::new(app_launcher::RealLauncher)),
                exporter: Some(Box::new(neural_cloth::app::export::ModelExporter)),
                ..Default::default()
            })
        }
        Some(Command::Inspect {
            file,
            avatar,
            joint_map,
            up,
        }) => inspect::run(&file, avatar.as_deref(), joint_map.as_deref(), up),
        Some(Command::Fit(args)) => fit::run(args),
        Some(Command::Train(args)) => train::run(*args),
        Some(Command::Eval(args)) => eval::eval(args),
        Some(Command::Bake(args)) => bake::run(args),
        Some(Command::Simulate(args)) => bake::simulate(args),
        Some(Command::Compare(args)) => compare::run(args),
        Some(Command::Bench(args)) => bench::run(args),
        Some(Command::Report(args)) => report::run(args),
        Some(Command::Screenshot(args)) => screenshot::run(args),
        Some(Command::Soak(args)) => soak::run(args),
    }
}

/// The text of an error for the terminal: the error and each cause in its chain, leaving out a
/// cause whose text the message already holds (our error types put their source's text, then
/// the file path, in their own message: printed again it would repeat, after the path).
pub fn error_text(error: &anyhow::Error) -> String {
    let mut text = error.to_string();
    for cause in error.chain().skip(1) {
        let cause = cause.to_string();
        if !text.contains(&cause) {
            text = format!("{text}: {cause}");
        }
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cause_already_in_the_message_is_not_repeated() {
        let io = std::io::Error::other("No space left on device");
        let e = anyhow::Error::from(neural_cloth::train::TrainError::io(
            io,
            std::path::Path::new("/disk/run.json"),
        ));
        assert_eq!(error_text(&e), "No space left on device: /disk/run.json");
        let e = anyhow::Error::from(std::io::Error::other("gone")).context("reading x.toml");
        assert_eq!(error_text(&e), "reading x.toml: gone");
    }
}
