//! Runs belong to the project (issue 15): opening a run folder's trained model, a project
//! reopening its run, checkpoint retention with the disk use, the in-app file browser where
//! the desktop has no file dialog, the prompts before quitting or resetting, and every motion
//! visible with its split.

use std::path::Path;
use std::time::Duration;

use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT, Queryable};
use neural_cloth::app::confirm_panel::Confirm;
use neural_cloth::app::file_picker::{DialogMode, desktop_dialog_possible};
use neural_cloth::app::project::ProjectFile;
use neural_cloth::app::{AppOptions, NeuralClothApp, TrainingState};
use neural_cloth::model::{ClothNetConfig, DescriptorConfig};
use neural_cloth::scene::config::GarmentSource;
use neural_cloth::scene::config::SceneConfig;
use neural_cloth::scene::procedural::build_builtin;
use neural_cloth::train::retention::Retention;
use neural_cloth::train::run_dir::garment_fingerprint;
use neural_cloth::train::{RunDir, RunLocation, TrainConfig, TrainEvent, TrainSetup, Trainer};

use super::{TINY, harness_with, options};

/// Trains the app's default network on [`TINY`] for `steps` steps into `run`, with a
/// checkpoint and a validation pass every step.
fn train_tiny_run(run: &Path, steps: u64) {
    let config = SceneConfig::from_toml_str(TINY).expect("tiny scene");
    let scene = build_builtin(&config).expect("tiny scene builds");
    let setup = TrainSetup {
        scene,
        scene_config: config,
        train: TrainConfig {
            batch_size: 2,
            window_secs: 0.2,
            max_steps: Some(steps),
            checkpoint_every: 1,
            validate_every: 1,
            seed: 3,
            ..Default::default()
        },
        model: ClothNetConfig::default(),
        descriptors: DescriptorConfig::default(),
        location: RunLocation::At(run.to_path_buf()),
    };
    let handle = Trainer::spawn(setup, None).expect("trainer starts");
    loop {
        match handle.recv_timeout(Duration::from_secs(300)) {
            Some(TrainEvent::Finished(result)) => {
                result.expect("the tiny run trains");
                return;
            }
            Some(_) => {}
            None => panic!("the trainer went silent"),
        }
    }
}

/// The app with the in-app file browser (no desktop dialog is tried).
fn in_app_harness() -> Harness<'static, NeuralClothApp> {
    harness_with(AppOptions {
        file_dialog: DialogMode::InApp,
        ..options(None)
    })
}

/// Waits for a run being opened, then settles the UI and lets the preview take its weights.
fn settle_run(h: &mut Harness<'static, NeuralClothApp>) {
    assert!(
        h.state_mut().state.wait_for_run(Duration::from_secs(120)),
        "the run opens"
    );
    h.run();
    assert!(
        h.state_mut()
            .state
            .preview
            .wait_until_built(Duration::from_secs(120)),
        "the preview model builds"
    );
    h.run();
}

/// Scrolls the widget labelled `label` into view (the scroll animates), then clicks it.
fn click_scrolled(h: &mut Harness<'static, NeuralClothApp>, label: &str) {
    h.get_by_label(label).scroll_to_me();
    h.run();
    h.get_by_label(label).click();
    h.run();
}

/// Clicks the in-app browser's entry for `name` (folders end in `/`).
fn click_entry(h: &mut Harness<'static, NeuralClothApp>, name: &str) {
    h.get_by_label(name).click();
    h.run();
}

