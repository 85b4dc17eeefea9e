//! The fused Adam against burn's: same parameters step by step, and either one's record
//! resumes the other.

use burn::module::{Module, Param};
use burn::nn::{Linear, LinearConfig};
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Distribution, Tensor};

use super::*;

/// A small module: two linear layers (with and without bias).
#[derive(Module, Debug)]
struct Small {
    a: Linear,
    b: Linear,
}

fn device() -> Device {
    Device::flex().autodiff()
}

fn small(device: &Device) -> Small {
    Small {
        a: LinearConfig::new(7, 33).init(device),
        b: LinearConfig::new(33, 5).with_bias(false).init(device),
    }
}

/// Gradients of a loss with large and small terms (so the moments differ a lot between
/// parameters) at step `k`.
fn grads(model: &Small, k: usize, device: &Device) -> GradientsParams {
    let values: Vec<f32> = (0..63)
        .map(|i| ((i * 7 + k * 13) as f32 * 0.37).sin() * (1.0 + k as f32))
        .collect();
    let x = Tensor::<1>::from_floats(values.as_slice(), device).reshape([9, 7]);
    let y = model.b.forward(model.a.forward(x).tanh());
    let loss = (y.clone() * y.clone()).sum() + y.sum().mul_scalar(1e-3);
    GradientsParams::from_grads(loss.backward(), model)
}

fn values(model: &Small) -> Vec<f32> {
    let mut out = Vec::new();
    for t in [
        model.a.weight.val().flatten::<1>(0, 1),
        model.b.weight.val().flatten::<1>(0, 1),
    ] {
        out.extend(t.inner().try_into_vec_as::<f32>().unwrap());
    }
    out.extend(
        model
            .a
            .bias
            .as_ref()
            .unwrap()
            .val()
            .inner()
            .try_into_vec_as::<f32>()
            .unwrap(),
    );
    out
}

fn assert_close(a: &[f32], b: &[f32], what: &str) {
    assert_eq!(a.len(), b.len());
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        let tolerance = 1e-6 * x.abs().max(y.abs()).max(1e-6);
        assert!(
            (x - y).abs() <= tolerance,
            "{what}: value {i}: {x} against {y}"
        );
    }
}

fn burn_step(optim: &mut ModuleOptimizer, model: Small, k: usize, d: &Device) -> Small {
    let g = grads(&model, k, d);
    optim.step(1e-2, model, g)
}

fn fused_step(optim: &mut TrainOptimiser, model: &mut Small, k: usize, d: &Device) {
    let g = grads(model, k, d);
    optim.step(1e-2, model, g).unwrap();
}

#[test]
fn the_fused_adam_equals_burns_over_several_steps() {
    let d = device();
    let start = small(&d);
    let mut burn_model = start.clone();
    let mut fused_model = start.clone();
    let mut burn_optim = AdamConfig::new().init();
    let mut fused = TrainOptimiser::new(true);
    for k in 0..6 {
        burn_model = burn_step(&mut burn_optim, burn_model, k, &d);
        fused_step(&mut fused, &mut fused_model, k, &d);
        assert_close(
            &values(&fused_model),
            &values(&burn_model),
            &format!("step {k}"),
        );
    }
    assert_ne!(values(&fused_model), values(&start));
    // The stepped parameters still train.
    let g = grads(&fused_model, 9, &d);
    assert!(g.len() >= 3);
}

