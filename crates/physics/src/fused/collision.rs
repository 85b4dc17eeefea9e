//! Fused collision energy `k Σ_v mask_v min(n_v·(x_v - p_v) - ε, 0)²` with its gradient, for
//! contacts already found (the nearest posed body vertex `p_v` and its unit normal `n_v`, see
//! [`crate::collision`]). No-collide vertices (mask 0) contribute nothing.

use crate::rest::GarmentRest;

use super::{Real, add_to, dot, sub, vertex};

/// Collision energy of one sample against `points` and `normals` (`V·3` values each), its
/// gradient added to `g`.
pub fn collision<T: Real>(
    rest: &GarmentRest,
    k: f64,
    eps_m: f64,
    x: &[T],
    points: &[f32],
    normals: &[f32],
    g: &mut [f64],
) -> f64 {
    let mut e = 0.0;
    for (v, &collides) in rest.collide.iter().enumerate() {
        if !collides {
            continue;
        }
        let p = vertex(points, v);
        let n = vertex(normals, v);
        let pen = dot(sub(vertex(x, v), p), n) - eps_m;
        if pen < 0.0 {
            e += pen * pen;
            add_to(g, v, n, 2.0 * k * pen);
        }
    }
    k * e
}
