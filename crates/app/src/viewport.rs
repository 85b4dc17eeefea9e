//! The 3D viewport inside egui: the [`Renderer`] draws into its own colour + depth texture from
//! an `egui_wgpu` paint callback (recorded into egui's encoder before egui's own pass), and the
//! texture, registered as an egui native texture, is painted as an image. Mouse: drag to orbit,
//! right/middle-drag or shift-drag to pan, scroll to zoom, double-click to reset.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use neural_cloth_render::{DrawOptions, OrbitCamera, RenderTarget, Renderer, SceneFrame};

/// Colour format of the viewport texture (what `register_native_texture` expects).
pub const VIEWPORT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// GPU objects shared between the UI and the paint callback.
struct GpuShared {
    renderer: Renderer,
    target: RenderTarget,
    /// Revision of the frame last uploaded (re-uploads only when it changes).
    uploaded: Option<u64>,
    /// Last upload or draw error, shown over the viewport (shared with the UI thread).
    error: Option<Arc<neural_cloth_render::RenderError>>,
}

/// Viewport GPU state that exists only when egui runs on wgpu.
struct ViewportGpu {
    render_state: egui_wgpu::RenderState,
    shared: Arc<Mutex<GpuShared>>,
    texture: egui::TextureId,
    stats: ResourceStats,
}

/// Counts of the GPU resources the viewport has made, for tests and the leak check: while the
/// viewport keeps its size, neither count may move from one frame to the next.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ResourceStats {
    /// Render targets (colour + depth textures) created since the viewport was built.
    pub targets_created: u64,
    /// egui native textures the viewport holds registered now (one, re-pointed on resize).
    pub registered_textures: u64,
    /// Times the renderer created buffers for a mesh or the collision markers
    /// ([`Renderer::buffer_allocations`]).
    pub buffer_allocations: u64,
}

/// Intervals between viewport frames longer than this are idle gaps, not frame times, ms.
const IDLE_GAP_MS: f64 = 1000.0;

/// Smoothed frame timing for the status bar and the debug overlay.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameTiming {
    /// Exponential moving average of the interval between viewport frames, ms.
    pub frame_ms: f64,
    /// Exponential moving average of the CPU time spent building and recording the viewport, ms.
    pub cpu_ms: f64,
}

/// The 3D viewport widget state.
pub struct Viewport {
    /// The camera (orbit/pan/zoom, reset to its home view).
    pub camera: OrbitCamera,
    /// Frame timing for the overlay.
    pub timing: FrameTiming,
    /// Show the frame-time overlay.
    pub show_timing: bool,
    /// Keep the camera on the body as it travels (walks, runs): the target follows the body's
    /// horizontal centre. Default true.
    pub follow: bool,
    /// Body centre the camera last followed.
    anchor: Option<neural_cloth_core::geometry::Vec3>,
    /// Body centre when the home view was framed.
    home_anchor: Option<neural_cloth_core::geometry::Vec3>,
    gpu: Option<ViewportGpu>,
    last_frame: Option<Instant>,
    rect: Option<egui::Rect>,
}

impl std::fmt::Debug for Viewport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Viewport")
            .field("camera", &self.camera)
            .field("gpu", &self.gpu.is_some())
            .finish()
    }
}

/// The paint callback: uploads the frame if new and records the 3D pass into egui's encoder.
struct ViewportCallback {
    shared: Arc<Mutex<GpuShared>>,
    frame: Arc<SceneFrame>,
    revision: u64,
    camera: OrbitCamera,
    options: DrawOptions,
}

/// Centre of the body's bounding box (the garment's when there is no body).
fn body_centre(frame: &SceneFrame) -> Option<neural_cloth_core::geometry::Vec3> {
    let (lo, hi) = frame.body.as_ref().or(frame.garment.as_ref())?.bounds()?;
    Some((lo + hi) * 0.5)
}

impl egui_wgpu::CallbackTrait for ViewportCallback {
    fn prepare(
        &self,
        _device: &wgpu::Device,
        _queue: &wgpu::Queue,
        _screen: &egui_wgpu::ScreenDescriptor,
        encoder: &mut wgpu::CommandEncoder,
        _resources: &mut egui_wgpu::CallbackResources,
    ) -> Vec<wgpu::CommandBuffer> {
        let Ok(mut gpu) = self.shared.lock() else {
            return Vec::new();
        };
        let gpu = &mut *gpu;
        if gpu.uploaded != Some(self.revision) {
            gpu.error = gpu.renderer.upload(&self.frame).err().map(Arc::new);
            gpu.uploaded = Some(self.revision);
        }
        if let Err(e) = gpu
            .renderer
            .render(encoder, &gpu.target, &self.camera, &self.options)
        {
            gpu.error = Some(Arc::new(e));
        }
        Vec::new()
    }

