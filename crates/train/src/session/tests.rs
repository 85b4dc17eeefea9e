//! Tests of the session's batch assembly.

use neural_cloth_core::scene::config::{GarmentSource, SceneConfig};
use neural_cloth_core::scene::procedural::build_builtin;
use neural_cloth_model::{ClothNetConfig, DescriptorConfig};

use crate::{RunLocation, TrainConfig, TrainSetup, prepare};

/// A session on a coarse default scene with a 0.5 s burn-in (15 frames at 30 fps).
fn session(random: bool, dir: &std::path::Path) -> super::NeuralSession {
    let mut config = SceneConfig::default_scene();
    if let GarmentSource::Builtin { resolution, .. } = &mut config.garment {
        *resolution = 300;
    }
    config.motions.truncate(2);
    let setup = TrainSetup {
        scene: build_builtin(&config).unwrap(),
        scene_config: config,
        train: TrainConfig {
            window_secs: 0.5,
            gru_burn_in_secs: 0.5,
            gru_burn_in_random: random,
            predrape_secs: 0.0,
            ..Default::default()
        },
        model: ClothNetConfig {
            static_hidden: vec![16],
            dynamic_hidden: vec![16],
            latent: 16,
            decoder_hidden: vec![16],
            ..Default::default()
        },
        descriptors: DescriptorConfig::default(),
        location: RunLocation::At(dir.to_path_buf()),
    };
    prepare(setup).unwrap().0
}

#[test]
fn a_random_burn_in_draws_each_steps_length_up_to_the_whole() {
    let dir = tempfile::tempdir().unwrap();
    let mut fixed = session(false, &dir.path().join("fixed"));
    let window = fixed.window_frames();
    assert_eq!(window, 18);
    assert_eq!(fixed.batch_frames(), window + 15);
    assert!((0..20).all(|_| fixed.step_batch_frames() == window + 15));
    let mut random = session(true, &dir.path().join("random"));
    let drawn: Vec<usize> = (0..200).map(|_| random.step_batch_frames()).collect();
    assert!(drawn.iter().all(|f| (window..=window + 15).contains(f)));
    assert!(
        drawn.contains(&window) && drawn.contains(&(window + 15)),
        "{drawn:?}"
    );
    // Validation keeps the whole burn-in.
    assert_eq!(random.batch_frames(), window + 15);
}
