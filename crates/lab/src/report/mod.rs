//! Evidence behind `neural-cloth report`: what accuracy costs in time, and the paper's claims
//! (§4.4–4.6) reproduced on small scenes with fixed seeds.
//!
//! - [`accuracy`]: the reference simulator at several iteration budgets and the neural model
//!   at several training durations, per-frame cost against the error to a converged reference
//!   simulation of the same motion (mean and 95th-percentile vertex distance, Eq. 8 residual).
//!   [`run_cost_experiment`] is also the app's "Cost" panel: any [`Scene`], a time budget, a
//!   progress/cancel callback, a serializable [`CostResult`].
//! - [`settings`]: training frame rate, temporal window, garment resolution and each scene
//!   effect against training step time, inference speed and the metrics reached in one budget.
//! - [`fidelity`]: disentanglement (`z_D = 0` for a still body, the `w` sweep), SNUG-style
//!   inertia against ours on a spinning skirt, and the Tab. 2 ablation.
//! - [`runs`]: timed training runs stepped synchronously, inference timing.
//! - [`plots`] (generic SVG panels through plotters), [`figures`] (the report's figures) and
//!   [`markdown`] (`REPORT.md`) write the results.
//!
//! Every experiment runs within a wall-clock budget ([`Plan`]); the numbers are measured on
//! the machine that runs it, and the Markdown states the machine and the command.

pub mod accuracy;
pub mod fidelity;
pub mod figures;
pub mod markdown;
pub mod plots;
pub mod runs;
pub mod settings;
pub mod training_checks;

pub use accuracy::{CostOptions, CostPoint, CostResult, Method, SpeedUp, run_cost_experiment};
pub use fidelity::{FidelityOptions, FidelityResult, run_fidelity};
pub use settings::{SettingRow, SettingsOptions, run_settings};

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use neural_cloth_core::scene::Scene;
use neural_cloth_core::scene::config::{GarmentSource, SceneConfig};

