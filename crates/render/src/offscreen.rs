//! Offscreen rendering on a device of our own (no window): the CLI's `screenshot`, tests and
//! the frame-time benchmark. The same [`Renderer`] and shaders as the viewport are used.

use std::time::{Duration, Instant};

use super::{DrawOptions, OrbitCamera, RenderError, RenderTarget, Renderer, SceneFrame};

/// Colour format of offscreen targets (the same as the viewport texture shown by egui).
pub const OFFSCREEN_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// Creates a device and queue without a window, preferring a hardware adapter and falling back
/// to any adapter (e.g. Mesa lavapipe). Returns a human-readable adapter description too.
pub fn headless_device() -> Result<(wgpu::Device, wgpu::Queue, String), RenderError> {
    // Vulkan/Metal/DX12 first (GL would probe for a display); `WGPU_BACKEND` overrides.
    let explicit = std::env::var_os("WGPU_BACKEND").is_some();
    let request = |backends: Option<wgpu::Backends>| {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        if let Some(b) = backends {
            desc.backends = b;
        }
        let instance = wgpu::Instance::new(desc);
        pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            apply_limit_buckets: false,
        }))
    };
    let adapter = match (
        explicit,
        request((!explicit).then_some(wgpu::Backends::PRIMARY)),
    ) {
        (false, Err(_)) => request(None),
        (_, found) => found,
    }
    .map_err(|e| RenderError::NoAdapter(e.to_string()))?;
    let info = adapter.get_info();
    let description = format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type);
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("neural-cloth offscreen device"),
        required_features: wgpu::Features::empty(),
        required_limits: wgpu::Limits::downlevel_defaults().using_resolution(adapter.limits()),
        ..Default::default()
    }))
    .map_err(|e| RenderError::NoAdapter(format!("{description}: {e}")))?;
    Ok((device, queue, description))
}

/// A headless renderer with its own device and a target of a fixed size.
#[derive(Debug)]
pub struct Offscreen {
    renderer: Renderer,
    target: RenderTarget,
    adapter: String,
}

impl Offscreen {
    /// Creates a device and a `size` pixel target (4× MSAA).
    pub fn new(size: [u32; 2]) -> Result<Self, RenderError> {
        Self::with_samples(size, 4)
    }

    /// Creates a device and a `size` pixel target with `sample_count` samples (1 or 4).
    pub fn with_samples(size: [u32; 2], sample_count: u32) -> Result<Self, RenderError> {
        Self::with_format(size, sample_count, OFFSCREEN_FORMAT)
    }

    /// Like [`Offscreen::with_samples`] with a colour `format` (8-bit RGBA or BGRA, linear
    /// or sRGB).
    pub fn with_format(
        size: [u32; 2],
        sample_count: u32,
        format: wgpu::TextureFormat,
    ) -> Result<Self, RenderError> {
        let (device, queue, adapter) = headless_device()?;
        let renderer = Renderer::with_samples(&device, &queue, format, sample_count);
        let target = renderer.create_target(size);
        Ok(Self {
            renderer,
            target,
            adapter,
        })
    }

    /// The adapter in use, e.g. "llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, Cpu)".
    pub fn adapter(&self) -> &str {
        &self.adapter
    }

    /// The renderer (to upload frames without reading back).
    pub fn renderer_mut(&mut self) -> &mut Renderer {
        &mut self.renderer
    }

