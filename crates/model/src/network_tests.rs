//! Tests of the cloth network: shapes, configuration, the basis bias scale.

use super::*;
use crate::descriptors::STATIC_DIM;
use burn::nn::Linear;
use burn::tensor::Device;

fn small() -> ClothNetConfig {
    ClothNetConfig {
        static_hidden: vec![8],
        joint_hidden: vec![4, 4],
        dynamic_hidden: vec![16],
        latent: 12,
        decoder_hidden: vec![10],
        init_std: 0.3,
        ..Default::default()
    }
}

#[test]
fn config_validation_and_toml_round_trip() {
    assert!(ClothNetConfig::default().validate().is_ok());
    assert!(
        ClothNetConfig {
            latent: 0,
            ..Default::default()
        }
        .validate()
        .is_err()
    );
    for bad in [0.0, 1.5, f64::NAN] {
        let c = ClothNetConfig {
            dynamic_basis_lr_scale: bad,
            ..Default::default()
        };
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("dynamic_basis_lr_scale"), "{e}");
    }
    assert!(
        ClothNetConfig {
            init_std: f64::NAN,
            ..Default::default()
        }
        .validate()
        .is_err()
    );
    let c = ClothNetConfig {
        encoder: EncoderKind::Entangled,
        ..small()
    };
    let back: ClothNetConfig = toml::from_str(&toml::to_string(&c).unwrap()).unwrap();
    assert_eq!(back, c);
    // A run saved before the dynamic basis existed reads without one, at the basis's rate.
    let old: ClothNetConfig = toml::from_str("latent = 12").unwrap();
    assert!(!old.dynamic_basis && ClothNetConfig::default().dynamic_basis);
    assert_eq!(old.dynamic_basis_lr_scale, LEGACY_BASIS_LR_SCALE);
    assert_eq!(
        ClothNetConfig::default().dynamic_basis_lr_scale,
        DEFAULT_DYNAMIC_BASIS_LR_SCALE
    );
    assert!(c.init(0, 5, &Device::flex()).is_err());
}

#[test]
fn basis_bias_scale_multiplies_the_stored_bias_in_burn_and_in_exported_weights() {
    use burn::module::Param;
    use burn::tensor::TensorData;
    let device = Device::flex();
    let mut net = ClothNetConfig {
        basis_bias_lr_scale: 0.25,
        ..small()
    }
    .init(3, 5, &device)
    .unwrap();
    let stored: Vec<f32> = (0..15).map(|i| i as f32 * 0.1 - 0.7).collect();
    let stored_t = Tensor::<1>::from_data(TensorData::new(stored.clone(), [15]), &device);
    net.decoder.basis.bias = Some(Param::from_tensor(stored_t.clone()));
    let mut unit = net.clone();
    unit.decoder.bias_scale = 1.0;
    unit.decoder.basis.bias = Some(Param::from_tensor(stored_t.mul_scalar(0.25)));
    let z = Tensor::<3>::ones([1, 2, 12], &device).mul_scalar(0.3);
    let (a, b) = (
        net.decode(z.clone())
            .into_data()
            .try_to_vec::<f32>()
            .unwrap(),
        unit.decode(z).into_data().try_to_vec::<f32>().unwrap(),
    );
    for (x, y) in a.iter().zip(&b) {
        assert!((x - y).abs() < 1e-6, "{x} vs {y}");
    }
    let weights = crate::weights::InferenceWeights::from_module(&net).unwrap();
    let bias = weights.basis.bias.unwrap();
    for (e, s) in bias.iter().zip(&stored) {
        assert!((e - 0.25 * s).abs() < 1e-6, "{e} vs {}", 0.25 * s);
    }
}

