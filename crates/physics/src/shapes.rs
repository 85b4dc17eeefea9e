//! Small procedural meshes for benchmarks, tests and quick experiments: a rectangular sheet, a
//! closed UV sphere (outward normals) and an open tube (a skirt-like cylinder).

use neural_cloth_core::geometry::{TriMesh, Vec3};

/// A `(nu+1) x (nv+1)` vertex sheet spanning `origin + s·u_m + t·v_m` for `s, t ∈ [0, 1]`.
/// Triangles are counter-clockwise seen from `u × v`.
pub fn sheet(nu: usize, nv: usize, origin: Vec3, u_m: Vec3, v_m: Vec3) -> TriMesh {
    let (nu, nv) = (nu.max(1), nv.max(1));
    let mut positions = Vec::with_capacity((nu + 1) * (nv + 1));
    for j in 0..=nv {
        for i in 0..=nu {
            positions.push(origin + u_m * (i as f32 / nu as f32) + v_m * (j as f32 / nv as f32));
        }
    }
    let mut faces = Vec::with_capacity(2 * nu * nv);
    let row = (nu + 1) as u32;
    for j in 0..nv as u32 {
        for i in 0..nu as u32 {
            let a = j * row + i;
            let (b, c, d) = (a + 1, a + row, a + row + 1);
            if (i + j) % 2 == 0 {
                faces.push([a, b, d]);
                faces.push([a, d, c]);
            } else {
                faces.push([a, b, c]);
                faces.push([b, d, c]);
            }
        }
    }
    TriMesh {
        positions,
        faces,
        uvs: None,
    }
}

/// A closed UV sphere with `rings >= 2` latitude bands and `segments >= 3` longitudes, outward
/// counter-clockwise triangles.
pub fn uv_sphere(center: Vec3, radius_m: f32, rings: usize, segments: usize) -> TriMesh {
    let (rings, segments) = (rings.max(2), segments.max(3));
    let mut positions = vec![center + Vec3::y() * radius_m];
    for r in 1..rings {
        let phi = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segments {
            let theta = std::f32::consts::TAU * s as f32 / segments as f32;
            let dir = Vec3::new(phi.sin() * theta.cos(), phi.cos(), -phi.sin() * theta.sin());
            positions.push(center + dir * radius_m);
        }
    }
    positions.push(center - Vec3::y() * radius_m);
    let bottom = (positions.len() - 1) as u32;
    let seg = segments as u32;
    let at = |r: u32, s: u32| 1 + r * seg + (s % seg);
    let mut faces = Vec::new();
    for s in 0..seg {
        faces.push([0, at(0, s), at(0, s + 1)]);
    }
    for r in 0..(rings as u32 - 2) {
        for s in 0..seg {
            let (a, b, c, d) = (at(r, s), at(r, s + 1), at(r + 1, s), at(r + 1, s + 1));
            faces.push([a, c, d]);
            faces.push([a, d, b]);
        }
    }
    let last = rings as u32 - 2;
    for s in 0..seg {
        faces.push([bottom, at(last, s + 1), at(last, s)]);
    }
    TriMesh {
        positions,
        faces,
        uvs: None,
    }
}

/// An open vertical tube (no caps) around the Y axis through `center`: `around >= 3` segments,
/// `rows >= 1` bands between `y_bottom` and `y_top`, radius growing linearly from `r_top` to
/// `r_bottom` (a flared skirt when `r_bottom > r_top`). Normals point outwards.
pub fn tube(
    center: Vec3,
    r_top_m: f32,
    r_bottom_m: f32,
    y_top_m: f32,
    y_bottom_m: f32,
    around: usize,
    rows: usize,
) -> TriMesh {
    let (around, rows) = (around.max(3), rows.max(1));
    let mut positions = Vec::with_capacity(around * (rows + 1));
    for j in 0..=rows {
        let t = j as f32 / rows as f32;
        let (r, y) = (
            r_top_m + (r_bottom_m - r_top_m) * t,
            y_top_m + (y_bottom_m - y_top_m) * t,
        );
        for i in 0..around {
            let theta = std::f32::consts::TAU * i as f32 / around as f32;
            positions.push(center + Vec3::new(r * theta.cos(), y, -r * theta.sin()));
        }
    }
    let n = around as u32;
    let mut faces = Vec::new();
    for j in 0..rows as u32 {
        for i in 0..n {
            let (a, b) = (j * n + i, j * n + (i + 1) % n);
            let (c, d) = (a + n, b + n);
            faces.push([a, c, d]);
            faces.push([a, d, b]);
        }
    }
    TriMesh {
        positions,
        faces,
        uvs: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_are_valid_with_outward_normals() {
        let s = uv_sphere(Vec3::new(0.0, 1.0, 0.0), 0.5, 8, 12);
        s.validate().unwrap();
        assert!(s.report().is_clean());
        for (p, n) in s.positions.iter().zip(s.vertex_normals()) {
            assert!((p - Vec3::new(0.0, 1.0, 0.0)).dot(&n) > 0.0);
        }
        let area: f32 = s.face_areas().iter().sum();
        assert!((area - std::f32::consts::PI).abs() < 0.2, "{area}");
        let t = tube(Vec3::zeros(), 0.2, 0.3, 1.0, 0.5, 16, 4);
        assert!(t.report().is_clean());
        for (p, n) in t.positions.iter().zip(t.vertex_normals()) {
            assert!(Vec3::new(p.x, 0.0, p.z).dot(&n) > 0.0);
        }
        let g = sheet(3, 2, Vec3::zeros(), Vec3::x(), Vec3::z() * 2.0);
        assert_eq!((g.positions.len(), g.faces.len()), (12, 12));
        assert!((g.face_areas().iter().sum::<f32>() - 2.0).abs() < 1e-5);
    }
}
