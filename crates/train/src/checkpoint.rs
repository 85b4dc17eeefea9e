//! Checkpoint folders of a run: writing them so that a crash, a kill or a full disk never
//! leaves a partial checkpoint behind, verifying them on reading, and recovering a run folder
//! after a crash.
//!
//! ```text
//! RUN/checkpoints/step-0000N/model.bpk       burn record of the network
//! RUN/checkpoints/step-0000N/optimizer.bpk   Adam state
//! RUN/checkpoints/step-0000N/state.json      {"step", "learning_rate", "files": {name: {bytes, checksum}}}
//! ```
//! A checkpoint is built in a hidden temporary folder (`.step-0000N.tmp-PID`) and renamed
//! into place when complete, so every `step-N` folder is complete. `state.json` records the
//! length and [`checksum`] of the two other files: a truncated or damaged file is refused on
//! reading instead of being handed to burn. Order of a write: checkpoint files, the metric
//! history (`RUN/metrics.json`, so the history never ends before the newest checkpoint), the
//! folder rename, `RUN/latest.json`, then pruning ([`super::retention`]). Checkpoints written
//! before checksums were recorded (no `files` in `state.json`) are read without the check.

use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use neural_cloth_core::io::export::atomic::{AtomicDir, write_atomic};

use super::TrainError;
use super::metrics::MetricHistory;
use super::run_dir::{CheckpointState, RunDir};

/// The network's weights in a checkpoint folder.
pub const MODEL_FILE: &str = "model.bpk";
/// The optimiser's state in a checkpoint folder.
pub const OPTIMIZER_FILE: &str = "optimizer.bpk";
/// Step, learning rate and file checksums in a checkpoint folder.
pub const STATE_FILE: &str = "state.json";

/// Length and checksum of one checkpoint file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
struct FileCheck {
    bytes: u64,
    checksum: u64,
}

/// The content of `state.json`.
#[derive(Debug, Serialize, Deserialize)]
struct StateFile {
    #[serde(flatten)]
    state: CheckpointState,
    /// Absent in checkpoints written before checksums were recorded.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    files: BTreeMap<String, FileCheck>,
}

/// Writes one checkpoint file, complete and synced, at the path it is given (a temporary in
/// the checkpoint's folder; [`RunDir::write_checkpoint_from`]).
pub type FileWriter<'a> = Box<dyn FnOnce(&Path) -> Result<(), TrainError> + 'a>;

/// What a fallback over checkpoints loaded, and the checkpoints it had to skip.
#[derive(Debug)]
pub struct Loaded<T> {
    /// Step of the checkpoint loaded.
    pub step: u64,
    /// What the loader returned.
    pub value: T,
    /// One line per newer checkpoint that could not be loaded (file path last).
    pub warnings: Vec<String>,
}

/// FNV-1a over little-endian 64-bit words (then the trailing bytes), seeded with the length.
/// Any change of a single word changes the result (each round is a bijection of the state).
pub fn checksum(bytes: &[u8]) -> u64 {
    fold_words(checksum_seed(bytes.len() as u64), bytes)
}

/// The state [`checksum`] starts from for `len` bytes.
fn checksum_seed(len: u64) -> u64 {
    0xcbf29ce484222325 ^ len
}

/// Folds `bytes` into the checksum state `h`: whole 64-bit words, then the trailing bytes
/// one by one (so only the last piece of a stream may have a length that is not a multiple
/// of 8).
fn fold_words(mut h: u64, bytes: &[u8]) -> u64 {
    const PRIME: u64 = 0x100000001b3;
    let mut words = bytes.chunks_exact(8);
    for w in &mut words {
        let mut a = [0u8; 8];
        a.copy_from_slice(w);
        h = (h ^ u64::from_le_bytes(a)).wrapping_mul(PRIME);
    }
    for b in words.remainder() {
        h = (h ^ u64::from(*b)).wrapping_mul(PRIME);
    }
    h
}

