//! Kill at any moment: `neural-cloth train --resume` with a checkpoint at every step, and
//! `neural-cloth bake`, are killed with SIGKILL at random moments (during checkpoint and cache
//! writes too) and started again each time. Every resume must start from the newest complete
//! checkpoint, no partial checkpoint may ever be visible, the step count never goes back past
//! a complete checkpoint and the metric history stays one record per step; a killed bake
//! leaves either no file or the previous complete one.
//!
//! The random moments come from a seed printed by each test; `NEURAL_CLOTH_KILL_SEED=N` replays
//! one.

use std::path::Path;
use std::time::{Duration, Instant};

use neural_cloth::train::RunDir;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

use super::fixture::{Running, small_run, temporaries, verified_steps};

/// Kills of the training process (the issue asks for at least 30).
const TRAIN_KILLS: usize = 32;
/// Kills of the bake process, before and after a first complete bake.
const BAKE_KILLS: usize = 12;

fn seed() -> u64 {
    let seed = std::env::var("NEURAL_CLOTH_KILL_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| {
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map(|d| d.as_nanos() as u64)
                .unwrap_or(1)
        });
    eprintln!("kill seed {seed} (replay with NEURAL_CLOTH_KILL_SEED={seed})");
    seed
}

/// The step of the newest complete checkpoint on disk, counting one moved aside by an
/// interrupted same-step replacement (resuming puts it back).
fn newest_complete(run: &Path) -> u64 {
    let aside = std::fs::read_dir(run.join("checkpoints"))
        .unwrap()
        .filter_map(|e| {
            let name = e.unwrap().file_name().to_string_lossy().into_owned();
            let (step, _) = name.strip_prefix(".step-")?.split_once(".old-")?;
            step.parse::<u64>().ok()
        })
        .max();
    verified_steps(run)
        .first()
        .copied()
        .into_iter()
        .chain(aside)
        .max()
        .unwrap_or(0)
}

/// The step a run resumed from, read from its `run folder: ... (from step N)` line.
fn resumed_from(log: &str) -> Option<u64> {
    let line = log.lines().find(|l| l.starts_with("run folder:"))?;
    let (_, tail) = line.rsplit_once("(from step ")?;
    tail.trim_end_matches(')').parse().ok()
}

/// Checks the history on disk: one training record per step from 1 on, reaching at least
/// `newest` (the newest complete checkpoint), times never going back, validations in order.
/// Returns its last step.
fn check_history(run: &Path, newest: u64, when: &str) -> u64 {
    let history = RunDir::open(run).unwrap().try_history().unwrap();
    let steps: Vec<u64> = history.train.iter().map(|r| r.step).collect();
    let last = steps.last().copied().unwrap_or(0);
    assert_eq!(steps, (1..=last).collect::<Vec<_>>(), "{when}: train steps");
    assert!(
        last >= newest,
        "{when}: history ends at {last}, checkpoint {newest}"
    );
    assert!(
        history
            .train
            .windows(2)
            .all(|w| w[1].wall_secs >= w[0].wall_secs),
        "{when}: training time went back"
    );
    assert!(
        history.validation.windows(2).all(|w| w[1].step > w[0].step)
            && history.validation.iter().all(|v| v.step <= last),
        "{when}: validation steps {:?}",
        history
            .validation
            .iter()
            .map(|v| v.step)
            .collect::<Vec<_>>()
    );
    last
}

fn train_args(steps: &str) -> Vec<&str> {
    vec![
        "train",
        "--resume",
        "run",
        "--steps",
        steps,
        "--checkpoint-every",
        "1",
        "--validate-every",
        "3",
    ]
}

#[test]
fn training_killed_at_random_moments_always_resumes_from_its_newest_complete_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    small_run(&run, 1);
    let mut rng = StdRng::seed_from_u64(seed());
    let started = Instant::now();
    let (mut newest_seen, mut resumes, mut mid_write) = (1, 0, 0);
    for k in 0..TRAIN_KILLS {
        let expected = newest_complete(&run);
        assert!(
            expected >= newest_seen,
            "kill {k}: the newest complete checkpoint went back from {newest_seen} to {expected}"
        );
        newest_seen = expected;
        let log_path = dir.path().join("train.log");
        let child = Running::start(&train_args("1000000"), dir.path(), &log_path);
        // One kill in five lands during start-up (recovery, loading); the others while
        // training, at a random moment after the run has started.
        if k % 5 == 0 {
            std::thread::sleep(Duration::from_secs_f64(rng.random_range(0.0..0.8)));
        } else {
            wait_for_start(&log_path);
            std::thread::sleep(Duration::from_secs_f64(rng.random_range(0.0..0.6)));
        }
        child.kill();
        let log = std::fs::read_to_string(&log_path).unwrap();
        assert!(
            !log.contains("panicked") && !log.contains("error"),
            "kill {k}: {log}"
        );
        if let Some(from) = resumed_from(&log) {
            assert_eq!(
                from, expected,
                "kill {k}: resumed from the wrong step: {log}"
            );
            resumes += 1;
        }
        let left = temporaries(&run);
        mid_write += usize::from(!left.is_empty());
        let newest = newest_complete(&run);
        check_history(&run, newest, &format!("after kill {k}"));
    }
    let expected = newest_complete(&run);
    let target = (expected + 3).to_string();
    let log_path = dir.path().join("final.log");
    let mut last = Running::start(&train_args(&target), dir.path(), &log_path);
    let status = wait_at_most(&mut last, Duration::from_secs(60));
    let log = std::fs::read_to_string(&log_path).unwrap();
    assert!(status.is_some_and(|s| s.success()), "final run: {log}");
    assert_eq!(resumed_from(&log), Some(expected), "{log}");
    assert!(temporaries(&run).is_empty(), "a resume tidies up");
    let steps = verified_steps(&run);
    assert_eq!(steps.first().copied(), Some(expected + 3));
    assert_eq!(
        check_history(&run, expected + 3, "at the end"),
        expected + 3
    );
    eprintln!(
        "{TRAIN_KILLS} kills in {:.0} s: {resumes} after the resume had started, {mid_write} \
         left an unfinished write, training reached step {}",
        started.elapsed().as_secs_f64(),
        expected + 3
    );
    // The kills must have landed while training ran, not only during start-up.
    assert!(
        resumes >= TRAIN_KILLS / 2,
        "only {resumes} kills after start-up"
    );
    assert!(mid_write > 0, "no kill interrupted a checkpoint write");
    assert!(expected > 5, "training made no progress: step {expected}");
}

