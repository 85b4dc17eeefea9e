//! `neural-cloth report`: runs the accuracy/time, settings and fidelity experiments within a
//! time budget and writes `REPORT.md`, `report/report.json` and the SVG figures (or, with
//! `--render-only`, re-draws them from a saved `report.json`).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;

use neural_cloth::report::{Report, ReportOptions, run_report, write_report};

/// Arguments of `report`.
#[derive(clap::Args, Debug)]
pub struct ReportArgs {
    /// Wall-clock budget of the whole report in minutes (under 5 minutes: a smoke run on small garments).
    #[arg(long, default_value_t = 30.0)]
    pub budget_minutes: f64,
    /// Scene file (TOML) of the accuracy and settings experiments; default: the built-in scene.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Folder receiving REPORT.md and report/ (figures and report.json).
    #[arg(long, default_value = "docs")]
    pub out: PathBuf,
    /// Seed of every training run.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Run nothing: re-draw REPORT.md and the figures from the saved OUT/report/report.json.
    #[arg(long)]
    pub render_only: bool,
}

/// Runs `report`.
pub fn run(args: ReportArgs) -> anyhow::Result<()> {
    if args.render_only {
        let json = args.out.join("report").join("report.json");
        let text = std::fs::read_to_string(&json)
            .with_context(|| format!("reading {}", json.display()))?;
        let report: Report =
            serde_json::from_str(&text).with_context(|| format!("parsing {}", json.display()))?;
        for path in write_report(&report, &args.out)? {
            eprintln!("wrote {}", path.display());
        }
        return Ok(());
    }
    anyhow::ensure!(
        args.budget_minutes.is_finite() && args.budget_minutes > 0.0,
        "--budget-minutes must be positive"
    );
    let scene = match &args.scene {
        Some(path) => Some(
            super::scene_args::scene_from_args(&super::scene_args::SceneArgs::file(Some(path)))
                .with_context(|| format!("loading {}", path.display()))?,
        ),
        None => None,
    };
    let mut command = format!(
        "neural-cloth report --budget-minutes {}",
        args.budget_minutes
    );
    if let Some(path) = &args.scene {
        command.push_str(&format!(" --scene {}", path.display()));
    }
    if args.out.as_path() != std::path::Path::new("docs") {
        command.push_str(&format!(" --out {}", args.out.display()));
    }
    if args.seed != 0 {
        command.push_str(&format!(" --seed {}", args.seed));
    }
    let options = ReportOptions {
        budget_secs: args.budget_minutes * 60.0,
        scene,
        seed: args.seed,
        command,
    };
    let started = Instant::now();
    let mut last_line = (String::new(), -1i64);
    let report = run_report(&options, &mut |p| {
        let percent = (p.fraction * 100.0).floor() as i64;
        if p.detail != last_line.0 || percent / 5 != last_line.1 / 5 {
            eprintln!(
                "[{:>6.0} s {:>3}%] {}: {}",
                started.elapsed().as_secs_f64(),
                percent,
                p.phase,
                p.detail
            );
            last_line = (p.detail.clone(), percent);
        }
        true
    })?;
    let written = write_report(&report, &args.out)?;
    for path in written {
        eprintln!("wrote {}", path.display());
    }
    eprintln!("report took {:.1} minutes", report.elapsed_secs / 60.0);
    Ok(())
}
