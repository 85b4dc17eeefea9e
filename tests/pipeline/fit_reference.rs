//! Fitting the network to reference frames, the diagnostic of issue 11 round 18.

use std::path::Path;

use neural_cloth::io::export::Pc2Writer;
use neural_cloth::model::DescriptorConfig;
use neural_cloth::scene::config::SceneConfig;
use neural_cloth::scene::procedural::build_builtin;
use neural_cloth::train::handle::Session;
use neural_cloth::train::{RunLocation, TrainConfig, TrainSetup, prepare};

use super::{quick_config, small_model, tiny_scene::TINY};

/// The tiny scene training on the idle in place of the walk and the spin (twice, the second
/// one second longer: the body stays where it is, and the target below on it) and `train`.
fn setup(dir: &Path, train: TrainConfig) -> TrainSetup {
    let text = TINY.replacen("\"walk\"", "\"idle\"", 1).replacen(
        "builtin = \"spin\"\nduration_secs = 1.0",
        "builtin = \"idle\"\nname = \"idle2\"\nduration_secs = 2.0",
        1,
    );
    let scene_config = SceneConfig::from_toml_str(&text).unwrap();
    TrainSetup {
        scene: build_builtin(&scene_config).unwrap(),
        scene_config,
        train,
        model: small_model(),
        descriptors: DescriptorConfig::default(),
        location: RunLocation::At(dir.to_path_buf()),
    }
}

/// Issue 11 round 18: with `fit_reference` the network is fitted to the frames of the given
/// caches (its step loss, the fit's distance, falls by more than half within 60 steps), a
/// folder that lacks a training motion's frames is refused before the first step, and the
/// still and mirrored windows that have no frames are refused by the configuration; with
/// `fit_physics_weight` the physics loss is descended too.
#[test]
fn fitting_to_reference_frames_lowers_the_distance_to_them() {
    let dir = tempfile::tempdir().unwrap();
    let refs = dir.path().join("refs");
    std::fs::create_dir(&refs).unwrap();
    let scene = setup(dir.path(), quick_config()).scene;
    // The template lowered by 3 cm on every frame: a target the skinned template misses.
    let target: Vec<_> = scene
        .garment
        .mesh
        .positions
        .iter()
        .map(|p| p - neural_cloth::geometry::Vec3::new(0.0, 0.03, 0.0))
        .collect();
    let fit = TrainConfig {
        fit_reference: Some(refs.clone()),
        still_fraction: 0.0,
        mirror_poses: false,
        // From the skinned template itself, not from a drape of its own.
        predrape_secs: 0.0,
        learning_rate: 3e-3,
        ..quick_config()
    };
    // Only the first idle is cached so far: refused, naming the second.
    let write = |name: &str| {
        let mut w = Pc2Writer::create(
            &refs.join(format!("{name}-1it-30fps-0.pc2")),
            target.len(),
            0.0,
            1.0,
        )
        .unwrap();
        for _ in 0..40 {
            w.write_frame(&target).unwrap();
        }
        w.finish().unwrap();
    };
    write("idle");
    let missing = prepare(setup(&dir.path().join("a"), fit.clone()))
        .err()
        .unwrap();
    assert!(missing.to_string().contains("'idle2'"), "{missing}");
    write("idle2");
    let (mut session, _) = prepare(setup(&dir.path().join("b"), fit.clone())).unwrap();
    let losses: Vec<f64> = (0..60)
        .map(|_| {
            let step = session.step().unwrap();
            assert!(step.is_finite(), "{step:?}");
            step.loss
        })
        .collect();
    let (first, last) = (losses[0], losses[55..].iter().sum::<f64>() / 5.0);
    assert!(last < 0.5 * first, "fit loss {first} -> {last}: {losses:?}");
    // With the physics loss added (round 19), the first step scores the same fit from the
    // same network, but its update differs: the second step's fit is another.
    let two_steps = |name: &str, weight: f64| {
        let config = TrainConfig {
            fit_physics_weight: weight,
            ..fit.clone()
        };
        let (mut s, _) = prepare(setup(&dir.path().join(name), config)).unwrap();
        [s.step().unwrap().loss, s.step().unwrap().loss]
    };
    let alone = two_steps("d", 0.0);
    let with_physics = two_steps("e", 1.0);
    assert_eq!(alone[0], with_physics[0]);
    assert_ne!(alone[1], with_physics[1]);
    // Still windows have no simulated frames.
    let still = TrainConfig {
        still_fraction: 0.25,
        ..fit
    };
    assert!(prepare(setup(&dir.path().join("c"), still)).is_err());
}
