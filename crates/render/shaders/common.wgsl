// Shared declarations, prepended to every neural-cloth shader (see src/render/pipelines.rs).
// Must match `Globals` in src/render/gpu.rs byte for byte.

struct Globals {
    clip_from_world: mat4x4<f32>,
    // xyz: camera position in world space (metres).
    eye_in_world: vec4<f32>,
    // xyz: unit direction towards the key light, world space.
    light_dir: vec4<f32>,
    // rgb: linear background colour; a: 1.
    background: vec4<f32>,
    // rgb: the background in display (sRGB-encoded) space.
    background_display: vec4<f32>,
    // rgb: linear wireframe colour; a: opacity.
    wire_color: vec4<f32>,
    // x, y: target size in pixels; z: 1 to encode sRGB in the shader (linear target), 0 otherwise;
    // w: collision marker diameter in pixels.
    viewport: vec4<f32>,
    // x: ground height (m); y: grid cell size (m); z: grid half extent (m); w: 1 to draw grid lines.
    grid: vec4<f32>,
};

@group(0) @binding(0) var<uniform> globals: Globals;

// 0-1 sRGB gamma from 0-1 linear.
fn gamma_from_linear(rgb: vec3<f32>) -> vec3<f32> {
    let c = clamp(rgb, vec3<f32>(0.0), vec3<f32>(1.0));
    let cutoff = c < vec3<f32>(0.0031308);
    let lower = c * 12.92;
    let higher = 1.055 * pow(c, vec3<f32>(1.0 / 2.4)) - 0.055;
    return select(higher, lower, cutoff);
}

// Final output: linear colour, encoded for the target format.
fn encode_output(rgb: vec3<f32>, alpha: f32) -> vec4<f32> {
    // A select, not a branch on a uniform (see the note in mesh.wgsl).
    let encoded = select(rgb, gamma_from_linear(rgb), globals.viewport.z > 0.5);
    return vec4<f32>(encoded, alpha);
}
