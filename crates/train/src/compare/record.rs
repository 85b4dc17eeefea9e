//! A training check: one `compare` of one motion with what the run was (garment, seed,
//! steps, minutes, dead units, finiteness), appended to a JSON-lines file by
//! `neural-cloth compare --record` and read back by `neural-cloth report`, so the report's
//! table of training targets comes from recorded measurements, not from prose.

use std::io::Write as _;
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::super::TrainError;
use super::super::trained::TrainedModel;
use super::{CompareReport, MotionComparison};

/// One recorded check of a trained run against the simulator on one motion.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainingCheck {
    /// The run folder, as given.
    pub run: String,
    /// What the run was, in words (`compare --label`), e.g. its non-default settings.
    #[serde(default)]
    pub label: Option<String>,
    /// Scene name of the run.
    pub scene: String,
    /// Garment name (`skirt`, `tshirt`, ...).
    pub garment: String,
    /// Training seed.
    pub seed: u64,
    /// Checkpoint step compared.
    pub steps: u64,
    /// Training wall-clock minutes up to that step (pauses excluded).
    pub train_minutes: f64,
    /// Threads the run could use (`RAYON_NUM_THREADS` when set, else the core count) at
    /// the time of the check; minutes are comparable only at equal threads.
    pub threads: usize,
    /// Dead units (worst revivable layer, %) at the last validation pass up to `steps`.
    pub dead_units_pct: Option<f64>,
    /// Every recorded training and validation loss up to `steps` is finite.
    pub finite: bool,
    /// Dynamic weight `w` of the network.
    pub w: f32,
    /// L-BFGS iterations per frame of the reference.
    pub iterations: usize,
    /// The comparison.
    pub motion: MotionComparison,
    /// The run was fitted to the simulator's frames
    /// ([`TrainConfig::fit_reference`](crate::TrainConfig::fit_reference)): a diagnostic,
    /// not the method, so the report judges no target on it. False in records made before
    /// the field existed.
    #[serde(default)]
    pub fitted_to_simulator: bool,
    /// Steps of the run's warm start from our simulator's frames of its training motions
    /// ([`TrainConfig::warm_start_steps`](crate::TrainConfig::warm_start_steps)); 0 (also in
    /// records made before the field existed) when none. The minutes of such a run do not
    /// include the simulation.
    #[serde(default)]
    pub warm_start_steps: u64,
}

impl TrainingCheck {
    /// The checks of `report` (one per motion) with the run's history up to the compared step.
    pub fn from_report(
        trained: &TrainedModel,
        report: &CompareReport,
        label: Option<&str>,
    ) -> Vec<TrainingCheck> {
        let history = trained.run.history();
        let upto = |r: &&crate::MetricRecord| r.step <= report.step;
        let train_minutes = history
            .train
            .iter()
            .filter(upto)
            .map(|r| r.wall_secs)
            .fold(0.0, f64::max)
            / 60.0;
        let dead_units_pct = history
            .validation
            .iter()
            .rfind(|r| upto(r))
            .map(|r| r.dead_units_pct);
        let finite = history
            .train
            .iter()
            .chain(&history.validation)
            .filter(upto)
            .all(|r| r.loss.is_finite());
        let threads = std::env::var("RAYON_NUM_THREADS")
            .ok()
            .and_then(|t| t.parse::<usize>().ok())
            .filter(|&t| t > 0)
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
        report
            .motions
            .iter()
            .map(|m| TrainingCheck {
                run: report.run.display().to_string(),
                label: label.map(str::to_string),
                scene: trained.scene.name.clone(),
                garment: report.garment.clone(),
                seed: trained.meta.train.seed,
                steps: report.step,
                train_minutes,
                threads,
                dead_units_pct,
                finite,
                w: report.options.w,
                iterations: report.options.iterations,
                motion: m.clone(),
                fitted_to_simulator: trained.meta.train.fit_reference.is_some(),
                warm_start_steps: trained.meta.train.warm_start_steps,
            })
            .collect()
    }
}

/// Appends `checks` to the JSON-lines file `path` (created when missing), one line each.
pub fn append_checks(path: &Path, checks: &[TrainingCheck]) -> Result<(), TrainError> {
    let mut text = String::new();
    for c in checks {
        let line = serde_json::to_string(c)
            .map_err(|e| TrainError::Data(format!("cannot encode a training check: {e}")))?;
        text.push_str(&line);
        text.push('\n');
    }
    let mut file = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)
        .map_err(|source| TrainError::File {
            source,
            path: path.to_path_buf(),
        })?;
    file.write_all(text.as_bytes())
        .map_err(|source| TrainError::File {
            source,
            path: path.to_path_buf(),
        })
}

/// Reads every check of the JSON-lines file `path`; a missing file reads as none. A line that
/// does not parse is an error naming its line number.
pub fn read_checks(path: &Path) -> Result<Vec<TrainingCheck>, TrainError> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(source) => {
            return Err(TrainError::File {
                source,
                path: path.to_path_buf(),
            });
        }
    };
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            serde_json::from_str(l)
                .map_err(|e| TrainError::Data(format!("line {}: {e}: {}", i + 1, path.display())))
        })
        .collect()
}
