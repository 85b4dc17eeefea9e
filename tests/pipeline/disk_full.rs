//! A full disk: checkpoints and bakes written into a small tmpfs mounted by the test (root
//! only; skipped with a message otherwise). A write that does not fit fails with a clear error
//! naming the file, leaves no partial file and keeps the previous files intact; training goes
//! on and writes the checkpoint again once there is room.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, Mutex};

use neural_cloth::physics::FabricParams;
use neural_cloth::train::handle::Session;
use neural_cloth::train::metrics::{MetricHistory, MetricRecord};
use neural_cloth::train::{
    RunDir, RunLocation, TrainConfig, TrainError, TrainEvent, TrainerHandle, prepare,
};

use super::fixture::{copy_dir, small_run, snapshot, temporaries, verified_steps};

/// What the run folder held just before room was made: checkpoint steps and temporaries.
type Seen = Arc<Mutex<Option<(Vec<u64>, Vec<PathBuf>)>>>;

/// A tmpfs of a given size, unmounted on drop.
struct Tmpfs {
    _parent: tempfile::TempDir,
    path: PathBuf,
}

impl Tmpfs {
    /// Mounts a tmpfs of `megabytes`; `None` (with a message) where mounting is not allowed.
    fn mount(megabytes: u32) -> Option<Self> {
        let parent = tempfile::tempdir().unwrap();
        let path = parent.path().join("small-disk");
        std::fs::create_dir(&path).unwrap();
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={megabytes}m"), "tmpfs"])
            .arg(&path)
            .output();
        match out {
            Ok(o) if o.status.success() => Some(Self {
                _parent: parent,
                path,
            }),
            Ok(o) => {
                eprintln!(
                    "skipped: cannot mount a tmpfs (the disk-full test needs root): {}",
                    String::from_utf8_lossy(&o.stderr).trim()
                );
                None
            }
            Err(e) => {
                eprintln!("skipped: cannot run mount (the disk-full test needs root): {e}");
                None
            }
        }
    }

    /// Fills the disk with a file `filler`, leaving about `free_kib` KiB free.
    fn fill(&self, free_kib: u64) -> PathBuf {
        let filler = self.path.join("filler");
        let mut file = std::fs::File::create(&filler).unwrap();
        let chunk = vec![0xa5u8; 64 << 10];
        let mut written = 0u64;
        while file.write_all(&chunk).is_ok() {
            written += chunk.len() as u64;
        }
        drop(file);
        let file = std::fs::OpenOptions::new()
            .write(true)
            .open(&filler)
            .unwrap();
        file.set_len(written.saturating_sub(free_kib << 10))
            .unwrap();
        filler
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(&self.path).status();
    }
}

/// The real session; before its `free_at`-th step it records the state of the run folder
/// (what the failed checkpoints left) and deletes the filler, making room.
struct RoomLater<S: Session> {
    inner: S,
    calls: u64,
    free_at: u64,
    filler: PathBuf,
    run: PathBuf,
    /// Steps of the checkpoint folders and the temporaries seen just before making room.
    seen: Seen,
}

impl<S: Session> Session for RoomLater<S> {
    fn step(&mut self) -> Result<MetricRecord, TrainError> {
        self.calls += 1;
        if self.calls == self.free_at {
            let steps = RunDir::open(&self.run).unwrap().checkpoint_steps();
            *self.seen.lock().unwrap() = Some((steps, temporaries(&self.run)));
            std::fs::remove_file(&self.filler).unwrap();
        }
        self.inner.step()
    }
    fn validate(&mut self) -> Result<MetricRecord, TrainError> {
        self.inner.validate()
    }
    fn weights_finite(&self) -> bool {
        self.inner.weights_finite()
    }
    fn snapshot(&self) -> Result<neural_cloth::model::ModelArtifact, TrainError> {
        self.inner.snapshot()
    }
    fn checkpoint(&mut self, step: u64, history: &MetricHistory) -> Result<PathBuf, TrainError> {
        self.inner.checkpoint(step, history)
    }
    fn restore_last_checkpoint(&mut self) -> Result<u64, TrainError> {
        self.inner.restore_last_checkpoint()
    }
    fn learning_rate(&self) -> f64 {
        self.inner.learning_rate()
    }
    fn set_learning_rate(&mut self, lr: f64) {
        self.inner.set_learning_rate(lr)
    }
    fn set_fabric(&mut self, fabric: FabricParams) -> Result<(), TrainError> {
        self.inner.set_fabric(fabric)
    }
    fn set_window(&mut self, window_secs: f32) -> Result<(), TrainError> {
        self.inner.set_window(window_secs)
    }
}

/// Resumes `run` up to `steps` with a checkpoint at every step; the filler is deleted before
/// the `free_at`-th step (never when 0). Returns the events and the run's result.
fn resume_on_full_disk(
    run: &Path,
    steps: u64,
    filler: &Path,
    free_at: u64,
    seen: Seen,
) -> (
    Vec<TrainEvent>,
    Result<neural_cloth::train::RunSummary, String>,
) {
    let config = TrainConfig {
        max_steps: Some(steps),
        checkpoint_every: 1,
        validate_every: 2,
        batch_size: 2,
        ..super::quick_config()
    };
    let setup = super::setup(run, config, Some(RunLocation::Resume(run.to_path_buf())));
    let (session, loop_config) = prepare(setup).unwrap();
    let session = RoomLater {
        inner: session,
        calls: 0,
        free_at,
        filler: filler.to_path_buf(),
        run: run.to_path_buf(),
        seen,
    };
    super::run_to_end(TrainerHandle::spawn_session(session, loop_config, None).unwrap())
}