/// Waits (at most 30 s) until the log at `path` shows that the run started.
fn wait_for_start(path: &Path) {
    let started = Instant::now();
    while started.elapsed() < Duration::from_secs(30) {
        let log = std::fs::read_to_string(path).unwrap_or_default();
        if log.contains("run folder:") {
            return;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Waits for `child` for at most `limit`; `None` when it had to be killed.
fn wait_at_most(child: &mut Running, limit: Duration) -> Option<std::process::ExitStatus> {
    let started = Instant::now();
    while started.elapsed() < limit {
        if let Some(status) = child.child.try_wait().unwrap() {
            return Some(status);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    None
}

fn bake_args(w: &'static str, out: &'static str) -> Vec<&'static str> {
    vec![
        "bake", "run", "--motion", "walk", "--fps", "1000", "--w", w, "--out", out,
    ]
}

/// Whether the temporary of `out` (`.out.tmp-PID`) exists in `dir`, i.e. a bake is writing.
fn writing(dir: &Path, out: &str) -> bool {
    std::fs::read_dir(dir).unwrap().any(|e| {
        let name = e.unwrap().file_name();
        name.to_string_lossy().starts_with(&format!(".{out}.tmp-"))
    })
}

/// Runs a bake to completion; returns its bytes and how long its file was being written.
fn full_bake(cwd: &Path, w: &'static str, out: &'static str) -> (Vec<u8>, Duration) {
    let mut child = Running::start(&bake_args(w, out), cwd, &cwd.join("bake.log"));
    let started = Instant::now();
    let mut first_write = None;
    let status = loop {
        if let Some(status) = child.child.try_wait().unwrap() {
            break Some(status);
        }
        if first_write.is_none() && writing(cwd, out) {
            first_write = Some(Instant::now());
        }
        if started.elapsed() > Duration::from_secs(60) {
            break None;
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    let log = std::fs::read_to_string(cwd.join("bake.log")).unwrap();
    assert!(status.is_some_and(|s| s.success()), "{log}");
    let write = first_write.map_or(Duration::from_millis(50), |t| t.elapsed());
    (std::fs::read(cwd.join(out)).unwrap(), write)
}

#[test]
fn a_bake_killed_mid_write_leaves_no_file_or_the_previous_complete_one() {
    let dir = tempfile::tempdir().unwrap();
    small_run(&dir.path().join("run"), 2);
    let (still, took) = full_bake(dir.path(), "0", "still.pc2");
    let (moving, _) = full_bake(dir.path(), "1", "moving.pc2");
    assert_ne!(
        still, moving,
        "the two bakes must differ to tell them apart"
    );
    let out = dir.path().join("out.pc2");
    let mut rng = StdRng::seed_from_u64(seed());
    let mut mid_write = 0;
    let window = took.as_secs_f64();
    for k in 0..BAKE_KILLS {
        // First half: no file yet; then a complete still bake is the previous file.
        let (w, previous) = if k < BAKE_KILLS / 2 {
            ("0", None)
        } else {
            if k == BAKE_KILLS / 2 {
                full_bake(dir.path(), "0", "out.pc2");
            }
            ("1", Some(&still))
        };
        let child = Running::start(
            &bake_args(w, "out.pc2"),
            dir.path(),
            &dir.path().join("k.log"),
        );
        // One kill in four at a random moment from the start, the others while it writes.
        if k % 4 == 0 {
            std::thread::sleep(Duration::from_secs_f64(rng.random_range(0.0..1.0)));
        } else {
            let started = Instant::now();
            while !writing(dir.path(), "out.pc2") && started.elapsed() < Duration::from_secs(30) {
                std::thread::sleep(Duration::from_millis(2));
            }
            std::thread::sleep(Duration::from_secs_f64(rng.random_range(0.0..window)));
        }
        child.kill();
        let finished = if w == "0" { &still } else { &moving };
        match std::fs::read(&out) {
            Err(_) => assert!(previous.is_none(), "kill {k}: the previous bake vanished"),
            Ok(bytes) => assert!(
                &bytes == finished || Some(&bytes) == previous,
                "kill {k}: a partial file of {} bytes is visible",
                bytes.len()
            ),
        }
        mid_write += usize::from(writing(dir.path(), "out.pc2"));
        // A killed writer cannot delete its temporary: clear it so the next kill counts anew.
        for entry in std::fs::read_dir(dir.path()).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            if name.starts_with(".out.pc2.tmp-") {
                std::fs::remove_file(path).unwrap();
            }
        }
        // Completed bakes replace the previous file: start the next kill from a known one.
        if k >= BAKE_KILLS / 2 {
            std::fs::write(&out, &still).unwrap();
        } else {
            let _ = std::fs::remove_file(&out);
        }
    }
    eprintln!("{BAKE_KILLS} bake kills, {mid_write} mid-write (writing takes {window:.2} s)");
    assert!(mid_write > 0, "no kill interrupted the write");
}