    /// Uploads `frame`, draws it and submits, without reading back; blocks until the GPU is
    /// done and returns how long the upload, draw and wait took.
    pub fn draw(
        &mut self,
        frame: &SceneFrame,
        camera: &OrbitCamera,
        options: &DrawOptions,
    ) -> Result<Duration, RenderError> {
        let start = Instant::now();
        self.renderer.upload(frame)?;
        let device = self.renderer.device().clone();
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("neural-cloth offscreen encoder"),
        });
        self.renderer
            .render(&mut encoder, &self.target, camera, options)?;
        let submission = self
            .renderer
            .queue()
            .submit(std::iter::once(encoder.finish()));
        device
            .poll(wgpu::PollType::Wait {
                submission_index: Some(submission),
                timeout: Some(super::target::READBACK_TIMEOUT),
            })
            .map_err(|e| RenderError::Readback(format!("waiting for the GPU: {e}")))?;
        Ok(start.elapsed())
    }

    /// Draws `frame` and reads the result back.
    pub fn render(
        &mut self,
        frame: &SceneFrame,
        camera: &OrbitCamera,
        options: &DrawOptions,
    ) -> Result<image::RgbaImage, RenderError> {
        self.draw(frame, camera, options)?;
        self.target
            .read_image(self.renderer.device(), self.renderer.queue())
    }
}

/// Renders one frame offscreen at `size` pixels on a fresh device and returns the image.
pub fn render_to_image(
    frame: &SceneFrame,
    camera: &OrbitCamera,
    options: &DrawOptions,
    size: [u32; 2],
) -> Result<image::RgbaImage, RenderError> {
    Offscreen::new(size)?.render(frame, camera, options)
}

/// The CLI's `neural-cloth screenshot`: renders `frame` (see [`SceneFrame::from_scene`]) at
/// `size` pixels; without a `camera` the view frames the body and garment from the front.
pub fn screenshot(
    frame: &SceneFrame,
    camera: Option<&OrbitCamera>,
    options: &DrawOptions,
    size: [u32; 2],
) -> Result<image::RgbaImage, RenderError> {
    let camera = match camera {
        Some(c) => *c,
        None => default_camera(frame),
    };
    render_to_image(frame, &camera, options, size)
}

/// The default view of a frame: framing body and garment from the front, a little from the
/// side and above (the app's start-up and reset view).
pub fn default_camera(frame: &SceneFrame) -> OrbitCamera {
    match frame.bounds() {
        Some((lo, hi)) => OrbitCamera::framing(lo, hi),
        None => OrbitCamera::default(),
    }
}

/// Frame-time statistics of [`measure_frame_times`], in milliseconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameTimes {
    /// Mean time per frame.
    pub mean_ms: f64,
    /// Median time per frame.
    pub median_ms: f64,
    /// Slowest frame.
    pub max_ms: f64,
}

/// Frames drawn before [`measure_frame_times`] starts timing (pipeline compilation, caches).
pub const FRAME_TIME_WARMUP: usize = 5;

