//! UI tests of the authoring app: the whole app (panels + 3D viewport) rendered offscreen by
//! egui_kittest on wgpu (Mesa lavapipe in CI), PNG snapshots under `tests/snapshots/`, and
//! state assertions after driving the UI (buttons, the w slider, file loading).
//!
//! Update snapshots with `UPDATE_SNAPSHOTS=1 cargo test --release --test app`.
//!
//! Layout: this file holds the shared helpers and most tests; the export dialog's tests live in
//! `app/export_dialog.rs`, start-up and the status bar in `app/status.rs`, the readable metric
//! curves in `app/curves.rs`, "Fit garment" in `app/fit.rs`, the joint map field in
//! `app/joint_map.rs`, runs in `app/runs.rs`, project files and the scene description in
//! `app/projects.rs` (one test binary).
//! The memory-leak tests are in `tests/leak.rs`, a binary of their own so that no other test
//! shares their process's resident memory.

#[path = "app/curves.rs"]
mod curves;
#[path = "app/export_dialog.rs"]
mod export_dialog;
#[path = "app/fit.rs"]
mod fit;
#[path = "app/joint_map.rs"]
mod joint_map;
#[path = "app/projects.rs"]
mod projects;
#[path = "app/runs.rs"]
mod runs;
#[path = "app/status.rs"]
mod status;
#[path = "common/tiny_scene.rs"]
mod tiny_scene;
#[path = "app/up_axis.rs"]
mod up_axis;
use tiny_scene::TINY;

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use egui_kittest::kittest::Queryable;
use egui_kittest::{Harness, SnapshotOptions};
use neural_cloth::app::LoadKind;
use neural_cloth::app::metrics::MetricRecord;
use neural_cloth::app::{
    AppError, AppOptions, NeuralClothApp, TrainerLauncher, TrainingRequest, TrainingState,
};
use neural_cloth::model::ModelArtifact;
use neural_cloth::physics::FabricParams;
use neural_cloth::train::TrainError;
use neural_cloth::train::handle::{LoopConfig, Session, TrainerHandle};
use neural_cloth::train::metrics::MetricHistory;

/// Window size of every snapshot, in points (pixels at 1 pixel per point).
const SIZE: egui::Vec2 = egui::vec2(960.0, 600.0);
/// Time shown on the timeline in snapshots, seconds.
const SHOWN_TIME_SECS: f32 = 1.3;

fn assets() -> PathBuf {
    PathBuf::from("../shared/assets")
}

/// Tolerates tiny rasteriser differences (e.g. another CPU running lavapipe).
fn snapshot_options() -> SnapshotOptions {
    SnapshotOptions::new()
        .threshold(1.5)
        .max_failed_pixels(1500)
}

fn options(launcher: Option<Box<dyn TrainerLauncher>>) -> AppOptions {
    let store = std::env::temp_dir()
        .join(format!("neural-cloth-app-test-{}", std::process::id()))
        .join("recent.json");
    AppOptions {
        launcher,
        recent_store: Some(store),
        ..Default::default()
    }
}

/// The app on the default scene, paused at [`SHOWN_TIME_SECS`].
fn harness(launcher: Option<Box<dyn TrainerLauncher>>) -> Harness<'static, NeuralClothApp> {
    harness_with(options(launcher))
}

/// [`harness`] with the given start-up options.
fn harness_with(options: AppOptions) -> Harness<'static, NeuralClothApp> {
    let mut harness = Harness::builder()
        .with_size(SIZE)
        .with_pixels_per_point(1.0)
        .wgpu()
        .build_eframe(move |cc| {
            let mut app = NeuralClothApp::new(&cc.egui_ctx, cc.wgpu_render_state.as_ref(), options)
                .expect("the default scene builds");
            app.state.playback.playing = false;
            let duration = app
                .state
                .current_motion()
                .map_or(0.0, |m| m.duration_secs());
            app.state.playback.seek(SHOWN_TIME_SECS, duration);
            app
        });
    harness.run();
    wait_for_preview(&mut harness);
    harness
}

