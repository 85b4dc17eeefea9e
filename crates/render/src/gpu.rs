//! Plain-old-data structs shared with the WGSL shaders (`#[repr(C)]`, `bytemuck::Pod`, padded
//! to WGSL's uniform layout), plus colour helpers: sRGB conversion and the strain heat-map.

use bytemuck::{Pod, Zeroable};

/// Per-frame uniform; matches `Globals` in `shaders/common.wgsl` (176 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct Globals {
    /// `clip_from_world`, column-major.
    pub clip_from_world: [[f32; 4]; 4],
    /// xyz: camera position in world space, metres; w unused.
    pub eye_in_world: [f32; 4],
    /// xyz: unit direction towards the key light, world space; w unused.
    pub light_dir: [f32; 4],
    /// Linear RGBA background colour.
    pub background: [f32; 4],
    /// The background in display (sRGB-encoded) space.
    pub background_display: [f32; 4],
    /// Linear RGBA wireframe colour.
    pub wire_color: [f32; 4],
    /// Target width and height in pixels, sRGB-encode flag (1 or 0), marker diameter in pixels.
    pub viewport: [f32; 4],
    /// Ground height (m), minor grid cell (m), grid half extent (m), grid-lines flag (1 or 0).
    pub grid: [f32; 4],
}

/// Per-mesh uniform; matches `MeshParams` in `shaders/mesh.wgsl` (48 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct MeshParams {
    /// Linear RGBA colour of front faces.
    pub base_color: [f32; 4],
    /// Linear RGBA colour of back faces, used when two-sided.
    pub back_color: [f32; 4],
    /// x: two-sided (1/0); y: per-vertex colours (1/0); z: specular strength × 1000; w unused.
    pub flags: [u32; 4],
}

/// One collision marker instance; matches the `points.wgsl` vertex inputs (28 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct PointInstance {
    /// Marker centre, world space, metres.
    pub pos_in_world: [f32; 3],
    /// Linear RGBA colour.
    pub color: [f32; 4],
}

/// Converts an sRGB-encoded colour channel in 0..1 to linear.
pub fn linear_from_srgb(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Converts an sRGB 8-bit colour to linear RGBA with alpha 1.
pub fn linear_rgba(r: u8, g: u8, b: u8) -> [f32; 4] {
    let f = |c: u8| linear_from_srgb(f32::from(c) / 255.0);
    [f(r), f(g), f(b), 1.0]
}

/// Heat-map colour (linear RGBA) for `value` in `[0, max]`: blue (0) through cyan, green and
/// yellow to red (`max` or more). Non-finite values and a non-positive `max` give blue.
pub fn heat_color(value: f32, max: f32) -> [f32; 4] {
    let t = if value.is_finite() && max > 0.0 {
        (value / max).clamp(0.0, 1.0)
    } else {
        0.0
    };
    // Piecewise-linear stops in sRGB space, then converted to linear.
    const STOPS: [(f32, [u8; 3]); 5] = [
        (0.0, [40, 70, 200]),
        (0.25, [40, 180, 220]),
        (0.5, [70, 200, 90]),
        (0.75, [240, 210, 50]),
        (1.0, [220, 40, 40]),
    ];
    let mut lo = STOPS[0];
    let mut hi = STOPS[STOPS.len() - 1];
    for pair in STOPS.windows(2) {
        if let [a, b] = pair
            && t >= a.0
            && t <= b.0
        {
            lo = *a;
            hi = *b;
            break;
        }
    }
    let span = hi.0 - lo.0;
    let u = if span > 0.0 { (t - lo.0) / span } else { 0.0 };
    let mix = |k: usize| {
        let c = f32::from(lo.1[k]) * (1.0 - u) + f32::from(hi.1[k]) * u;
        linear_from_srgb(c / 255.0)
    };
    [mix(0), mix(1), mix(2), 1.0]
}

/// Averages per-edge values (e.g. strain) onto vertices: each vertex gets the mean of the
/// values of its incident edges (0 for isolated vertices). Edges with an out-of-range vertex
/// and non-finite values are skipped; extra or missing values are ignored.
pub fn vertex_values_from_edges(
    vertex_count: usize,
    edges: &[[u32; 2]],
    values: &[f32],
) -> Vec<f32> {
    let mut sum = vec![0.0f32; vertex_count];
    let mut count = vec![0u32; vertex_count];
    for (edge, &v) in edges.iter().zip(values) {
        if !v.is_finite() {
            continue;
        }
        for &i in edge {
            if let (Some(s), Some(c)) = (sum.get_mut(i as usize), count.get_mut(i as usize)) {
                *s += v;
                *c += 1;
            }
        }
    }
    sum.iter()
        .zip(&count)
        .map(|(s, &c)| if c > 0 { s / c as f32 } else { 0.0 })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_sizes_match_wgsl() {
        assert_eq!(std::mem::size_of::<Globals>(), 176);
        assert_eq!(std::mem::size_of::<MeshParams>(), 48);
        assert_eq!(std::mem::size_of::<PointInstance>(), 28);
    }

    #[test]
    fn heat_map_runs_blue_to_red() {
        let cold = heat_color(0.0, 0.1);
        let hot = heat_color(0.2, 0.1);
        assert!(cold[2] > cold[0] && hot[0] > hot[2]);
        assert_eq!(heat_color(f32::NAN, 1.0), cold);
        assert_eq!(heat_color(1.0, 0.0), cold);
        let mid = heat_color(0.5, 1.0);
        assert!(mid[1] > mid[0] && mid[1] > mid[2]);
    }

    #[test]
    fn srgb_round_values() {
        assert_eq!(linear_from_srgb(0.0), 0.0);
        assert!((linear_from_srgb(1.0) - 1.0).abs() < 1e-6);
        assert!((linear_from_srgb(0.5) - 0.214).abs() < 1e-3);
    }

    #[test]
    fn edge_values_average_onto_vertices() {
        let v = vertex_values_from_edges(4, &[[0, 1], [1, 2], [2, 9]], &[1.0, 3.0, f32::NAN]);
        assert_eq!(v, vec![1.0, 2.0, 3.0, 0.0]);
    }
}