#[test]
fn either_record_resumes_the_other_optimiser() {
    let d = device();
    let mut model = small(&d);
    let mut fused = TrainOptimiser::new(true);
    for k in 0..3 {
        fused_step(&mut fused, &mut model, k, &d);
    }
    // Fused state → burn's optimiser, and burn's state after a step → the fused one.
    let bytes = fused.to_bytes().unwrap();
    let mut burn_optim = match TrainOptimiser::new(false)
        .load_bytes(bytes.clone())
        .unwrap()
    {
        TrainOptimiser::Burn(o) => o,
        TrainOptimiser::Fused(_) => unreachable!(),
    };
    let mut resumed = fused.load_bytes(bytes).unwrap();
    let mut fused_model = model.clone();
    fused_step(&mut resumed, &mut fused_model, 3, &d);
    let burn_model = burn_step(&mut burn_optim, model.clone(), 3, &d);
    assert_close(
        &values(&fused_model),
        &values(&burn_model),
        "after resuming",
    );

    let burn_bytes = burn_optim.into_bytes().unwrap();
    let mut from_burn = TrainOptimiser::new(true).load_bytes(burn_bytes).unwrap();
    let burn_model = burn_step(&mut burn_optim, burn_model, 4, &d);
    fused_step(&mut from_burn, &mut fused_model, 4, &d);
    assert_close(
        &values(&fused_model),
        &values(&burn_model),
        "burn's record, fused",
    );
}

#[test]
fn an_uninterrupted_run_equals_a_resumed_one() {
    let d = device();
    let mut straight = small(&d);
    let mut optim = TrainOptimiser::new(true);
    for k in 0..2 {
        fused_step(&mut optim, &mut straight, k, &d);
    }
    let saved = optim.to_bytes().unwrap();
    let mut resumed_model = straight.clone();
    let mut resumed = TrainOptimiser::new(true).load_bytes(saved).unwrap();
    for k in 2..4 {
        fused_step(&mut optim, &mut straight, k, &d);
        fused_step(&mut resumed, &mut resumed_model, k, &d);
    }
    assert_eq!(values(&straight), values(&resumed_model));
}

#[test]
fn the_streamed_record_is_the_record_and_the_moments_go_on() {
    let d = device();
    let mut model = small(&d);
    let mut optim = TrainOptimiser::new(true);
    for k in 0..2 {
        fused_step(&mut optim, &mut model, k, &d);
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("optimizer.bpk");
    optim.write_file(&path).unwrap();
    let bytes = optim.to_bytes().unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), bytes.to_vec());
    // Steps after the write update the moments the record shared (no stale copy), and a
    // resume from the file follows the same path.
    let mut resumed_model = model.clone();
    let saved = Bytes::from_bytes_vec(std::fs::read(&path).unwrap());
    let mut resumed = TrainOptimiser::new(true).load_bytes(saved).unwrap();
    for k in 2..4 {
        fused_step(&mut optim, &mut model, k, &d);
        fused_step(&mut resumed, &mut resumed_model, k, &d);
    }
    assert_eq!(values(&model), values(&resumed_model));
    assert_ne!(optim.to_bytes().unwrap().to_vec(), bytes.to_vec());
    // Either kind's failure to write names the file, last.
    let missing = dir.path().join("no/such/folder/optimizer.bpk");
    for optim in [optim, TrainOptimiser::new(false)] {
        let e = optim.write_file(&missing).unwrap_err().to_string();
        assert!(e.ends_with(&missing.display().to_string()), "{e}");
        assert!(!missing.exists());
    }
}

#[test]
fn a_state_of_another_network_is_refused_by_name() {
    let d = device();
    let mut model = small(&d);
    let mut optim = TrainOptimiser::new(true);
    fused_step(&mut optim, &mut model, 0, &d);
    let bytes = optim.to_bytes().unwrap();
    // The first layer's weight under its id, with another size.
    let mut wrong = small(&d);
    wrong.a = LinearConfig::new(8, 33).init(&d);
    let weight = Tensor::random([8, 33], Distribution::Default, &d).require_grad();
    wrong.a.weight = Param::initialized(model.a.weight.id, weight);
    let mut loaded = TrainOptimiser::new(true).load_bytes(bytes).unwrap();
    let x = Tensor::<2>::ones([2, 8], &d);
    let g = GradientsParams::from_grads(wrong.a.forward(x).sum().backward(), &wrong);
    let e = loaded.step(1e-2, &mut wrong, g).unwrap_err().to_string();
    assert!(e.contains("another network"), "{e}");
}

