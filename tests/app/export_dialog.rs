//! The export dialog: USD and the presets on offer, the frame count and size shown before
//! writing, the request handed to the exporter, progress, and errors that leave the app
//! running.

use std::sync::Mutex;

use egui_kittest::kittest::Queryable;
use neural_cloth::app::export::{ExportFormat, ExportRequest, Exporter};
use neural_cloth::app::{AppError, NeuralClothApp};
use neural_cloth::bake::{BakeError, Preset};
use neural_cloth::io::export::ExportError;

use super::{harness_with, options};

type H = egui_kittest::Harness<'static, NeuralClothApp>;

/// The app with a recording exporter.
fn recording_app() -> (H, std::sync::Arc<Recorder>) {
    let recorder = std::sync::Arc::new(Recorder::default());
    let h = harness_with(neural_cloth::app::AppOptions {
        exporter: Some(Box::new(Shared(recorder.clone()))),
        ..options(None)
    });
    (h, recorder)
}

/// Steps until the export's result is in (or fails the test after 30 s).
fn wait_for_result(h: &mut H) {
    let start = std::time::Instant::now();
    while h.state().export.last_result.is_none() {
        assert!(start.elapsed().as_secs() < 30, "the export finishes");
        h.step();
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    h.run();
}

/// A fresh empty folder for this test's files.
fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("nc-export-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp folder");
    dir
}

/// Records the requests it gets; fails the ones whose path contains "fail".
#[derive(Default)]
struct Recorder {
    requests: Mutex<Vec<(ExportFormat, Option<Preset>, String)>>,
    /// Motion, body and rest-pose OBJ of each request.
    extras: Mutex<Vec<(usize, bool, bool)>>,
}

/// The recorder shared between the app and the test.
struct Shared(std::sync::Arc<Recorder>);

impl Exporter for Shared {
    fn export(
        &self,
        request: ExportRequest,
        progress: &mut dyn FnMut(usize, usize) -> bool,
    ) -> Result<String, AppError> {
        let path = request.path.display().to_string();
        if let Ok(mut r) = self.0.requests.lock() {
            r.push((request.format, request.preset, path.clone()));
        }
        if let Ok(mut r) = self.0.extras.lock() {
            r.push((request.motion, request.include_body, request.rest_obj));
        }
        for k in 1..=3 {
            if !progress(k, 3) {
                return Err(BakeError::Cancelled.into());
            }
        }
        match path.contains("fail") {
            true => Err(ExportError::Format {
                reason: "output folder does not exist".into(),
                path: request.path.clone(),
            }
            .into()),
            false => Ok(format!("wrote 3 frames to {path}")),
        }
    }
}

/// The shown values of every combo box labelled `label` (the Fabric panel has a "preset" too).
fn combo_values(h: &egui_kittest::Harness<'static, NeuralClothApp>, label: &str) -> Vec<String> {
    use egui_kittest::kittest::NodeT;
    h.query_all_by_role_and_label(egui::accesskit::Role::ComboBox, label)
        .filter_map(|n| n.accesskit_node().value())
        .collect()
}