#[test]
fn open_run_through_the_in_app_browser_shows_its_trained_model_and_the_project_reopens_it() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("skirt-run");
    train_tiny_run(&run, 3);
    let steps = RunDir { root: run.clone() }.checkpoint_steps();
    let newest = steps[0];

    let mut h = in_app_harness();
    assert_eq!(h.state().state.preview.describe(), "untrained model");
    // Runs panel > Open run…: the in-app browser opens on the runs folder; go to the run's
    // parent, select the run's folder and open it.
    click_scrolled(&mut h, "Open run…");
    assert!(
        h.state().picker.is_browsing(),
        "the in-app browser opens: {:?}",
        h.state().state.messages
    );
    h.state_mut().picker.browse_to(dir.path());
    h.run();
    click_entry(&mut h, "skirt-run/");
    h.get_by_label("Use this folder").click();
    // The run opens in the background (a spinner animates meanwhile).
    h.step();
    assert!(!h.state().picker.is_browsing());
    settle_run(&mut h);
    let s = &h.state().state;
    assert_eq!(s.training.run_dir.as_deref(), Some(run.as_path()));
    assert_eq!(s.training.progress.step, newest);
    assert!(!s.training.history.train.is_empty(), "the run's curves");
    assert_eq!(s.scene.config.name, "tiny", "the run's own scene");
    assert_eq!(s.preview.describe(), format!("model at step {newest}"));
    assert_eq!(s.runs.recent.paths.first(), Some(&run));
    assert!(matches!(s.training.state(), TrainingState::Finished(Ok(_))));

    // The project records the run; reopened in a fresh app, it shows the trained model again.
    let project = dir.path().join("tiny.toml");
    assert!(h.state_mut().state.save_project(&project));
    let text = std::fs::read_to_string(&project).unwrap();
    assert!(text.contains("run = \"skirt-run\""), "{text}");
    assert!(!h.state().state.has_unsaved_changes());

    let mut again = in_app_harness();
    assert!(again.state_mut().open_project(&project));
    settle_run(&mut again);
    let s = &again.state().state;
    assert_eq!(s.training.run_dir.as_deref(), Some(run.as_path()));
    assert_eq!(s.training.progress.step, newest);
    assert_eq!(s.preview.describe(), format!("model at step {newest}"));
    assert!(
        !s.has_unsaved_changes(),
        "a reopened project has nothing to save"
    );
    again.get_by_label_contains(&format!("{} checkpoints", steps.len()));

    // Retention: keep only the newest checkpoint; the run folder gets the policy and
    // "Prune run now" deletes the others.
    again.state_mut().state.runs.retention = Retention {
        keep_newest: 1,
        keep_best: false,
    };
    again.run();
    assert_eq!(
        RunDir { root: run.clone() }
            .retention()
            .unwrap()
            .keep_newest,
        1,
        "the policy is written into the run folder"
    );
    click_scrolled(&mut again, "Prune run now");
    again.run();
    assert_eq!(
        RunDir { root: run.clone() }.checkpoint_steps(),
        vec![newest]
    );
    again.get_by_label_contains("1 checkpoints");
}

#[test]
fn a_reopened_project_takes_its_runs_retention_and_has_nothing_to_save() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    train_tiny_run(&run, 2);
    let mut h = in_app_harness();
    assert!(h.state_mut().state.open_run(&run, true));
    settle_run(&mut h);
    let project = dir.path().join("p.toml");
    assert!(h.state_mut().state.save_project(&project));
    // The run's policy changes after the project was saved (the app of another project, or
    // a hand edit): the run folder is its one home.
    let policy = Retention {
        keep_newest: 7,
        keep_best: false,
    };
    RunDir { root: run.clone() }.set_retention(policy).unwrap();

    let mut again = in_app_harness();
    assert!(again.state_mut().open_project(&project));
    settle_run(&mut again);
    let s = &again.state().state;
    assert_eq!(s.runs.retention, policy, "the run's own policy is shown");
    assert!(
        !s.has_unsaved_changes(),
        "a freshly opened project has nothing to save"
    );
}

#[test]
fn a_project_shows_a_runs_weights_only_on_the_garment_skin_it_was_trained_on() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    train_tiny_run(&run, 2);
    // The run's garment as a file: the same mesh, but loaded it gets other skin weights (the
    // app smooths a file's weights 3 times, the built-in t-shirt's 5 times).
    let scene = build_builtin(&SceneConfig::from_toml_str(TINY).unwrap()).unwrap();
    let garment = dir.path().join("garment.obj");
    let text = neural_cloth::io::export::obj_seq::obj_text(
        &scene.garment.mesh.positions,
        &scene.garment.mesh.faces,
        None,
        "garment",
    );
    std::fs::write(&garment, text).unwrap();
    let project = dir.path().join("p.toml");
    let mut project_scene = SceneConfig::default_scene();
    project_scene.garment = GarmentSource::File {
        path: garment.clone(),
        units: None,
        up: neural_cloth::scene::UpAxis::Auto,
        smoothing_passes: None,
    };
    ProjectFile {
        scene: project_scene,
        run: Some(run.clone()),
        ..Default::default()
    }
    .save(&project)
    .unwrap();

    let mut h = in_app_harness();
    assert!(h.state_mut().open_project(&project));
    assert!(h.state_mut().state.wait_for_run(Duration::from_secs(120)));
    h.run();
    let s = &h.state().state;
    let shown = s.scene.garment.as_ref().unwrap();
    assert_eq!(
        garment_fingerprint(shown),
        garment_fingerprint(&scene.garment),
        "the same mesh"
    );
    assert!(
        !s.preview.describe().starts_with("model at step") && s.training.run_dir.is_none(),
        "the weights are not shown: {} {:?}",
        s.preview.describe(),
        s.messages
    );
    assert!(
        s.messages
            .iter()
            .any(|m| m.text.contains("skin weights changed")),
        "{:?}",
        s.messages
    );
}

