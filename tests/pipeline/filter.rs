//! The gradient filter in training (issue 11, round 7).

use neural_cloth::model::DescriptorConfig;
use neural_cloth::train::handle::Session;
use neural_cloth::train::{RunLocation, TrainConfig, TrainSetup, prepare};

use super::{quick_config, small_model, tiny_skirt};

/// Issue 11: the gradient filter (`precondition_stiffness`) trains the pinned skirt with every
/// effect on, finite; the loss it reports is the physics loss (the first step, before any
/// update, scores the same with and without it) and the update it makes is another.
#[test]
fn the_gradient_filter_trains_the_pinned_skirt_with_every_effect() {
    let losses = |beta: f64, moving_only: bool, dynamic_only: bool| {
        let dir = tempfile::tempdir().unwrap();
        let (scene, scene_config) = tiny_skirt(|e| e.friction = true);
        let (mut session, _) = prepare(TrainSetup {
            scene,
            scene_config,
            train: TrainConfig {
                precondition_stiffness: beta,
                precondition_moving_only: moving_only,
                precondition_dynamic_only: dynamic_only,
                predrape_secs: 0.0,
                ..quick_config()
            },
            model: small_model(),
            descriptors: DescriptorConfig::default(),
            location: RunLocation::At(dir.path().to_path_buf()),
        })
        .unwrap();
        let steps: Vec<f64> = (0..3)
            .map(|_| {
                let step = session.step().unwrap();
                assert!(step.is_finite(), "{step:?}");
                step.loss
            })
            .collect();
        assert!(session.validate().unwrap().is_finite());
        steps
    };
    let plain = losses(0.0, false, false);
    let filtered = losses(0.01, false, false);
    let moving = losses(0.01, true, false);
    let dynamic = losses(0.01, false, true);
    let relative = |a: f64, b: f64| (a - b).abs() / a.abs().max(b.abs()).max(1e-12);
    assert!(
        relative(plain[0], filtered[0]) < 1e-6,
        "{plain:?} {filtered:?}"
    );
    assert!(
        relative(plain[2], filtered[2]) > 1e-6,
        "{plain:?} {filtered:?}"
    );
    assert!(
        relative(filtered[2], moving[2]) > 1e-6,
        "{filtered:?} {moving:?}"
    );
    // Filtering the dynamic terms only: the same first loss, another update than both.
    assert!(
        relative(plain[0], dynamic[0]) < 1e-6,
        "{plain:?} {dynamic:?}"
    );
    // The dynamic terms are a small part of this loss: with the dynamic basis at 8/512
    // (round 27) the third loss differs by ~8e-7 relative, where equal first losses agree
    // to ~4e-9, so the bar sits between the two.
    for other in [&plain, &filtered] {
        assert!(
            relative(other[2], dynamic[2]) > 1e-7,
            "{other:?} {dynamic:?}"
        );
    }
    let bad = TrainConfig {
        precondition_stiffness: -1.0,
        ..quick_config()
    };
    assert!(bad.validate(30.0).is_err());
}
