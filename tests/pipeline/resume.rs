//! `train --resume` trains on the scene the run recorded and refuses a different `--scene`;
//! a new run never overwrites an existing one; headless GPU use (training on the GPU backend,
//! `screenshot`) prints no display errors.

use std::path::Path;
use std::process::Command;

use super::fixture::{small_run, snapshot};

fn cli(args: &[&str], cwd: &Path) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_neural-cloth"))
        .args(args)
        .current_dir(cwd)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn resume_trains_on_the_recorded_scene_and_refuses_a_different_one() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    small_run(&run, 2);
    // No --scene: the run's own tiny scene, not the built-in default one.
    let (ok, log) = cli(&["train", "--resume", "run", "--steps", "3"], dir.path());
    assert!(ok && log.contains("(from step 2)"), "{log}");
    // The same scene given again is accepted.
    std::fs::write(dir.path().join("tiny.toml"), super::TINY).unwrap();
    let (ok, log) = cli(
        &[
            "train",
            "--resume",
            "run",
            "--scene",
            "tiny.toml",
            "--steps",
            "4",
        ],
        dir.path(),
    );
    assert!(ok && log.contains("(from step 3)"), "{log}");
    // Another one is refused, naming the difference; the run is left as it was.
    std::fs::write(
        dir.path().join("other.toml"),
        super::TINY.replace("resolution = 400", "resolution = 500"),
    )
    .unwrap();
    let before = snapshot(&run);
    let (ok, log) = cli(
        &[
            "train",
            "--resume",
            "run",
            "--scene",
            "other.toml",
            "--steps",
            "5",
        ],
        dir.path(),
    );
    assert!(!ok, "{log}");
    assert!(
        log.contains("garment.resolution is 400 in the run, 500 in the given scene"),
        "{log}"
    );
    assert!(log.trim_end().ends_with("run/scene.toml"), "{log}");
    assert!(snapshot(&run) == before, "the run changed");
    // A run goes on at the rate it was trained at (issue 14: the scene's, recorded in run.json).
    let (ok, log) = cli(
        &["train", "--resume", "run", "--fps", "60", "--steps", "5"],
        dir.path(),
    );
    assert!(
        !ok && log.contains("trained at 30 frames per second"),
        "{log}"
    );
    assert!(snapshot(&run) == before, "the run changed");
    let refused = |edit: &dyn Fn(&mut neural_cloth::scene::Scene)| {
        let (mut scene, scene_config) = super::tiny();
        edit(&mut scene);
        neural_cloth::train::prepare(neural_cloth::train::TrainSetup {
            scene,
            scene_config,
            train: super::quick_config(),
            model: super::small_model(),
            descriptors: neural_cloth::model::DescriptorConfig::default(),
            location: neural_cloth::train::RunLocation::Resume(run.clone()),
        })
        .err()
        .expect("refused")
        .to_string()
    };
    let text = refused(&|scene| scene.training_fps = 60.0);
    assert!(
        text.contains("trained at 30 frames per second, the scene is at 60"),
        "{text}"
    );
    assert!(snapshot(&run) == before, "the run changed");
    // The effects' one home is the run's scene.toml: a resume with other effects is refused.
    let text = refused(&|scene| scene.effects.bending = !scene.effects.bending);
    assert!(
        text.contains("other effects than the scene's (bending"),
        "{text}"
    );
    assert!(snapshot(&run) == before, "the run changed");
}

/// Review of issue 14: a run trained at another rate resumes with the command line that
/// started it (`--scene` and `--fps` repeated).
#[test]
fn a_run_at_another_rate_resumes_with_its_own_command_line() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tiny.toml"), super::TINY).unwrap();
    let start = [
        "train",
        "--scene",
        "tiny.toml",
        "--fps",
        "60",
        "--predrape-secs",
        "0",
        "--steps",
        "2",
        "--out",
        "run60",
    ];
    let (ok, log) = cli(&start, dir.path());
    assert!(ok, "{log}");
    let mut again = start.to_vec();
    let n = again.len();
    again[n - 2..].copy_from_slice(&["--resume", "run60"]);
    again[n - 3] = "3";
    let (ok, log) = cli(&again, dir.path());
    assert!(ok && log.contains("(from step 2)"), "{log}");
    let (ok, log) = cli(
        &["train", "--resume", "run60", "--fps", "30", "--steps", "4"],
        dir.path(),
    );
    assert!(
        !ok && log.contains("trained at 60 frames per second"),
        "{log}"
    );
}

#[test]
fn a_new_run_into_a_folder_holding_a_run_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    small_run(&run, 1);
    std::fs::write(dir.path().join("tiny.toml"), super::TINY).unwrap();
    let before = snapshot(&run);
    let (ok, log) = cli(
        &[
            "train",
            "--scene",
            "tiny.toml",
            "--steps",
            "1",
            "--out",
            "run",
        ],
        dir.path(),
    );
    assert!(!ok && log.contains("already holds a run"), "{log}");
    assert!(snapshot(&run) == before, "the run changed");
}

/// Mesa's Vulkan device-selection layer connects to Wayland at every adapter enumeration;
/// without `XDG_RUNTIME_DIR` libwayland complains on stderr. Headless commands turn the
/// layer off, so training on the GPU backend prints nothing of the kind.
#[test]
fn gpu_training_without_a_desktop_session_prints_no_display_error() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tiny.toml"), super::TINY).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_neural-cloth"))
        .args([
            "train",
            "--scene",
            "tiny.toml",
            "--steps",
            "0",
            "--batch",
            "2",
        ])
        .args([
            "--backend",
            "wgpu",
            "--predrape-secs",
            "0",
            "--no-centre-init",
        ])
        .args(["--out", "gpu"])
        .current_dir(dir.path())
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove("NODEVICE_SELECT")
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&out.stderr);
    // Before the fix this run printed the libwayland error four times on this machine.
    assert!(!log.contains("XDG_RUNTIME_DIR"), "{log}");
    if !out.status.success() {
        eprintln!("no GPU adapter here: the run stopped early: {log}");
    }
}

/// `screenshot` renders offscreen through Vulkan (lavapipe here): without a desktop session it
/// prints nothing about the missing display either.
#[test]
fn screenshot_without_a_desktop_session_prints_no_display_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_neural-cloth"))
        .args(["screenshot", "--width", "64", "--height", "48"])
        .args(["--out", "shot.png"])
        .current_dir(dir.path())
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove("NODEVICE_SELECT")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&out.stderr);
    assert!(!log.contains("XDG_RUNTIME_DIR"), "{log}");
    if out.status.success() {
        assert!(dir.path().join("shot.png").is_file());
    } else {
        eprintln!("no GPU adapter here: the screenshot stopped early: {log}");
    }
}