#[test]
fn dynamic_branch_has_no_bias_and_shapes_hold() {
    let device = Device::flex();
    let net = small().init(3, 5, &device).unwrap();
    assert_eq!(net.kind(), EncoderKind::Disentangled);
    let dynamic = net.dynamic_encoder.as_ref().unwrap();
    assert!(
        dynamic
            .joint_mlp
            .layers
            .iter()
            .chain(&dynamic.mlp.layers)
            .all(|l| l.bias.is_none())
    );
    assert!(dynamic.gru.update_gate.input_transform.bias.is_none());
    assert!(net.decoder.basis.bias.is_some());
    assert!(
        net.static_encoder
            .as_ref()
            .unwrap()
            .layers
            .iter()
            .all(|l| l.bias.is_some())
    );
    let s = Tensor::<4>::ones([2, 4, 3, STATIC_DIM], &device);
    let d = Tensor::<4>::ones([2, 4, 3, DYNAMIC_DIM], &device);
    assert_eq!(
        net.forward(s.clone(), Some(d.clone()), 1.0).dims(),
        [2, 4, 5, 3]
    );
    assert_eq!(
        net.forward_last(s, Some(d), 1.0, 3, None, 0).dims(),
        [2, 3, 5, 3]
    );
    let st = ClothNetConfig {
        encoder: EncoderKind::StaticOnly,
        ..small()
    }
    .init(3, 5, &device)
    .unwrap();
    assert!(!st.has_dynamic_branch());
    let en = ClothNetConfig {
        encoder: EncoderKind::Entangled,
        ..small()
    }
    .init(3, 5, &device)
    .unwrap();
    assert!(en.static_encoder.is_none());
    let s = Tensor::<4>::ones([1, 2, 3, STATIC_DIM], &device);
    assert_eq!(en.forward(s, None, 1.0).dims(), [1, 2, 5, 3]);
}

#[test]
fn dynamic_input_scale_divides_the_descriptors_and_folds_into_exported_weights() {
    let device = Device::flex();
    let scale: Vec<f32> = (0..DYNAMIC_DIM).map(|c| 0.5 + c as f32).collect();
    let scaled = ClothNetConfig {
        dynamic_input_scale: scale.clone(),
        ..small()
    }
    .init(3, 5, &device)
    .unwrap();
    // The same weights without a scale, fed descriptors divided by hand.
    let mut plain = scaled.clone();
    plain.dynamic_encoder.as_mut().unwrap().input_inv_scale = Vec::new();
    let s = Tensor::<4>::ones([1, 4, 3, STATIC_DIM], &device).mul_scalar(0.2);
    let raw: Vec<f32> = (0..4 * 3 * DYNAMIC_DIM)
        .map(|i| ((i * 7919) % 23) as f32 - 11.0)
        .collect();
    let divided: Vec<f32> = raw
        .iter()
        .enumerate()
        .map(|(i, v)| v / scale[i % DYNAMIC_DIM])
        .collect();
    let tensor = |v: Vec<f32>| {
        Tensor::<4>::from_data(
            burn::tensor::TensorData::new(v, [1, 4, 3, DYNAMIC_DIM]),
            &device,
        )
    };
    let read = |t: Tensor<4>| t.into_data().try_to_vec::<f32>().unwrap();
    let a = read(scaled.forward(s.clone(), Some(tensor(raw.clone())), 1.0));
    let b = read(plain.forward(s.clone(), Some(tensor(divided)), 1.0));
    let moved = read(plain.forward(s, Some(tensor(raw)), 1.0));
    assert!(a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-5));
    assert!(
        a.iter().zip(&moved).any(|(x, y)| (x - y).abs() > 1e-4),
        "the scale must change the output of the same raw descriptors"
    );
    // Exported weights take raw descriptors: the first per-joint layer carries 1/s per row.
    let (ws, wp) = (
        crate::weights::InferenceWeights::from_module(&scaled).unwrap(),
        crate::weights::InferenceWeights::from_module(&plain).unwrap(),
    );
    let (first_s, first_p) = (
        &ws.recurrent.as_ref().unwrap().joint_layers[0],
        &wp.recurrent.as_ref().unwrap().joint_layers[0],
    );
    for (r, (rs, rp)) in first_s
        .weight
        .chunks_exact(first_s.d_out)
        .zip(first_p.weight.chunks_exact(first_p.d_out))
        .enumerate()
    {
        for (x, y) in rs.iter().zip(rp) {
            assert!(
                (x - y / scale[r]).abs() < 1e-6,
                "row {r}: {x} vs {}",
                y / scale[r]
            );
        }
    }
    let bad = ClothNetConfig {
        dynamic_input_scale: vec![1.0; 5],
        ..small()
    };
    assert!(bad.validate().is_err());
}