    fn paint(
        &self,
        _info: egui::PaintCallbackInfo,
        _pass: &mut wgpu::RenderPass<'static>,
        _resources: &egui_wgpu::CallbackResources,
    ) {
        // The 3D pass already ran in `prepare`; egui paints its result as an image.
    }
}

impl Viewport {
    /// A viewport drawing with `render_state` (None: the viewport shows a notice instead, e.g.
    /// in UI tests without a GPU renderer).
    pub fn new(render_state: Option<&egui_wgpu::RenderState>) -> Self {
        let gpu = render_state.map(|rs| {
            let samples = Renderer::preferred_sample_count(&rs.adapter.get_info());
            let renderer = Renderer::with_samples(&rs.device, &rs.queue, VIEWPORT_FORMAT, samples);
            let target = renderer.create_target([64, 64]);
            let texture = rs.renderer.write().register_native_texture(
                &rs.device,
                target.color_view(),
                wgpu::FilterMode::Linear,
            );
            let shared = GpuShared {
                renderer,
                target,
                uploaded: None,
                error: None,
            };
            ViewportGpu {
                render_state: rs.clone(),
                shared: Arc::new(Mutex::new(shared)),
                texture,
                stats: ResourceStats {
                    targets_created: 1,
                    registered_textures: 1,
                    buffer_allocations: 0,
                },
            }
        });
        Self {
            camera: OrbitCamera::default(),
            timing: FrameTiming::default(),
            show_timing: false,
            follow: true,
            anchor: None,
            home_anchor: None,
            gpu,
            last_frame: None,
            rect: None,
        }
    }

    /// True when the viewport can draw (egui runs on wgpu).
    pub fn has_gpu(&self) -> bool {
        self.gpu.is_some()
    }

    /// What the viewport has allocated on the GPU (all zero without a GPU).
    pub fn resource_stats(&self) -> ResourceStats {
        let Some(gpu) = &self.gpu else {
            return ResourceStats::default();
        };
        let buffer_allocations = gpu
            .shared
            .lock()
            .map_or(0, |s| s.renderer.buffer_allocations());
        ResourceStats {
            buffer_allocations,
            ..gpu.stats
        }
    }

    /// The status bar's frame time: "viewport 16.7 ms/frame (60 fps)", None before two frames
    /// have been drawn close enough together to time.
    pub fn frame_time_text(&self) -> Option<String> {
        let ms = self.timing.frame_ms;
        (ms > 0.0).then(|| format!("viewport {ms:.1} ms/frame ({:.0} fps)", 1e3 / ms))
    }

    /// Where the viewport was last laid out, in points.
    pub fn rect(&self) -> Option<egui::Rect> {
        self.rect
    }

    /// Frames the camera on `frame`'s body and garment and makes that the home view.
    pub fn frame_scene(&mut self, frame: &SceneFrame) {
        self.camera = neural_cloth_render::offscreen::default_camera(frame);
        self.home_anchor = body_centre(frame);
        self.anchor = self.home_anchor;
    }

    /// Returns to the home view (centred on where the body is now when following it).
    pub fn reset_camera(&mut self) {
        self.camera.reset();
        if let (true, Some(now), Some(home)) = (self.follow, self.anchor, self.home_anchor) {
            self.camera.target.x += now.x - home.x;
            self.camera.target.z += now.z - home.z;
        }
    }

    /// Moves the camera target with the body's horizontal travel since the last frame.
    fn follow_body(&mut self, frame: &SceneFrame) {
        let Some(now) = body_centre(frame) else {
            return;
        };
        if let (true, Some(before)) = (self.follow, self.anchor) {
            self.camera.target.x += now.x - before.x;
            self.camera.target.z += now.z - before.z;
        }
        self.anchor = Some(now);
    }

