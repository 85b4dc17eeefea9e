//! Fused in-plane energies with their gradients: mass-spring edges, Baraff-Witkin stretch and
//! shear, StVK. Same formulas, regularisers and degenerate-element rules as
//! [`crate::energies::membrane`]: edge lengths are `sqrt(|d|² + ε²)`, `|w|` carries a
//! `1e-12` regulariser, and faces with zero rest `|cross|` contribute nothing.

use crate::energies::membrane::W_EPS2;
use crate::rest::GarmentRest;

use super::{Real, add_to, axpy, dot, scale, sub, vertex};

/// Mass-spring energy `k Σ_e (l_e - l̄_e)²` of one sample, its gradient added to `g`.
pub fn mass_spring<T: Real>(rest: &GarmentRest, k: f64, x: &[T], g: &mut [f64]) -> f64 {
    let eps2 = rest.edge_eps2_m2;
    let mut e = 0.0;
    for (&[a, b], &l_rest) in rest.edges.iter().zip(&rest.edge_rest_m) {
        let (a, b) = (a as usize, b as usize);
        let d = sub(vertex(x, a), vertex(x, b));
        let l = (dot(d, d) + eps2).sqrt();
        let r = l - l_rest;
        e += r * r;
        let s = 2.0 * k * r / l;
        add_to(g, a, d, s);
        add_to(g, b, d, -s);
    }
    k * e
}

/// Runs `psi` on every face with a non-zero rest `|cross|`: it gets the deformation gradient
/// columns `(w_u, w_v)` and `|c̄|`, and returns the face energy and its gradient with respect to
/// `w_u` and `w_v`; the gradient is pulled back to the three corners into `g`. Returns the
/// summed face energies.
#[inline(always)]
fn per_face<T: Real>(
    rest: &GarmentRest,
    x: &[T],
    g: &mut [f64],
    psi: impl Fn([f64; 3], [f64; 3], f64) -> (f64, [f64; 3], [f64; 3]),
) -> f64 {
    let mut e = 0.0;
    for ((face, inv), &area2) in rest
        .faces
        .iter()
        .zip(&rest.face_inv_rest)
        .zip(&rest.face_area2_m2)
    {
        if area2 == 0.0 {
            continue;
        }
        let [i0, i1, i2] = face.map(|i| i as usize);
        let [c00, c01, c10, c11] = *inv;
        let x0 = vertex(x, i0);
        let d1 = sub(vertex(x, i1), x0);
        let d2 = sub(vertex(x, i2), x0);
        let wu = axpy(scale(d1, c00), c10, d2);
        let wv = axpy(scale(d1, c01), c11, d2);
        let (face_e, gwu, gwv) = psi(wu, wv, area2);
        e += face_e;
        let gd1 = axpy(scale(gwu, c00), c01, gwv);
        let gd2 = axpy(scale(gwu, c10), c11, gwv);
        add_to(g, i1, gd1, 1.0);
        add_to(g, i2, gd2, 1.0);
        add_to(
            g,
            i0,
            [gd1[0] + gd2[0], gd1[1] + gd2[1], gd1[2] + gd2[2]],
            -1.0,
        );
    }
    e
}

/// Baraff-Witkin stretch `k Σ_f |c̄_f| ((|w_u|-1)² + (|w_v|-1)²)` of one sample.
pub fn baraff_witkin_stretch<T: Real>(rest: &GarmentRest, k: f64, x: &[T], g: &mut [f64]) -> f64 {
    per_face(rest, x, g, |wu, wv, area2| {
        let nu = (dot(wu, wu) + W_EPS2).sqrt();
        let nv = (dot(wv, wv) + W_EPS2).sqrt();
        let (su, sv) = (nu - 1.0, nv - 1.0);
        let s = 2.0 * k * area2;
        (
            k * area2 * (su * su + sv * sv),
            scale(wu, s * su / nu),
            scale(wv, s * sv / nv),
        )
    })
}

/// Baraff-Witkin shear `k Σ_f |c̄_f| (w_u·w_v)²` of one sample.
pub fn baraff_witkin_shear<T: Real>(rest: &GarmentRest, k: f64, x: &[T], g: &mut [f64]) -> f64 {
    per_face(rest, x, g, |wu, wv, area2| {
        let sh = dot(wu, wv);
        let s = 2.0 * k * area2 * sh;
        (k * area2 * sh * sh, scale(wv, s), scale(wu, s))
    })
}

/// StVK `Σ_f |c̄_f| (μ tr(G²) + λ/2 tr(G)²)` with `G = ½(FᵀF - I)` of one sample.
pub fn stvk<T: Real>(rest: &GarmentRest, lambda: f64, mu: f64, x: &[T], g: &mut [f64]) -> f64 {
    per_face(rest, x, g, |wu, wv, area2| {
        let g00 = 0.5 * (dot(wu, wu) - 1.0);
        let g11 = 0.5 * (dot(wv, wv) - 1.0);
        let g01 = 0.5 * dot(wu, wv);
        let tr = g00 + g11;
        let psi = mu * (g00 * g00 + g11 * g11 + 2.0 * g01 * g01) + 0.5 * lambda * tr * tr;
        // dψ/dw_u = (2μ G00 + λ tr) w_u + 2μ G01 w_v, and symmetrically for w_v.
        let (a, b, c) = (
            2.0 * mu * g00 + lambda * tr,
            2.0 * mu * g11 + lambda * tr,
            2.0 * mu * g01,
        );
        (
            area2 * psi,
            scale(axpy(scale(wu, a), c, wv), area2),
            scale(axpy(scale(wv, b), c, wu), area2),
        )
    })
}
