//! Bending: `k_b Σ_h w_h (θ_h - θ̄_h)²` with `w_h = l̄²/(8(|c̄_0|+|c̄_1|))` (paper Eq. 6 in the
//! official `|cross|` convention) and signed dihedral angles from `atan2`.
//!
//! The angle difference is computed directly as `atan2(sin(θ-θ̄), cos(θ-θ̄))` from the current
//! `(sin, cos)` pair and the rest `(sin θ̄, cos θ̄)`, so it never jumps at ±π (fully folded
//! hinges are smooth). Face normals and the hinge edge are normalised with per-hinge
//! regularisers, and a hinge whose faces have collapsed to (near) zero area contributes a
//! constant with zero gradient instead of `atan2(0, 0)`.

use burn::tensor::Tensor;

use crate::physics::tensors::{RestTensors, dot, gather, norm2, per_sample};

/// Below this `sin² + cos²` (normalised pieces, ~1 when healthy) a hinge counts as collapsed.
const COLLAPSED: f64 = 1e-12;

/// Signed dihedral angle change `θ - θ̄` per hinge, `[B, H, 1]` in radians, wrapped to (-π, π].
pub fn dihedral_change(x: &Tensor<3>, rt: &RestTensors) -> Option<Tensor<3>> {
    let [e0, e1, o0, o1] = rt.hinge.as_ref()?;
    let [_, rest_cos, rest_sin, n_eps2, e_eps2] = rt.hinge_consts.as_ref()?;
    let p0 = gather(x, e0);
    let edge = gather(x, e1) - p0.clone();
    let n0 = edge.clone().cross(gather(x, o0) - p0.clone(), 2);
    let n1 = (gather(x, o1) - p0).cross(edge.clone(), 2);
    let unit = |v: Tensor<3>, eps2: &Tensor<3>| {
        let len = (norm2(v.clone()) + eps2.clone()).sqrt();
        v / len
    };
    let n0 = unit(n0, n_eps2);
    let n1 = unit(n1, n_eps2);
    let e = unit(edge, e_eps2);
    let sin = dot(n0.clone().cross(n1.clone(), 2), e);
    let cos = dot(n0, n1);
    // sin(θ-θ̄) and cos(θ-θ̄), scaled by |n0||n1|.
    let y = sin.clone() * rest_cos.clone() - cos.clone() * rest_sin.clone();
    let xx = cos * rest_cos.clone() + sin * rest_sin.clone();
    let collapsed = (y.clone().square() + xx.clone().square()).lower_elem(COLLAPSED);
    let y = y.mask_fill(collapsed.clone(), 0.0);
    let xx = xx.mask_fill(collapsed, 1.0);
    Some(y.atan2(xx))
}

/// Bending energy per sample, `[B]` joules.
pub fn bending(x: &Tensor<3>, rt: &RestTensors, k_bending: f32) -> Tensor<1> {
    let (Some(delta), Some([weight, ..])) = (dihedral_change(x, rt), rt.hinge_consts.as_ref()) else {
        return rt.zeros(x.dims()[0]);
    };
    per_sample(delta.square() * weight.clone()).mul_scalar(k_bending)
}