    /// Applies mouse input on `response` to the camera.
    fn handle_input(&mut self, ui: &egui::Ui, response: &egui::Response) {
        let delta = response.drag_delta();
        let shift = ui.input(|i| i.modifiers.shift);
        let height = response.rect.height().max(1.0);
        if response.dragged_by(egui::PointerButton::Secondary)
            || response.dragged_by(egui::PointerButton::Middle)
            || (shift && response.dragged_by(egui::PointerButton::Primary))
        {
            self.camera.pan(delta.x, delta.y, height);
        } else if response.dragged_by(egui::PointerButton::Primary) {
            self.camera.orbit(-delta.x * 0.008, delta.y * 0.008);
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            let pinch = ui.input(|i| i.zoom_delta());
            if scroll != 0.0 {
                self.camera.zoom((-scroll * 0.0015).exp());
            }
            if pinch != 1.0 && pinch > 0.0 {
                self.camera.zoom(1.0 / pinch);
            }
        }
        if response.double_clicked() {
            self.reset_camera();
        }
    }

    /// Shows the viewport filling the available space, drawing `frame` (identified by
    /// `revision`: the same revision is not uploaded twice) with `options`.
    pub fn ui(
        &mut self,
        ui: &mut egui::Ui,
        frame: &Arc<SceneFrame>,
        revision: u64,
        options: &DrawOptions,
    ) -> egui::Response {
        let started = Instant::now();
        self.follow_body(frame);
        if let Some(last) = self.last_frame.replace(started) {
            let dt_ms = last.elapsed().as_secs_f64() * 1e3;
            // A longer gap is a pause between redraws (nothing moved), not a frame time.
            if dt_ms <= IDLE_GAP_MS {
                self.timing.frame_ms = if self.timing.frame_ms > 0.0 {
                    0.9 * self.timing.frame_ms + 0.1 * dt_ms
                } else {
                    dt_ms
                };
            }
        }
        let size = ui.available_size().max(egui::vec2(32.0, 32.0));
        let (rect, response) = ui.allocate_exact_size(size, egui::Sense::click_and_drag());
        self.rect = Some(rect);
        self.handle_input(ui, &response);
        let painter = ui.painter_at(rect);
        let Some(gpu) = &mut self.gpu else {
            painter.rect_filled(rect, 0.0, egui::Color32::from_rgb(36, 40, 48));
            painter.text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "3D viewport needs the wgpu renderer",
                egui::FontId::proportional(14.0),
                egui::Color32::GRAY,
            );
            return response;
        };
        let ppp = ui.ctx().pixels_per_point();
        let size_px = [
            (rect.width() * ppp).round().max(1.0) as u32,
            (rect.height() * ppp).round().max(1.0) as u32,
        ];
        let mut error = None;
        if let Ok(mut shared) = gpu.shared.lock() {
            if shared.target.size() != size_px {
                shared.target = shared.renderer.create_target(size_px);
                gpu.stats.targets_created += 1;
                let device = &gpu.render_state.device;
                gpu.render_state
                    .renderer
                    .write()
                    .update_egui_texture_from_wgpu_texture(
                        device,
                        shared.target.color_view(),
                        wgpu::FilterMode::Linear,
                        gpu.texture,
                    );
            }
            error = shared.error.clone();
        }
        let callback = ViewportCallback {
            shared: gpu.shared.clone(),
            frame: frame.clone(),
            revision,
            camera: self.camera,
            options: *options,
        };
        painter.add(egui_wgpu::Callback::new_paint_callback(rect, callback));
        let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
        painter.image(gpu.texture, rect, uv, egui::Color32::WHITE);
        if let Some(e) = error {
            painter.text(
                rect.left_bottom() + egui::vec2(8.0, -8.0),
                egui::Align2::LEFT_BOTTOM,
                e.to_string(),
                egui::FontId::proportional(13.0),
                egui::Color32::from_rgb(255, 120, 100),
            );
        }
        let cpu_ms = started.elapsed().as_secs_f64() * 1e3;
        self.timing.cpu_ms = if self.timing.cpu_ms > 0.0 {
            0.9 * self.timing.cpu_ms + 0.1 * cpu_ms
        } else {
            cpu_ms
        };
        if self.show_timing {
            let fps = if self.timing.frame_ms > 0.0 {
                1e3 / self.timing.frame_ms
            } else {
                0.0
            };
            let text = format!(
                "{:.1} ms/frame ({fps:.0} fps), viewport CPU {:.2} ms, {}×{} px",
                self.timing.frame_ms, self.timing.cpu_ms, size_px[0], size_px[1]
            );
            painter.text(
                rect.left_top() + egui::vec2(8.0, 8.0),
                egui::Align2::LEFT_TOP,
                text,
                egui::FontId::monospace(12.0),
                egui::Color32::from_rgb(220, 220, 120),
            );
        }
        response
    }
}
