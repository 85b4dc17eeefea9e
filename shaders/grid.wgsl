// Ground: a large square at the ground height with anti-aliased grid lines (1 m major,
// `grid.y` minor) fading into the background with distance;
// it faces +Y and is culled from below. `common.wgsl` is prepended.

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) pos_in_world: vec3<f32>,
};

@vertex
fn vs_main(@builtin(vertex_index) vertex_index: u32) -> VertexOut {
    var corners = array<vec2<f32>, 6>(
        vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, 1.0), vec2<f32>(1.0, -1.0),
        vec2<f32>(-1.0, -1.0), vec2<f32>(-1.0, 1.0), vec2<f32>(1.0, 1.0),
    );
    let c = corners[vertex_index % 6u] * globals.grid.z;
    let centre = floor(globals.eye_in_world.xz);
    let p = vec3<f32>(c.x + centre.x, globals.grid.x, c.y + centre.y);
    var out: VertexOut;
    out.clip = globals.clip_from_world * vec4<f32>(p, 1.0);
    out.pos_in_world = p;
    return out;
}

// Coverage of lines of the given spacing at `xz`, anti-aliased over one pixel.
fn grid_lines(xz: vec2<f32>, spacing: f32, width_px: f32) -> f32 {
    let coord = xz / spacing;
    let deriv = max(fwidth(coord), vec2<f32>(1e-6));
    let g = abs(fract(coord - 0.5) - 0.5) / deriv;
    let line = min(g.x, g.y);
    return 1.0 - clamp(line - 0.5 * width_px + 0.5, 0.0, 1.0);
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    let xz = in.pos_in_world.xz;
    let floor_color = globals.background.rgb * 1.18 + vec3<f32>(0.012);
    var color = floor_color;
    if globals.grid.w > 0.5 {
        let minor = grid_lines(xz, max(globals.grid.y, 1e-3), 1.0);
        let major = grid_lines(xz, 1.0, 1.6);
        color = mix(color, vec3<f32>(0.27, 0.29, 0.33), minor * 0.35);
        color = mix(color, vec3<f32>(0.40, 0.43, 0.48), major * 0.6);
        // Axis lines: X red, Z blue.
        let axis = abs(xz) / max(fwidth(xz), vec2<f32>(1e-6));
        color = mix(color, vec3<f32>(0.62, 0.22, 0.22), 1.0 - clamp(axis.y - 0.8, 0.0, 1.0));
        color = mix(color, vec3<f32>(0.22, 0.32, 0.66), 1.0 - clamp(axis.x - 0.8, 0.0, 1.0));
    }
    // Fade into the background with distance from the camera's footprint.
    let dist = length(in.pos_in_world - globals.eye_in_world.xyz);
    let fade = clamp(1.0 - dist / (0.9 * globals.grid.z), 0.0, 1.0);
    let alpha = fade * fade;
    return encode_output(mix(globals.background.rgb, color, alpha), 1.0);
}