/// Lets the preview model finish building in the background, then settles the UI.
fn wait_for_preview(h: &mut Harness<'static, NeuralClothApp>) {
    let built = h
        .state_mut()
        .state
        .preview
        .wait_until_built(Duration::from_secs(120));
    assert!(built, "the preview model builds");
    h.run();
}

/// The viewport's pixels cut out of a full render.
fn viewport_image(harness: &mut Harness<'static, NeuralClothApp>) -> image::RgbaImage {
    let image = harness.render().expect("render");
    let rect = harness.state().viewport.rect().expect("viewport laid out");
    let (x, y) = (rect.min.x.max(0.0) as u32, rect.min.y.max(0.0) as u32);
    let w = (rect.width() as u32).min(image.width() - x);
    let h = (rect.height() as u32).min(image.height() - y);
    image::imageops::crop_imm(&image, x, y, w, h).to_image()
}

/// The w slider (its value box carries the same label).
fn w_slider<'a>(h: &'a Harness<'static, NeuralClothApp>) -> egui_kittest::Node<'a> {
    h.get_by_role_and_label(egui::accesskit::Role::Slider, "w (dynamics)")
}

/// Scrolls the button labelled `label` into view and clicks it.
fn click(h: &mut Harness<'static, NeuralClothApp>, label: &str) {
    h.step();
    h.get_by_label(label).scroll_to_me();
    h.step();
    h.get_by_label(label).click();
}

fn differing_pixels(a: &image::RgbaImage, b: &image::RgbaImage) -> usize {
    a.pixels()
        .zip(b.pixels())
        .filter(|(p, q)| p.0.iter().zip(q.0).any(|(x, y)| x.abs_diff(y) > 8))
        .count()
}

#[test]
fn default_scene_at_start() {
    let mut h = harness(None);
    let app = h.state();
    assert!(
        app.viewport.has_gpu(),
        "kittest's wgpu render state reaches the viewport"
    );
    assert!(
        app.state.scene.garment.is_some(),
        "the default scene has a garment"
    );
    assert!(
        !app.state.scene.avatar.motions.is_empty(),
        "the default scene has motions"
    );
    assert_eq!(*app.state.training.state(), TrainingState::Idle);
    h.get_by_label("Train");
    w_slider(&h);
    let image = viewport_image(&mut h);
    // The viewport shows more than the background: body and garment cover a good share.
    let background = image.get_pixel(2, 2).0;
    let covered = image
        .pixels()
        .filter(|p| p.0.iter().zip(background).any(|(a, b)| a.abs_diff(b) > 30))
        .count();
    assert!(
        covered > (image.width() * image.height()) as usize / 20,
        "only {covered} pixels differ from the background"
    );
    h.snapshot_options("default_scene", &snapshot_options());
}

fn synthetic_history() -> MetricHistory {
    let mut history = MetricHistory::default();
    for step in 1..=300u64 {
        let s = step as f64;
        let record = MetricRecord {
            step,
            wall_secs: s * 0.12,
            loss: 5.0 / (1.0 + s / 20.0),
            strain: 0.02 + 0.3 * (-s / 60.0).exp() + 0.004 * (s * 0.7).sin(),
            bending: 0.05 + 0.2 * (-s / 90.0).exp(),
            collision_pct: 25.0 * (-s / 40.0).exp() + 0.5,
            gravity: -0.4 - 0.1 * (-s / 50.0).exp(),
            inertia: 0.01 * (-s / 30.0).exp(),
            ..Default::default()
        };
        history.train.push(record);
        if step % 50 == 0 {
            history.validation.push(MetricRecord {
                strain: record.strain * 1.2,
                collision_pct: record.collision_pct * 1.3,
                ..record
            });
        }
    }
    history
}

#[test]
fn curve_panel_with_metrics() {
    let mut h = harness(None);
    h.state_mut().state.training.history = synthetic_history();
    h.run();
    h.snapshot_options("metric_curves", &snapshot_options());
    // Switching the x axis to wall-clock time through the UI changes what is plotted.
    let before = h.render().expect("render");
    h.get_by_label("wall-clock (s)").click();
    h.run();
    assert_eq!(
        h.state().state.curves.x_axis,
        neural_cloth::app::metrics::XAxis::WallClock
    );
    let after = h.render().expect("render");
    assert!(differing_pixels(&before, &after) > 100);
}