#[test]
fn the_dialog_offers_usd_and_presets_and_reports_the_result() {
    let recorder = std::sync::Arc::new(Recorder::default());
    let mut h = harness_with(neural_cloth::app::AppOptions {
        exporter: Some(Box::new(Shared(recorder.clone()))),
        ..options(None)
    });
    {
        let export = &mut h.state_mut().state.export;
        export.open = true;
        export.format = ExportFormat::Usd;
        export.path = "walk.usda".into();
        export.preset = Some(Preset::Unreal);
    }
    h.run();
    h.get_by_label("Export baked sequence");
    assert!(combo_values(&h, "format").contains(&"USD point cache (.usda)".to_string()));
    assert!(
        combo_values(&h, "preset")
            .iter()
            .any(|v| v.starts_with("Unreal (Z up, cm")),
        "{:?}",
        combo_values(&h, "preset")
    );
    // The frame count and size are shown before anything is written.
    h.get_by_label_contains("frames, about");
    h.get_by_label("Export").click();
    let start = std::time::Instant::now();
    while h.state().export.last_result.is_none() {
        assert!(start.elapsed().as_secs() < 30, "the export finishes");
        h.step();
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    h.run();
    assert_eq!(
        h.state()
            .export
            .last_result
            .as_ref()
            .and_then(|r| r.as_ref().ok())
            .map(String::as_str),
        Some("wrote 3 frames to walk.usda")
    );
    // Shown in the dialog and in the status bar.
    assert!(h.query_all_by_label("wrote 3 frames to walk.usda").count() >= 1);

    // glTF takes no preset: the request carries none, and a failure is shown, not fatal.
    {
        let export = &mut h.state_mut().state.export;
        export.format = ExportFormat::Glb;
        export.path = "fail/walk.glb".into();
    }
    h.run();
    h.get_by_label_contains("glTF is always Y up");
    h.get_by_label("Export").click();
    let start = std::time::Instant::now();
    while h
        .state()
        .export
        .last_result
        .as_ref()
        .is_none_or(|r| r.is_ok())
    {
        assert!(start.elapsed().as_secs() < 30, "the export finishes");
        h.step();
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    h.run();
    assert!(
        h.query_all_by_label_contains("output folder does not exist: fail/walk.glb")
            .count()
            >= 1
    );
    let requests = recorder.requests.lock().unwrap().clone();
    assert_eq!(
        requests,
        vec![
            (ExportFormat::Usd, Some(Preset::Unreal), "walk.usda".into()),
            (ExportFormat::Glb, None, "fail/walk.glb".into()),
        ]
    );
}

#[test]
fn export_extension_follows_the_format_and_a_typed_extension_picks_the_format() {
    let (mut h, _) = recording_app();
    h.state_mut().state.export.open = true;
    h.run();
    assert_eq!(h.state().state.export.path, "export/garment.glb");
    // Choose PC2 in the format menu: the file name follows.
    h.get_by_role_and_label(egui::accesskit::Role::ComboBox, "format")
        .click();
    h.run();
    h.get_by_label("PC2 point cache").click();
    h.run();
    assert_eq!(h.state().state.export.format, ExportFormat::Pc2);
    assert_eq!(h.state().state.export.path, "export/garment.pc2");
    // The OBJ sequence is a folder: no extension.
    h.get_by_role_and_label(egui::accesskit::Role::ComboBox, "format")
        .click();
    h.run();
    h.get_by_label("OBJ sequence").click();
    h.run();
    assert_eq!(h.state().state.export.path, "export/garment");
    // Typing a name with another format's extension selects that format.
    h.state_mut().state.export.path.clear();
    h.run();
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, "path")
        .click();
    h.run();
    h.get_by_role_and_label(egui::accesskit::Role::TextInput, "path")
        .type_text("walk.mdd");
    h.run();
    assert_eq!(h.state().state.export.path, "walk.mdd");
    assert_eq!(h.state().state.export.format, ExportFormat::Mdd);
}

#[test]
fn export_over_an_existing_file_asks_first() {
    let (mut h, recorder) = recording_app();
    let dir = scratch("overwrite");
    let existing = dir.join("walk.pc2");
    std::fs::write(&existing, b"a good cache").expect("write");
    {
        let export = &mut h.state_mut().state.export;
        export.open = true;
        export.format = ExportFormat::Pc2;
        export.path = existing.display().to_string();
    }
    h.run();
    h.get_by_label_contains("(exists)");
    h.get_by_label("Export").click();
    h.run();
    h.get_by_label_contains("already exists. Overwrite?");
    assert!(recorder.requests.lock().unwrap().is_empty(), "nothing yet");
    // Keeping the file withdraws the export.
    h.get_by_label("Keep the existing files").click();
    h.run();
    assert!(h.query_by_label_contains("already exists").is_none());
    assert!(recorder.requests.lock().unwrap().is_empty());
    assert_eq!(std::fs::read(&existing).unwrap(), b"a good cache");
    // Asked again, and this time overwritten.
    h.get_by_label("Export").click();
    h.run();
    h.get_by_label("Overwrite").click();
    wait_for_result(&mut h);
    assert_eq!(recorder.requests.lock().unwrap().len(), 1);
    // A new name is written without a question.
    h.state_mut().state.export.path = dir.join("new.pc2").display().to_string();
    h.state_mut().export.last_result = None;
    h.run();
    h.get_by_label("Export").click();
    wait_for_result(&mut h);
    assert_eq!(recorder.requests.lock().unwrap().len(), 2);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn export_dialog_opens_on_the_motion_on_screen_and_lists_its_files() {
    let (mut h, recorder) = recording_app();
    h.state_mut().state.playback.motion = 2;
    h.run();
    h.get_by_label("File").click();
    h.run();
    h.get_by_label("Export baked sequence…").click();
    h.run();
    assert!(h.state().state.export.open);
    assert_eq!(h.state().state.export.motion, 2, "the motion on screen");
    let dir = scratch("outputs");
    {
        let export = &mut h.state_mut().state.export;
        export.format = ExportFormat::Pc2;
        export.path = dir.join("walk.pc2").display().to_string();
    }
    h.run();
    // Only the cache by default; the rest-pose OBJ when asked for, listed before writing.
    assert!(h.query_by_label_contains("walk.obj").is_none());
    assert!(h.query_by_label_contains("walk.body.pc2").is_none());
    h.get_by_label("also write the rest-pose OBJ").click();
    h.run();
    h.get_by_label_contains("walk.obj");
    h.get_by_label("writes:");
    h.get_by_label_contains("frames, about");
    h.get_by_label("Export").click();
    wait_for_result(&mut h);
    assert_eq!(*recorder.extras.lock().unwrap(), vec![(2, false, true)]);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn browsing_for_the_obj_sequence_chooses_a_folder() {
    let recorder = std::sync::Arc::new(Recorder::default());
    let mut h = harness_with(neural_cloth::app::AppOptions {
        exporter: Some(Box::new(Shared(recorder))),
        file_dialog: neural_cloth::app::file_picker::DialogMode::InApp,
        ..options(None)
    });
    let dir = scratch("obj-folder");
    std::fs::create_dir_all(dir.join("frames")).expect("frames folder");
    h.state_mut().state.export.open = true;
    h.state_mut().state.export.format = ExportFormat::ObjSequence;
    h.state_mut().state.export.path = dir.join("frames").display().to_string();
    h.run();
    h.get_by_label("Browse…").click();
    h.run();
    assert!(h.state().picker.is_browsing(), "the in-app browser opens");
    // A folder is chosen (no save-file name field, no export.obj).
    h.get_by_label("Use this folder").click();
    h.run();
    let export = &h.state().state.export;
    assert_eq!(export.format, ExportFormat::ObjSequence);
    assert!(
        !export.path.ends_with(".obj"),
        "the OBJ sequence's folder gets no extension: {}",
        export.path
    );
    assert!(
        std::path::Path::new(&export.path).is_dir(),
        "{}",
        export.path
    );
}
