//! Fused bending energy `k Σ_h w_h (θ_h - θ̄_h)²` with its gradient, following
//! [`crate::physics::energies::bending`] step by step: face normals scaled by their rest
//! `1/|c̄|`, the hinge edge normalised with the edge regulariser, the angle change taken as
//! `atan2(sin(θ-θ̄), cos(θ-θ̄))`, and collapsed hinges (`sin² + cos² < 1e-12`) contributing a
//! zero angle change with zero gradient.
//!
//! Normals are recomputed per hinge rather than stored per face: two cross products per hinge
//! cost less than a scratch array of face normals and its second pass, and keep the kernel free
//! of per-sample buffers beyond the gradient.

use crate::physics::energies::bending::COLLAPSED;
use crate::physics::rest::GarmentRest;

use super::{Real, add_to, axpy, cross, dot, scale, sub, vertex};

/// Corners, `x1 - x0`, `x2 - x0` and the scaled normal `s (x1 - x0) × (x2 - x0)` of face `f`.
#[inline(always)]
fn face_normal<T: Real>(
    rest: &GarmentRest,
    x: &[T],
    f: usize,
) -> ([usize; 3], [f64; 3], [f64; 3], [f64; 3]) {
    let corners = rest.faces[f].map(|i| i as usize);
    let x0 = vertex(x, corners[0]);
    let a = sub(vertex(x, corners[1]), x0);
    let b = sub(vertex(x, corners[2]), x0);
    let n = scale(cross(a, b), rest.face_normal_scale[f]);
    (corners, a, b, n)
}

/// Pulls the gradient `gn` of a scaled face normal back to the face's corners.
#[inline(always)]
fn add_normal_gradient(
    g: &mut [f64],
    corners: [usize; 3],
    a: [f64; 3],
    b: [f64; 3],
    gn: [f64; 3],
    s: f64,
) {
    // n = s a × b: δn = s (δa × b + a × δb), so ∂/∂a = s b × gn and ∂/∂b = s gn × a.
    let gns = scale(gn, s);
    let ga = cross(b, gns);
    let gb = cross(gns, a);
    add_to(g, corners[1], ga, 1.0);
    add_to(g, corners[2], gb, 1.0);
    add_to(
        g,
        corners[0],
        [ga[0] + gb[0], ga[1] + gb[1], ga[2] + gb[2]],
        -1.0,
    );
}

/// Bending energy of one sample, its gradient added to `g`.
pub fn bending<T: Real>(rest: &GarmentRest, k: f64, x: &[T], g: &mut [f64]) -> f64 {
    let eps2 = rest.edge_eps2_m2;
    let mut e = 0.0;
    for h in 0..rest.hinges.len() {
        let w = rest.hinge_weight[h];
        if w == 0.0 {
            continue;
        }
        let [e0, e1, ..] = rest.hinges[h].map(|i| i as usize);
        let [f0, f1] = rest.hinge_faces[h].map(|f| f as usize);
        let (rc, rs) = (rest.hinge_rest_cos[h], rest.hinge_rest_sin[h]);
        let (c0, a0, b0, n0) = face_normal(rest, x, f0);
        let (c1, a1, b1, n1) = face_normal(rest, x, f1);
        let edge = sub(vertex(x, e1), vertex(x, e0));
        let l = (dot(edge, edge) + eps2).sqrt();
        let u = scale(edge, 1.0 / l);
        let n0xn1 = cross(n0, n1);
        let sin = dot(n0xn1, u);
        let cos = dot(n0, n1);
        let y = sin * rc - cos * rs;
        let xx = cos * rc + sin * rs;
        let r2 = y * y + xx * xx;
        if r2 < COLLAPSED {
            continue;
        }
        let delta = y.atan2(xx);
        e += w * delta * delta;
        let gd = 2.0 * k * w * delta;
        let (gy, gx) = (gd * xx / r2, -gd * y / r2);
        let gsin = gy * rc + gx * rs;
        let gcos = gx * rc - gy * rs;
        // sin = (n0 × n1)·u = n0·(n1 × u) = n1·(u × n0); cos = n0·n1.
        let gn0 = axpy(scale(cross(n1, u), gsin), gcos, n1);
        let gn1 = axpy(scale(cross(u, n0), gsin), gcos, n0);
        let gu = scale(n0xn1, gsin);
        let gedge = scale(axpy(gu, -dot(u, gu), u), 1.0 / l);
        add_to(g, e1, gedge, 1.0);
        add_to(g, e0, gedge, -1.0);
        add_normal_gradient(g, c0, a0, b0, gn0, rest.face_normal_scale[f0]);
        add_normal_gradient(g, c1, a1, b1, gn1, rest.face_normal_scale[f1]);
    }
    k * e
}
