//! The export dialog: USD and the presets on offer, the frame count and size shown before
//! writing, the request handed to the exporter, progress, and errors that leave the app
//! running.

use std::sync::Mutex;

use egui_kittest::kittest::Queryable;
use neural_cloth::app::NeuralClothApp;
use neural_cloth::app::export::{ExportFormat, ExportRequest, Exporter};
use neural_cloth::bake::Preset;

use super::{harness_with, options};

/// Records the requests it gets; fails the ones whose path contains "fail".
#[derive(Default)]
struct Recorder {
    requests: Mutex<Vec<(ExportFormat, Option<Preset>, String)>>,
}

/// The recorder shared between the app and the test.
struct Shared(std::sync::Arc<Recorder>);

impl Exporter for Shared {
    fn export(
        &self,
        request: ExportRequest,
        progress: &mut dyn FnMut(usize, usize) -> bool,
    ) -> Result<String, String> {
        let path = request.path.display().to_string();
        if let Ok(mut r) = self.0.requests.lock() {
            r.push((request.format, request.preset, path.clone()));
        }
        for k in 1..=3 {
            if !progress(k, 3) {
                return Err("bake cancelled".into());
            }
        }
        match path.contains("fail") {
            true => Err(format!("output folder does not exist: {path}")),
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
    while h.state().state.export.last_result.is_none() {
        assert!(start.elapsed().as_secs() < 30, "the export finishes");
        h.step();
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    h.run();
    assert_eq!(
        h.state().state.export.last_result,
        Some(Ok("wrote 3 frames to walk.usda".into()))
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
        .state
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