#[test]
fn w_slider_changes_the_shown_garment() {
    let mut h = harness(None);
    // A motion with strong dynamics, chosen in the motion list.
    h.get_by_label_contains("run (").scroll_to_me();
    h.step();
    h.get_by_label_contains("run (").click();
    h.run();
    let shown = h.state().state.current_motion().map(|m| m.name.clone());
    assert_eq!(shown.as_deref(), Some("run"));
    let duration = h
        .state()
        .state
        .current_motion()
        .map_or(0.0, |m| m.duration_secs());
    h.state_mut().state.playback.seek(SHOWN_TIME_SECS, duration);
    w_slider(&h).set_value_accesskit(0.0);
    h.run();
    assert_eq!(h.state().state.w, 0.0);
    let at0 = viewport_image(&mut h);
    let garment0 = h
        .state_mut()
        .state
        .scene_frame()
        .0
        .garment
        .clone()
        .expect("garment");
    w_slider(&h).set_value_accesskit(2.0);
    h.run();
    assert_eq!(h.state().state.w, 2.0);
    let at2 = viewport_image(&mut h);
    let garment2 = h
        .state_mut()
        .state
        .scene_frame()
        .0
        .garment
        .clone()
        .expect("garment");
    assert!(
        h.state().state.preview.is_active(),
        "the preview model runs: {}",
        h.state().state.preview.describe()
    );
    let moved = garment0
        .positions
        .iter()
        .zip(&garment2.positions)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0f32, f32::max);
    assert!(
        moved > 0.005,
        "w = 0 and w = 2 give the same garment (max difference {moved} m)"
    );
    if let Some(dir) = std::env::var_os("NEURAL_CLOTH_DEBUG_DIR") {
        let _ = at0.save(Path::new(&dir).join("w0.png"));
        let _ = at2.save(Path::new(&dir).join("w2.png"));
    }
    let changed = differing_pixels(&at0, &at2);
    assert!(
        changed > 200,
        "only {changed} viewport pixels differ between w = 0 and w = 2"
    );
    egui_kittest::image_snapshot_options(&at0, "viewport_w0", &snapshot_options());
    egui_kittest::image_snapshot_options(&at2, "viewport_w2", &snapshot_options());
}

#[test]
fn broken_garment_file_shows_an_error() {
    // A fixed path, since the snapshot shows it in the error message.
    let dir = PathBuf::from("/tmp/neural-cloth-app-test");
    std::fs::create_dir_all(&dir).expect("temp dir");
    let broken = dir.join("broken_garment.obj");
    std::fs::write(
        &broken,
        "v 0 0 0\nv 1 0 0\nf 1 2 x\nthis is not an OBJ file\n",
    )
    .expect("write");
    let mut h = harness(None);
    let before = h
        .state()
        .state
        .scene
        .garment
        .as_ref()
        .map(|g| g.name.clone());
    h.state_mut().state.typed.garment = broken.display().to_string();
    h.run();
    click(&mut h, "Load garment");
    h.run();
    let app = h.state();
    let error = app
        .state
        .last_error()
        .expect("an error message is shown")
        .to_string();
    assert!(
        error.ends_with("broken_garment.obj"),
        "the error names the file last: {error}"
    );
    assert_eq!(
        app.state.scene.garment.as_ref().map(|g| g.name.clone()),
        before,
        "the scene is unchanged"
    );
    assert!(
        h.get_all_by_label_contains("broken_garment.obj").count() >= 1,
        "the error is on screen"
    );
    h.snapshot_options("load_error", &snapshot_options());
}