#[test]
fn dynamic_basis_starts_at_zero_gets_a_gradient_and_scales_with_w() {
    use burn::module::Param;
    use burn::tensor::{Distribution, TensorData};
    let device = Device::flex().autodiff();
    device.seed(7);
    let (j, v, t) = (3, 5, 4);
    let plain = ClothNetConfig {
        dynamic_basis: false,
        ..small()
    }
    .init(j, v, &device)
    .unwrap();
    assert!(plain.decoder.dynamic_basis.is_none());
    let mut net = ClothNetConfig {
        dynamic_basis: true,
        ..small()
    }
    .init(j, v, &device)
    .unwrap();
    // Same encoders and decoder: only the (zero) dynamic basis differs.
    net.static_encoder = plain.static_encoder.clone();
    net.dynamic_encoder = plain.dynamic_encoder.clone();
    net.decoder.mlp = plain.decoder.mlp.clone();
    net.decoder.basis = plain.decoder.basis.clone();
    let s = Tensor::<4>::random(
        [2, t, j, STATIC_DIM],
        Distribution::Normal(0.0, 1.0),
        &device,
    );
    let d = Tensor::<4>::random(
        [2, t, j, DYNAMIC_DIM],
        Distribution::Normal(0.0, 1.0),
        &device,
    );
    let out = |n: &ClothNet, w: f32| {
        n.forward(s.clone(), Some(d.clone()), w)
            .into_data()
            .try_to_vec::<f32>()
            .unwrap()
    };
    assert_eq!(
        out(&net, 1.0),
        out(&plain, 1.0),
        "a zero dynamic basis changes nothing"
    );
    // The first backward pass reaches the dynamic basis.
    let loss = net
        .forward(s.clone(), Some(d.clone()), 1.0)
        .powi_scalar(2)
        .sum();
    let grads = loss.backward();
    let basis = net.decoder.dynamic_basis.as_ref().unwrap();
    let g = basis
        .weight
        .grad(&grads)
        .unwrap()
        .abs()
        .sum()
        .into_scalar::<f32>();
    assert!(g > 0.0, "the dynamic basis has no gradient");
    // With a non-zero dynamic basis, its term is linear in w on top of the shared decoder.
    let k = net.latent * v * 3;
    let values: Vec<f32> = (0..k).map(|i| ((i % 7) as f32 - 3.0) * 2.0).collect();
    net.decoder.dynamic_basis = Some(Linear {
        weight: Param::from_tensor(Tensor::from_data(
            TensorData::new(values, [net.latent, v * 3]),
            &device,
        )),
        bias: None,
    });
    for w in [0.0, 0.5, 2.0] {
        let with: Vec<f32> = out(&net, w);
        let without = out(&plain, w);
        let (z, z_d) = net.codes(s.clone(), Some(d.clone()), w);
        let expected: Vec<f32> = match z_d {
            Some(z_d) => {
                let extra = dense(
                    z_d.mul_scalar(net.decoder.dynamic_scale),
                    net.decoder.dynamic_basis.as_ref().unwrap().weight.val(),
                    None,
                );
                (plain.decode(z) + extra.reshape([2, t, v, 3]))
                    .into_data()
                    .try_to_vec::<f32>()
                    .unwrap()
            }
            None => plain.decode(z).into_data().try_to_vec::<f32>().unwrap(),
        };
        let err = with
            .iter()
            .zip(&expected)
            .fold(0.0f32, |m, (a, b)| m.max((a - b).abs()));
        assert!(err < 1e-5, "w {w}: offsets differ by {err}");
        if w == 0.0 {
            assert_eq!(with, without, "w = 0 leaves out the dynamic basis");
        } else {
            assert_ne!(with, without, "w {w}: the dynamic basis must act");
        }
    }
}

#[test]
fn a_window_after_a_burn_in_continues_the_whole_sequence() {
    use burn::tensor::Distribution;
    let device = Device::flex();
    let net = small().init(3, 5, &device).unwrap();
    let (b, h, t) = (2, 6, 4);
    let s = Tensor::<4>::random([b, h + t, 3, STATIC_DIM], Distribution::Default, &device);
    let d = Tensor::<4>::random([b, h + t, 3, DYNAMIC_DIM], Distribution::Default, &device);
    // The whole sequence in one pass, and the window alone after a burn-in of the frames
    // before it: the same last frames.
    let whole = net.forward_last(s.clone(), Some(d.clone()), 1.0, 3, None, 0);
    let state = net.burn_in_state(d.clone().narrow(1, 0, h));
    assert!(state.is_some());
    let window = net.forward_last(
        s.clone().narrow(1, h, t),
        Some(d.clone().narrow(1, h, t)),
        1.0,
        3,
        state,
        0,
    );
    let diff = (whole - window.clone()).abs().max().into_scalar::<f32>();
    assert!(diff < 1e-5, "burn-in then window differs by {diff}");
    // Without the burn-in the window starts from zero and differs.
    let cold = net.forward_last(s.narrow(1, h, t), Some(d.narrow(1, h, t)), 1.0, 3, None, 0);
    let gap = (cold - window).abs().max().into_scalar::<f32>();
    assert!(gap > 1e-4, "the burn-in changed nothing ({gap})");
    assert!(
        net.burn_in_state(Tensor::zeros([b, 0, 3, DYNAMIC_DIM], &device))
            .is_none()
    );
}

