//! The wgpu renderer: owns GPU buffers for the body, the garment (positions and normals
//! rewritten every frame), collision markers and per-frame uniforms, and records one render
//! pass into a [`RenderTarget`]. It knows nothing about egui.

use std::sync::Arc;

use wgpu::util::DeviceExt;

use super::frame::{MeshFrame, SceneFrame};
use super::gpu::{Globals, MeshParams, PointInstance, linear_rgba};
use super::pipelines::Pipelines;
use super::{OrbitCamera, RenderError, RenderTarget};

/// What to draw and how; every field is a user-facing viewport toggle.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct DrawOptions {
    /// Draw the avatar body. Default true.
    pub show_body: bool,
    /// Draw the garment. Default true.
    pub show_garment: bool,
    /// Colour the garment by its per-vertex colours (strain heat-map) when it has them. Default false.
    pub heat_map: bool,
    /// Draw the garment's edges over it. Default false.
    pub wireframe: bool,
    /// Draw collision markers. Default false.
    pub collision_points: bool,
    /// Draw the ground plane with grid lines. Default true.
    pub grid: bool,
}

impl Default for DrawOptions {
    fn default() -> Self {
        Self {
            show_body: true,
            show_garment: true,
            heat_map: false,
            wireframe: false,
            collision_points: false,
            grid: true,
        }
    }
}

/// Colour of the body (sRGB 8-bit).
pub const BODY_SRGB: [u8; 3] = [196, 180, 166];
/// Colour of the outside of the garment (sRGB 8-bit).
pub const GARMENT_SRGB: [u8; 3] = [70, 132, 200];
/// Colour of the inside of the garment (sRGB 8-bit).
pub const GARMENT_BACK_SRGB: [u8; 3] = [150, 92, 70];
/// Viewport background (sRGB 8-bit).
pub const BACKGROUND_SRGB: [u8; 3] = [36, 40, 48];
/// Collision marker colour (sRGB 8-bit).
pub const COLLISION_SRGB: [u8; 3] = [255, 60, 50];

/// GPU copy of one [`MeshFrame`].
#[derive(Debug)]
struct GpuMesh {
    faces: Arc<[[u32; 3]]>,
    edges: Arc<[[u32; 2]]>,
    vertex_count: usize,
    positions: wgpu::Buffer,
    normals: wgpu::Buffer,
    colors: wgpu::Buffer,
    has_colors: bool,
    indices: wgpu::Buffer,
    index_count: u32,
    edge_indices: Option<(wgpu::Buffer, u32)>,
    params: wgpu::Buffer,
    params_group: wgpu::BindGroup,
}

impl GpuMesh {
    fn new(device: &wgpu::Device, pipelines: &Pipelines, name: &str, mesh: &MeshFrame) -> Self {
        let usage = wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST;
        let init = |what: &str, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(&format!("neural-cloth {name} {what}")),
                contents,
                usage,
            })
        };
        let positions = init("positions", bytemuck::cast_slice(&mesh.positions), usage);
        let normals = init("normals", bytemuck::cast_slice(&mesh.normals), usage);
        let colors = match &mesh.colors {
            Some(c) => init("colours", bytemuck::cast_slice(c), usage),
            None => device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(&format!("neural-cloth {name} colours")),
                size: (mesh.positions.len() * 16) as u64,
                usage,
                mapped_at_creation: false,
            }),
        };
        let indices = init(
            "indices",
            bytemuck::cast_slice(&mesh.faces),
            wgpu::BufferUsages::INDEX,
        );
        let edge_indices = (!mesh.edges.is_empty()).then(|| {
            (
                init(
                    "edge indices",
                    bytemuck::cast_slice(&mesh.edges),
                    wgpu::BufferUsages::INDEX,
                ),
                (mesh.edges.len() * 2) as u32,
            )
        });
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(&format!("neural-cloth {name} params")),
            size: std::mem::size_of::<MeshParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let params_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&format!("neural-cloth {name} params group")),
            layout: &pipelines.mesh_params_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: params.as_entire_binding(),
            }],
        });
        Self {
            faces: mesh.faces.clone(),
            edges: mesh.edges.clone(),
            vertex_count: mesh.positions.len(),
            positions,
            normals,
            colors,
            has_colors: mesh.colors.is_some(),
            indices,
            index_count: (mesh.faces.len() * 3) as u32,
            edge_indices,
            params,
            params_group,
        }
    }

    /// True when `mesh` has this mesh's vertex count and connectivity.
    fn same_topology(&self, mesh: &MeshFrame) -> bool {
        self.vertex_count == mesh.positions.len()
            && (Arc::ptr_eq(&self.faces, &mesh.faces) || self.faces == mesh.faces)
            && (Arc::ptr_eq(&self.edges, &mesh.edges) || self.edges == mesh.edges)
    }

    fn update(&mut self, queue: &wgpu::Queue, mesh: &MeshFrame) {
        queue.write_buffer(&self.positions, 0, bytemuck::cast_slice(&mesh.positions));
        queue.write_buffer(&self.normals, 0, bytemuck::cast_slice(&mesh.normals));
        if let Some(c) = &mesh.colors {
            queue.write_buffer(&self.colors, 0, bytemuck::cast_slice(c));
        }
        self.has_colors = mesh.colors.is_some();
    }
}

