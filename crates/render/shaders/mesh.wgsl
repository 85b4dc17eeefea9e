// Shaded triangle meshes (avatar body and garment) with per-vertex normals, optional
// per-vertex colours (strain heat-map) and two-sided lighting for cloth.
// `common.wgsl` is prepended.

struct MeshParams {
    // Linear RGB colour of front faces; a: opacity.
    base_color: vec4<f32>,
    // Linear RGB colour of back faces (used when two-sided).
    back_color: vec4<f32>,
    // x: 1 = two-sided (cloth); y: 1 = use per-vertex colours; z: specular strength (x1000).
    flags: vec4<u32>,
};

@group(1) @binding(0) var<uniform> params: MeshParams;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) pos_in_world: vec3<f32>,
    @location(1) normal_in_world: vec3<f32>,
    @location(2) color: vec4<f32>,
};

@vertex
fn vs_main(
    @location(0) pos_in_world: vec3<f32>,
    @location(1) normal_in_world: vec3<f32>,
    @location(2) color: vec4<f32>,
) -> VertexOut {
    var out: VertexOut;
    out.clip = globals.clip_from_world * vec4<f32>(pos_in_world, 1.0);
    out.pos_in_world = pos_in_world;
    out.normal_in_world = normal_in_world;
    out.color = color;
    return out;
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    let two_sided = params.flags.x == 1u;
    // Selects, not branches on uniforms: Mesa's lavapipe (22.3) specialises a shader for the
    // values of uniforms that steer an `if` and compiled a new variant on every draw of this
    // pipeline, keeping about 1 MB each for good (issue 15's leak: ~2 MB per viewport frame).
    let sided = select(params.base_color.rgb, params.back_color.rgb, two_sided && !front);
    let base = select(sided, in.color.rgb, params.flags.y == 1u);
    // Normals of zero length (never expected) fall back to the view direction.
    let to_eye = globals.eye_in_world.xyz - in.pos_in_world;
    let v = normalize(select(vec3<f32>(0.0, 1.0, 0.0), to_eye, dot(to_eye, to_eye) > 1e-12));
    var n = in.normal_in_world;
    n = select(v, normalize(n), dot(n, n) > 1e-12);
    if !front {
        n = -n;
    }
    let l = globals.light_dir.xyz;
    // Hemisphere ambient: cool sky above, warm bounce from the ground.
    let sky = vec3<f32>(0.60, 0.66, 0.76);
    let ground = vec3<f32>(0.30, 0.27, 0.24);
    let ambient = mix(ground, sky, 0.5 + 0.5 * n.y);
    // Wrapped diffuse softens the terminator, which suits cloth.
    let diffuse = max((dot(n, l) + 0.25) / 1.25, 0.0);
    // A fill light from the camera side keeps shadowed folds readable.
    let fill = max(dot(n, v), 0.0);
    let h = normalize(l + v);
    let spec_strength = f32(params.flags.z) / 1000.0;
    let spec = spec_strength * pow(max(dot(n, h), 0.0), 48.0);
    let rim = 0.12 * pow(1.0 - max(dot(n, v), 0.0), 3.0);
    let lit = base * (0.42 * ambient + 0.78 * diffuse + 0.18 * fill) + vec3<f32>(spec + rim);
    return encode_output(lit, 1.0);
}