/// Draws `frames` frames (each produced by `make_frame(k)`, uploaded and drawn, waiting for
/// the GPU each time, as the viewport does per repaint) after [`FRAME_TIME_WARMUP`] untimed
/// ones, and reports the frame times.
pub fn measure_frame_times(
    offscreen: &mut Offscreen,
    camera: &OrbitCamera,
    options: &DrawOptions,
    frames: usize,
    mut make_frame: impl FnMut(usize) -> SceneFrame,
) -> Result<FrameTimes, RenderError> {
    let mut times = Vec::with_capacity(frames.max(1));
    for k in 0..frames.max(1) + FRAME_TIME_WARMUP {
        let start = Instant::now();
        let frame = make_frame(k);
        offscreen.draw(&frame, camera, options)?;
        if k >= FRAME_TIME_WARMUP {
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    times.sort_by(f64::total_cmp);
    let mean_ms = times.iter().sum::<f64>() / times.len().max(1) as f64;
    let median_ms = times.get(times.len() / 2).copied().unwrap_or(0.0);
    let max_ms = times.last().copied().unwrap_or(0.0);
    Ok(FrameTimes {
        mean_ms,
        median_ms,
        max_ms,
    })
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::{MeshFrame, heat_color};
    use neural_cloth_core::geometry::Vec3;

    /// A 1 m square "garment" facing +Z at height 1 m, split into a 4x4 grid of quads.
    fn cloth(colored: bool) -> MeshFrame {
        let n = 5u32;
        let positions: Vec<Vec3> = (0..n * n)
            .map(|k| Vec3::new((k % n) as f32 / 4.0 - 0.5, 0.5 + (k / n) as f32 / 4.0, 0.0))
            .collect();
        let mut faces = Vec::new();
        for y in 0..n - 1 {
            for x in 0..n - 1 {
                let i = y * n + x;
                faces.push([i, i + 1, i + n + 1]);
                faces.push([i, i + n + 1, i + n]);
            }
        }
        let topology = neural_cloth_core::geometry::Topology::from_faces(positions.len(), &faces);
        let mut mesh = MeshFrame::new(positions, Arc::from(faces), Arc::from(topology.edges));
        if colored {
            mesh.colors = Some(
                mesh.positions
                    .iter()
                    .map(|p| heat_color(p.x + 0.5, 1.0))
                    .collect(),
            );
        }
        mesh
    }

    fn frame(colored: bool) -> SceneFrame {
        SceneFrame {
            garment: Some(cloth(colored)),
            collision_points: vec![Vec3::new(0.0, 1.0, 0.01)],
            ..Default::default()
        }
    }

    fn camera() -> OrbitCamera {
        OrbitCamera::new(Vec3::new(0.0, 1.0, 0.0), 0.0, 0.0, 2.0)
    }

    fn pixel(img: &image::RgbaImage, x: u32, y: u32) -> [u8; 4] {
        img.get_pixel(x, y).0
    }

    #[test]
    fn draws_garment_over_background_and_grid() {
        let mut off =
            Offscreen::new([160, 120]).expect("a wgpu adapter (install mesa-vulkan-drivers)");
        let img = off
            .render(&frame(false), &camera(), &DrawOptions::default())
            .unwrap();
        assert_eq!(img.dimensions(), (160, 120));
        // Top-left corner: background colour, opaque.
        let bg = pixel(&img, 1, 1);
        assert_eq!(bg[3], 255);
        assert!(
            bg.iter()
                .take(3)
                .zip(crate::renderer::BACKGROUND_SRGB)
                .all(|(a, b)| a.abs_diff(b) <= 2),
            "{bg:?}"
        );
        // Centre: the blue garment (front faces the camera).
        let c = pixel(&img, 80, 60);
        assert!(c[2] > c[0] + 40, "centre {c:?}");
        // The ground (y = 0, below the camera) shows up in the bottom rows and differs from the sky.
        let ground = pixel(&img, 5, 118);
        assert_ne!(ground, bg);
    }

    #[test]
    fn toggles_change_the_image() {
        let mut off = Offscreen::new([128, 96]).expect("a wgpu adapter");
        let plain = off
            .render(&frame(true), &camera(), &DrawOptions::default())
            .unwrap();
        let heat = off
            .render(
                &frame(true),
                &camera(),
                &DrawOptions {
                    heat_map: true,
                    ..Default::default()
                },
            )
            .unwrap();
        let wire = off
            .render(
                &frame(true),
                &camera(),
                &DrawOptions {
                    wireframe: true,
                    ..Default::default()
                },
            )
            .unwrap();
        let points = off
            .render(
                &frame(true),
                &camera(),
                &DrawOptions {
                    collision_points: true,
                    ..Default::default()
                },
            )
            .unwrap();
        let hidden = off
            .render(
                &frame(true),
                &camera(),
                &DrawOptions {
                    show_garment: false,
                    ..Default::default()
                },
            )
            .unwrap();
        for (name, img) in [
            ("heat", &heat),
            ("wire", &wire),
            ("points", &points),
            ("hidden", &hidden),
        ] {
            let differing = plain
                .pixels()
                .zip(img.pixels())
                .filter(|(a, b)| a != b)
                .count();
            assert!(differing > 20, "{name}: only {differing} pixels differ");
        }
        // Heat-map: left edge of the cloth is cold (blue), right edge hot (red).
        let left = pixel(&heat, 64 - 20, 48);
        let right = pixel(&heat, 64 + 20, 48);
        assert!(
            left[2] > left[0] && right[0] > right[2],
            "{left:?} {right:?}"
        );
        // Collision marker at the centre is red.
        let p = pixel(&points, 64, 48);
        assert!(p[0] > 150 && p[1] < 120, "{p:?}");
    }

    #[test]
    fn back_faces_are_lit_with_the_inside_colour() {
        let mut off = Offscreen::new([96, 96]).expect("a wgpu adapter");
        let behind = OrbitCamera::new(Vec3::new(0.0, 1.0, 0.0), std::f32::consts::PI, 0.0, 2.0);
        let img = off
            .render(&frame(false), &behind, &DrawOptions::default())
            .unwrap();
        let c = pixel(&img, 48, 48);
        assert!(c[0] > c[2], "inside should be warm: {c:?}");
    }

    #[test]
    fn rejects_bad_meshes_without_panicking() {
        let mut off = Offscreen::new([32, 32]).expect("a wgpu adapter");
        let mut bad = frame(false);
        if let Some(g) = bad.garment.as_mut() {
            g.faces = Arc::from(vec![[0, 1, 99]]);
        }
        let err = off
            .render(&bad, &camera(), &DrawOptions::default())
            .unwrap_err();
        assert!(matches!(err, RenderError::InvalidMesh { .. }), "{err}");
        let mut nan = frame(false);
        if let Some(g) = nan.garment.as_mut() {
            g.positions[3].x = f32::NAN;
        }
        assert!(
            off.render(&nan, &camera(), &DrawOptions::default())
                .is_err()
        );
        // A good frame afterwards still renders.
        assert!(
            off.render(&frame(false), &camera(), &DrawOptions::default())
                .is_ok()
        );
    }
}

#[cfg(test)]
mod scene_tests {
    use super::*;

    /// The built-in scene, framed by the default camera, shows garment and body colours; set
    /// `NEURAL_CLOTH_RENDER_PNG=/path.png` to keep the image for a look.
    #[test]
    fn default_scene_renders_framed() {
        let scene = neural_cloth_core::scene::procedural::default_scene().expect("default scene");
        let motion = scene
            .motions
            .first()
            .map(|(m, _)| m.clone())
            .expect("a motion");
        let pose = motion.sample(1.3);
        let mut frame = SceneFrame::from_scene(&scene.avatar, &pose, Some(&scene.garment), None);
        frame.collision_points = frame
            .garment
            .as_ref()
            .map(|g| g.positions.iter().step_by(97).copied().collect())
            .unwrap_or_default();
        let options = DrawOptions {
            collision_points: true,
            ..Default::default()
        };
        let image = screenshot(&frame, None, &options, [480, 360]).expect("a wgpu adapter");
        if let Some(path) = std::env::var_os("NEURAL_CLOTH_RENDER_PNG") {
            image.save(&path).expect("save png");
            // The overlays too, beside it.
            if let Some(g) = frame.garment.as_mut() {
                g.colors = Some(
                    g.positions
                        .iter()
                        .map(|p| crate::heat_color(p.y - 1.0, 0.5))
                        .collect(),
                );
            }
            let all = DrawOptions {
                heat_map: true,
                wireframe: true,
                collision_points: true,
                ..Default::default()
            };
            let overlays = screenshot(&frame, None, &all, [480, 360]).expect("render");
            overlays
                .save(std::path::Path::new(&path).with_extension("overlays.png"))
                .expect("save png");
        }
        let blueish = image
            .pixels()
            .filter(|p| p.0[2] > p.0[0].saturating_add(40))
            .count();
        let body = image
            .pixels()
            .filter(|p| p.0[0] > 120 && p.0[0] > p.0[2].saturating_add(10))
            .count();
        let total = (image.width() * image.height()) as usize;
        assert!(blueish > total / 50, "garment covers only {blueish} pixels");
        assert!(body > total / 100, "body covers only {body} pixels");
    }
}

#[cfg(test)]
mod bench {
    use super::*;
    use std::sync::atomic::{AtomicBool, Ordering};

    /// Frame time of the viewport path on the default scene: per frame the body and garment
    /// are re-skinned (as during playback), normals recomputed, uploaded, drawn and waited
    /// for; with 0, 1 and 2 busy CPU threads standing in for a training run. Prints the
    /// numbers; run with
    /// `cargo test --release -p neural-cloth-render offscreen::bench -- --ignored --nocapture`.
    #[test]
    #[ignore = "benchmark: prints frame times, asserts nothing about speed"]
    fn viewport_frame_time_default_scene() {
        let scene = neural_cloth_core::scene::procedural::default_scene().expect("default scene");
        let motion = scene
            .motions
            .iter()
            .map(|(m, _)| m)
            .find(|m| m.name == "walk")
            .expect("walk")
            .clone();
        let size: [u32; 2] = match std::env::var("NEURAL_CLOTH_BENCH_SIZE")
            .ok()
            .and_then(|s| s.split_once('x').map(|(w, h)| (w.parse(), h.parse())))
        {
            Some((Ok(w), Ok(h))) => [w, h],
            _ => [1000, 640],
        };
        let first = SceneFrame::from_scene(
            &scene.avatar,
            &motion.sample(0.0),
            Some(&scene.garment),
            None,
        );
        let camera = default_camera(&first);
        let start = std::time::Instant::now();
        for k in 0..120 {
            let pose = motion.sample(k as f32 / 60.0);
            std::hint::black_box(SceneFrame::from_scene(
                &scene.avatar,
                &pose,
                Some(&scene.garment),
                None,
            ));
        }
        println!(
            "frame building (skinning + normals) alone: {:.2} ms",
            start.elapsed().as_secs_f64() * 1e3 / 120.0
        );
        let variants = [
            (1, OFFSCREEN_FORMAT, DrawOptions::default()),
            (
                1,
                OFFSCREEN_FORMAT,
                DrawOptions {
                    grid: false,
                    ..Default::default()
                },
            ),
            (4, OFFSCREEN_FORMAT, DrawOptions::default()),
        ];
        let only_idle = std::env::var_os("NEURAL_CLOTH_BENCH_IDLE_ONLY").is_some();
        {
            let mut off = Offscreen::with_samples(size, 1).expect("a wgpu adapter");
            let empty = DrawOptions::default();
            let times =
                measure_frame_times(&mut off, &camera, &empty, 60, |_| SceneFrame::default())
                    .expect("render");
            println!(
                "ground grid only (no meshes) {}x{}: mean {:.2} ms",
                size[0], size[1], times.mean_ms
            );
        }
        for (samples, format, options) in variants {
            let mut off = Offscreen::with_format(size, samples, format).expect("a wgpu adapter");
            for busy in [0usize, 1, 2].into_iter().filter(|b| !only_idle || *b == 0) {
                let stop = AtomicBool::new(false);
                let times = std::thread::scope(|s| {
                    for _ in 0..busy {
                        s.spawn(|| {
                            let mut x = 1u64;
                            while !stop.load(Ordering::Relaxed) {
                                for _ in 0..10_000 {
                                    x = std::hint::black_box(
                                        x.wrapping_mul(6364136223846793005).wrapping_add(1),
                                    );
                                }
                            }
                        });
                    }
                    let times = measure_frame_times(&mut off, &camera, &options, 120, |k| {
                        let pose = motion.sample(k as f32 / 60.0);
                        SceneFrame::from_scene(&scene.avatar, &pose, Some(&scene.garment), None)
                    });
                    stop.store(true, Ordering::Relaxed);
                    times
                })
                .expect("render");
                println!(
                    "viewport {}x{} x{samples} samples {format:?} grid {} on {}, {busy} busy CPU threads: mean {:.2} ms ({:.0} fps), median {:.2} ms, max {:.2} ms",
                    size[0],
                    size[1],
                    options.grid,
                    off.adapter(),
                    times.mean_ms,
                    1e3 / times.mean_ms.max(1e-6),
                    times.median_ms,
                    times.max_ms
                );
            }
        }
    }
}
