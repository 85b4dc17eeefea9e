//! Render pipelines: shaded meshes, wireframe lines, collision-marker discs and the ground
//! grid, all drawing into a [`super::RenderTarget`] of one colour format and sample count.

use super::target::DEPTH_FORMAT;

/// WGSL shared by every shader (the `Globals` uniform and output encoding).
const COMMON_WGSL: &str = include_str!("../shaders/common.wgsl");
/// Shaded triangle meshes.
const MESH_WGSL: &str = include_str!("../shaders/mesh.wgsl");
/// Wireframe lines.
const LINES_WGSL: &str = include_str!("../shaders/lines.wgsl");
/// Collision markers.
const POINTS_WGSL: &str = include_str!("../shaders/points.wgsl");
/// Ground grid.
const GRID_WGSL: &str = include_str!("../shaders/grid.wgsl");

/// The WGSL source of each shader with `common.wgsl` prepended, by name (for tests/tools).
pub fn shader_sources() -> [(&'static str, String); 4] {
    [
        ("mesh", format!("{COMMON_WGSL}\n{MESH_WGSL}")),
        ("lines", format!("{COMMON_WGSL}\n{LINES_WGSL}")),
        ("points", format!("{COMMON_WGSL}\n{POINTS_WGSL}")),
        ("grid", format!("{COMMON_WGSL}\n{GRID_WGSL}")),
    ]
}

/// Bind group layouts and pipelines, created once per device and target format.
#[derive(Debug)]
pub struct Pipelines {
    /// Layout of group 0: the `Globals` uniform.
    pub globals_layout: wgpu::BindGroupLayout,
    /// Layout of group 1 for meshes: the `MeshParams` uniform.
    pub mesh_params_layout: wgpu::BindGroupLayout,
    /// Shaded triangles (position, normal, colour streams).
    pub mesh: wgpu::RenderPipeline,
    /// Line list over a position stream.
    pub lines: wgpu::RenderPipeline,
    /// Instanced discs.
    pub points: wgpu::RenderPipeline,
    /// Ground plane.
    pub grid: wgpu::RenderPipeline,
}

fn uniform_layout(device: &wgpu::Device, label: &str) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        }],
    })
}

fn module(device: &wgpu::Device, name: &str, source: String) -> wgpu::ShaderModule {
    device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(&format!("neural-cloth {name} shader")),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    })
}

const fn vec3_stream(location: u32) -> [wgpu::VertexAttribute; 1] {
    [wgpu::VertexAttribute {
        format: wgpu::VertexFormat::Float32x3,
        offset: 0,
        shader_location: location,
    }]
}

const POSITION_ATTR: [wgpu::VertexAttribute; 1] = vec3_stream(0);
const NORMAL_ATTR: [wgpu::VertexAttribute; 1] = vec3_stream(1);
const COLOR_ATTR: [wgpu::VertexAttribute; 1] = [wgpu::VertexAttribute {
    format: wgpu::VertexFormat::Float32x4,
    offset: 0,
    shader_location: 2,
}];
const POINT_ATTRS: [wgpu::VertexAttribute; 2] = [
    wgpu::VertexAttribute {
        format: wgpu::VertexFormat::Float32x3,
        offset: 0,
        shader_location: 0,
    },
    wgpu::VertexAttribute {
        format: wgpu::VertexFormat::Float32x4,
        offset: 12,
        shader_location: 1,
    },
];

fn stream(
    stride: u64,
    attributes: &'static [wgpu::VertexAttribute],
    step_mode: wgpu::VertexStepMode,
) -> Option<wgpu::VertexBufferLayout<'static>> {
    Some(wgpu::VertexBufferLayout {
        array_stride: stride,
        step_mode,
        attributes,
    })
}

/// Settings that differ between the pipelines.
struct PipelineSpec<'a> {
    name: &'a str,
    module: &'a wgpu::ShaderModule,
    layout: &'a wgpu::PipelineLayout,
    buffers: &'a [Option<wgpu::VertexBufferLayout<'a>>],
    topology: wgpu::PrimitiveTopology,
    cull_mode: Option<wgpu::Face>,
    depth_write: bool,
    blend: Option<wgpu::BlendState>,
}