#[test]
fn loading_through_the_dialog_path_updates_the_scene() {
    let mut h = harness(None);
    let motions_before = h.state().state.scene.avatar.motions.len();
    let walk = assets().join("motions/cmu_02_01_walk.bvh");
    // `load_file` is what the Browse… dialog and the typed-path field call.
    assert!(
        h.state_mut().state.load_file(LoadKind::Motion, &walk),
        "{:?}",
        h.state().state.last_error()
    );
    h.run();
    let app = h.state();
    assert_eq!(app.state.scene.avatar.motions.len(), motions_before + 1);
    assert_eq!(
        app.state.playback.motion, motions_before,
        "the new motion is selected"
    );
    assert!(
        app.state
            .current_motion()
            .is_some_and(|m| m.duration_secs() > 1.0)
    );
    // An avatar file replaces the avatar.
    let cesium = assets().join("avatars/CesiumMan.glb");
    assert!(
        h.state_mut().state.load_file(LoadKind::Avatar, &cesium),
        "{:?}",
        h.state().state.last_error()
    );
    h.run();
    assert_eq!(h.state().state.scene.avatar.name, "CesiumMan");
    // A missing file is an error, not a panic.
    assert!(!h.state_mut().state.load_file(
        LoadKind::Garment,
        Path::new("../shared/assets/garments/missing.obj")
    ));
    assert!(
        h.state()
            .state
            .last_error()
            .is_some_and(|e| e.ends_with("missing.obj"))
    );
}

#[test]
fn project_save_and_open_round_trip() {
    let dir = tempfile::tempdir().expect("temp dir");
    let file = dir.path().join("setup.toml");
    let mut h = harness(None);
    {
        let s = &mut h.state_mut().state;
        s.apply_preset("denim");
        s.set_w(1.7);
        s.train_config.window_secs = 1.25;
        s.draw.wireframe = true;
        assert!(s.save_project(&file), "{:?}", s.last_error());
        s.apply_preset("silk");
        s.set_w(0.2);
        s.train_config.window_secs = 0.5;
        s.draw.wireframe = false;
    }
    assert!(h.state_mut().open_project(&file));
    let s = &h.state().state;
    assert_eq!(*s.fabric(), FabricParams::preset("denim").expect("preset"));
    assert_eq!(
        (s.w, s.train_config.window_secs, s.draw.wireframe),
        (1.7, 1.25, true)
    );
    assert_eq!(
        s.recent.paths.first().map(|p| p.ends_with("setup.toml")),
        Some(true)
    );
}

/// A training session that produces decaying metrics quickly, without a network.
struct FakeSession {
    steps: u64,
}

impl Session for FakeSession {
    fn step(&mut self) -> Result<MetricRecord, TrainError> {
        self.steps += 1;
        std::thread::sleep(Duration::from_millis(2));
        let s = self.steps as f64;
        Ok(MetricRecord {
            loss: 1.0 / s,
            strain: 0.1 / s,
            bending: 0.05,
            collision_pct: 10.0 / s,
            gravity: -0.3,
            inertia: 0.01,
            ..Default::default()
        })
    }
    fn validate(&mut self) -> Result<MetricRecord, TrainError> {
        self.step()
    }
    fn weights_finite(&self) -> bool {
        true
    }
    fn snapshot(&self) -> Result<ModelArtifact, TrainError> {
        Err(TrainError::Data("no network in the fake session".into()))
    }
    fn checkpoint(&mut self, step: u64, _history: &MetricHistory) -> Result<PathBuf, TrainError> {
        Ok(PathBuf::from(format!("fake-checkpoint-{step}")))
    }
    fn restore_last_checkpoint(&mut self) -> Result<u64, TrainError> {
        Err(TrainError::NoCheckpointYet)
    }
    fn learning_rate(&self) -> f64 {
        1e-3
    }
    fn set_learning_rate(&mut self, _lr: f64) {}
    fn set_fabric(&mut self, _fabric: FabricParams) -> Result<(), TrainError> {
        Ok(())
    }
    fn set_window(&mut self, _window_secs: f32) -> Result<(), TrainError> {
        Ok(())
    }
}

/// Starts [`FakeSession`]s and records the requests it got.
struct FakeLauncher {
    requests: Arc<std::sync::Mutex<Vec<TrainingRequest>>>,
}

