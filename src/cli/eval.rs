//! `eval`: the paper's §4.2 metrics of a trained run on one split of its scene's motions.

use std::path::PathBuf;

use neural_cloth::scene::config::Split;

/// Arguments of `eval`.
#[derive(clap::Args, Debug)]
pub struct EvalArgs {
    /// Run folder (or checkpoint folder) of a trained model.
    pub checkpoint: PathBuf,
    /// Split to evaluate: train, validation or test.
    #[arg(long, default_value = "test")]
    pub split: String,
    /// Dynamic weight w in [0, 2].
    #[arg(long, default_value_t = 1.0)]
    pub w: f32,
}

/// Runs `eval`: prints the §4.2 metrics per motion and their mean, as JSON.
pub fn eval(args: EvalArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        (0.0..=2.0).contains(&args.w),
        "w = {} is outside [0, 2]",
        args.w
    );
    let split = match args.split.as_str() {
        "train" => Split::Train,
        "validation" => Split::Validation,
        "test" => Split::Test,
        other => anyhow::bail!("unknown split '{other}' (train, validation, test)"),
    };
    let trained = neural_cloth::train::load_trained(&args.checkpoint)?;
    for w in &trained.warnings {
        eprintln!("warning: {w}");
    }
    let names: Vec<&str> = trained
        .scene
        .motions_in(split)
        .map(|m| m.name.as_str())
        .collect();
    let count = |s: Split| trained.scene.motions_in(s).count();
    anyhow::ensure!(
        !names.is_empty(),
        "the run's scene has no motion in the {} split (train {}, validation {}, test {}); \
         choose another with --split: {}",
        args.split,
        count(Split::Train),
        count(Split::Validation),
        count(Split::Test),
        args.checkpoint.display()
    );
    eprintln!(
        "evaluating the {} split: {} motions ({})",
        args.split,
        names.len(),
        names.join(", ")
    );
    let report = neural_cloth::train::evaluate(&trained, split, args.w)?;
    println!("{}", serde_json::to_string_pretty(&report)?);
    // The official code's definitions, beside ours (on stderr: stdout stays pure JSON).
    eprintln!(
        "bending (paper): {:.4} rad (ours {:.4})\nstretch (paper): {:.4} (ours: strain {:.4})",
        report.mean.paper_bending,
        report.mean.bending,
        report.mean.paper_stretch,
        report.mean.strain
    );
    Ok(())
}
