// Collision markers: one screen-aligned disc per instance, a fixed size in pixels, drawn on
// top of the surfaces they sit on. `common.wgsl` is prepended.

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) corner: vec2<f32>,
    @location(1) color: vec4<f32>,
};

@vertex
fn vs_main(
    @builtin(vertex_index) vertex_index: u32,
    @location(0) pos_in_world: vec3<f32>,
    @location(1) color: vec4<f32>,
) -> VertexOut {
    // Two triangles covering [-1, 1]^2.
    var corners = array<vec2<f32>, 6>(
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, -1.0), vec2<f32>(1.0, 1.0),
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, 1.0), vec2<f32>(-1.0, 1.0),
    );
    let corner = corners[vertex_index % 6u];
    var clip = globals.clip_from_world * vec4<f32>(pos_in_world, 1.0);
    let size_px = max(globals.viewport.w, 1.0);
    let px_to_ndc = vec2<f32>(2.0 / max(globals.viewport.x, 1.0), 2.0 / max(globals.viewport.y, 1.0));
    clip = vec4<f32>(clip.xy + corner * 0.5 * size_px * px_to_ndc * clip.w, clip.z * 1.01, clip.w);
    var out: VertexOut;
    out.clip = clip;
    out.corner = corner;
    out.color = color;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    let r = length(in.corner);
    if r > 1.0 {
        discard;
    }
    // Dark outline for contrast on any background.
    let rgb = select(in.color.rgb, in.color.rgb * 0.35, r > 0.7);
    return encode_output(rgb, 1.0);
}
