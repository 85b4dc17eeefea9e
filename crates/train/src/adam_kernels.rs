//! The fused Adam's update kernels: burn's per-value update and the row-normalised one of
//! the decoder bases ([`super::FusedAdam::with_basis_row_norm`]), in place over host buffers.

use rayon::prelude::*;

use super::{BasisRowNorm, CHUNK, Coefficients};

/// burn's Adam update of `p` with gradient `g` and moments `m`, `v`, in place, in parallel
/// chunks.
pub(super) fn update_all(p: &mut [f32], g: &[f32], m: &mut [f32], v: &mut [f32], k: &Coefficients) {
    p.par_chunks_mut(CHUNK)
        .zip(g.par_chunks(CHUNK))
        .zip(m.par_chunks_mut(CHUNK))
        .zip(v.par_chunks_mut(CHUNK))
        .for_each(|(((p, g), m), v)| update_chunk(p, g, m, v, k));
}

impl BasisRowNorm {
    /// True for a rank-2 parameter (`[latent, V·3]`) whose module path names a basis this
    /// setting normalises by rows (`basis`: the shared basis, `dynamic_basis`: the dynamic
    /// one).
    pub(super) fn covers(self, path: Option<&str>, shape: &[usize]) -> bool {
        let names: &[&str] = match self {
            Self::Off => return false,
            Self::Dynamic => &["dynamic_basis"],
            Self::Both => &["basis", "dynamic_basis"],
        };
        shape.len() == 2
            && shape[1] > 0
            && path.is_some_and(|p| p.split('.').any(|part| names.contains(&part)))
    }
}

/// Adam with one second moment per row of `row_len` values: `m ← β₁m + (1-β₁)g` per value,
/// `v_row ← β₂v_row + (1-β₂)·mean(g²)` over the row, `θ ← θ - lr · (c·m) / (√v_row + ε')`.
/// Within a row the update keeps the shape of the (averaged) gradient instead of moving every
/// value by about the rate: for a basis row, a pattern over the garment's vertices, the
/// physics gradient's smooth field stays smooth. `v` holds the row's moment in every entry.
pub(super) fn update_rows(
    p: &mut [f32],
    g: &[f32],
    m: &mut [f32],
    v: &mut [f32],
    row_len: usize,
    k: &Coefficients,
) {
    p.par_chunks_mut(row_len)
        .zip(g.par_chunks(row_len))
        .zip(m.par_chunks_mut(row_len))
        .zip(v.par_chunks_mut(row_len))
        .for_each(|(((p, g), m), v)| {
            let mean_g2 =
                g.iter().map(|&x| f64::from(x) * f64::from(x)).sum::<f64>() / g.len().max(1) as f64;
            let shared = v.first().copied().unwrap_or(0.0) * k.beta_2
                + (mean_g2 as f32) * k.one_minus_beta_2;
            let denominator = shared.sqrt() + k.epsilon;
            for (((p, &g), m), v) in p.iter_mut().zip(g).zip(m.iter_mut()).zip(v.iter_mut()) {
                *m = *m * k.beta_1 + g * k.one_minus_beta_1;
                *v = shared;
                *p -= ((*m * k.combined) / denominator) * k.lr;
            }
        });
}

/// One chunk of [`update_all`], compiled for AVX2 where the CPU has it (the same IEEE
/// operations in the same order either way: Rust never contracts `a·b + c` into an FMA).
fn update_chunk(p: &mut [f32], g: &[f32], m: &mut [f32], v: &mut [f32], k: &Coefficients) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked just above).
        unsafe { update_chunk_avx2(p, g, m, v, k) };
        return;
    }
    update_chunk_portable(p, g, m, v, k);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn update_chunk_avx2(p: &mut [f32], g: &[f32], m: &mut [f32], v: &mut [f32], k: &Coefficients) {
    update_chunk_portable(p, g, m, v, k);
}

/// The update of each value, in burn's order of operations:
/// `m ← β₁m + (1-β₁)g`, `v ← β₂v + (1-β₂)g²`, `θ ← θ - lr · (c·m) / (√v + ε')`.
#[inline(always)]
fn update_chunk_portable(p: &mut [f32], g: &[f32], m: &mut [f32], v: &mut [f32], k: &Coefficients) {
    for (((p, &g), m), v) in p.iter_mut().zip(g).zip(m.iter_mut()).zip(v.iter_mut()) {
        *m = *m * k.beta_1 + g * k.one_minus_beta_1;
        *v = *v * k.beta_2 + (g * g) * k.one_minus_beta_2;
        let step = (*m * k.combined) / (v.sqrt() + k.epsilon);
        *p -= step * k.lr;
    }
}
