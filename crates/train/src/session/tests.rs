//! Tests of the session's batch assembly.

use neural_cloth_core::scene::config::{GarmentSource, SceneConfig};
use neural_cloth_core::scene::procedural::build_builtin;
use neural_cloth_model::{ClothNetConfig, DescriptorConfig};

use burn::tensor::{Tensor, TensorData};

use crate::{RunLocation, TrainConfig, TrainSetup, prepare};

/// A session on a coarse default scene with a 0.5 s burn-in (15 frames at 30 fps).
fn session(random: bool, dir: &std::path::Path) -> super::NeuralSession {
    session_with(
        TrainConfig {
            gru_burn_in_secs: 0.5,
            gru_burn_in_random: random,
            ..Default::default()
        },
        dir,
    )
}

/// A session on a coarse default scene (two motions, a 0.5 s window, no pre-drape) with
/// `train`'s other settings.
fn session_with(train: TrainConfig, dir: &std::path::Path) -> super::NeuralSession {
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
            predrape_secs: 0.0,
            ..train
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

#[test]
fn the_boosted_history_projects_the_last_velocity_further() {
    let device = burn::tensor::Device::flex();
    let t1 = Tensor::<3>::from_data(TensorData::new(vec![1.0f32, 2.0, 3.0], [1, 1, 3]), &device);
    let t2 = Tensor::<3>::from_data(TensorData::new(vec![0.5f32, 2.0, 4.0], [1, 1, 3]), &device);
    // 2 x1 - x2' = x1 + (1 + α)(x1 - x2) with α = 0.25.
    let x2 = crate::losses::boosted_history(&t1, t2.clone(), 0.25);
    let projected = (t1.clone().mul_scalar(2.0) - x2)
        .into_data()
        .try_to_vec::<f32>()
        .unwrap();
    let expected = [1.0 + 1.25 * 0.5, 2.0, 3.0 - 1.25];
    for (p, e) in projected.iter().zip(expected) {
        assert!((p - e).abs() < 1e-6, "{projected:?}");
    }
    let plain = crate::losses::boosted_history(&t1, t2.clone(), 0.0);
    assert_eq!(plain.into_data(), t2.into_data());
}

#[test]
fn the_momentum_boost_changes_the_inertia_loss_until_its_schedule_ends() {
    let dir = tempfile::tempdir().unwrap();
    let boosted = TrainConfig {
        momentum_boost: 0.5,
        momentum_boost_steps: 1,
        ..Default::default()
    };
    let mut s = session_with(boosted, dir.path());
    let windows = s.train.sample_windows(4, true, &mut s.rng);
    let batch = s
        .train
        .batch_with_still(&windows, 0, s.batch_frames(), 3, &s.garment.skin);
    let (x, _) = s.predict(&s.model, &batch, 0, &[]);
    let x = x.detach();
    let x_t = super::stack_frames(&x, 2, 3, 4);
    let inertia = |s: &super::NeuralSession| {
        let terms = s.dynamic_losses(&x, &x_t, &batch, None, 4).unwrap();
        terms.inertia.unwrap().into_scalar::<f64>()
    };
    let first = inertia(&s);
    s.filter.restore(1);
    let after = inertia(&s);
    s.config.momentum_boost = 0.0;
    let plain = inertia(&s);
    assert!(first.is_finite() && plain > 0.0);
    assert_ne!(first, plain, "the boost acts on the first step's inertia");
    assert_eq!(after, plain, "past its schedule the boost is off");
}

/// Regression: burn draws a parameter's initial values at its first use, so two runs prepared
/// with one seed in one process (the app training twice, the tests) started from different
/// weights: the second drew after the first one's draws. The network now draws them all when
/// it is built.
#[test]
fn two_runs_prepared_with_one_seed_in_one_process_start_from_the_same_weights() {
    let dir = tempfile::tempdir().unwrap();
    let config = TrainConfig::default();
    let mut a = session_with(config.clone(), &dir.path().join("a"));
    let mut b = session_with(config, &dir.path().join("b"));
    let windows = a.train.sample_windows(4, true, &mut a.rng);
    assert_eq!(windows, b.train.sample_windows(4, true, &mut b.rng));
    let batch = a
        .train
        .batch_with_still(&windows, 0, a.batch_frames(), 3, &a.garment.skin);
    // The first session's forward pass draws nothing that the second one's weights see.
    let (xa, _) = a.predict(&a.model, &batch, 0, &[]);
    let (xb, _) = b.predict(&b.model, &batch, 0, &[]);
    assert_eq!(xa.into_data(), xb.into_data());
}

#[test]
fn the_mirrored_copies_join_when_both_the_step_and_the_fraction_are_reached() {
    use super::mirrored_joined;
    let half = TrainConfig {
        mirror_from_fraction: 0.5,
        ..Default::default()
    };
    assert!(!mirrored_joined(&half, 10, Some(0.49)));
    assert!(mirrored_joined(&half, 10, Some(0.5)));
    // An open-ended run has no half: the copies are in from the start.
    assert!(mirrored_joined(&half, 0, None));
    let both = TrainConfig {
        mirror_from_step: 100,
        ..half
    };
    assert!(!mirrored_joined(&both, 99, Some(0.9)));
    assert!(!mirrored_joined(&both, 100, Some(0.1)));
    assert!(mirrored_joined(&both, 100, Some(0.5)));
    // The default: half-way through a bounded run, from the first step of an open one.
    let default = TrainConfig::default();
    assert!(!mirrored_joined(&default, 0, Some(0.0)));
    assert!(mirrored_joined(&default, 0, Some(0.5)));
    assert!(mirrored_joined(&default, 0, None));
    // Without the fraction: from the first step.
    let throughout = TrainConfig {
        mirror_from_fraction: 0.0,
        ..default
    };
    assert!(mirrored_joined(&throughout, 0, Some(0.0)));
}

#[test]
fn a_late_start_of_the_mirrored_copies_is_noted_once_when_they_join() {
    use crate::handle::Session;
    let dir = tempfile::tempdir().unwrap();
    let mut late = session_with(
        TrainConfig {
            batch_size: 2,
            mirror_from_step: 2,
            ..Default::default()
        },
        dir.path(),
    );
    let notes: Vec<Option<String>> = (0..4)
        .map(|_| {
            late.step().unwrap();
            late.take_note()
        })
        .collect();
    assert_eq!(notes[..2], [None, None]);
    let joined = notes[2].as_deref().unwrap_or_default();
    assert!(
        joined.contains("from step 3") && joined.contains("mirrored"),
        "{joined}"
    );
    assert_eq!(notes[3], None);
    // With the copies from the first step (an open-ended run), nothing joins: no note.
    let mut throughout = session_with(
        TrainConfig {
            batch_size: 2,
            ..Default::default()
        },
        &dir.path().join("throughout"),
    );
    for _ in 0..2 {
        throughout.step().unwrap();
        assert_eq!(throughout.take_note(), None);
    }
}

#[test]
fn still_windows_that_skip_the_dynamic_encoder_train_as_if_they_went_through_it() {
    use crate::handle::Session;
    let dir = tempfile::tempdir().unwrap();
    let config = |skip: bool| TrainConfig {
        batch_size: 4,
        still_fraction: 0.5,
        skip_still_dynamics: skip,
        ..Default::default()
    };
    let mut skip = session_with(config(true), &dir.path().join("skip"));
    let mut through = session_with(config(false), &dir.path().join("through"));
    assert_eq!(skip.config.still_windows(4, true), 2);
    for step in 0..3 {
        let (a, b) = (skip.step().unwrap(), through.step().unwrap());
        let gap = (a.loss - b.loss).abs();
        assert!(
            gap <= 1e-5 * b.loss.abs().max(1e-6),
            "step {step}: loss {} against {}",
            a.loss,
            b.loss
        );
    }
    // The weights after three steps, the dynamic encoder's included, agree too.
    let weight = |s: &super::NeuralSession| -> Vec<f32> {
        let enc = s.model.dynamic_encoder.as_ref().unwrap();
        enc.gru
            .update_gate
            .hidden_transform
            .weight
            .val()
            .into_data()
            .try_to_vec::<f32>()
            .unwrap()
    };
    let (wa, wb) = (weight(&skip), weight(&through));
    let initial = weight(&session_with(config(true), &dir.path().join("fresh")));
    assert!(wa.iter().zip(&initial).any(|(a, c)| a != c), "no update");
    for (a, b) in wa.iter().zip(&wb) {
        assert!((a - b).abs() <= 1e-5, "{a} against {b}");
    }
}

/// Every float parameter's gradient in `grads`, flattened, in the order of `model`'s fields.
fn flat_gradients(
    model: &neural_cloth_model::ClothNet,
    grads: &burn::optim::GradientsParams,
) -> Vec<Vec<f32>> {
    use burn::module::{Module, ModuleVisitor, Param};
    struct Collect<'a>(&'a burn::optim::GradientsParams, Vec<Vec<f32>>);
    impl ModuleVisitor for Collect<'_> {
        fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
            if let Some(g) = self.0.get::<D>(param.id) {
                self.1.push(g.into_data().try_to_vec::<f32>().unwrap());
            }
        }
    }
    let mut collect = Collect(grads, Vec::new());
    model.visit(&mut collect);
    collect.1
}

