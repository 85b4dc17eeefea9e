//! The GRU unroll over a window for training: burn's [`Gru`] parameters and gate equations
//! (see [`super::gru`]), with fewer, larger matrix products.
//!
//! burn's `Gru::forward` runs six `[B, d] × [d, H]` products per frame (input and hidden
//! transform of each gate) and writes each frame's state into the output with a
//! `slice_assign` of the whole `[B, T, H]` tensor. Here the input transforms of all frames are
//! one `[B·T, d] × [d, 3H]` product before the loop (the three gates side by side), each frame
//! does one `[B, H] × [H, 3H]` hidden product, and the states are stacked once at the end. The
//! arithmetic of each gate is the same; only the summation order inside the products may
//! differ (float rounding, tested against burn's within 1e-5).

use burn::nn::activation::Activation;
use burn::nn::{Gru, Linear};
use burn::tensor::Tensor;
use burn::tensor::activation::{sigmoid, tanh};

/// True when [`unroll`] computes exactly burn's equations for `gru`: reset after the hidden
/// product, sigmoid gates, tanh candidate, no clipping (burn's defaults, ours).
pub fn supported(gru: &Gru) -> bool {
    gru.reset_after
        && gru.clip.is_none()
        && matches!(gru.gate_activation, Activation::Sigmoid(_))
        && matches!(gru.hidden_activation, Activation::Tanh(_))
}

/// The three gates' weights side by side (`[d, 3H]`, update | reset | new) and their biases
/// (`None` when the transforms have none).
fn stacked(layers: [&Linear; 3]) -> (Tensor<2>, Option<Tensor<1>>) {
    let weight = Tensor::cat(layers.iter().map(|l| l.weight.val()).collect(), 1);
    let biases: Option<Vec<Tensor<1>>> = layers
        .iter()
        .map(|l| l.bias.as_ref().map(|b| b.val()))
        .collect();
    (weight, biases.map(|b| Tensor::cat(b, 0)))
}

fn with_bias(x: Tensor<2>, bias: &Option<Tensor<1>>) -> Tensor<2> {
    match bias {
        Some(b) => x + b.clone().unsqueeze(),
        None => x,
    }
}

/// `[B, T, d]` inputs -> `[B, T, H]` states from `state` (`[B, H]`) or zero, as
/// `gru.forward(x, state)`; falls back to it when the GRU is not [`supported`].
pub fn unroll(gru: &Gru, x: Tensor<3>, state: Option<Tensor<2>>) -> Tensor<3> {
    if !supported(gru) {
        return gru.forward(x, state);
    }
    let [b, t, d] = x.dims();
    let h_dim = gru.d_hidden;
    let gates = [&gru.update_gate, &gru.reset_gate, &gru.new_gate];
    let (wx, bx) = stacked(gates.map(|g| &g.input_transform));
    let (wh, bh) = stacked(gates.map(|g| &g.hidden_transform));
    // Frame-major rows, so each frame's block is contiguous: [T·B, 3H].
    let frames = x.swap_dims(0, 1).reshape([t * b, d]);
    let gx = with_bias(frames.matmul(wx), &bx);
    let h0 = state.unwrap_or_else(|| Tensor::zeros([b, h_dim], &gx.device()));
    Tensor::stack(run(gx, wh, &bh, h0, b, t, h_dim), 1)
}

/// The states of each frame from `h`, with the frame-major input products `gx` (`[T·B, 3H]`,
/// biases included), the stacked hidden weights `wh` (`[H, 3H]`) and biases `bh`.
fn run(
    gx: Tensor<2>,
    wh: Tensor<2>,
    bh: &Option<Tensor<1>>,
    mut h: Tensor<2>,
    b: usize,
    t: usize,
    h_dim: usize,
) -> Vec<Tensor<2>> {
    let mut states = Vec::with_capacity(t);
    for k in 0..t {
        let gx_k = gx.clone().narrow(0, k * b, b);
        let gh = with_bias(h.clone().matmul(wh.clone()), bh);
        // Update and reset gates together: σ(x W_x + b_x + h W_h + b_h).
        let ur = sigmoid(gx_k.clone().narrow(1, 0, 2 * h_dim) + gh.clone().narrow(1, 0, 2 * h_dim));
        let u = ur.clone().narrow(1, 0, h_dim);
        let r = ur.narrow(1, h_dim, h_dim);
        let n = tanh(gx_k.narrow(1, 2 * h_dim, h_dim) + r * gh.narrow(1, 2 * h_dim, h_dim));
        let one_minus_u = u.clone().neg().add_scalar(1.0);
        h = n.mul(one_minus_u) + u.mul(h);
        states.push(h.clone());
    }
    states
}

