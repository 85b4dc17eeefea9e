// Wireframe: the garment's edges drawn as a line list over its own position buffer, pulled
// slightly towards the camera so they win the depth test against their own surface.
// `common.wgsl` is prepended.

@vertex
fn vs_main(@location(0) pos_in_world: vec3<f32>) -> @builtin(position) vec4<f32> {
    var clip = globals.clip_from_world * vec4<f32>(pos_in_world, 1.0);
    // Reversed-Z: a larger depth is nearer. Scale depth up by 0.2% (about 2 mm at 1 m).
    clip.z = clip.z * 1.002;
    return clip;
}

@fragment
fn fs_main() -> @location(0) vec4<f32> {
    return encode_output(globals.wire_color.rgb, globals.wire_color.a);
}
