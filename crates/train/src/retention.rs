//! Checkpoint retention of a run folder: which checkpoints are kept after each new one (the
//! newest few and the best by validation), how much disk the run uses, and pruning an existing
//! run by hand.
//!
//! The policy lives in the run folder as `RUN/retention.json` (machine-written), so the app can
//! change it while the trainer runs: the trainer reads it at every prune. A run without the
//! file keeps [`Retention::default`].

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use neural_cloth_core::io::export::atomic::write_atomic;

use super::TrainError;
use super::metrics::MetricHistory;
use super::run_dir::{KEEP_CHECKPOINTS, RunDir};

/// The retention policy's file in a run folder.
pub const RETENTION_FILE: &str = "retention.json";
/// Most checkpoints [`Retention::keep_newest`] may ask for.
pub const MAX_KEEP_NEWEST: usize = 1000;

/// Which checkpoints of a run survive pruning.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Retention {
    /// How many of the newest checkpoints to keep, 1..=[`MAX_KEEP_NEWEST`]; default
    /// [`KEEP_CHECKPOINTS`].
    pub keep_newest: usize,
    /// Also keep the checkpoint with the lowest validation loss; default true.
    pub keep_best: bool,
}

impl Default for Retention {
    fn default() -> Self {
        Self {
            keep_newest: KEEP_CHECKPOINTS,
            keep_best: true,
        }
    }
}

impl Retention {
    /// The policy with `keep_newest` brought into its range.
    pub fn clamped(self) -> Self {
        Self {
            keep_newest: self.keep_newest.clamp(1, MAX_KEEP_NEWEST),
            ..self
        }
    }
}

/// Disk use of a run folder.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DiskUsage {
    /// Bytes of every file in the run folder.
    pub total_bytes: u64,
    /// Bytes of the checkpoint folders.
    pub checkpoint_bytes: u64,
    /// Complete checkpoint folders.
    pub checkpoints: usize,
}

/// Bytes of every file under `path` (0 for what cannot be read; links are not followed).
pub fn folder_bytes(path: &Path) -> u64 {
    let Ok(meta) = std::fs::symlink_metadata(path) else {
        return 0;
    };
    if !meta.is_dir() {
        return meta.len();
    }
    std::fs::read_dir(path)
        .map(|entries| {
            entries
                .filter_map(|e| e.ok())
                .map(|e| folder_bytes(&e.path()))
                .sum()
        })
        .unwrap_or(0)
}

/// Bytes as a short text ("95.3 MB").
pub fn format_bytes(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KB", "MB", "GB", "TB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1000.0 && unit + 1 < UNITS.len() {
        value /= 1000.0;
        unit += 1;
    }
    match unit {
        0 => format!("{bytes} B"),
        _ => format!("{value:.1} {}", UNITS[unit]),
    }
}

/// The checkpoint of `steps` with the lowest validation loss: each checkpoint is scored by the
/// newest validation pass at or before its step (none: not scored); ties go to the newer one.
pub fn best_by_validation(steps: &[u64], history: &MetricHistory) -> Option<u64> {
    let score = |step: u64| {
        history
            .validation
            .iter()
            .rfind(|v| v.step <= step && v.loss.is_finite())
            .map(|v| v.loss)
    };
    steps
        .iter()
        .filter_map(|&s| score(s).map(|loss| (s, loss)))
        .min_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
        .map(|(s, _)| s)
}