#[cfg(test)]
mod tests {
    use burn::nn::GruConfig;
    use burn::tensor::{Device, Distribution};

    use super::*;

    fn close(a: Tensor<3>, b: Tensor<3>, what: &str) {
        let (a, b) = (
            a.inner().try_into_vec_as::<f32>().unwrap(),
            b.inner().try_into_vec_as::<f32>().unwrap(),
        );
        let scale = b.iter().fold(0f32, |m, v| m.max(v.abs())).max(1e-6);
        for (i, (x, y)) in a.iter().zip(&b).enumerate() {
            assert!((x - y).abs() <= 1e-5 * scale, "{what} {i}: {x} against {y}");
        }
    }

    fn grads_of(gru: &Gru, x: &Tensor<3>, fast: bool) -> Vec<Vec<f32>> {
        let y = if fast {
            unroll(gru, x.clone(), None)
        } else {
            gru.forward(x.clone(), None)
        };
        let dims = y.dims();
        let values: Vec<f32> = (0..dims.iter().product::<usize>())
            .map(|i| (i as f32 * 0.7).sin())
            .collect();
        let weights = Tensor::<1>::from_floats(values.as_slice(), &y.device()).reshape(dims);
        let g = (y * weights).sum().backward();
        let mut out = vec![x.grad(&g).unwrap().try_into_vec_as::<f32>().unwrap()];
        for gate in [&gru.update_gate, &gru.reset_gate, &gru.new_gate] {
            for l in [&gate.input_transform, &gate.hidden_transform] {
                out.push(l.weight.grad(&g).unwrap().try_into_vec_as().unwrap());
                if let Some(b) = &l.bias {
                    out.push(b.grad(&g).unwrap().try_into_vec_as().unwrap());
                }
            }
        }
        out
    }

    #[test]
    fn the_unroll_equals_burns_gru_with_and_without_biases() {
        let d = Device::flex().autodiff();
        for bias in [false, true] {
            let gru = GruConfig::new(7, 12, bias).init(&d);
            assert!(supported(&gru));
            let x = Tensor::<3>::random([3, 5, 7], Distribution::Normal(0.0, 1.0), &d);
            close(
                unroll(&gru, x.clone(), None),
                gru.forward(x.clone(), None),
                "states",
            );
            let h0 = Tensor::<2>::random([3, 12], Distribution::Normal(0.0, 0.5), &d);
            close(
                unroll(&gru, x.clone(), Some(h0.clone())),
                gru.forward(x.clone(), Some(h0)),
                "states from a state",
            );
        }
    }

    #[test]
    fn the_unroll_has_burns_gradients() {
        let d = Device::flex().autodiff();
        let gru = GruConfig::new(6, 10, true).init(&d);
        let x = Tensor::<3>::random([2, 4, 6], Distribution::Normal(0.0, 1.0), &d).require_grad();
        let fast = grads_of(&gru, &x, true);
        let slow = grads_of(&gru, &x, false);
        for (k, (a, b)) in fast.iter().zip(&slow).enumerate() {
            let scale = b.iter().fold(0f32, |m, v| m.max(v.abs())).max(1e-6);
            for (x, y) in a.iter().zip(b) {
                assert!(
                    (x - y).abs() <= 1e-5 * scale,
                    "gradient {k}: {x} against {y}"
                );
            }
        }
    }

    #[test]
    fn a_zero_input_from_a_zero_state_stays_zero_without_biases() {
        let d = Device::flex();
        let gru = GruConfig::new(4, 8, false).init(&d);
        let y = unroll(&gru, Tensor::zeros([2, 3, 4], &d), None);
        assert!(
            y.try_into_vec_as::<f32>()
                .unwrap()
                .iter()
                .all(|v| *v == 0.0)
        );
    }
}
