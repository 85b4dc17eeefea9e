//! Tests of the training configuration (kept apart so the settings read as one file).

use super::*;

#[test]
fn lr_schedule_is_flat_then_falls_to_the_final_factor() {
    assert_eq!(warmup_factor(0, 0), 1.0);
    assert_eq!(warmup_factor(0, 4), 0.25);
    assert_eq!(warmup_factor(3, 4), 1.0);
    assert_eq!(warmup_factor(99, 4), 1.0);
    assert_eq!(lr_schedule_factor(0.0, 0.3, 0.1), 1.0);
    assert_eq!(lr_schedule_factor(0.7, 0.3, 0.1), 1.0);
    assert!((lr_schedule_factor(0.85, 0.3, 0.1) - 0.55).abs() < 1e-12);
    assert!((lr_schedule_factor(1.0, 0.3, 0.1) - 0.1).abs() < 1e-12);
    assert!((lr_schedule_factor(1.5, 0.3, 0.1) - 0.1).abs() < 1e-12);
    assert_eq!(lr_schedule_factor(0.99, 0.0, 0.1), 1.0);
    let mut last = 1.0;
    for i in 0..=100 {
        let f = lr_schedule_factor(i as f64 / 100.0, 0.3, 0.1);
        assert!(f <= last + 1e-15, "not monotone at {i}");
        last = f;
    }
}

#[test]
fn window_frames_follow_the_window() {
    let c = TrainConfig::default();
    assert_eq!(c.window_frames(30.0), 30 + 3);
    let paper = TrainConfig {
        window_secs: PRE_ROUND_12_WINDOW_SECS,
        ..Default::default()
    };
    assert_eq!(paper.window_frames(30.0), 15 + 3);
    let c = TrainConfig {
        window_secs: 0.1,
        ..Default::default()
    };
    assert_eq!(c.window_frames(60.0), 6 + 3);
}

#[test]
fn burn_in_is_off_by_default_and_bounded() {
    let c = TrainConfig::default();
    assert_eq!(c.burn_in_frames(30.0), 0);
    let c = TrainConfig {
        gru_burn_in_secs: 1.5,
        ..Default::default()
    };
    assert_eq!(c.burn_in_frames(30.0), 45);
    assert!(c.validate(30.0).is_ok());
    let c = TrainConfig {
        gru_burn_in_secs: 11.0,
        ..Default::default()
    };
    assert_eq!(c.validate(30.0).unwrap_err().field, "gru_burn_in_secs");
}

