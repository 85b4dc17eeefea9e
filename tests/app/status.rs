//! Start-up and the status bar (issue 15): the app opens paused, so it does not redraw until
//! asked, and the status bar shows the viewport's frame time while it redraws.

use std::time::Duration;

use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT, Queryable};
use neural_cloth::app::NeuralClothApp;

use super::{SIZE, options};

#[test]
fn the_app_starts_paused_and_the_status_bar_shows_the_frame_time() {
    // The app as it opens itself: nothing here touches the playback.
    let start = options(None);
    let mut h = Harness::builder()
        .with_size(SIZE)
        .with_pixels_per_point(1.0)
        .wgpu()
        .build_eframe(move |cc| {
            NeuralClothApp::new(&cc.egui_ctx, cc.wgpu_render_state.as_ref(), start)
                .expect("the default scene builds")
        });
    assert!(
        h.state_mut()
            .state
            .preview
            .wait_until_built(Duration::from_secs(120)),
        "the preview model builds"
    );
    // `run` settles only when nothing asks for another frame: a playing app never would.
    h.run();
    assert!(!h.state().state.playback.playing, "the app opens paused");
    assert_eq!(h.state().state.playback.time_secs, 0.0);
    h.get_by_label("viewport idle (paused)");
    h.get_by_label("Play").click();
    for _ in 0..8 {
        h.step();
        h.render().expect("render");
    }
    assert!(h.state().state.playback.playing);
    assert!(
        h.state().state.playback.time_secs > 0.0,
        "time runs after Play"
    );
    let node = h.get_by_label_contains("ms/frame");
    let shown = node
        .accesskit_node()
        .label()
        .or_else(|| node.accesskit_node().value())
        .unwrap_or_default();
    assert!(shown.starts_with("viewport "), "{shown}");
    assert!(h.query_by_label("viewport idle (paused)").is_none());
}

/// The app as it opens itself, without a trainer.
fn app() -> Harness<'static, NeuralClothApp> {
    Harness::builder()
        .with_size(SIZE)
        .with_pixels_per_point(1.0)
        .wgpu()
        .build_eframe(move |cc| {
            NeuralClothApp::new(&cc.egui_ctx, cc.wgpu_render_state.as_ref(), options(None))
                .expect("the default scene builds")
        })
}

#[test]
fn save_project_without_a_path_asks_where_even_without_a_desktop_dialog() {
    // No desktop portal in the test: the in-app file browser asks where to save.
    let mut h = app();
    h.run();
    assert!(h.state().state.project_path.is_none());
    h.get_by_label("File").click();
    h.run();
    h.get_by_label("Save project").click();
    h.run();
    assert!(h.state().picker.is_browsing(), "a file browser opens");
    h.get_by_label("Cancel").click();
    h.run();
    assert!(!h.state().picker.is_browsing());
    assert!(h.state().state.project_path.is_none());
}

#[test]
fn a_broken_project_file_is_refused_and_the_settings_stay() {
    let dir = tempfile::tempdir().unwrap();
    let broken = dir.path().join("broken.toml");
    std::fs::write(&broken, "version = 1\n[view]\nplayback_speed = nan\n").unwrap();
    let mut h = app();
    h.run();
    let before = {
        let s = &h.state().state;
        (s.fabric().clone(), s.w, s.playback.speed)
    };
    assert!(!h.state_mut().open_project(&broken));
    let s = &h.state().state;
    let error = s.last_error().unwrap_or_default().to_string();
    assert!(
        error.contains("playback_speed") && error.ends_with(&broken.display().to_string()),
        "{error}"
    );
    assert_eq!((s.fabric().clone(), s.w, s.playback.speed), before);
    assert!(s.playback.speed.is_finite());
}