impl TrainerLauncher for FakeLauncher {
    fn launch(
        &mut self,
        request: TrainingRequest,
        notify: Arc<dyn Fn() + Send + Sync>,
    ) -> Result<TrainerHandle, AppError> {
        let config = LoopConfig {
            run_dir: request.run_dir.clone(),
            start_step: 0,
            history: MetricHistory::default(),
            max_steps: None,
            max_secs: None,
            validate_every: 10,
            snapshot_every: 10,
            checkpoint_every: 1000,
            max_rollbacks: 3,
            dead_limit_pct: 90.0,
            lr_decay: (0.0, 1.0),
            warmup_steps: 0,
            warnings: Vec::new(),
        };
        if let Ok(mut r) = self.requests.lock() {
            r.push(request);
        }
        TrainerHandle::spawn_session(FakeSession { steps: 0 }, config, Some(notify)).map_err(
            |source| AppError::Thread {
                name: "fake trainer".into(),
                source,
            },
        )
    }
}

/// Steps the UI until `done` holds (a generous bound; this is not a timing assertion).
fn step_until(
    h: &mut Harness<'static, NeuralClothApp>,
    what: &str,
    done: impl Fn(&NeuralClothApp) -> bool,
) {
    let start = Instant::now();
    while !done(h.state()) {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "timed out waiting for {what}"
        );
        std::thread::sleep(Duration::from_millis(5));
        h.step();
    }
}

#[test]
fn train_pause_resume_stop_through_the_buttons() {
    let requests = Arc::new(std::sync::Mutex::new(Vec::new()));
    let mut h = harness(Some(Box::new(FakeLauncher {
        requests: requests.clone(),
    })));
    click(&mut h, "Train");
    h.step();
    assert_eq!(*h.state().state.training.state(), TrainingState::Running);
    let request_fps = requests
        .lock()
        .map(|r| r.first().map(|q| q.scene.training_fps))
        .ok()
        .flatten();
    assert_eq!(
        request_fps,
        Some(h.state().state.scene.config.training_fps),
        "the launcher got the app's settings"
    );
    step_until(&mut h, "training metrics", |app| {
        app.state.training.history.train.len() >= 5
            && !app.state.training.history.validation.is_empty()
    });
    assert!(h.state().state.training.progress.step >= 5);
    click(&mut h, "Pause");
    h.step();
    assert_eq!(*h.state().state.training.state(), TrainingState::Paused);
    click(&mut h, "Resume");
    h.step();
    assert_eq!(*h.state().state.training.state(), TrainingState::Running);
    click(&mut h, "Stop");
    h.step();
    step_until(&mut h, "the run to finish", |app| {
        matches!(app.state.training.state(), TrainingState::Finished(_))
    });
    assert!(
        matches!(
            h.state().state.training.state(),
            TrainingState::Finished(Ok(_))
        ),
        "{:?}",
        h.state().state.training.state()
    );
    assert!(h.state().state.training.last_checkpoint.is_some());
    click(&mut h, "Reset");
    h.run();
    // The run is in no saved project: Reset asks first.
    h.get_by_label("Reset training").click();
    h.run();
    assert_eq!(*h.state().state.training.state(), TrainingState::Idle);
    assert!(h.state().state.training.history.train.is_empty());
}

#[test]
fn a_run_on_a_scene_changed_since_says_so_issue_15() {
    // Issue 15: after loading another garment the preview said "untrained model" while the
    // step counter ran, and nothing said what was training.
    let mut h = harness(Some(Box::new(FakeLauncher {
        requests: Arc::new(std::sync::Mutex::new(Vec::new())),
    })));
    let says = "the run trains the scene as it was when Train was pressed; the preview shows \
                the changed scene, untrained (Reset, then Train, to train it)";
    click(&mut h, "Train");
    h.step();
    assert_eq!(*h.state().state.training.state(), TrainingState::Running);
    h.run_steps(2);
    assert!(
        h.query_by_label(says).is_none(),
        "the scene has not changed"
    );
    // Another set of effects changes the scene the network is built for.
    let state = &mut h.state_mut().state;
    state.scene.config.effects.bending = !state.scene.config.effects.bending;
    state.effects_changed();
    assert!(h.state().state.trains_another_scene());
    h.run_steps(2);
    h.get_by_label(says);
    // Stopped, the run no longer trains anything.
    click(&mut h, "Stop");
    step_until(&mut h, "the run to finish", |app| {
        matches!(app.state.training.state(), TrainingState::Finished(_))
    });
    h.run_steps(2);
    assert!(h.query_by_label(says).is_none());
}