/// Checks that a mesh is drawable: matching lengths, indices in range, something to draw.
fn validate(name: &str, mesh: &MeshFrame) -> Result<(), RenderError> {
    let n = mesh.positions.len();
    let bad = |reason: String| {
        Err(RenderError::InvalidMesh {
            name: name.to_owned(),
            reason,
        })
    };
    if n == 0 || mesh.faces.is_empty() {
        return bad(format!(
            "{n} vertices and {} faces: nothing to draw",
            mesh.faces.len()
        ));
    }
    if mesh.normals.len() != n {
        return bad(format!("{} normals for {n} vertices", mesh.normals.len()));
    }
    if let Some(c) = &mesh.colors
        && c.len() != n
    {
        return bad(format!("{} colours for {n} vertices", c.len()));
    }
    let max_face = mesh.faces.iter().flatten().max().copied().unwrap_or(0);
    let max_edge = mesh.edges.iter().flatten().max().copied().unwrap_or(0);
    if max_face.max(max_edge) as usize >= n {
        return bad(format!(
            "index {} out of range for {n} vertices",
            max_face.max(max_edge)
        ));
    }
    if !mesh
        .positions
        .iter()
        .chain(&mesh.normals)
        .all(|p| p.iter().all(|v| v.is_finite()))
    {
        return bad("non-finite position or normal".into());
    }
    Ok(())
}

/// Draws scene frames into render targets of one colour format and sample count.
#[derive(Debug)]
pub struct Renderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    format: wgpu::TextureFormat,
    sample_count: u32,
    pipelines: Pipelines,
    globals: wgpu::Buffer,
    globals_group: wgpu::BindGroup,
    body: Option<GpuMesh>,
    garment: Option<GpuMesh>,
    points: Option<(wgpu::Buffer, usize)>,
    point_count: u32,
    ground_y: f32,
    allocations: u64,
}

