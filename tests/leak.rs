//! Issue 15's memory leak: the viewport grew the process by about 1 MB per mesh draw (~2 MB
//! per redraw) while playing or orbiting, for ever. Mesa's lavapipe compiled a new variant of
//! the mesh shader on every draw because the shader branched on a uniform (`params.flags`),
//! and kept each one. Hundreds of headless frames must leave the viewport's GPU resource counts
//! and the process's resident memory where they were after a warm-up.
//!
//! A binary of its own: resident memory is per process, so no other test may run beside these
//! (the two here take turns through [`ONE_AT_A_TIME`]).

use std::sync::Mutex;
use std::time::Duration;

use egui_kittest::Harness;
use neural_cloth::app::{AppOptions, NeuralClothApp};
use neural_cloth::render::{DrawOptions, Offscreen};

/// Serialises the tests of this binary (they measure the whole process).
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// Frames drawn before the first measurement (allocator pools, lavapipe's first draws).
const WARM_UP_FRAMES: usize = 60;
/// Frames drawn between the two measurements.
const MEASURED_FRAMES: usize = 300;
/// Allowed growth over [`MEASURED_FRAMES`], in viewport images: the leak grew about two per
/// frame (600 over the run); allocator noise stays far below this.
const ALLOWED_GROWTH_IMAGES: u64 = 40;

/// Resident set size of this process in bytes (`/proc/self/statm`, Linux).
fn resident_bytes() -> u64 {
    let statm = std::fs::read_to_string("/proc/self/statm").expect("/proc/self/statm (Linux)");
    let pages: u64 = statm
        .split_whitespace()
        .nth(1)
        .and_then(|p| p.parse().ok())
        .expect("statm's second field is the resident page count");
    // 4 KiB pages on the x86-64 and aarch64 Linux machines these tests run on.
    pages * 4096
}

/// Every overlay on, so that every pipeline draws (mesh, heat-map colours, wireframe lines,
/// collision points, grid).
fn all_overlays() -> DrawOptions {
    DrawOptions {
        show_body: true,
        show_garment: true,
        heat_map: true,
        wireframe: true,
        collision_points: true,
        grid: true,
    }
}

/// The app on the default scene with its preview model built and playback on.
fn playing_app() -> Harness<'static, NeuralClothApp> {
    let store = std::env::temp_dir()
        .join(format!("neural-cloth-leak-test-{}", std::process::id()))
        .join("recent.json");
    let options = AppOptions {
        recent_store: Some(store),
        ..Default::default()
    };
    let mut h = Harness::builder()
        .with_size(egui::vec2(960.0, 600.0))
        .with_pixels_per_point(1.0)
        .wgpu()
        .build_eframe(move |cc| {
            let mut app = NeuralClothApp::new(&cc.egui_ctx, cc.wgpu_render_state.as_ref(), options)
                .expect("the default scene builds");
            // Paused until the preview is built, so that the harness can settle.
            app.state.playback.playing = false;
            app
        });
    h.run();
    assert!(
        h.state_mut()
            .state
            .preview
            .wait_until_built(Duration::from_secs(120)),
        "the preview model builds"
    );
    h.state_mut().state.draw = all_overlays();
    h.state_mut().state.playback.playing = true;
    h
}

/// One redraw as the window does it: an egui frame, then a wgpu render of it (which runs the
/// viewport's paint callback and so the 3D pass).
fn redraw(h: &mut Harness<'static, NeuralClothApp>) {
    h.step();
    h.render().expect("kittest renders the frame");
}

#[test]
fn viewport_memory_leak_per_redraw_issue_15() {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let mut h = playing_app();
    for _ in 0..WARM_UP_FRAMES {
        redraw(&mut h);
    }
    let viewport = h.state().viewport.rect().expect("viewport laid out");
    let image_bytes = (viewport.width() * viewport.height() * 4.0) as u64;
    let stats_before = h.state().viewport.resource_stats();
    let egui_textures_before = h.ctx.tex_manager().read().num_allocated();
    let time_before = h.state().state.playback.time_secs;
    let rss_before = resident_bytes();
    for k in 0..MEASURED_FRAMES {
        // Orbit too: that grew memory with playback stopped.
        if k % 2 == 0 {
            h.state_mut().viewport.camera.orbit(0.01, 0.0);
        }
        redraw(&mut h);
    }
    let rss_after = resident_bytes();
    let stats_after = h.state().viewport.resource_stats();
    let grown = rss_after.saturating_sub(rss_before);
    eprintln!(
        "{MEASURED_FRAMES} redraws of a {}x{} viewport ({} KiB a frame): resident {} -> {} MiB \
         (+{} KiB), {stats_after:?}",
        viewport.width(),
        viewport.height(),
        image_bytes >> 10,
        rss_before >> 20,
        rss_after >> 20,
        grown >> 10,
    );
    assert_ne!(
        h.state().state.playback.time_secs,
        time_before,
        "playback ran during the measurement"
    );
    assert_eq!(
        stats_after, stats_before,
        "the viewport made GPU resources while its size and scene stayed the same"
    );
    assert_eq!(stats_after.registered_textures, 1);
    assert_eq!(
        h.ctx.tex_manager().read().num_allocated(),
        egui_textures_before,
        "egui textures were allocated per frame"
    );
    assert!(
        grown < ALLOWED_GROWTH_IMAGES * image_bytes,
        "resident memory grew by {} MiB over {MEASURED_FRAMES} redraws",
        grown >> 20
    );
}

#[test]
fn offscreen_renderer_memory_stays_bounded_issue_15() {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    // The frame of the default scene with every overlay, drawn by the renderer the CLI's
    // `screenshot` and `bench` use (no egui involved).
    let (frame, camera) = {
        let mut h = playing_app();
        let (frame, _) = h.state_mut().state.scene_frame();
        (frame, h.state().viewport.camera)
    };
    assert!(
        frame.body.is_some() && frame.garment.is_some(),
        "the frame has a body and a garment to draw"
    );
    let size = [660, 355];
    let image_bytes = u64::from(size[0] * size[1] * 4);
    let mut off = Offscreen::with_samples(size, 1).expect("a wgpu adapter (lavapipe)");
    let options = all_overlays();
    for _ in 0..WARM_UP_FRAMES {
        off.draw(&frame, &camera, &options).expect("draw");
    }
    let allocations = off.renderer_mut().buffer_allocations();
    let rss_before = resident_bytes();
    for _ in 0..MEASURED_FRAMES {
        off.draw(&frame, &camera, &options).expect("draw");
    }
    let grown = resident_bytes().saturating_sub(rss_before);
    eprintln!(
        "{MEASURED_FRAMES} offscreen draws on {}: +{} KiB resident",
        off.adapter(),
        grown >> 10
    );
    assert_eq!(
        off.renderer_mut().buffer_allocations(),
        allocations,
        "drawing the same frame again created buffers"
    );
    assert!(
        grown < ALLOWED_GROWTH_IMAGES * image_bytes,
        "resident memory grew by {} MiB over {MEASURED_FRAMES} draws",
        grown >> 20
    );
}
