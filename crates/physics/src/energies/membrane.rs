//! In-plane (membrane) energies: mass-spring edges, squared Baraff-Witkin stretch and shear, and
//! Saint Venant-Kirchhoff. Each returns one value per batch sample (`[B]`, joules), using the
//! `|cross|`-weighted convention described in [`crate::fabric`].

use burn::tensor::Tensor;

use crate::tensors::{RestTensors, dot, gather, norm2, per_sample};

/// Squared regulariser under `|w|` square roots (unitless): keeps gradients finite when a
/// triangle collapses completely.
pub(crate) const W_EPS2: f64 = 1e-12;

/// Current edge lengths `[B, E, 1]` in metres (`sqrt(|d|² + eps²)`), or None without edges.
pub fn edge_lengths(x: &Tensor<3>, rt: &RestTensors) -> Option<Tensor<3>> {
    let [a, b] = rt.edge.as_ref()?;
    let d = gather(x, a) - gather(x, b);
    let eps2 = rt.edge_eps2_m2;
    Some(norm2(d).add_scalar(eps2).sqrt())
}

/// Mass-spring energy `k Σ_e (l_e - l̄_e)²` per sample.
pub fn mass_spring(x: &Tensor<3>, rt: &RestTensors, k: f32) -> Tensor<1> {
    let (Some(len), Some(rest)) = (edge_lengths(x, rt), rt.edge_rest.as_ref()) else {
        return rt.zeros(x.dims()[0]);
    };
    per_sample((len - rest.clone()).square()).mul_scalar(k)
}

/// Deformation gradient columns `(w_u, w_v)`, each `[B, F, 3]`, or None without faces.
pub fn deformation(x: &Tensor<3>, rt: &RestTensors) -> Option<(Tensor<3>, Tensor<3>)> {
    let [f0, f1, f2] = rt.face.as_ref()?;
    let [c00, c01, c10, c11] = rt.face_inv.as_ref()?;
    let x0 = gather(x, f0);
    let d1 = gather(x, f1) - x0.clone();
    let d2 = gather(x, f2) - x0;
    let wu = d1.clone() * c00.clone() + d2.clone() * c10.clone();
    let wv = d1 * c01.clone() + d2 * c11.clone();
    Some((wu, wv))
}

/// Per-face stretch `(|w_u| - 1, |w_v| - 1)` and shear `w_u·w_v`, each `[B, F, 1]`.
pub fn stretch_and_shear(
    x: &Tensor<3>,
    rt: &RestTensors,
) -> Option<(Tensor<3>, Tensor<3>, Tensor<3>)> {
    let (wu, wv) = deformation(x, rt)?;
    let su = norm2(wu.clone()).add_scalar(W_EPS2).sqrt().sub_scalar(1.0);
    let sv = norm2(wv.clone()).add_scalar(W_EPS2).sqrt().sub_scalar(1.0);
    Some((su, sv, dot(wu, wv)))
}

/// Squared Baraff-Witkin energies per sample: `(k_stretch Σ 2A (s_u² + s_v²), k_shear Σ 2A sh²)`.
pub fn baraff_witkin(
    x: &Tensor<3>,
    rt: &RestTensors,
    k_stretch: f32,
    k_shear: f32,
) -> (Tensor<1>, Tensor<1>) {
    let b = x.dims()[0];
    let (Some((su, sv, sh)), Some(area2)) = (stretch_and_shear(x, rt), rt.face_area2.as_ref())
    else {
        return (rt.zeros(b), rt.zeros(b));
    };
    let stretch = per_sample((su.square() + sv.square()) * area2.clone()).mul_scalar(k_stretch);
    let shear = per_sample(sh.square() * area2.clone()).mul_scalar(k_shear);
    (stretch, shear)
}

/// Green strain components `(G00, G11, G01)`, each `[B, F, 1]`.
pub fn green_strain(x: &Tensor<3>, rt: &RestTensors) -> Option<(Tensor<3>, Tensor<3>, Tensor<3>)> {
    let (wu, wv) = deformation(x, rt)?;
    let g00 = norm2(wu.clone()).sub_scalar(1.0).mul_scalar(0.5);
    let g11 = norm2(wv.clone()).sub_scalar(1.0).mul_scalar(0.5);
    let g01 = dot(wu, wv).mul_scalar(0.5);
    Some((g00, g11, g01))
}

/// StVK energy per sample: `Σ 2A (μ tr(G²) + λ/2 tr(G)²)`.
pub fn stvk(x: &Tensor<3>, rt: &RestTensors, lambda: f32, mu: f32) -> Tensor<1> {
    let b = x.dims()[0];
    let (Some((g00, g11, g01)), Some(area2)) = (green_strain(x, rt), rt.face_area2.as_ref()) else {
        return rt.zeros(b);
    };
    let tr = g00.clone() + g11.clone();
    let tr_g2 = g00.square() + g11.square() + g01.square().mul_scalar(2.0);
    let psi = tr_g2.mul_scalar(mu) + tr.square().mul_scalar(0.5 * lambda);
    per_sample(psi * area2.clone())
}