#[test]
fn garbage_is_not_an_optimiser_state() {
    let e = FusedAdam::from_bytes(Bytes::from_bytes_vec(b"not a burnpack".to_vec()))
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("optimiser state"), "{e}");
}

#[test]
fn the_config_picks_the_fused_adam_on_the_cpu_only() {
    let cpu = TrainConfig::default();
    assert!(TrainOptimiser::for_config(&cpu).is_fused());
    let wgpu = TrainConfig {
        backend: BackendKind::Wgpu,
        ..TrainConfig::default()
    };
    assert!(!TrainOptimiser::for_config(&wgpu).is_fused());
    let off = TrainConfig {
        fused_adam: false,
        ..TrainConfig::default()
    };
    assert!(!TrainOptimiser::for_config(&off).is_fused());
}

/// A module with a field named like the decoder's basis (`[latent, V·3]`, bias-free) and an
/// ordinary layer.
#[derive(Module, Debug)]
struct WithBasis {
    basis: Linear,
    other: Linear,
}

/// One step of the optimiser on `model` with the loss `Σ basis ⊙ target_b + Σ other ⊙
/// target_o` (so the gradients are exactly the targets).
fn step_with_gradients(optim: &mut TrainOptimiser, model: &mut WithBasis, d: &Device) {
    let target_b: Vec<f32> = (0..4 * 12).map(|i| 0.01 * (i as f32 + 1.0)).collect();
    let target_o: Vec<f32> = (0..3 * 2).map(|i| 0.5 - 0.2 * i as f32).collect();
    let tb = Tensor::<1>::from_floats(target_b.as_slice(), d).reshape([4, 12]);
    let to = Tensor::<1>::from_floats(target_o.as_slice(), d).reshape([3, 2]);
    let loss = (model.basis.weight.val() * tb).sum() + (model.other.weight.val() * to).sum();
    let g = GradientsParams::from_grads(loss.backward(), &*model);
    optim.step(1e-2, model, g).unwrap();
}

fn weights(l: &Linear) -> Vec<f32> {
    l.weight.val().inner().try_into_vec_as::<f32>().unwrap()
}

#[test]
fn row_normalised_basis_rows_move_along_the_gradient_and_other_layers_as_before() {
    let d = device();
    let start = WithBasis {
        basis: LinearConfig::new(4, 12).with_bias(false).init(&d),
        other: LinearConfig::new(3, 2).with_bias(false).init(&d),
    };
    let mut plain_model = start.clone();
    let mut row_model = start.clone();
    let mut plain = TrainOptimiser::new(true);
    let mut row = TrainOptimiser::new(true).with_basis_row_norm(BasisRowNorm::Both);
    step_with_gradients(&mut plain, &mut plain_model, &d);
    step_with_gradients(&mut row, &mut row_model, &d);
    let before = weights(&start.basis);
    // Per-value Adam's first step moves every value by the rate (sign of the gradient).
    for (a, b) in weights(&plain_model.basis).iter().zip(&before) {
        assert!(((b - a) - 1e-2).abs() < 1e-4, "per-value step {}", b - a);
    }
    // Row-normalised: each row's step is the row's gradient over its root mean square.
    for r in 0..4 {
        let g: Vec<f32> = (0..12)
            .map(|c| 0.01 * ((r * 12 + c) as f32 + 1.0))
            .collect();
        let rms = (g.iter().map(|x| x * x).sum::<f32>() / 12.0).sqrt();
        let after = weights(&row_model.basis);
        for (c, g) in g.iter().enumerate() {
            let i = r * 12 + c;
            let step = before[i] - after[i];
            let expected = 1e-2 * g / rms;
            assert!(
                (step - expected).abs() < 1e-3 * expected.abs().max(1e-3) + 1e-6,
                "row {r} value {c}: step {step} against {expected}"
            );
        }
    }
    // Layers that are not a basis keep burn's per-value Adam.
    assert_close(
        &weights(&row_model.other),
        &weights(&plain_model.other),
        "other layer",
    );
    // `Dynamic` normalises the dynamic basis only: a field named `basis` steps per value.
    let mut dynamic_model = start.clone();
    let mut dynamic = TrainOptimiser::new(true).with_basis_row_norm(BasisRowNorm::Dynamic);
    step_with_gradients(&mut dynamic, &mut dynamic_model, &d);
    assert_close(
        &weights(&dynamic_model.basis),
        &weights(&plain_model.basis),
        "dynamic only",
    );
    // The record keeps the mode out of its format: a resumed row-normalised optimiser steps
    // as the one it was saved from.
    let saved = row.to_bytes().unwrap();
    let mut resumed = TrainOptimiser::new(true)
        .with_basis_row_norm(BasisRowNorm::Both)
        .load_bytes(saved)
        .unwrap();
    let mut a = row_model.clone();
    let mut b = row_model.clone();
    step_with_gradients(&mut row, &mut a, &d);
    step_with_gradients(&mut resumed, &mut b, &d);
    assert_close(&weights(&a.basis), &weights(&b.basis), "resumed basis");
}

