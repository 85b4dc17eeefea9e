//! One GRU time step on plain slices, with exactly burn's gate equations
//! (`burn-nn` 0.22 `modules/rnn/gru.rs`):
//!
//! ```text
//! u = σ(x W_xu + b_xu + h W_hu + b_hu)
//! r = σ(x W_xr + b_xr + h W_hr + b_hr)
//! n = tanh(x W_xn + b_xn + r ⊙ (h W_hn + b_hn))        reset_after = true (default)
//! n = tanh(x W_xn + b_xn + (r ⊙ h) W_hn + b_hn)        reset_after = false
//! h' = n ⊙ (1 - u) + u ⊙ h                               (then clipped if configured)
//! ```
//!
//! With no biases, `x = 0` and `h = 0` give `h' = 0` exactly.

use super::weights::{GruWeights, LinearLayer};

/// Scratch buffers for [`gru_step`], sized once.
#[derive(Clone, Debug)]
pub struct GruScratch {
    gx: Vec<f32>,
    gh: Vec<f32>,
    rh: Vec<f32>,
}

impl GruScratch {
    /// Buffers for a GRU with `d_hidden` units.
    pub fn new(d_hidden: usize) -> Self {
        Self {
            gx: vec![0.0; 3 * d_hidden],
            gh: vec![0.0; 3 * d_hidden],
            rh: vec![0.0; d_hidden],
        }
    }
}

/// Logistic sigmoid.
#[inline]
pub fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// Advances the state `h` (`d_hidden` values) by one input `x` (`d_in` values) in place.
/// Allocates nothing; `scratch` must come from [`GruScratch::new`] with the same width.
pub fn gru_step<L: LinearLayer>(
    w: &GruWeights<L>,
    x: &[f32],
    h: &mut [f32],
    scratch: &mut GruScratch,
) {
    let n = w.d_hidden;
    w.input.forward(x, &mut scratch.gx);
    w.hidden.forward(h, &mut scratch.gh);
    let (gx, gh) = (&mut scratch.gx, &mut scratch.gh);
    // Update and reset gates (kept in gx[..2n]).
    for (x, y) in gx[..2 * n].iter_mut().zip(&gh[..2 * n]) {
        *x = sigmoid(*x + y);
    }
    if w.reset_after {
        for (g, r) in gh[2 * n..].iter_mut().zip(&gx[n..2 * n]) {
            *g *= r;
        }
    } else {
        // Recompute the new gate's hidden product with the reset state.
        for ((rh, hv), r) in scratch.rh.iter_mut().zip(h.iter()).zip(&gx[n..2 * n]) {
            *rh = hv * r;
        }
        w.hidden
            .forward_columns(&scratch.rh, 2 * n, &mut gh[2 * n..]);
    }
    for (i, hv) in h.iter_mut().enumerate().take(n) {
        let cand = (gx[2 * n + i] + gh[2 * n + i]).tanh();
        let u = gx[i];
        let mut v = cand * (1.0 - u) + u * *hv;
        if let Some(c) = w.clip {
            v = v.clamp(-c, c);
        }
        *hv = v;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::weights::DenseWeights;
    use burn::nn::GruConfig;
    use burn::tensor::{Device, Tensor, TensorData};

    fn check(bias: bool, reset_after: bool) {
        let device = Device::flex();
        device.seed(7);
        let gru = GruConfig::new(3, 4, bias)
            .with_reset_after(reset_after)
            .init(&device);
        let w = GruWeights::from_gru(&gru, "test").unwrap();
        let xs: Vec<f32> = (0..15)
            .map(|v| ((v * 37 % 11) as f32 - 5.0) * 0.3)
            .collect();
        let out: Vec<f32> = gru
            .forward(
                Tensor::<3>::from_data(TensorData::new(xs.clone(), [1, 5, 3]), &device),
                None,
            )
            .try_into_vec_as::<f32>()
            .unwrap();
        let mut h = vec![0.0; 4];
        let mut s = GruScratch::new(4);
        for t in 0..5 {
            gru_step(&w, &xs[t * 3..t * 3 + 3], &mut h, &mut s);
            for i in 0..4 {
                assert!(
                    (h[i] - out[t * 4 + i]).abs() < 1e-5,
                    "bias {bias} reset_after {reset_after} t {t}"
                );
            }
        }
    }

    #[test]
    fn matches_burn_gru() {
        check(false, true);
        check(true, true);
        check(true, false);
    }

    #[test]
    fn zero_in_zero_out_without_bias() {
        let dense = |d_in| DenseWeights {
            d_in,
            d_out: 6,
            weight: vec![0.7; d_in * 6],
            bias: None,
        };
        let w = GruWeights {
            d_in: 3,
            d_hidden: 2,
            input: dense(3),
            hidden: dense(2),
            reset_after: true,
            clip: None,
        };
        let mut h = vec![0.0; 2];
        gru_step(&w, &[0.0; 3], &mut h, &mut GruScratch::new(2));
        assert!(h.iter().all(|v| *v == 0.0));
        gru_step(&w, &[1.0, 0.0, 0.0], &mut h, &mut GruScratch::new(2));
        assert!(h.iter().all(|v| *v != 0.0));
    }
}
