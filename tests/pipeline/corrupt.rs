//! Damaged and missing checkpoint files: `train --resume`, `eval` and `bake` fall back to the
//! previous complete checkpoint with a warning naming the file, or stop with an error naming
//! it; never a panic, never a fresh start over the run.

use std::path::{Path, PathBuf};
use std::process::Command;

use super::fixture::{copy_dir, small_run, snapshot};

/// Runs the binary in `cwd`; returns success, stdout and stderr.
fn cli(args: &[&str], cwd: &Path) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_neural-cloth"))
        .args(args)
        .current_dir(cwd)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn checkpoint_file(run: &Path, step: u64, name: &str) -> PathBuf {
    run.join(format!("checkpoints/step-{step:08}/{name}"))
}

fn flip_byte(path: &Path) {
    let mut bytes = std::fs::read(path).unwrap();
    let k = bytes.len() / 2;
    bytes[k] ^= 0x40;
    std::fs::write(path, bytes).unwrap();
}

fn truncate(path: &Path) {
    let bytes = std::fs::read(path).unwrap();
    std::fs::write(path, &bytes[..bytes.len() / 2]).unwrap();
}

/// The checkpoint step `eval` used (the `step` of its mean record).
fn eval_step(stdout: &str) -> u64 {
    let v: serde_json::Value = serde_json::from_str(stdout).unwrap();
    v["mean"]["step"].as_u64().unwrap()
}

/// A damage done to a copy of the fixture run (newest checkpoint: step 4) and what each
/// command must then do.
struct Case {
    name: &'static str,
    damage: fn(&Path),
    /// The file the fallback warning of `eval` and `bake` must name (relative to the run);
    /// `None`: no fallback warning.
    named: Option<&'static str>,
    /// The same for `--resume`.
    resume_named: Option<&'static str>,
    /// Step `--resume` must start from.
    resume_from: u64,
    /// Step `eval` and `bake` must use.
    eval_step: u64,
}

fn check_case(fixture: &Path, case: &Case) {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    copy_dir(fixture, &run);
    (case.damage)(&run);
    let name = case.name;
    let warned_of = |named: Option<&str>, stderr: &str| match named {
        Some(n) => {
            let file = Path::new("run").join(n).display().to_string();
            stderr
                .lines()
                .any(|l| l.starts_with("warning: checkpoint step") && l.ends_with(&file))
        }
        None => !stderr.contains("warning: checkpoint step"),
    };
    let warned = |stderr: &str| warned_of(case.named, stderr);
    let (ok, stdout, stderr) = cli(&["eval", "run", "--split", "validation"], dir.path());
    assert!(ok, "{name}: eval failed: {stderr}");
    assert_eq!(eval_step(&stdout), case.eval_step, "{name}: eval step");
    assert!(warned(&stderr), "{name}: eval warning: {stderr}");
    let (ok, _, stderr) = cli(
        &["bake", "run", "--motion", "walk", "--out", "w.pc2"],
        dir.path(),
    );
    assert!(ok, "{name}: bake failed: {stderr}");
    assert!(warned(&stderr), "{name}: bake warning: {stderr}");
    assert!(dir.path().join("w.pc2").is_file());
    let (ok, stdout, stderr) = cli(&["train", "--resume", "run", "--steps", "6"], dir.path());
    assert!(ok, "{name}: resume failed: {stderr}");
    let from = format!("(from step {})", case.resume_from);
    assert!(stderr.contains(&from), "{name}: want {from}: {stderr}");
    assert!(
        warned_of(case.resume_named, &stderr),
        "{name}: resume warning: {stderr}"
    );
    assert!(stdout.contains("\"steps\": 6"), "{name}: {stdout}");
    let history = neural_cloth::train::RunDir::open(&run).unwrap().history();
    let steps: Vec<u64> = history.train.iter().map(|r| r.step).collect();
    assert_eq!(steps, (1..=6).collect::<Vec<_>>(), "{name}: history");
    assert!(
        super::fixture::temporaries(&run).is_empty(),
        "{name}: temporaries left"
    );
    super::fixture::verified_steps(&run);
}

#[test]
fn a_damaged_or_partial_newest_checkpoint_falls_back_to_the_previous_one() {
    let fixture = tempfile::tempdir().unwrap();
    let run = fixture.path().join("run");
    small_run(&run, 4);
    let cases = [
        Case {
            name: "model byte flipped",
            damage: |r| flip_byte(&checkpoint_file(r, 4, "model.bpk")),
            named: Some("checkpoints/step-00000004/model.bpk"),
            resume_named: Some("checkpoints/step-00000004/model.bpk"),
            resume_from: 3,
            eval_step: 3,
        },
        Case {
            name: "model truncated",
            damage: |r| truncate(&checkpoint_file(r, 4, "model.bpk")),
            named: Some("checkpoints/step-00000004/model.bpk"),
            resume_named: Some("checkpoints/step-00000004/model.bpk"),
            resume_from: 3,
            eval_step: 3,
        },
        Case {
            // Evaluating and baking need no optimiser: they keep the newest checkpoint.
            name: "optimizer byte flipped",
            damage: |r| flip_byte(&checkpoint_file(r, 4, "optimizer.bpk")),
            named: None,
            resume_named: Some("checkpoints/step-00000004/optimizer.bpk"),
            resume_from: 3,
            eval_step: 4,
        },
        Case {
            name: "state.json missing",
            damage: |r| std::fs::remove_file(checkpoint_file(r, 4, "state.json")).unwrap(),
            named: Some("checkpoints/step-00000004/state.json"),
            resume_named: Some("checkpoints/step-00000004/state.json"),
            resume_from: 3,
            eval_step: 3,
        },
        Case {
            name: "partial folder (model only)",
            damage: |r| {
                std::fs::remove_file(checkpoint_file(r, 4, "state.json")).unwrap();
                std::fs::remove_file(checkpoint_file(r, 4, "optimizer.bpk")).unwrap();
            },
            named: Some("checkpoints/step-00000004/state.json"),
            resume_named: Some("checkpoints/step-00000004/state.json"),
            resume_from: 3,
            eval_step: 3,
        },
        Case {
            // An unfinished write left by a crash is not a checkpoint, and resuming removes it.
            name: "unfinished temporary folder",
            damage: |r| {
                let temp = r.join("checkpoints/.step-00000005.tmp-1");
                std::fs::create_dir(&temp).unwrap();
                std::fs::write(temp.join("model.bpk"), b"half a model").unwrap();
            },
            named: None,
            resume_named: None,
            resume_from: 4,
            eval_step: 4,
        },
    ];
    for case in &cases {
        check_case(&run, case);
    }
}

