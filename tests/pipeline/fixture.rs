//! Shared by the crash, corruption and disk-full tests: a small trained run with a checkpoint
//! at every step, the `neural-cloth` binary as a child process, and snapshots of folders.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use neural_cloth::train::{RunDir, TrainConfig, Trainer};

/// Trains a run of the small network on the tiny scene at `run` for `steps` steps, with a
/// checkpoint at every step (the newest three are kept) and a validation every other step.
pub fn small_run(run: &Path, steps: u64) {
    let config = TrainConfig {
        max_steps: Some(steps),
        checkpoint_every: 1,
        validate_every: 2,
        predrape_secs: 0.0,
        batch_size: 2,
        ..super::quick_config()
    };
    let (_, result) =
        super::run_to_end(Trainer::spawn(super::setup(run, config, None), None).unwrap());
    assert_eq!(result.unwrap().steps, steps);
}

/// Copies the folder `from` to `to` (recursively).
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.path().is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), target).unwrap();
        }
    }
}

/// Every file under `dir` with its bytes.
pub fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let bytes = std::fs::read(&path).unwrap();
                out.insert(path, bytes);
            }
        }
    }
    out
}

/// Hidden temporaries (`.NAME.tmp-PID`, `.NAME.old-PID`, `.NAME.del-PID`) under `dir`.
pub fn temporaries(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for entry in entries {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            let hidden = [".tmp-", ".old-", ".del-"];
            if name.starts_with('.') && hidden.iter().any(|h| name.contains(h)) {
                out.push(path.clone());
            }
            if path.is_dir() {
                stack.push(path);
            }
        }
    }
    out
}

/// Checks every checkpoint folder of `run` (each must be complete and match its checksums)
/// and returns their steps, newest first.
pub fn verified_steps(run: &Path) -> Vec<u64> {
    let dir = RunDir::open(run).unwrap();
    let steps = dir.checkpoint_steps();
    for &step in &steps {
        if let Err(e) = dir.read_checkpoint(step) {
            panic!("a partial or damaged checkpoint is visible: {e}");
        }
    }
    steps
}

/// `neural-cloth ARGS` started in `cwd` with its output going to `log`; killed (SIGKILL) when
/// dropped.
pub struct Running {
    /// The child process.
    pub child: Child,
}

impl Running {
    /// Starts the binary.
    pub fn start(args: &[&str], cwd: &Path, log: &Path) -> Self {
        let log = std::fs::File::create(log).unwrap();
        let child = Command::new(env!("CARGO_BIN_EXE_neural-cloth"))
            .args(args)
            .current_dir(cwd)
            .stdout(Stdio::null())
            .stderr(log)
            .spawn()
            .unwrap();
        Self { child }
    }

    /// Sends SIGKILL and waits for the process to end.
    pub fn kill(mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