#[test]
fn without_a_desktop_dialog_the_in_app_browser_saves_and_opens_projects() {
    let dir = tempfile::tempdir().unwrap();
    // As the app opens by itself; this machine has no desktop portal, so Auto falls back.
    let mode = if desktop_dialog_possible() {
        DialogMode::InApp
    } else {
        DialogMode::Auto
    };
    let mut h = harness_with(AppOptions {
        file_dialog: mode,
        ..options(None)
    });
    h.state_mut().state.set_w(1.5);
    h.get_by_label("File").click();
    h.run();
    h.get_by_label("Save project").click();
    h.run();
    assert!(h.state().picker.is_browsing(), "Save project asks where");
    h.state_mut().picker.browse_to(dir.path());
    h.run();
    h.get_by_label("Save").click();
    h.run();
    let saved = dir.path().join("project.toml");
    assert!(saved.is_file(), "the browser's default name is used");
    assert_eq!(
        h.state().state.project_path.as_deref(),
        Some(saved.as_path())
    );
    // Change w, then open the saved project through the browser: w comes back.
    h.state_mut().state.set_w(0.25);
    assert!(h.state().state.has_unsaved_changes());
    h.get_by_label("File").click();
    h.run();
    h.get_by_label("Open project…").click();
    h.run();
    assert!(h.state().picker.is_browsing());
    click_entry(&mut h, "project.toml");
    h.get_by_label("Open").click();
    h.run();
    assert_eq!(h.state().state.w, 1.5);
    assert!(!h.state().picker.is_browsing());
}

#[test]
fn the_file_menu_path_field_keeps_the_menu_open() {
    let mut h = in_app_harness();
    h.get_by_label("File").click();
    h.run();
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, "Project path:")
        .click();
    h.run();
    // The menu is still open: its rows are still there.
    h.get_by_label("Run folder:");
    h.get_by_label("Quit");
}

#[test]
fn quitting_or_resetting_with_unsaved_work_asks_first() {
    // Nothing changed: Quit closes at once.
    let mut h = in_app_harness();
    h.get_by_label("File").click();
    h.run();
    h.get_by_label("Quit").click();
    h.run();
    assert!(h.state().quit_confirmed && h.state().confirm.is_none());

    // A changed setting: Quit asks; Cancel keeps the app; Quit without saving goes.
    let mut h = in_app_harness();
    h.state_mut().state.set_w(0.3);
    h.get_by_label("File").click();
    h.run();
    h.get_by_label("Quit").click();
    h.run();
    assert_eq!(h.state().confirm, Some(Confirm::Quit));
    h.get_by_label("Quit neural-cloth?");
    h.get_by_label("Cancel").click();
    h.run();
    assert!(h.state().confirm.is_none() && !h.state().quit_confirmed);
    h.get_by_label("File").click();
    h.run();
    h.get_by_label("Quit").click();
    h.run();
    h.get_by_label("Quit without saving").click();
    h.run();
    assert!(h.state().quit_confirmed);

    // Reset with unsaved work asks too; confirming resets.
    let mut h = in_app_harness();
    h.state_mut().state.set_w(0.3);
    click_scrolled(&mut h, "Reset");
    h.run();
    assert_eq!(h.state().confirm, Some(Confirm::Reset));
    h.get_by_label("Reset the training?");
    h.get_by_label("Reset training").click();
    h.run();
    assert!(h.state().confirm.is_none());
}

#[test]
fn every_motion_is_listed_with_its_split() {
    let mut h = in_app_harness();
    let names: Vec<(String, String)> = {
        let s = &h.state().state;
        s.scene
            .avatar
            .motions
            .iter()
            .zip(&s.scene.splits)
            .map(|(m, split)| {
                let split = neural_cloth::app::motions_panel::split_name(*split).to_string();
                (m.name.clone(), split)
            })
            .collect()
    };
    assert!(names.len() >= 6, "{names:?}");
    assert!(names.iter().any(|(_, s)| s == "validation"));
    assert!(names.iter().any(|(_, s)| s == "test"));
    h.run();
    let training_top = h.get_by_label("Training").rect().min.y;
    for (name, split) in &names {
        let prefix = format!("{name} (");
        let text = |n: &egui_kittest::Node<'_>| {
            let node = n.accesskit_node();
            node.label().or_else(|| node.value()).unwrap_or_default()
        };
        let row = h
            .get_all_by_label_contains(&prefix)
            .find(|n| text(n).starts_with(&prefix))
            .expect("the motion's row");
        let label = text(&row);
        assert!(label.ends_with(&format!("· {split}")), "{label}");
        // Laid out in full above the next section, not hidden in a short scrolled list.
        assert!(row.rect().max.y <= training_top, "{label} is hidden");
    }
}