/// Length and [`checksum`] of the file at `path`, read in 1 MiB pieces; errors name `shown`.
fn check_file(path: &Path, shown: &Path) -> Result<FileCheck, TrainError> {
    let io = |e| TrainError::io(e, shown);
    let mut file = std::fs::File::open(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    let mut h = checksum_seed(len);
    let mut buffer = vec![0u8; 1 << 20];
    let mut read_total = 0u64;
    loop {
        // Fill the whole buffer (short reads happen), so every piece but the last is whole words.
        let mut filled = 0;
        while filled < buffer.len() {
            match file.read(&mut buffer[filled..]) {
                Ok(0) => break,
                Ok(n) => filled += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(io(e)),
            }
        }
        h = fold_words(h, &buffer[..filled]);
        read_total += filled as u64;
        if filled < buffer.len() {
            break;
        }
    }
    if read_total != len {
        return Err(corrupt(
            format!("read {read_total} bytes of a {len}-byte file"),
            shown,
        ));
    }
    Ok(FileCheck {
        bytes: len,
        checksum: h,
    })
}

/// `message` without its mentions of `path`: `" 'PATH…'"` (a quoted name that starts with
/// it, such as a writer's scratch file beside it) and a trailing `": PATH"`.
fn without_path(message: &str, path: &Path) -> String {
    let path = path.display().to_string();
    let mut out = message
        .strip_suffix(&format!(": {path}"))
        .unwrap_or(message)
        .to_string();
    let quoted = format!(" '{path}");
    while let Some(start) = out.find(&quoted) {
        let after = start + quoted.len();
        let Some(close) = out[after..].find('\'') else {
            break;
        };
        out.replace_range(start..after + close + 1, "");
    }
    out
}

fn corrupt(reason: impl Into<String>, path: &Path) -> TrainError {
    TrainError::Corrupt {
        reason: reason.into(),
        path: path.to_path_buf(),
    }
}

/// Writes `bytes` to `path` and syncs it; errors name `shown` (the file's final path).
pub(crate) fn write_synced(path: &Path, bytes: &[u8], shown: &Path) -> Result<(), TrainError> {
    let mut file = std::fs::File::create(path).map_err(|e| TrainError::io(e, shown))?;
    file.write_all(bytes)
        .and_then(|()| file.sync_all())
        .map_err(|e| TrainError::io(e, shown))
}

/// Syncs a folder so that the renames inside it survive a power cut (best effort).
fn sync_dir(path: &Path) {
    if let Ok(dir) = std::fs::File::open(path) {
        let _ = dir.sync_all();
    }
}

/// The step of a checkpoint folder name `step-N`.
pub(crate) fn step_of(name: &str) -> Option<u64> {
    name.strip_prefix("step-")?.parse().ok()
}

impl RunDir {
    /// Folder of the checkpoints.
    pub fn checkpoints_dir(&self) -> PathBuf {
        self.root.join("checkpoints")
    }

    /// Steps of the checkpoint folders present, newest first (temporaries are not listed).
    pub fn checkpoint_steps(&self) -> Vec<u64> {
        let Ok(entries) = std::fs::read_dir(self.checkpoints_dir()) else {
            return Vec::new();
        };
        let mut steps: Vec<u64> = entries
            .filter_map(|e| e.ok())
            .filter(|e| e.path().is_dir())
            .filter_map(|e| step_of(&e.file_name().to_string_lossy()))
            .collect();
        steps.sort_unstable_by(|a, b| b.cmp(a));
        steps
    }

    /// The step recorded in `latest.json`, if it is readable.
    pub fn latest_json_step(&self) -> Option<u64> {
        let text = std::fs::read_to_string(self.root.join("latest.json")).ok()?;
        let v: serde_json::Value = serde_json::from_str(&text).ok()?;
        v.get("step")?.as_u64()
    }

    /// Step of the newest checkpoint whose state file reads and whose files have their
    /// recorded lengths (a cheap check; [`Self::read_checkpoint_file`] verifies checksums).
    pub fn latest_step(&self) -> Option<u64> {
        self.checkpoint_steps().into_iter().find(|&step| {
            self.read_state_file(step).is_ok_and(|s| {
                [MODEL_FILE, OPTIMIZER_FILE].iter().all(|name| {
                    let path = self.checkpoint_path(step).join(name);
                    let len = std::fs::metadata(&path).map(|m| m.len()).ok();
                    len.is_some() && s.files.get(*name).is_none_or(|c| Some(c.bytes) == len)
                })
            })
        })
    }

    fn read_state_file(&self, step: u64) -> Result<StateFile, TrainError> {
        let path = self.checkpoint_path(step).join(STATE_FILE);
        let bytes = std::fs::read(&path).map_err(|e| TrainError::io(e, &path))?;
        let file: StateFile = serde_json::from_slice(&bytes)
            .map_err(|e| corrupt(format!("unreadable checkpoint state ({e})"), &path))?;
        if file.state.step != step {
            return Err(corrupt(
                format!("the state records step {}, not {step}", file.state.step),
                &path,
            ));
        }
        Ok(file)
    }

    /// The state of checkpoint `step` (its `state.json`, checked against the folder name).
    pub fn read_state(&self, step: u64) -> Result<CheckpointState, TrainError> {
        Ok(self.read_state_file(step)?.state)
    }

    /// File `name` of checkpoint `step`, verified against the length and checksum its
    /// `state.json` records.
    pub fn read_checkpoint_file(&self, step: u64, name: &str) -> Result<Vec<u8>, TrainError> {
        let state = self.read_state_file(step)?;
        let path = self.checkpoint_path(step).join(name);
        let bytes = std::fs::read(&path).map_err(|e| TrainError::io(e, &path))?;
        if let Some(check) = state.files.get(name) {
            if bytes.len() as u64 != check.bytes {
                return Err(corrupt(
                    format!(
                        "checkpoint file is {} bytes long, its state records {}",
                        bytes.len(),
                        check.bytes
                    ),
                    &path,
                ));
            }
            if checksum(&bytes) != check.checksum {
                return Err(corrupt(
                    "checkpoint file does not match its recorded checksum (damaged)",
                    &path,
                ));
            }
        }
        Ok(bytes)
    }

    /// Reads the verified model bytes, optimiser bytes and state of checkpoint `step`.
    pub fn read_checkpoint(
        &self,
        step: u64,
    ) -> Result<(Vec<u8>, Vec<u8>, CheckpointState), TrainError> {
        let state = self.read_state(step)?;
        let model = self.read_checkpoint_file(step, MODEL_FILE)?;
        let optimizer = self.read_checkpoint_file(step, OPTIMIZER_FILE)?;
        Ok((model, optimizer, state))
    }

    /// Calls `load` on the checkpoints newest first until one succeeds. `Ok(None)` when the run
    /// has no checkpoint at all; an error when there are checkpoints but none loads (the
    /// newest one's error), or when `latest.json` names a checkpoint that is gone.
    pub fn newest_loadable<T>(
        &self,
        mut load: impl FnMut(u64) -> Result<T, TrainError>,
    ) -> Result<Option<Loaded<T>>, TrainError> {
        let steps = self.checkpoint_steps();
        if steps.is_empty() {
            return match self.latest_json_step() {
                Some(step) => Err(TrainError::Checkpoint(format!(
                    "latest.json names step {step} but no checkpoint folder is left: {}",
                    self.checkpoints_dir().display()
                ))),
                None => Ok(None),
            };
        }
        let mut failures: Vec<(u64, TrainError)> = Vec::new();
        for &step in &steps {
            match load(step) {
                Ok(value) => {
                    let warnings = failures
                        .iter()
                        .map(|(bad, e)| {
                            format!("checkpoint step {bad} is unusable, using step {step}: {e}")
                        })
                        .collect();
                    return Ok(Some(Loaded {
                        step,
                        value,
                        warnings,
                    }));
                }
                Err(e) => failures.push((step, e)),
            }
        }
        let count = failures.len();
        let (step, newest) = failures.swap_remove(0);
        Err(TrainError::Checkpoint(format!(
            "none of the {count} checkpoints can be loaded; the newest (step {step}): {newest}"
        )))
    }

    /// [`Self::write_checkpoint_from`] with the two files' bytes in hand.
    #[cfg(test)]
    pub(crate) fn write_checkpoint(
        &self,
        state: CheckpointState,
        model_bytes: &[u8],
        optimizer_bytes: &[u8],
        history: &MetricHistory,
    ) -> Result<PathBuf, TrainError> {
        self.write_checkpoint_from(
            state,
            Box::new(|p| write_synced(p, model_bytes, p)),
            Box::new(|p| write_synced(p, optimizer_bytes, p)),
            history,
        )
    }

    /// Writes the checkpoint of `state.step` (replacing one of the same step), the metric
    /// history and `latest.json`, then prunes old checkpoints. Returns the checkpoint folder.
    /// On error nothing partial is left and the previous checkpoints are intact.
    ///
    /// Each file is written by its own writer, one after the other, so that a writer may
    /// stream its file (the optimiser's moments, 108 MB on the default scene, are never copied
    /// whole) and the two files' data are never held at once. Each file's length and checksum
    /// are read back from the disk.
    pub fn write_checkpoint_from(
        &self,
        state: CheckpointState,
        model: FileWriter<'_>,
        optimizer: FileWriter<'_>,
        history: &MetricHistory,
    ) -> Result<PathBuf, TrainError> {
        let path = self.checkpoint_path(state.step);
        let dir = AtomicDir::create(&path)?;
        let mut files = BTreeMap::new();
        for (name, write) in [(MODEL_FILE, model), (OPTIMIZER_FILE, optimizer)] {
            let temp = dir.temp_path().join(name);
            write(&temp).map_err(|e| TrainError::WriteFile {
                reason: without_path(&e.to_string(), &temp),
                path: path.join(name),
            })?;
            files.insert(name.to_string(), check_file(&temp, &path.join(name))?);
        }
        let state_json = serde_json::to_vec_pretty(&StateFile { state, files })
            .map_err(|e| TrainError::Checkpoint(e.to_string()))?;
        let state_path = path.join(STATE_FILE);
        write_synced(&dir.temp_path().join(STATE_FILE), &state_json, &state_path)?;
        let history_json =
            serde_json::to_vec(history).map_err(|e| TrainError::Checkpoint(e.to_string()))?;
        write_atomic(&self.root.join("metrics.json"), &history_json)?;
        let path = self.commit_replacing(dir, &path)?;
        sync_dir(&self.checkpoints_dir());
        write_atomic(
            &self.root.join("latest.json"),
            format!("{{\"step\": {}}}\n", state.step).as_bytes(),
        )?;
        sync_dir(&self.root);
        self.prune(history);
        Ok(path)
    }

    /// Renames `dir` onto `path`; an existing checkpoint there is moved aside first
    /// (`.step-N.old-PID`, which [`Self::recover`] restores after a crash) and deleted after.
    fn commit_replacing(&self, dir: AtomicDir, path: &Path) -> Result<PathBuf, TrainError> {
        if !path.exists() {
            return Ok(dir.commit()?);
        }
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let aside = path.with_file_name(format!(".{name}.old-{}", std::process::id()));
        std::fs::rename(path, &aside).map_err(|e| TrainError::io(e, path))?;
        match dir.commit() {
            Ok(p) => {
                let _ = std::fs::remove_dir_all(&aside);
                Ok(p)
            }
            Err(e) => {
                let _ = std::fs::rename(&aside, path);
                Err(e.into())
            }
        }
    }

    /// Tidies the run folder after a crash: deletes unfinished temporaries (`.NAME.tmp-PID`)
    /// and half-deleted old checkpoints (`.step-N.del-PID`), and puts back a checkpoint moved aside by an interrupted replacement. Returns what it
    /// did, one line per entry (empty when the folder was clean).
    pub fn recover(&self) -> Vec<String> {
        let mut done = Vec::new();
        for folder in [self.root.clone(), self.checkpoints_dir()] {
            let Ok(entries) = std::fs::read_dir(&folder) else {
                continue;
            };
            for entry in entries.filter_map(|e| e.ok()) {
                let name = entry.file_name().to_string_lossy().into_owned();
                let Some(hidden) = name.strip_prefix('.') else {
                    continue;
                };
                let path = entry.path();
                if hidden.contains(".tmp-") || hidden.contains(".del-") {
                    let removed = if path.is_dir() {
                        std::fs::remove_dir_all(&path)
                    } else {
                        std::fs::remove_file(&path)
                    };
                    if removed.is_ok() && hidden.contains(".tmp-") {
                        done.push(format!("removed an unfinished write: {}", path.display()));
                    }
                } else if let Some((original, _)) = hidden.split_once(".old-")
                    && step_of(original).is_some()
                {
                    let target = folder.join(original);
                    if target.exists() {
                        let _ = std::fs::remove_dir_all(&path);
                    } else if std::fs::rename(&path, &target).is_ok() {
                        done.push(format!(
                            "restored a checkpoint whose replacement was interrupted: {}",
                            target.display()
                        ));
                    }
                }
            }
        }
        done
    }

    /// Deletes the checkpoints the run's retention policy does not keep (by default the newest
    /// [`super::run_dir::KEEP_CHECKPOINTS`] and the best by validation; see
    /// [`super::retention`]). An unreadable policy keeps every checkpoint (the app reports it
    /// when it opens the run).
    fn prune(&self, history: &MetricHistory) {
        if let Ok(retention) = self.retention() {
            self.prune_with(retention, history);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(step: u64) -> CheckpointState {
        CheckpointState {
            step,
            learning_rate: 1e-3,
        }
    }

    fn run_with(steps: &[u64]) -> (tempfile::TempDir, RunDir) {
        let dir = tempfile::tempdir().unwrap();
        let run = RunDir::create(dir.path()).unwrap();
        for &s in steps {
            let model = vec![s as u8; 1000 + s as usize];
            run.write_checkpoint(state(s), &model, &[7; 64], &MetricHistory::default())
                .unwrap();
        }
        (dir, run)
    }

    #[test]
    fn checksum_sees_every_single_byte_flip_and_the_length() {
        let data: Vec<u8> = (0..1003u32).map(|i| (i * 31 % 251) as u8).collect();
        let sum = checksum(&data);
        for i in 0..data.len() {
            let mut d = data.clone();
            d[i] ^= 0x10;
            assert_ne!(checksum(&d), sum, "flip at {i}");
        }
        assert_ne!(checksum(&data[..1002]), sum);
        assert_ne!(checksum(&[0, 0]), checksum(&[0]));
    }

    #[test]
    fn a_writer_failure_leaves_out_the_temporary() {
        let temp = Path::new("/r/checkpoints/.step-3.tmp-9/model.bpk");
        assert_eq!(
            without_path(
                "I/O error: cannot write to '/r/checkpoints/.step-3.tmp-9/model.bpk.9-1.tmp': \
                 No space left on device (os error 28)",
                temp
            ),
            "I/O error: cannot write to: No space left on device (os error 28)"
        );
        assert_eq!(
            without_path(
                "No space left on device (os error 28): /r/checkpoints/.step-3.tmp-9/model.bpk",
                temp
            ),
            "No space left on device (os error 28)"
        );
        assert_eq!(without_path("other 'x': y", temp), "other 'x': y");
    }

    #[test]
    fn a_file_read_in_pieces_has_the_checksum_of_its_bytes() {
        let dir = tempfile::tempdir().unwrap();
        // Sizes around the 1 MiB piece: whole pieces, a trailing odd piece, a short file.
        for len in [0usize, 13, (1 << 20) - 3, 1 << 20, 3 * (1 << 20) + 5] {
            let data: Vec<u8> = (0..len).map(|i| (i * 131 % 253) as u8).collect();
            let path = dir.path().join(format!("f{len}"));
            std::fs::write(&path, &data).unwrap();
            let check = check_file(&path, &path).unwrap();
            assert_eq!(check.bytes, len as u64);
            assert_eq!(check.checksum, checksum(&data), "{len} bytes");
        }
        let missing = dir.path().join("missing.bpk");
        let e = check_file(&missing, &missing).unwrap_err().to_string();
        assert!(e.ends_with("missing.bpk"), "{e}");
    }

    #[test]
    fn a_damaged_file_is_refused_naming_it_and_the_previous_checkpoint_is_used() {
        let (_dir, run) = run_with(&[1, 2]);
        let model = run.checkpoint_path(2).join(MODEL_FILE);
        let mut bytes = std::fs::read(&model).unwrap();
        bytes[500] ^= 1;
        std::fs::write(&model, &bytes).unwrap();
        let err = run.read_checkpoint(2).unwrap_err().to_string();
        assert!(err.ends_with(&model.display().to_string()), "{err}");
        assert!(err.contains("checksum"), "{err}");
        let loaded = run
            .newest_loadable(|s| run.read_checkpoint(s))
            .unwrap()
            .unwrap();
        assert_eq!(loaded.step, 1);
        assert_eq!(loaded.warnings.len(), 1);
        assert!(
            loaded.warnings[0].contains("step 2"),
            "{:?}",
            loaded.warnings
        );
        // Truncated: the length check names the file too.
        std::fs::write(&model, &bytes[..100]).unwrap();
        let err = run.read_checkpoint(2).unwrap_err().to_string();
        assert!(err.contains("100 bytes long"), "{err}");
        assert_eq!(run.latest_step(), Some(1));
    }

    #[test]
    fn no_loadable_checkpoint_is_an_error_not_a_fresh_start() {
        let (_dir, run) = run_with(&[1]);
        let state = run.checkpoint_path(1).join(STATE_FILE);
        std::fs::remove_file(&state).unwrap();
        let err = run
            .newest_loadable(|s| run.read_checkpoint(s))
            .unwrap_err()
            .to_string();
        assert!(err.ends_with(&state.display().to_string()), "{err}");
        // All folders gone while latest.json names one: an error as well.
        std::fs::remove_dir_all(run.checkpoint_path(1)).unwrap();
        let err = run
            .newest_loadable(|s| run.read_checkpoint(s))
            .unwrap_err()
            .to_string();
        assert!(err.contains("latest.json names step 1"), "{err}");
        // A run that never wrote a checkpoint starts from nothing.
        std::fs::remove_file(run.root.join("latest.json")).unwrap();
        assert!(
            run.newest_loadable(|s| run.read_checkpoint(s))
                .unwrap()
                .is_none()
        );
    }

    #[test]
    fn rewriting_a_step_keeps_one_complete_checkpoint_and_recover_tidies_a_crash() {
        let (_dir, run) = run_with(&[1, 2, 3, 4]);
        assert_eq!(run.checkpoint_steps(), vec![4, 3, 2]);
        run.write_checkpoint(state(4), &[9; 10], &[8; 10], &MetricHistory::default())
            .unwrap();
        assert_eq!(run.read_checkpoint(4).unwrap().0, vec![9; 10]);
        // A crash between moving step 4 aside and committing its replacement, with a
        // temporary left behind: recover puts step 4 back and deletes the temporary.
        let aside = run.checkpoints_dir().join(".step-00000004.old-99");
        std::fs::rename(run.checkpoint_path(4), &aside).unwrap();
        let temp = run.checkpoints_dir().join(".step-00000005.tmp-99");
        std::fs::create_dir(&temp).unwrap();
        std::fs::write(temp.join(MODEL_FILE), b"half").unwrap();
        std::fs::write(run.root.join(".metrics.json.tmp-99"), b"{").unwrap();
        let doomed = run.checkpoints_dir().join(".step-00000001.del-99");
        std::fs::create_dir(&doomed).unwrap();
        std::fs::write(doomed.join(STATE_FILE), b"{}").unwrap();
        assert_eq!(run.checkpoint_steps(), vec![3, 2]);
        let done = run.recover();
        assert_eq!(done.len(), 3, "{done:?}");
        assert_eq!(run.checkpoint_steps(), vec![4, 3, 2]);
        assert_eq!(run.read_checkpoint(4).unwrap().0, vec![9; 10]);
        assert!(!temp.exists() && !aside.exists() && !doomed.exists());
        assert!(run.recover().is_empty());
    }

    #[test]
    fn checkpoints_without_checksums_still_read() {
        let (_dir, run) = run_with(&[1]);
        let path = run.checkpoint_path(1).join(STATE_FILE);
        std::fs::write(&path, r#"{"step": 1, "learning_rate": 0.001}"#).unwrap();
        let (model, _, s) = run.read_checkpoint(1).unwrap();
        assert_eq!((model.len(), s.step), (1001, 1));
    }
}