#[test]
fn validation_names_the_field() {
    assert!(TrainConfig::default().validate(30.0).is_ok());
    let refused = |config: TrainConfig| config.validate(30.0).unwrap_err().field;
    assert_eq!(
        refused(TrainConfig {
            window_secs: 0.0,
            ..Default::default()
        }),
        "window_secs"
    );
    assert_eq!(
        refused(TrainConfig {
            batch_size: 0,
            ..Default::default()
        }),
        "batch_size"
    );
    // Row-normalised bases need the fused Adam of the CPU backend.
    let wgpu = TrainConfig {
        basis_row_norm: BasisRowNorm::Dynamic,
        backend: BackendKind::Wgpu,
        ..Default::default()
    };
    assert_eq!(refused(wgpu), "basis_row_norm");
    let unfused = TrainConfig {
        basis_row_norm: BasisRowNorm::Both,
        fused_adam: false,
        ..Default::default()
    };
    assert_eq!(refused(unfused), "basis_row_norm");
    let cpu = TrainConfig {
        basis_row_norm: BasisRowNorm::Both,
        ..Default::default()
    };
    assert!(cpu.validate(30.0).is_ok());
    // The weight average: a decay below 1, with the fused Adam only.
    for decay in [-0.1, 1.0] {
        let bad = TrainConfig {
            weight_average: decay,
            ..Default::default()
        };
        assert_eq!(refused(bad), "weight_average");
    }
    let unfused = TrainConfig {
        weight_average: 0.99,
        fused_adam: false,
        ..Default::default()
    };
    assert_eq!(refused(unfused), "weight_average");
    let averaged = TrainConfig {
        weight_average: 0.99,
        ..Default::default()
    };
    assert!(averaged.validate(30.0).is_ok());
    // The history propagation: in [0, 100], with the gradient filter only.
    for beta in [-1.0, 101.0] {
        let bad = TrainConfig {
            history_propagation: beta,
            ..Default::default()
        };
        assert_eq!(refused(bad), "history_propagation");
    }
    let unfiltered = TrainConfig {
        history_propagation: 1.0,
        precondition_stiffness: 0.0,
        ..Default::default()
    };
    assert_eq!(refused(unfiltered), "history_propagation");
    let propagated = TrainConfig {
        history_propagation: 1.0,
        ..Default::default()
    };
    assert!(propagated.validate(30.0).is_ok());
    // The history adjoint: in [0, 100], with the gradient filter only.
    for bad in [
        TrainConfig {
            history_adjoint: -1.0,
            ..Default::default()
        },
        TrainConfig {
            history_adjoint: 1.0,
            precondition_stiffness: 0.0,
            ..Default::default()
        },
    ] {
        assert_eq!(refused(bad), "history_adjoint");
    }
    // Fitting to reference frames: no still or augmented windows (no simulated frames).
    let with_still = TrainConfig {
        fit_reference: Some("runs/x/reference".into()),
        ..Default::default()
    };
    assert_eq!(refused(with_still), "still_fraction");
    let mirrored = TrainConfig {
        fit_reference: Some("runs/x/reference".into()),
        still_fraction: 0.0,
        ..Default::default()
    };
    assert_eq!(refused(mirrored.clone()), "mirror_poses");
    // The fit's physics weight: in range, and only with a fit.
    for bad in [
        TrainConfig {
            fit_physics_weight: 1.0,
            ..Default::default()
        },
        TrainConfig {
            fit_reference: Some("runs/x/reference".into()),
            still_fraction: 0.0,
            mirror_poses: false,
            fit_physics_weight: -1.0,
            ..Default::default()
        },
    ] {
        assert_eq!(refused(bad), "fit_physics_weight");
    }
    let fitted = TrainConfig {
        mirror_poses: false,
        ..mirrored
    };
    assert!(fitted.validate(30.0).is_ok());
    // The warm start: bounded, and not on top of the diagnostic fit.
    for bad in [
        TrainConfig {
            warm_start_steps: 2_000_000,
            ..Default::default()
        },
        TrainConfig {
            warm_start_steps: 10,
            ..fitted.clone()
        },
    ] {
        assert_eq!(refused(bad), "warm_start_steps");
    }
    let few = TrainConfig {
        warm_start_steps: 10,
        warm_start_iterations: 5,
        ..Default::default()
    };
    assert_eq!(refused(few), "warm_start_iterations");
    let warm = TrainConfig {
        warm_start_steps: 150,
        ..Default::default()
    };
    assert!(warm.validate(30.0).is_ok());
    let mirror_frames = TrainConfig {
        warm_start_mirror_frames: true,
        ..warm.clone()
    };
    assert!(mirror_frames.validate(30.0).is_ok());
    for bad in [
        TrainConfig {
            mirror_poses: false,
            ..mirror_frames.clone()
        },
        TrainConfig {
            warm_start_steps: 0,
            ..mirror_frames
        },
    ] {
        assert_eq!(refused(bad), "warm_start_mirror_frames");
    }
    // The copies' late start needs copies.
    let later = TrainConfig {
        mirror_from_step: 500,
        ..Default::default()
    };
    assert!(later.validate(30.0).is_ok());
    let no_copies = TrainConfig {
        mirror_poses: false,
        ..later
    };
    assert_eq!(refused(no_copies), "mirror_from_step");
    // The copies' late start as a fraction of the run: below 1; without copies it has nothing
    // to start (the default fraction stays valid with `--no-mirror`).
    let half = TrainConfig {
        mirror_from_fraction: 0.5,
        ..Default::default()
    };
    assert!(half.validate(30.0).is_ok());
    let no_copies = TrainConfig {
        mirror_poses: false,
        ..half.clone()
    };
    assert!(no_copies.validate(30.0).is_ok());
    for bad in [
        TrainConfig {
            mirror_from_fraction: 1.0,
            ..half.clone()
        },
        TrainConfig {
            mirror_from_fraction: -0.1,
            ..half.clone()
        },
        TrainConfig {
            mirror_from_fraction: f64::NAN,
            ..half
        },
    ] {
        assert_eq!(refused(bad), "mirror_from_fraction");
    }
    // The momentum boost: in [0, 1], with a schedule length.
    for (boost, steps, field) in [
        (-0.1, 100, "momentum_boost"),
        (1.5, 100, "momentum_boost"),
        (0.2, 0, "momentum_boost_steps"),
    ] {
        let bad = TrainConfig {
            momentum_boost: boost,
            momentum_boost_steps: steps,
            ..Default::default()
        };
        assert_eq!(refused(bad), field);
    }
    // The rate is the scene's: checked against the trainer's range by its own name.
    let e = TrainConfig::default().validate(2.0).unwrap_err();
    assert_eq!(e.field, "training_fps");
    // The loss frames must fit the window at the given rate: 0.25 s holds 8 + 3 frames at
    // 30 fps, 15 + 3 at 60.
    let short = TrainConfig {
        window_secs: 0.25,
        loss_frames: 12,
        ..Default::default()
    };
    assert_eq!(short.validate(30.0).unwrap_err().field, "loss_frames");
    assert!(short.validate(60.0).is_ok());
}

