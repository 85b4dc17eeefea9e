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

// Coverage (0..1) of lines `width_px` wide at distance `g_px` pixels from the nearest line.
fn line_coverage(g_px: vec2<f32>, width_px: f32) -> f32 {
    return 1.0 - clamp(min(g_px.x, g_px.y) - 0.5 * width_px + 0.5, 0.0, 1.0);
}

// Blended in display (gamma) space with display-space constants: no per-pixel transfer
// function, which matters on software rasterisers where the ground covers half the screen.
@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    let xz = in.pos_in_world.xz;
    let background = globals.background_display.rgb;
    var color = background + vec3<f32>(0.052);
    // One derivative serves every line family: fwidth(xz / s) = fwidth(xz) / s.
    let fw = max(fwidth(xz), vec2<f32>(1e-6));
    let cell = max(globals.grid.y, 1e-3);
    let minor = line_coverage(abs(fract(xz / cell - 0.5) - 0.5) * cell / fw, 1.0);
    let major = line_coverage(abs(fract(xz - 0.5) - 0.5) / fw, 1.6);
    color = mix(color, vec3<f32>(0.56, 0.58, 0.61), minor * 0.35);
    color = mix(color, vec3<f32>(0.66, 0.68, 0.72), major * 0.7);
    // Axis lines: X red, Z blue.
    let axis = abs(xz) / fw;
    color = mix(color, vec3<f32>(0.81, 0.51, 0.51), 1.0 - clamp(axis.y - 0.8, 0.0, 1.0));
    color = mix(color, vec3<f32>(0.51, 0.60, 0.83), 1.0 - clamp(axis.x - 0.8, 0.0, 1.0));
    // Fade into the background with distance from the camera.
    let dist = length(in.pos_in_world - globals.eye_in_world.xyz);
    let fade = clamp(1.0 - dist / (0.9 * globals.grid.z), 0.0, 1.0);
    let out = mix(background, color, fade * fade);
    // sRGB target: the hardware encodes, so hand it (approximately) linear values. A select,
    // not a branch on a uniform (see the note in mesh.wgsl).
    return vec4<f32>(select(out * out, out, globals.viewport.z > 0.5), 1.0);
}