fn pipeline(
    device: &wgpu::Device,
    format: wgpu::TextureFormat,
    samples: u32,
    spec: PipelineSpec<'_>,
) -> wgpu::RenderPipeline {
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(&format!("neural-cloth {} pipeline", spec.name)),
        layout: Some(spec.layout),
        vertex: wgpu::VertexState {
            module: spec.module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: spec.buffers,
        },
        primitive: wgpu::PrimitiveState {
            topology: spec.topology,
            strip_index_format: None,
            front_face: wgpu::FrontFace::Ccw,
            cull_mode: spec.cull_mode,
            unclipped_depth: false,
            polygon_mode: wgpu::PolygonMode::Fill,
            conservative: false,
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(spec.depth_write),
            depth_compare: Some(wgpu::CompareFunction::GreaterEqual),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: wgpu::MultisampleState {
            count: samples,
            mask: !0,
            alpha_to_coverage_enabled: false,
        },
        fragment: Some(wgpu::FragmentState {
            module: spec.module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format,
                blend: spec.blend,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

impl Pipelines {
    /// Compiles the shaders and builds every pipeline for `format` and `samples` (1 or 4).
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat, samples: u32) -> Self {
        let globals_layout = uniform_layout(device, "neural-cloth globals layout");
        let mesh_params_layout = uniform_layout(device, "neural-cloth mesh params layout");
        let global_only = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("neural-cloth globals pipeline layout"),
            bind_group_layouts: &[Some(&globals_layout)],
            immediate_size: 0,
        });
        let mesh_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("neural-cloth mesh pipeline layout"),
            bind_group_layouts: &[Some(&globals_layout), Some(&mesh_params_layout)],
            immediate_size: 0,
        });
        let [mesh_src, lines_src, points_src, grid_src] = shader_sources();
        let mesh_module = module(device, mesh_src.0, mesh_src.1);
        let lines_module = module(device, lines_src.0, lines_src.1);
        let points_module = module(device, points_src.0, points_src.1);
        let grid_module = module(device, grid_src.0, grid_src.1);
        let vertex = wgpu::VertexStepMode::Vertex;
        let alpha_blend = Some(wgpu::BlendState::ALPHA_BLENDING);
        let mesh = pipeline(
            device,
            format,
            samples,
            PipelineSpec {
                name: "mesh",
                module: &mesh_module,
                layout: &mesh_layout,
                buffers: &[
                    stream(12, &POSITION_ATTR, vertex),
                    stream(12, &NORMAL_ATTR, vertex),
                    stream(16, &COLOR_ATTR, vertex),
                ],
                topology: wgpu::PrimitiveTopology::TriangleList,
                cull_mode: None,
                depth_write: true,
                blend: None,
            },
        );
        let lines = pipeline(
            device,
            format,
            samples,
            PipelineSpec {
                name: "lines",
                module: &lines_module,
                layout: &global_only,
                buffers: &[stream(12, &POSITION_ATTR, vertex)],
                topology: wgpu::PrimitiveTopology::LineList,
                cull_mode: None,
                depth_write: false,
                blend: alpha_blend,
            },
        );
        let points = pipeline(
            device,
            format,
            samples,
            PipelineSpec {
                name: "points",
                module: &points_module,
                layout: &global_only,
                buffers: &[stream(28, &POINT_ATTRS, wgpu::VertexStepMode::Instance)],
                topology: wgpu::PrimitiveTopology::TriangleList,
                cull_mode: None,
                depth_write: true,
                blend: None,
            },
        );
        let grid = pipeline(
            device,
            format,
            samples,
            PipelineSpec {
                name: "grid",
                module: &grid_module,
                layout: &global_only,
                buffers: &[],
                topology: wgpu::PrimitiveTopology::TriangleList,
                cull_mode: Some(wgpu::Face::Back),
                depth_write: true,
                blend: None,
            },
        );
        Self {
            globals_layout,
            mesh_params_layout,
            mesh,
            lines,
            points,
            grid,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_shader_parses_and_validates() {
        for (name, source) in shader_sources() {
            let module = wgpu::naga::front::wgsl::parse_str(&source)
                .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&source)));
            let mut validator = wgpu::naga::valid::Validator::new(
                wgpu::naga::valid::ValidationFlags::all(),
                wgpu::naga::valid::Capabilities::empty(),
            );
            validator
                .validate(&module)
                .unwrap_or_else(|e| panic!("{name}: {e:?}"));
        }
    }

    /// Issue 15: lavapipe compiled (and kept) a new shader variant on every draw of a pipeline
    /// whose shader branched on a uniform, about 1 MB a draw. Uniform-driven choices are
    /// `select`s; `tests/leak.rs` measures the memory.
    #[test]
    fn no_shader_branches_on_a_uniform() {
        for (name, source) in shader_sources() {
            for (n, line) in source.lines().enumerate() {
                let code = line.split("//").next().unwrap_or_default();
                let branches = code.contains("if ") || code.contains("while ");
                let on_uniform = code.contains("globals.") || code.contains("params.");
                assert!(
                    !(branches && on_uniform),
                    "{name} line {}: a branch on a uniform: {line}",
                    n + 1
                );
            }
        }
    }
}