#[test]
fn momentum_boost_falls_linearly_to_zero() {
    let c = TrainConfig {
        momentum_boost: 0.2,
        momentum_boost_steps: 100,
        ..Default::default()
    };
    assert!(c.validate(30.0).is_ok());
    assert_eq!(c.momentum_boost_at(0), 0.2);
    assert!((c.momentum_boost_at(50) - 0.1).abs() < 1e-12);
    assert_eq!(c.momentum_boost_at(100), 0.0);
    assert_eq!(c.momentum_boost_at(5000), 0.0);
    assert_eq!(TrainConfig::default().momentum_boost_at(0), 0.0);
}

#[test]
fn round_trips_through_toml() {
    let c = TrainConfig {
        batch_size: 8,
        inertia_mode: InertiaMode::Snug,
        ..Default::default()
    };
    let text = toml::to_string(&c).unwrap();
    assert_eq!(toml::from_str::<TrainConfig>(&text).unwrap(), c);
}

/// Runs saved before the fraction existed had their copies from the start: they keep them.
#[test]
fn a_config_saved_without_the_copies_fraction_reads_as_copies_from_the_start() {
    let new = TrainConfig::default();
    assert_eq!(new.mirror_from_fraction, 0.5);
    let mut table = toml::Table::try_from(&new).unwrap();
    assert!(table.remove("mirror_from_fraction").is_some());
    let saved: TrainConfig = toml::from_str(&toml::to_string(&table).unwrap()).unwrap();
    assert_eq!(saved.mirror_from_fraction, 0.0);
    assert_eq!(
        TrainConfig {
            mirror_from_fraction: 0.5,
            ..saved
        },
        new
    );
}

#[test]
fn a_runs_progress_is_the_larger_share_of_its_steps_and_its_minutes() {
    use crate::config::run_progress;
    assert_eq!(run_progress(50, None, 30.0, None), None);
    assert_eq!(run_progress(50, Some(200), 30.0, None), Some(0.25));
    assert_eq!(run_progress(50, None, 30.0, Some(60.0)), Some(0.5));
    assert_eq!(run_progress(50, Some(100), 30.0, Some(120.0)), Some(0.5));
    assert_eq!(run_progress(10, Some(100), 90.0, Some(60.0)), Some(1.5));
}
