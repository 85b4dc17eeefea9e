//! Fused bending energy `k Σ_h w_h (θ_h - θ̄_h)²` with its gradient, following
//! [`crate::energies::bending`] step by step: face normals scaled by their rest
//! `1/|c̄|`, the hinge edge normalised with the edge regulariser, the angle change taken as
//! `atan2(sin(θ-θ̄), cos(θ-θ̄))`, and collapsed hinges (`sin² + cos² < 1e-12`) contributing a
//! zero angle change with zero gradient.
//!
//! Three passes over one sample, with a reused scratch of `6F` values: the scaled normal of
//! every face; per hinge, the energy and the gradient with respect to the two normals (summed
//! per face) and the hinge edge; per face, the normal's gradient pulled back to its corners.
//! Each face is thus handled once, not once per hinge it belongs to.

use crate::energies::bending::COLLAPSED;
use crate::rest::GarmentRest;

use super::{Real, add_to, axpy, cross, dot, scale, sub, vertex};

/// Corners, `x1 - x0` and `x2 - x0` of face `f`.
#[inline(always)]
fn face_edges<T: Real>(rest: &GarmentRest, x: &[T], f: usize) -> ([usize; 3], [f64; 3], [f64; 3]) {
    let corners = rest.faces[f].map(|i| i as usize);
    let x0 = vertex(x, corners[0]);
    let a = sub(vertex(x, corners[1]), x0);
    let b = sub(vertex(x, corners[2]), x0);
    (corners, a, b)
}

#[inline(always)]
fn get3(v: &[f64], i: usize) -> [f64; 3] {
    [v[3 * i], v[3 * i + 1], v[3 * i + 2]]
}

/// Bending energy of one sample, its gradient added to `g`; `scratch` is resized to `6F`
/// (face normals, then their gradients).
pub fn bending<T: Real>(
    rest: &GarmentRest,
    k: f64,
    x: &[T],
    g: &mut [f64],
    scratch: &mut Vec<f64>,
) -> f64 {
    let nf = rest.faces.len();
    scratch.clear();
    scratch.resize(6 * nf, 0.0);
    let (normals, gnormals) = scratch.split_at_mut(3 * nf);
    // Pass 1: scaled face normals s (x1 - x0) × (x2 - x0).
    for (f, n) in normals.chunks_exact_mut(3).enumerate() {
        let (_, a, b) = face_edges(rest, x, f);
        n.copy_from_slice(&scale(cross(a, b), rest.face_normal_scale[f]));
    }
    // Pass 2: hinges.
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
        let (n0, n1) = (get3(normals, f0), get3(normals, f1));
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
        add_to(gnormals, f0, axpy(scale(cross(n1, u), gsin), gcos, n1), 1.0);
        add_to(gnormals, f1, axpy(scale(cross(u, n0), gsin), gcos, n0), 1.0);
        let gu = scale(n0xn1, gsin);
        let gedge = scale(axpy(gu, -dot(u, gu), u), 1.0 / l);
        add_to(g, e1, gedge, 1.0);
        add_to(g, e0, gedge, -1.0);
    }
    // Pass 3: n = s a × b, so δn = s (δa × b + a × δb): ∂/∂a = s b × gn, ∂/∂b = s gn × a.
    for f in 0..nf {
        let gn = get3(gnormals, f);
        if gn == [0.0; 3] {
            continue;
        }
        let (corners, a, b) = face_edges(rest, x, f);
        let gns = scale(gn, rest.face_normal_scale[f]);
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
    k * e
}