/// The gradient of a batch stepped in two halves on two threads is the whole batch's: the
/// parts' losses are weighted by their shares of the samples and of the windows with inertia.
#[test]
fn a_batch_in_two_halves_has_the_whole_batchs_loss_and_gradient() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = session_with(TrainConfig::default(), dir.path());
    assert!(s.filter.steps_taken() == 0 && s.config.precondition_stiffness > 0.0);
    let (b, still, augment, predicted) = (8, 2, 2, 4);
    let windows = s.train.sample_windows(b, true, &mut s.rng);
    let frames = s.batch_frames();
    let part_batch = |s: &super::NeuralSession, part: super::split::Part, picks: Vec<i64>| {
        s.part_batch(&windows, part, frames, predicted, picks)
    };
    let filters = s.step_filters().unwrap();
    assert!(filters.filter.is_some(), "the default filter acts");
    // The augmented windows take the codes of windows 5 and 6, in the second half either way.
    let whole = super::split::parts(b, still, augment, false).remove(0);
    let whole = part_batch(&s, whole, vec![5, 6]);
    let whole = s.descend(&s.model, &whole, &filters).unwrap();
    let halves = super::split::parts(b, still, augment, true);
    assert_eq!(halves.len(), 2);
    let picks = [vec![], vec![1, 2]];
    let halves: Vec<_> = halves
        .into_iter()
        .zip(picks)
        .map(|(part, picks)| part_batch(&s, part, picks))
        .collect();
    let (m0, m1) = (
        super::split::fresh_leaves(&s.model),
        super::split::fresh_leaves(&s.model),
    );
    let (h0, h1) = rayon::join(
        || s.descend(&m0, &halves[0], &filters),
        || s.descend(&m1, &halves[1], &filters),
    );
    let (h0, h1) = (h0.unwrap(), h1.unwrap());
    let loss = h0.loss + h1.loss;
    assert!(
        (loss - whole.loss).abs() <= 1e-5 * whole.loss.abs(),
        "{loss} against {}",
        whole.loss
    );
    let split = super::split::sum_gradients(&s.model, vec![h0.grads, h1.grads]);
    let (a, c) = (
        flat_gradients(&s.model, &whole.grads),
        flat_gradients(&s.model, &split),
    );
    assert_eq!(a.len(), c.len());
    assert!(a.len() > 10, "{} parameters with gradients", a.len());
    let mut largest = 0.0f32;
    for (a, c) in a.iter().zip(&c) {
        assert_eq!(a.len(), c.len());
        let scale = a.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let diff = a
            .iter()
            .zip(c)
            .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()));
        largest = largest.max(scale);
        assert!(diff <= 1e-4 * scale + 1e-9, "max diff {diff} of {scale}");
    }
    assert!(largest > 0.0);
}