#[test]
fn still_rows_skipped_by_the_dynamic_encoder_change_no_output_and_no_gradient() {
    use burn::tensor::Distribution;
    let device = Device::flex().autodiff();
    device.seed(11);
    let net = small().init(3, 5, &device).unwrap();
    let (b, t, quiet) = (4, 6, 2);
    let s = Tensor::<4>::random([b, t, 3, STATIC_DIM], Distribution::Default, &device);
    let moving = Tensor::<4>::random(
        [b - quiet, t, 3, DYNAMIC_DIM],
        Distribution::Normal(0.0, 1.0),
        &device,
    );
    let d = Tensor::cat(
        vec![Tensor::zeros([quiet, t, 3, DYNAMIC_DIM], &device), moving],
        0,
    );
    let weights = Tensor::<4>::random([b, 3, 5, 3], Distribution::Normal(0.0, 1.0), &device);
    let run = |q: usize| {
        let y = net.forward_last(s.clone(), Some(d.clone()), 1.0, 3, None, q);
        let g = (y.clone() * weights.clone()).sum().backward();
        let enc = net.dynamic_encoder.as_ref().unwrap();
        let grads: Vec<Vec<f32>> = [
            enc.joint_mlp.layers[0].weight.grad(&g),
            enc.mlp.layers[0].weight.grad(&g),
            enc.gru.update_gate.hidden_transform.weight.grad(&g),
            enc.gru.new_gate.input_transform.weight.grad(&g),
            net.static_encoder.as_ref().unwrap().layers[0]
                .weight
                .grad(&g),
            net.decoder.basis.weight.grad(&g),
        ]
        .into_iter()
        .map(|t| t.unwrap().try_into_vec_as::<f32>().unwrap())
        .collect();
        (y.inner().try_into_vec_as::<f32>().unwrap(), grads)
    };
    let (y_all, g_all) = run(0);
    let (y_skip, g_skip) = run(quiet);
    let scale = y_all.iter().fold(1e-6f32, |m, v| m.max(v.abs()));
    for (a, c) in y_all.iter().zip(&y_skip) {
        assert!((a - c).abs() <= 1e-6 * scale, "output {a} against {c}");
    }
    for (k, (ga, gs)) in g_all.iter().zip(&g_skip).enumerate() {
        let scale = ga.iter().fold(1e-6f32, |m, v| m.max(v.abs()));
        assert!(
            ga.iter().any(|v| *v != 0.0),
            "parameter {k} got no gradient"
        );
        for (a, c) in ga.iter().zip(gs) {
            assert!(
                (a - c).abs() <= 1e-5 * scale,
                "gradient {k}: {a} against {c}"
            );
        }
    }
    // An encoder with biases gives zero rows a nonzero code: it computes every row.
    let en = ClothNetConfig {
        encoder: EncoderKind::Entangled,
        ..small()
    }
    .init(3, 5, &device)
    .unwrap();
    let enc = en.entangled_encoder.as_ref().unwrap();
    assert!(!enc.bias_free());
    assert!(net.dynamic_encoder.as_ref().unwrap().bias_free());
    let zeros = Tensor::<4>::zeros([2, t, 3, STATIC_DIM + DYNAMIC_DIM], &device);
    let mut biased = en.clone();
    for l in &mut biased.entangled_encoder.as_mut().unwrap().joint_mlp.layers {
        l.bias = l.bias.take().map(|p| p.map(|b| b.ones_like()));
    }
    let codes = biased
        .entangled_encoder
        .as_ref()
        .unwrap()
        .forward_after_quiet(zeros, None, 2);
    assert!(codes.abs().max().into_scalar::<f32>() > 0.0);
}