#[test]
fn the_networks_two_bases_are_the_ones_normalised_by_rows() {
    let d = device();
    let config = neural_cloth_model::ClothNetConfig {
        static_hidden: vec![8],
        joint_hidden: vec![4, 4],
        dynamic_hidden: vec![16],
        latent: 12,
        decoder_hidden: vec![10],
        dynamic_basis: true,
        ..Default::default()
    };
    for (which, expected) in [
        (BasisRowNorm::Off, 0),
        (BasisRowNorm::Dynamic, 1),
        (BasisRowNorm::Both, 2),
    ] {
        let mut model = config.init(3, 5, &d).unwrap();
        let dynamic = model.decoder.dynamic_basis_weight().unwrap();
        let loss = (model.decoder.basis_weight() * model.decoder.basis_weight()).sum()
            + (dynamic.clone() * dynamic).sum();
        let g = GradientsParams::from_grads(loss.backward(), &model);
        let mut adam = FusedAdam::new().with_basis_row_norm(which);
        adam.step(1e-3, &mut model, g).unwrap();
        let covered: Vec<&str> = adam
            .states
            .values()
            .filter(|s| which.covers(s.path.as_deref(), &s.shape))
            .filter_map(|s| s.path.as_deref())
            .collect();
        assert_eq!(covered.len(), expected, "{which:?}: {covered:?}");
        // The covered rows hold one second moment each.
        for s in adam.states.values() {
            if which.covers(s.path.as_deref(), &s.shape) {
                for row in s.v.chunks(s.shape[1]) {
                    assert!(row.iter().all(|&x| x == row[0]), "{:?}", s.path);
                }
            }
        }
    }
}

#[test]
fn the_weight_average_follows_its_formula_and_leaves_training_alone() {
    let d = device();
    let start = small(&d);
    let decay = 0.5;
    let mut plain = TrainOptimiser::new(true);
    let mut averaging = TrainOptimiser::Fused(FusedAdam::new().with_weight_average(decay));
    let (mut plain_model, mut model) = (start.clone(), start.clone());
    let mut expected: Option<Vec<f32>> = None;
    for k in 0..4 {
        fused_step(&mut plain, &mut plain_model, k, &d);
        fused_step(&mut averaging, &mut model, k, &d);
        // The average does not change the optimiser's own path.
        assert_eq!(values(&model), values(&plain_model), "step {k}");
        let t = (k + 1) as f32;
        let d_t = decay.min((1.0 + t) / (10.0 + t));
        let now = values(&model);
        expected = Some(match expected {
            None => now,
            Some(a) => a
                .iter()
                .zip(&now)
                .map(|(a, p)| d_t * a + (1.0 - d_t) * p)
                .collect(),
        });
    }
    let averaged = values(&averaging.averaged(model.clone()));
    let expected = expected.unwrap();
    assert_close(&averaged, &expected, "averaged weights");
    assert_ne!(averaged, values(&model), "the average is not the last step");
    // Without an average (the default) the module comes back as it is.
    assert_eq!(values(&plain.averaged(model.clone())), values(&model));
}