#[test]
fn a_run_of_which_no_checkpoint_loads_is_refused_and_left_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    small_run(&run, 3);
    for step in 1..=3 {
        flip_byte(&checkpoint_file(&run, step, "model.bpk"));
    }
    let before = snapshot(&run);
    // Messages name the files as the user named the run: relative to the working folder.
    let newest = checkpoint_file(Path::new("run"), 3, "model.bpk")
        .display()
        .to_string();
    for args in [
        vec!["train", "--resume", "run", "--steps", "5"],
        vec!["eval", "run", "--split", "validation"],
        vec!["bake", "run", "--motion", "walk", "--out", "w.pc2"],
    ] {
        let (ok, _, stderr) = cli(&args, dir.path());
        assert!(!ok, "{args:?} succeeded: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
        let error = stderr
            .lines()
            .find(|l| l.starts_with("error:"))
            .unwrap_or_else(|| panic!("{args:?}: no error line: {stderr}"));
        assert!(error.contains("none of the 3 checkpoints"), "{error}");
        assert!(error.ends_with(&newest), "{error}");
        assert_eq!(stderr.matches(&newest).count(), 1, "said once: {stderr}");
    }
    assert!(!dir.path().join("w.pc2").exists());
    assert!(snapshot(&run) == before, "the run folder changed");
}

#[test]
fn runs_of_older_and_newer_formats() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    small_run(&run, 3);
    // An older run: no checksums in state.json, no avatar fingerprint in run.json.
    for step in 1..=3 {
        let state = format!("{{\"step\": {step}, \"learning_rate\": 0.001}}");
        std::fs::write(checkpoint_file(&run, step, "state.json"), state).unwrap();
    }
    let meta_path = run.join("run.json");
    let mut meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&meta_path).unwrap()).unwrap();
    meta.as_object_mut().unwrap().remove("avatar_fingerprint");
    std::fs::write(&meta_path, serde_json::to_vec_pretty(&meta).unwrap()).unwrap();
    let (ok, stdout, stderr) = cli(&["eval", "run", "--split", "validation"], dir.path());
    assert!(ok, "{stderr}");
    assert_eq!(eval_step(&stdout), 3);
    // Without checksums a truncated model is caught by decoding it: no panic, a fallback.
    truncate(&checkpoint_file(&run, 3, "model.bpk"));
    let (ok, stdout, stderr) = cli(&["eval", "run", "--split", "validation"], dir.path());
    assert!(ok, "{stderr}");
    assert_eq!(eval_step(&stdout), 2, "{stderr}");
    let model = checkpoint_file(Path::new("run"), 3, "model.bpk")
        .display()
        .to_string();
    assert!(stderr.lines().any(|l| l.ends_with(&model)), "{stderr}");
    let (ok, _, stderr) = cli(&["train", "--resume", "run", "--steps", "4"], dir.path());
    assert!(ok && stderr.contains("(from step 2)"), "{stderr}");
    // A newer format is refused by name.
    meta["version"] = 99.into();
    std::fs::write(&meta_path, serde_json::to_vec_pretty(&meta).unwrap()).unwrap();
    for args in [
        vec!["train", "--resume", "run"],
        vec!["eval", "run", "--split", "validation"],
        vec!["bake", "run", "--motion", "walk"],
    ] {
        let (ok, _, stderr) = cli(&args, dir.path());
        assert!(!ok, "{args:?}");
        assert!(
            stderr.contains("format version 99") && stderr.trim_end().ends_with("run/run.json"),
            "{args:?}: {stderr}"
        );
    }
}

#[test]
fn a_damaged_metric_history_is_reported_and_training_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    small_run(&run, 2);
    std::fs::write(run.join("metrics.json"), b"{\"train\": [").unwrap();
    let (ok, _, stderr) = cli(&["train", "--resume", "run", "--steps", "3"], dir.path());
    assert!(ok, "{stderr}");
    let lines: Vec<&str> = stderr
        .lines()
        .filter(|l| l.contains("run/metrics.json"))
        .collect();
    assert_eq!(lines.len(), 1, "said once: {stderr}");
    assert!(
        lines[0].starts_with("warning: the metric history starts over"),
        "{stderr}"
    );
}
