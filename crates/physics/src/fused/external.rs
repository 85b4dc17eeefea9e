//! Fused gravity potential `-Σ_v m_v x_v·g` with its (constant) gradient `-m_v g`.

use crate::rest::GarmentRest;

use super::{Real, add_to, dot, vertex};

/// Gravity potential of one sample, its gradient added to `g`.
pub fn gravity<T: Real>(rest: &GarmentRest, gravity: [f64; 3], x: &[T], g: &mut [f64]) -> f64 {
    let mut e = 0.0;
    for (v, &m) in rest.mass_kg.iter().enumerate() {
        e -= m * dot(vertex(x, v), gravity);
        add_to(g, v, gravity, -m);
    }
    e
}