/// Errors of the report.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A setting is out of range or the scene cannot be used.
    #[error("report: {0}")]
    Invalid(String),
    /// Building a scene failed.
    #[error(transparent)]
    Config(#[from] neural_cloth_core::scene::config::ConfigError),
    /// A scene-level error.
    #[error(transparent)]
    Scene(#[from] neural_cloth_core::scene::SceneError),
    /// The train layer refused.
    #[error(transparent)]
    Train(#[from] neural_cloth_train::TrainError),
    /// A training step or validation failed.
    #[error("training run '{label}': {reason}")]
    Run {
        /// The run.
        label: String,
        /// What failed.
        reason: String,
    },
    /// The physics layer refused.
    #[error(transparent)]
    Physics(#[from] neural_cloth_physics::PhysicsError),
    /// The model layer refused.
    #[error(transparent)]
    Model(#[from] neural_cloth_model::ModelError),
    /// Writing a file failed.
    #[error(transparent)]
    Export(#[from] neural_cloth_core::io::export::ExportError),
    /// Drawing a plot failed.
    #[error("plot '{name}': {reason}")]
    Plot {
        /// The figure.
        name: String,
        /// What failed.
        reason: String,
    },
    /// Serialising the results failed.
    #[error("results: {0}")]
    Json(#[from] serde_json::Error),
    /// The progress callback asked to stop.
    #[error("report cancelled")]
    Cancelled,
}

/// Where an experiment is; `fraction` goes from 0 to 1 over the whole job.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Progress {
    /// Experiment name, e.g. "accuracy".
    pub phase: String,
    /// Fraction done, 0..=1.
    pub fraction: f64,
    /// What is running now.
    pub detail: String,
}

/// A progress callback: returning false cancels the job at the next check.
pub type ProgressFn<'a> = dyn FnMut(&Progress) -> bool + 'a;

/// Maps the progress of a part (`0..=1`) into `[start, start + span]` of the whole and names
/// its phase; returns the callback's answer.
pub(crate) fn report_part(
    progress: &mut ProgressFn<'_>,
    phase: &str,
    start: f64,
    span: f64,
    part: &Progress,
) -> bool {
    progress(&Progress {
        phase: phase.to_string(),
        fraction: (start + span * part.fraction.clamp(0.0, 1.0)).clamp(0.0, 1.0),
        detail: part.detail.clone(),
    })
}

/// How the budget is shared between the experiments.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// The whole budget, seconds.
    pub budget_secs: f64,
    /// Accuracy against time (default run, simulator sweep, evaluation), seconds.
    pub accuracy_secs: f64,
    /// Fidelity experiments (five skirt runs, disentanglement, reference spin), seconds.
    pub fidelity_secs: f64,
    /// Settings sweep (about eleven runs), seconds.
    pub settings_secs: f64,
    /// Vertex count of built-in garments in the accuracy and settings experiments; `None`
    /// keeps the scene's own resolution.
    pub main_resolution: Option<usize>,
    /// Vertex count of the fidelity skirt.
    pub fidelity_resolution: usize,
    /// Duration of the fidelity scene's spin, seconds.
    pub spin_secs: f32,
    /// Simulator iteration budgets of the accuracy sweep.
    pub sim_iterations: Vec<usize>,
    /// Iterations per frame of the accuracy reference.
    pub reference_iterations: usize,
}

/// Budgets below this many seconds get small garments (a smoke run).
pub const SMOKE_BELOW_SECS: f64 = 300.0;

impl Plan {
    /// The plan for `budget_secs` of wall-clock time: 35% accuracy, 30% fidelity, 33% settings
    /// (2% slack for scene building, plots and files). Small budgets use small garments.
    pub fn for_budget(budget_secs: f64) -> Self {
        let smoke = budget_secs < SMOKE_BELOW_SECS;
        Self {
            budget_secs,
            accuracy_secs: 0.35 * budget_secs,
            fidelity_secs: 0.30 * budget_secs,
            settings_secs: 0.33 * budget_secs,
            main_resolution: smoke.then_some(300),
            fidelity_resolution: if smoke { 200 } else { 400 },
            spin_secs: if smoke { 1.5 } else { 4.0 },
            sim_iterations: if smoke {
                vec![1, 4, 15]
            } else {
                vec![1, 2, 5, 10, 20, 50]
            },
            reference_iterations: if smoke { 60 } else { 200 },
        }
    }
}

/// What `neural-cloth report` does.
#[derive(Clone, Debug)]
pub struct ReportOptions {
    /// Wall-clock budget in seconds; > 0 (the CLI's default is 30 minutes).
    pub budget_secs: f64,
    /// The scene of the accuracy and settings experiments (`None`: the built-in default).
    pub scene: Option<(Scene, SceneConfig)>,
    /// Seed of every run; default 0.
    pub seed: u64,
    /// The command line to print in the report.
    pub command: String,
}

/// Everything the report measured.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Report {
    /// The command that produced it.
    pub command: String,
    /// CPU, cores and memory.
    pub machine: String,
    /// Seed of every run.
    pub seed: u64,
    /// How the budget was shared.
    pub plan: Plan,
    /// Seconds the whole report took.
    pub elapsed_secs: f64,
    /// Name of the accuracy/settings scene.
    pub scene_name: String,
    /// Accuracy against time, with the default run's training curves.
    pub accuracy: CostResult,
    /// Settings against cost.
    pub settings: Vec<SettingRow>,
    /// Fidelity experiments.
    pub fidelity: FidelityResult,
}

/// CPU model, core count and memory (Linux `/proc`), else the core count.
pub fn machine_description() -> String {
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let read = |path: &str, key: &str| {
        std::fs::read_to_string(path).ok().and_then(|t| {
            t.lines().find_map(|l| {
                l.strip_prefix(key)
                    .map(|v| v.trim_start_matches([' ', '\t', ':']).trim().to_string())
            })
        })
    };
    let model = read("/proc/cpuinfo", "model name").unwrap_or_else(|| "unknown CPU".into());
    let mem = read("/proc/meminfo", "MemTotal").unwrap_or_default();
    format!("{model}, {cores} cores, {mem} memory")
}

/// The built-in default scene at `resolution` vertices (`None`: its own resolution).
pub fn default_scene_at(resolution: Option<usize>) -> Result<(Scene, SceneConfig), ReportError> {
    let config = SceneConfig::default_scene();
    rebuild_at(&config, resolution)
}

/// `config` rebuilt with its built-in garment at `resolution` vertices (file garments and
/// `None` keep theirs). Only built-in scenes can be rebuilt here.
pub fn rebuild_at(
    config: &SceneConfig,
    resolution: Option<usize>,
) -> Result<(Scene, SceneConfig), ReportError> {
    let mut config = config.clone();
    if let (GarmentSource::Builtin { resolution: r, .. }, Some(n)) =
        (&mut config.garment, resolution)
    {
        *r = n;
    }
    let scene = neural_cloth_core::scene::procedural::build_builtin(&config)?;
    Ok((scene, config))
}

/// Runs every experiment within `options.budget_secs`. `progress` sees the whole job go from
/// 0 to 1; returning false cancels.
pub fn run_report(
    options: &ReportOptions,
    progress: &mut ProgressFn<'_>,
) -> Result<Report, ReportError> {
    if !(options.budget_secs.is_finite() && options.budget_secs > 0.0) {
        return Err(ReportError::Invalid(format!(
            "budget {} s is not positive",
            options.budget_secs
        )));
    }
    let started = Instant::now();
    let plan = Plan::for_budget(options.budget_secs);
    let (scene, config) = match &options.scene {
        Some((s, c)) => match plan.main_resolution {
            Some(_) if matches!(c.garment, GarmentSource::Builtin { .. }) => {
                rebuild_at(c, plan.main_resolution)?
            }
            _ => (s.clone(), c.clone()),
        },
        None => default_scene_at(plan.main_resolution)?,
    };
    // Each phase ends at its share of the budget; an overrun is taken from the next phase.
    let deadline = |share: f64| share * options.budget_secs;
    let left_until = |end: f64| (end - started.elapsed().as_secs_f64()).max(0.0);
    let total = plan.accuracy_secs + plan.fidelity_secs + plan.settings_secs;
    let (a_span, f_span) = (plan.accuracy_secs / total, plan.fidelity_secs / total);

    let cost = CostOptions {
        budget_secs: left_until(deadline(0.35)),
        sim_iterations: plan.sim_iterations.clone(),
        reference_iterations: plan.reference_iterations,
        seed: options.seed,
        ..CostOptions::default()
    };
    let accuracy = run_cost_experiment(&scene, &cost, &mut |p| {
        report_part(progress, "accuracy", 0.0, a_span, p)
    })?;

    let fidelity_options = FidelityOptions {
        budget_secs: left_until(deadline(0.65)),
        resolution: plan.fidelity_resolution,
        spin_secs: plan.spin_secs,
        seed: options.seed,
    };
    let fidelity = run_fidelity(&fidelity_options, &mut |p| {
        report_part(progress, "fidelity", a_span, f_span, p)
    })?;

    let settings_options = SettingsOptions {
        budget_secs: left_until(deadline(0.98)),
        seed: options.seed,
    };
    let settings = run_settings(&scene, &config, &settings_options, &mut |p| {
        report_part(
            progress,
            "settings",
            a_span + f_span,
            1.0 - a_span - f_span,
            p,
        )
    })?;

    Ok(Report {
        command: options.command.clone(),
        machine: machine_description(),
        seed: options.seed,
        plan,
        elapsed_secs: started.elapsed().as_secs_f64(),
        scene_name: scene.name.clone(),
        accuracy,
        settings,
        fidelity,
    })
}

/// Recorded training checks beside `report.json` (`compare --record`), rendered into the report.
pub const TRAINING_CHECKS_FILE: &str = "training_checks.jsonl";

/// Writes `REPORT.md` into `out_dir` and `report.json` plus the SVG figures into
/// `out_dir/report/` (with the training checks of `out_dir/report/training_checks.jsonl`);
/// returns the paths written. Every file is written atomically.
pub fn write_report(report: &Report, out_dir: &Path) -> Result<Vec<PathBuf>, ReportError> {
    use neural_cloth_core::io::export::atomic::write_atomic;
    let figures_dir = out_dir.join("report");
    std::fs::create_dir_all(&figures_dir).map_err(|e| {
        ReportError::Invalid(format!("cannot create {}: {e}", figures_dir.display()))
    })?;
    let mut written = Vec::new();
    for (name, svg) in figures::all_figures(report)? {
        let path = figures_dir.join(name);
        write_atomic(&path, svg.as_bytes())?;
        written.push(path);
    }
    let json_path = figures_dir.join("report.json");
    write_atomic(&json_path, serde_json::to_string(report)?.as_bytes())?;
    written.push(json_path);
    let checks_path = figures_dir.join(TRAINING_CHECKS_FILE);
    let checks = neural_cloth_train::compare::read_checks(&checks_path)?;
    let md_path = out_dir.join("REPORT.md");
    write_atomic(&md_path, markdown::render(report, &checks).as_bytes())?;
    written.push(md_path);
    Ok(written)
}