impl RunDir {
    /// The run's retention policy: `retention.json`, the default when the file is absent, an
    /// error naming the file when it cannot be read or parsed (a hand-edited policy that does
    /// not parse must not silently fall back to deleting checkpoints).
    pub fn retention(&self) -> Result<Retention, TrainError> {
        let path = self.root.join(RETENTION_FILE);
        let bytes = match std::fs::read(&path) {
            Ok(bytes) => bytes,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Retention::default()),
            Err(e) => {
                return Err(TrainError::Corrupt {
                    reason: format!("retention policy unreadable ({e})"),
                    path,
                });
            }
        };
        serde_json::from_slice::<Retention>(&bytes)
            .map(Retention::clamped)
            .map_err(|e| TrainError::Corrupt {
                reason: format!("retention policy does not parse ({e})"),
                path,
            })
    }

    /// Writes the run's retention policy (atomically); the next prune follows it.
    pub fn set_retention(&self, retention: Retention) -> Result<(), TrainError> {
        let json = serde_json::to_vec_pretty(&retention.clamped())
            .map_err(|e| TrainError::Checkpoint(e.to_string()))?;
        write_atomic(&self.root.join(RETENTION_FILE), &json)?;
        Ok(())
    }

    /// The checkpoint steps `retention` keeps, newest first.
    pub fn kept_steps(&self, retention: Retention, history: &MetricHistory) -> Vec<u64> {
        let steps = self.checkpoint_steps();
        let retention = retention.clamped();
        let best = best_by_validation(&steps, history).filter(|_| retention.keep_best);
        steps
            .iter()
            .enumerate()
            .filter(|(k, s)| *k < retention.keep_newest || Some(**s) == best)
            .map(|(_, s)| *s)
            .collect()
    }

    /// Deletes the checkpoints `retention` does not keep; returns the deleted folders. Each
    /// is first renamed to a hidden `.step-N.del-PID` (atomic), so that a crash while deleting
    /// never leaves a half-deleted checkpoint under a checkpoint's name. Such folders left by
    /// an earlier prune (a crash, or a removal that failed) are removed first; a checkpoint
    /// counts as deleted only when its removal succeeded.
    pub fn prune_with(&self, retention: Retention, history: &MetricHistory) -> Vec<PathBuf> {
        self.prune_removing(retention, history, |path| std::fs::remove_dir_all(path))
    }

    /// [`Self::prune_with`] removing folders with `remove` (tests make it fail).
    fn prune_removing(
        &self,
        retention: Retention,
        history: &MetricHistory,
        remove: impl Fn(&Path) -> std::io::Result<()>,
    ) -> Vec<PathBuf> {
        self.sweep_deleting(&remove);
        let kept = self.kept_steps(retention, history);
        let mut deleted = Vec::new();
        for step in self.checkpoint_steps() {
            if kept.contains(&step) {
                continue;
            }
            let path = self.checkpoint_path(step);
            let doomed = path.with_file_name(format!(".step-{step:08}.del-{}", std::process::id()));
            if std::fs::rename(&path, &doomed).is_ok() && remove(&doomed).is_ok() {
                deleted.push(path);
            }
        }
        deleted
    }

    /// Removes the hidden `.step-N.del-PID` folders of checkpoints whose deletion did not
    /// finish (they are no checkpoints any more, but still use disk).
    fn sweep_deleting(&self, remove: &impl Fn(&Path) -> std::io::Result<()>) {
        let Ok(entries) = std::fs::read_dir(self.checkpoints_dir()) else {
            return;
        };
        for entry in entries.filter_map(|e| e.ok()) {
            let name = entry.file_name().to_string_lossy().into_owned();
            let leftover = name
                .strip_prefix(".step-")
                .is_some_and(|rest| rest.contains(".del-"));
            if leftover && entry.path().is_dir() {
                let _ = remove(&entry.path());
            }
        }
    }

    /// How much disk the run folder uses, and how many checkpoints it holds.
    pub fn disk_usage(&self) -> DiskUsage {
        DiskUsage {
            total_bytes: folder_bytes(&self.root),
            checkpoint_bytes: folder_bytes(&self.checkpoints_dir()),
            checkpoints: self.checkpoint_steps().len(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::MetricRecord;
    use crate::run_dir::CheckpointState;

    fn run_with(steps: &[u64], history: &MetricHistory) -> (tempfile::TempDir, RunDir) {
        let dir = tempfile::tempdir().unwrap();
        let run = RunDir::create(dir.path()).unwrap();
        for &step in steps {
            let state = CheckpointState {
                step,
                learning_rate: 1e-3,
            };
            run.write_checkpoint(state, &[1; 100], &[2; 50], history)
                .unwrap();
        }
        (dir, run)
    }

    fn validation(losses: &[(u64, f64)]) -> MetricHistory {
        MetricHistory {
            train: Vec::new(),
            validation: losses
                .iter()
                .map(|&(step, loss)| MetricRecord {
                    step,
                    loss,
                    ..Default::default()
                })
                .collect(),
        }
    }

    #[test]
    fn the_best_checkpoint_by_validation_survives_with_the_newest() {
        // Validation is best at step 20; checkpoints every 10 steps.
        let history = validation(&[(10, 3.0), (20, 1.0), (30, 2.0), (40, 2.5), (50, 2.2)]);
        let (_dir, run) = run_with(&[10, 20, 30, 40, 50, 60], &history);
        assert_eq!(
            best_by_validation(&run.checkpoint_steps(), &history),
            Some(20)
        );
        assert_eq!(run.checkpoint_steps(), vec![60, 50, 40, 20]);
        // Without the best: only the newest three.
        run.set_retention(Retention {
            keep_newest: 3,
            keep_best: false,
        })
        .unwrap();
        let deleted = run.prune_with(run.retention().unwrap(), &history);
        assert_eq!(deleted, vec![run.checkpoint_path(20)]);
        assert_eq!(run.checkpoint_steps(), vec![60, 50, 40]);
    }

    #[test]
    fn the_policy_in_the_run_folder_steers_the_trainers_pruning() {
        let history = MetricHistory::default();
        let (_dir, run) = run_with(&[1], &history);
        run.set_retention(Retention {
            keep_newest: 1,
            keep_best: true,
        })
        .unwrap();
        for step in 2..=4 {
            let state = CheckpointState {
                step,
                learning_rate: 1e-3,
            };
            run.write_checkpoint(state, &[1; 100], &[2; 50], &history)
                .unwrap();
        }
        assert_eq!(run.checkpoint_steps(), vec![4]);
        let usage = run.disk_usage();
        assert_eq!(usage.checkpoints, 1);
        assert!(usage.checkpoint_bytes >= 150, "{usage:?}");
        assert!(usage.total_bytes > usage.checkpoint_bytes, "{usage:?}");
        // A zero is brought into range.
        std::fs::write(run.root.join(RETENTION_FILE), br#"{"keep_newest": 0}"#).unwrap();
        assert_eq!(run.retention().unwrap().keep_newest, 1);
    }

    #[test]
    fn a_malformed_retention_file_keeps_every_checkpoint() {
        let history = MetricHistory::default();
        let (_dir, run) = run_with(&[1], &history);
        // A hand edit that does not parse (a string where a number belongs).
        std::fs::write(
            run.root.join(RETENTION_FILE),
            br#"{"keep_newest": "50", "keep_best": true}"#,
        )
        .unwrap();
        let error = run.retention().unwrap_err().to_string();
        assert!(
            error.contains("does not parse") && error.ends_with(RETENTION_FILE),
            "{error}"
        );
        for step in 2..=6 {
            let state = CheckpointState {
                step,
                learning_rate: 1e-3,
            };
            run.write_checkpoint(state, &[1; 100], &[2; 50], &history)
                .unwrap();
        }
        assert_eq!(run.checkpoint_steps(), vec![6, 5, 4, 3, 2, 1]);
        // Without the file the default policy applies again.
        std::fs::remove_file(run.root.join(RETENTION_FILE)).unwrap();
        assert_eq!(run.retention().unwrap(), Retention::default());
    }

    #[test]
    fn leftover_deletions_are_swept_and_a_failed_removal_is_not_reported() {
        let history = MetricHistory::default();
        let (_dir, run) = run_with(&[], &history);
        run.set_retention(Retention {
            keep_newest: 10,
            keep_best: false,
        })
        .unwrap();
        for step in 1..=4 {
            let state = CheckpointState {
                step,
                learning_rate: 1e-3,
            };
            run.write_checkpoint(state, &[1; 100], &[2; 50], &history)
                .unwrap();
        }
        // A deletion an earlier prune did not finish (a crash, or a removal that failed).
        let leftover = run.checkpoints_dir().join(".step-00000000.del-99");
        std::fs::create_dir_all(&leftover).unwrap();
        std::fs::write(leftover.join("model.bin"), [0u8; 4096]).unwrap();
        let keep_one = Retention {
            keep_newest: 3,
            keep_best: false,
        };
        let deleted = run.prune_with(keep_one, &history);
        assert_eq!(deleted, vec![run.checkpoint_path(1)]);
        assert!(!leftover.exists(), "the leftover deletion was not swept");
        // A removal that fails: the step is not reported deleted, and the next prune sweeps
        // its hidden folder.
        let keep_two = Retention {
            keep_newest: 2,
            ..keep_one
        };
        let failing = |_: &Path| Err(std::io::Error::other("device busy"));
        assert!(run.prune_removing(keep_two, &history, failing).is_empty());
        assert_eq!(run.checkpoint_steps(), vec![4, 3]);
        let hidden = |run: &RunDir| {
            std::fs::read_dir(run.checkpoints_dir())
                .unwrap()
                .filter(|e| {
                    e.as_ref()
                        .unwrap()
                        .file_name()
                        .to_string_lossy()
                        .contains(".del-")
                })
                .count()
        };
        assert_eq!(hidden(&run), 1);
        run.prune_with(keep_two, &history);
        assert_eq!(hidden(&run), 0);
    }

    #[test]
    fn sizes_read_as_people_write_them() {
        assert_eq!(format_bytes(512), "512 B");
        assert_eq!(format_bytes(95_300_000), "95.3 MB");
        assert_eq!(format_bytes(2_500_000_000), "2.5 GB");
    }
}