#[test]
fn without_a_trainer_train_reports_an_error() {
    let mut h = harness(None);
    click(&mut h, "Train");
    h.run();
    assert_eq!(*h.state().state.training.state(), TrainingState::Idle);
    assert!(
        h.state()
            .state
            .last_error()
            .is_some_and(|e| e.contains("no trainer"))
    );
}

/// The "Check against simulation" button of the Cost panel.
fn check_button_disabled(h: &mut Harness<'static, NeuralClothApp>) -> bool {
    use egui_kittest::kittest::NodeT;
    let label = "Check against simulation";
    let button = egui::accesskit::Role::Button;
    h.get_by_role_and_label(button, label).scroll_to_me();
    h.run();
    h.get_by_role_and_label(button, label)
        .accesskit_node()
        .is_disabled()
}

#[test]
fn check_against_simulation_needs_a_trained_run() {
    let mut h = harness(None);
    h.get_by_label("Cost").scroll_to_me();
    h.run();
    h.get_by_label("Cost").click_accesskit();
    h.run();
    assert!(check_button_disabled(&mut h), "disabled without a run");
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("run.json"), "{}").unwrap();
    std::fs::write(dir.path().join("latest.json"), "{\"step\": 1}").unwrap();
    h.state_mut().state.training.run_dir = Some(dir.path().to_path_buf());
    h.run();
    assert!(!check_button_disabled(&mut h), "enabled with a checkpoint");
}

#[test]
fn a_check_result_shows_every_row_compare_prints() {
    use neural_cloth::train::compare::{
        CompareOptions, CompareReport, HemComparison, HemPair, MetricPair, MotionComparison,
        MotionMeasures, ReferenceInfo, RigidSplit,
    };
    let hem = HemPair {
        network_m: 0.2,
        simulator_m: 0.21,
        network_static_m: 0.17,
        simulator_static_m: 0.168,
    };
    let measures = MotionMeasures {
        frames: 3,
        rigid: Some(RigidSplit::default()),
        hem: Some(HemComparison {
            vertices: 10,
            still: Some(hem),
            moving: Some(hem),
        }),
        ..Default::default()
    };
    let motion = MotionComparison {
        name: "spin".into(),
        measures,
        metrics: MetricPair::default(),
        objective: Default::default(),
        reference: ReferenceInfo {
            path: PathBuf::from("spin.pc2"),
            cached: true,
            simulate_secs: 0.0,
        },
    };
    let expected: Vec<&str> = measures
        .rows()
        .iter()
        .map(|r| r.label)
        .chain(motion.metric_rows().iter().map(|r| r.label))
        .collect();
    let mut h = harness(None);
    h.get_by_label("Cost").scroll_to_me();
    h.run();
    h.get_by_label("Cost").click_accesskit();
    h.state_mut().cost.check.job.result = Some(Ok(CompareReport {
        run: PathBuf::from("run"),
        step: 1,
        garment: "skirt".into(),
        vertices: 3,
        fps: 30.0,
        below_hips: true,
        options: CompareOptions::default(),
        motions: vec![motion],
    }));
    h.run();
    for label in [
        "distance after rigid fit, mm",
        "hem radius sim static, m",
        "training objective, J",
    ] {
        assert!(
            expected.contains(&label),
            "{label} is one of compare's rows"
        );
    }
    for label in expected {
        let shown = h.query_all_by_label(label).next().is_some();
        assert!(shown, "the app shows '{label}'");
    }
}