impl Renderer {
    /// A renderer for 4× multisampled targets of `target_format` (use
    /// `Rgba8Unorm` for textures shown by egui; the shaders then encode sRGB themselves).
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target_format: wgpu::TextureFormat,
    ) -> Self {
        Self::with_samples(device, queue, target_format, 4)
    }

    /// Samples per pixel suited to an adapter: 4× MSAA on GPUs, 1 on software rasterisers
    /// (lavapipe/llvmpipe), where multisampling roughly doubles the frame time.
    pub fn preferred_sample_count(info: &wgpu::AdapterInfo) -> u32 {
        if info.device_type == wgpu::DeviceType::Cpu {
            1
        } else {
            4
        }
    }

    /// A renderer for targets with `sample_count` samples per pixel (1, or 4 for MSAA).
    pub fn with_samples(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target_format: wgpu::TextureFormat,
        sample_count: u32,
    ) -> Self {
        let sample_count = if sample_count > 1 { 4 } else { 1 };
        let pipelines = Pipelines::new(device, target_format, sample_count);
        let globals = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("neural-cloth globals"),
            size: std::mem::size_of::<Globals>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let globals_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("neural-cloth globals group"),
            layout: &pipelines.globals_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: globals.as_entire_binding(),
            }],
        });
        Self {
            device: device.clone(),
            queue: queue.clone(),
            format: target_format,
            sample_count,
            pipelines,
            globals,
            globals_group,
            body: None,
            garment: None,
            points: None,
            point_count: 0,
            ground_y: 0.0,
            allocations: 0,
        }
    }

    /// A render target of `size` pixels that this renderer can draw into.
    pub fn create_target(&self, size: [u32; 2]) -> RenderTarget {
        RenderTarget::new(&self.device, size, self.format, self.sample_count)
    }

    /// The device this renderer was created on.
    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// The queue this renderer writes buffers with.
    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// Uploads `frame`: creates buffers when a mesh's connectivity changed, otherwise only
    /// rewrites positions, normals and colours. An invalid mesh is dropped (not drawn) and
    /// reported; the rest of the frame is still uploaded.
    pub fn upload(&mut self, frame: &SceneFrame) -> Result<(), RenderError> {
        let (body, new_body) = Self::upload_mesh(
            &self.device,
            &self.queue,
            &self.pipelines,
            &mut self.body,
            "body",
            frame.body.as_ref(),
        );
        let (garment, new_garment) = Self::upload_mesh(
            &self.device,
            &self.queue,
            &self.pipelines,
            &mut self.garment,
            "garment",
            frame.garment.as_ref(),
        );
        self.allocations += u64::from(new_body) + u64::from(new_garment);
        self.upload_points(&frame.collision_points);
        self.ground_y = if frame.ground_y.is_finite() {
            frame.ground_y
        } else {
            0.0
        };
        body.and(garment)
    }

    /// Uploads one mesh into `slot`; the flag is true when new buffers were created.
    fn upload_mesh(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        pipelines: &Pipelines,
        slot: &mut Option<GpuMesh>,
        name: &str,
        mesh: Option<&MeshFrame>,
    ) -> (Result<(), RenderError>, bool) {
        let Some(mesh) = mesh else {
            *slot = None;
            return (Ok(()), false);
        };
        if let Err(e) = validate(name, mesh) {
            *slot = None;
            return (Err(e), false);
        }
        match slot {
            Some(gpu) if gpu.same_topology(mesh) => {
                gpu.update(queue, mesh);
                (Ok(()), false)
            }
            _ => {
                *slot = Some(GpuMesh::new(device, pipelines, name, mesh));
                (Ok(()), true)
            }
        }
    }

    fn upload_points(&mut self, points: &[neural_cloth_core::geometry::Vec3]) {
        let color = linear_rgba(COLLISION_SRGB[0], COLLISION_SRGB[1], COLLISION_SRGB[2]);
        let instances: Vec<PointInstance> = points
            .iter()
            .filter(|p| p.iter().all(|v| v.is_finite()))
            .map(|p| PointInstance {
                pos_in_world: [p.x, p.y, p.z],
                color,
            })
            .collect();
        self.point_count = instances.len() as u32;
        if instances.is_empty() {
            return;
        }
        let needed = instances.len();
        let fits = matches!(&self.points, Some((_, capacity)) if *capacity >= needed);
        if !fits {
            let capacity = needed.next_power_of_two().max(64);
            let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("neural-cloth collision markers"),
                size: (capacity * std::mem::size_of::<PointInstance>()) as u64,
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            self.points = Some((buffer, capacity));
            self.allocations += 1;
        }
        if let Some((buffer, _)) = &self.points {
            self.queue
                .write_buffer(buffer, 0, bytemuck::cast_slice(&instances));
        }
    }

    /// Writes the per-frame uniforms for `camera` looking into `target`.
    fn write_globals(&self, target: &RenderTarget, camera: &OrbitCamera, options: &DrawOptions) {
        let (right, up) = camera.right_up();
        let back = right.cross(&up);
        let light =
            neural_cloth_core::geometry::safe_normalize(-right * 0.45 + up * 0.8 + back * 0.55)
                .unwrap_or_else(neural_cloth_core::geometry::Vec3::y);
        let eye = camera.eye();
        let m = camera.clip_from_world(target.aspect());
        let mut clip_from_world = [[0.0f32; 4]; 4];
        for (c, col) in clip_from_world.iter_mut().enumerate() {
            for (r, v) in col.iter_mut().enumerate() {
                *v = m[(r, c)];
            }
        }
        let [w, h] = target.size();
        let wire = linear_rgba(18, 24, 34);
        let globals = Globals {
            clip_from_world,
            eye_in_world: [eye.x, eye.y, eye.z, 1.0],
            light_dir: [light.x, light.y, light.z, 0.0],
            background: linear_rgba(BACKGROUND_SRGB[0], BACKGROUND_SRGB[1], BACKGROUND_SRGB[2]),
            background_display: [
                f32::from(BACKGROUND_SRGB[0]) / 255.0,
                f32::from(BACKGROUND_SRGB[1]) / 255.0,
                f32::from(BACKGROUND_SRGB[2]) / 255.0,
                1.0,
            ],
            wire_color: [wire[0], wire[1], wire[2], 0.4],
            viewport: [
                w as f32,
                h as f32,
                if self.format.is_srgb() { 0.0 } else { 1.0 },
                8.0,
            ],
            grid: [
                self.ground_y,
                0.25,
                12.0,
                if options.grid { 1.0 } else { 0.0 },
            ],
        };
        self.queue
            .write_buffer(&self.globals, 0, bytemuck::bytes_of(&globals));
    }

    /// Records one render pass drawing the uploaded frame into `target`.
    pub fn render(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        target: &RenderTarget,
        camera: &OrbitCamera,
        options: &DrawOptions,
    ) -> Result<(), RenderError> {
        if target.format() != self.format || target.sample_count() != self.sample_count {
            return Err(RenderError::TargetMismatch {
                expected: format!("{:?} x{}", self.format, self.sample_count),
                found: format!("{:?} x{}", target.format(), target.sample_count()),
            });
        }
        self.write_globals(target, camera, options);
        let mesh_params =
            |base: [u8; 3], back: [u8; 3], two_sided: bool, colors: bool, specular: u32| {
                MeshParams {
                    base_color: linear_rgba(base[0], base[1], base[2]),
                    back_color: linear_rgba(back[0], back[1], back[2]),
                    flags: [u32::from(two_sided), u32::from(colors), specular, 0],
                }
            };
        if let Some(body) = &self.body {
            let p = mesh_params(BODY_SRGB, BODY_SRGB, false, false, 180);
            self.queue
                .write_buffer(&body.params, 0, bytemuck::bytes_of(&p));
        }
        if let Some(garment) = &self.garment {
            let p = mesh_params(
                GARMENT_SRGB,
                GARMENT_BACK_SRGB,
                true,
                options.heat_map && garment.has_colors,
                60,
            );
            self.queue
                .write_buffer(&garment.params, 0, bytemuck::bytes_of(&p));
        }
        let bg = BACKGROUND_SRGB.map(|c| f64::from(c) / 255.0);
        let clear = if self.format.is_srgb() {
            let l = |c: f64| f64::from(super::gpu::linear_from_srgb(c as f32));
            wgpu::Color {
                r: l(bg[0]),
                g: l(bg[1]),
                b: l(bg[2]),
                a: 1.0,
            }
        } else {
            wgpu::Color {
                r: bg[0],
                g: bg[1],
                b: bg[2],
                a: 1.0,
            }
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("neural-cloth viewport pass"),
            color_attachments: &[Some(target.color_attachment(clear))],
            depth_stencil_attachment: Some(target.depth_attachment()),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_bind_group(0, &self.globals_group, &[]);
        let shown = [
            (&self.body, options.show_body),
            (&self.garment, options.show_garment),
        ];
        pass.set_pipeline(&self.pipelines.mesh);
        for (mesh, visible) in shown {
            let (Some(mesh), true) = (mesh, visible) else {
                continue;
            };
            pass.set_bind_group(1, &mesh.params_group, &[]);
            pass.set_vertex_buffer(0, mesh.positions.slice(..));
            pass.set_vertex_buffer(1, mesh.normals.slice(..));
            pass.set_vertex_buffer(2, mesh.colors.slice(..));
            pass.set_index_buffer(mesh.indices.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..mesh.index_count, 0, 0..1);
        }
        if options.grid {
            pass.set_pipeline(&self.pipelines.grid);
            pass.draw(0..6, 0..1);
        }
        if let (true, true, Some(garment)) =
            (options.wireframe, options.show_garment, &self.garment)
            && let Some((edges, count)) = &garment.edge_indices
        {
            pass.set_pipeline(&self.pipelines.lines);
            pass.set_vertex_buffer(0, garment.positions.slice(..));
            pass.set_index_buffer(edges.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..*count, 0, 0..1);
        }
        if let (true, Some((points, _))) = (
            options.collision_points && self.point_count > 0,
            &self.points,
        ) {
            pass.set_pipeline(&self.pipelines.points);
            pass.set_vertex_buffer(0, points.slice(..));
            pass.draw(0..6, 0..self.point_count);
        }
        Ok(())
    }

    /// How many times this renderer has created GPU buffers for a mesh or for the collision
    /// markers (a new connectivity or more markers than fit). Playing a motion or moving the
    /// camera only rewrites buffers, so this stays put; the leak test checks that it does.
    pub fn buffer_allocations(&self) -> u64 {
        self.allocations
    }
}
