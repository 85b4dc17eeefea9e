//! Bending: `k_b Σ_h w_h (θ_h - θ̄_h)²` with `w_h = l̄²/(8(|c̄_0|+|c̄_1|))` (paper Eq. 6 in the
//! official `|cross|` convention) and signed dihedral angles from `atan2`.
//!
//! The angle difference is computed directly as `atan2(sin(θ-θ̄), cos(θ-θ̄))` from the current
//! `(sin, cos)` pair and the rest `(sin θ̄, cos θ̄)`, so it never jumps at ±π (fully folded
//! hinges are smooth). Face normals are computed once per face and scaled by their rest
//! `1/|c̄|` (unit length at rest, whatever the garment's scale), the hinge edge is normalised
//! with a regulariser, and a hinge whose faces have collapsed contributes a constant with zero
//! gradient instead of `atan2(0, 0)`.

use burn::tensor::Tensor;

use crate::tensors::{RestTensors, dot, gather, norm2, per_sample};

/// Below this `sin² + cos²` (~1 when healthy) a hinge counts as collapsed.
pub(crate) const COLLAPSED: f64 = 1e-12;

/// Face normals scaled by `1/|c̄_f|` (unit length at rest, 0 for degenerate faces), `[B, F, 3]`.
pub fn scaled_face_normals(x: &Tensor<3>, rt: &RestTensors) -> Option<Tensor<3>> {
    let [f0, f1, f2] = rt.face.as_ref()?;
    let scale = rt.face_normal_scale.as_ref()?;
    let x0 = gather(x, f0);
    let n = (gather(x, f1) - x0.clone()).cross(gather(x, f2) - x0, 2);
    Some(n * scale.clone())
}

/// Signed dihedral angle change `θ - θ̄` per hinge, `[B, H, 1]` in radians, wrapped to (-π, π].
pub fn dihedral_change(x: &Tensor<3>, rt: &RestTensors) -> Option<Tensor<3>> {
    let [e0, e1, h0, h1] = rt.hinge.as_ref()?;
    let [_, rest_cos, rest_sin] = rt.hinge_consts.as_ref()?;
    let normals = scaled_face_normals(x, rt)?;
    let n0 = gather(&normals, h0);
    let n1 = gather(&normals, h1);
    let edge = gather(x, e1) - gather(x, e0);
    let e = edge.clone() / (norm2(edge).add_scalar(rt.edge_eps2_m2)).sqrt();
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
    let (Some(delta), Some([weight, ..])) = (dihedral_change(x, rt), rt.hinge_consts.as_ref())
    else {
        return rt.zeros(x.dims()[0]);
    };
    per_sample(delta.square() * weight.clone()).mul_scalar(k_bending)
}