fn warnings(events: &[TrainEvent]) -> Vec<String> {
    events
        .iter()
        .filter_map(|e| match e {
            TrainEvent::Warning(w) => Some(w.clone()),
            _ => None,
        })
        .collect()
}

#[test]
fn a_checkpoint_on_a_full_disk_fails_cleanly_and_is_written_again_later() {
    let Some(disk) = Tmpfs::mount(24) else {
        return;
    };
    let normal = tempfile::tempdir().unwrap();
    small_run(&normal.path().join("run"), 2);
    let run = disk.path.join("run");
    copy_dir(&normal.path().join("run"), &run);
    // Only the newest three: which checkpoints survive is then a function of the steps alone
    // (the best by validation is pinned in the retention tests).
    RunDir::open(&run)
        .unwrap()
        .set_retention(neural_cloth::train::retention::Retention {
            keep_newest: 3,
            keep_best: false,
        })
        .unwrap();
    let filler = disk.fill(300);
    let seen = Arc::new(Mutex::new(None));
    // Checkpoints 3 and 4 do not fit; room is made before step 5.
    let (events, result) = resume_on_full_disk(&run, 7, &filler, 3, seen.clone());
    assert_eq!(result.unwrap().steps, 7);
    let warned = warnings(&events);
    for step in [3, 4] {
        let folder = format!("step-{step:08}");
        let line = warned
            .iter()
            .find(|w| w.contains(&format!("checkpoint of step {step} could not")))
            .unwrap_or_else(|| panic!("no warning for step {step}: {warned:?}"));
        assert!(line.contains("No space left on device"), "{line}");
        let file = line.rsplit(": ").next().unwrap();
        assert!(file.contains(&folder) && file.starts_with('/'), "{line}");
    }
    let (steps, left) = seen.lock().unwrap().clone().unwrap();
    assert_eq!(steps, vec![2, 1], "the previous checkpoints, untouched");
    assert!(left.is_empty(), "partial files left: {left:?}");
    let written: Vec<u64> = events
        .iter()
        .filter_map(|e| match e {
            TrainEvent::Checkpoint { step, .. } => Some(*step),
            _ => None,
        })
        .collect();
    assert_eq!(written, vec![5, 6, 7, 7], "{written:?}");
    assert_eq!(verified_steps(&run), vec![7, 6, 5]);
    let history = RunDir::open(&run).unwrap().history();
    let logged: Vec<u64> = history.train.iter().map(|r| r.step).collect();
    assert_eq!(logged, (1..=7).collect::<Vec<_>>());

    // Full again and no room made: the final checkpoint fails with an error naming the file;
    // the checkpoints before stay intact and loadable.
    let filler = disk.fill(300);
    let before = snapshot(&run);
    let (_, result) = resume_on_full_disk(&run, 8, &filler, 0, Arc::new(Mutex::new(None)));
    let error = result.unwrap_err();
    assert!(
        error.starts_with("the final checkpoint (step 8) could not be written")
            && error.contains("No space left on device")
            && error.ends_with("step-00000008/model.bpk"),
        "{error}"
    );
    assert!(temporaries(&run).is_empty());
    let after = snapshot(&run);
    let checkpoint_files = |s: &std::collections::BTreeMap<PathBuf, Vec<u8>>| {
        s.iter()
            .filter(|(p, _)| p.starts_with(run.join("checkpoints")))
            .map(|(p, b)| (p.clone(), b.clone()))
            .collect::<Vec<_>>()
    };
    assert!(checkpoint_files(&after) == checkpoint_files(&before));
    assert_eq!(verified_steps(&run), vec![7, 6, 5]);
}

#[test]
fn a_bake_on_a_full_disk_fails_cleanly_and_keeps_the_previous_file() {
    let Some(disk) = Tmpfs::mount(8) else {
        return;
    };
    let normal = tempfile::tempdir().unwrap();
    small_run(&normal.path().join("run"), 1);
    disk.fill(200);
    // Every streaming writer: the point caches and USD (text, frames streamed to disk).
    for (format, name) in [
        ("pc2", "walk.pc2"),
        ("mdd", "walk.mdd"),
        ("usd", "walk.usda"),
    ] {
        let out = disk.path.join(name);
        std::fs::write(&out, b"the previous bake").unwrap();
        let output = Command::new(env!("CARGO_BIN_EXE_neural-cloth"))
            .args(["bake", "run", "--motion", "walk", "--fps", "1000"])
            .args(["--format", format, "--out"])
            .arg(&out)
            .current_dir(normal.path())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(!output.status.success(), "{format}: {stderr}");
        let error = stderr
            .lines()
            .find(|l| l.starts_with("error:"))
            .unwrap_or_else(|| panic!("{format}: {stderr}"));
        assert!(
            error.contains("No space left on device")
                && error.ends_with(&out.display().to_string()),
            "{format}: {error}"
        );
        assert_eq!(
            std::fs::read(&out).unwrap(),
            b"the previous bake",
            "{format}"
        );
        assert!(
            temporaries(&disk.path).is_empty(),
            "{format}: a partial file is left"
        );
    }
}
