//! The `train` command's flags applied to the settings they override: each given flag
//! replaces the scene's default (or a resumed run's own value) in [`TrainConfig`], the
//! network's [`ClothNetConfig`] or the [`DescriptorConfig`] of a new run.

use neural_cloth::model::{ClothNetConfig, DescriptorConfig};
use neural_cloth::train::{BackendKind, TrainConfig};

use super::train::{Backend, TrainArgs};

/// `target = value` for each flag given (`Some(value)`); flags not given leave their
/// target as it was.
macro_rules! override_from {
    ($($flag:expr => $target:expr),* $(,)?) => {
        $(if let Some(value) = $flag {
            $target = value;
        })*
    };
}

/// Applies every training and network flag of `args` to `train`, and returns the network
/// settings with theirs (the defaults otherwise).
pub fn apply_flags(args: &TrainArgs, train: &mut TrainConfig) -> ClothNetConfig {
    let mut model = ClothNetConfig::default();
    match args.backend {
        Some(Backend::Cpu) => train.backend = BackendKind::Cpu,
        Some(Backend::Wgpu) => train.backend = BackendKind::Wgpu,
        None => {}
    }
    override_from! {
        args.checkpoint_every => train.checkpoint_every,
        args.validate_every => train.validate_every,
        args.batch => train.batch_size,
        args.window => train.window_secs,
        args.gru_burn_in => train.gru_burn_in_secs,
        args.seed => train.seed,
        args.learning_rate => train.learning_rate,
        args.basis_lr_scale => model.basis_lr_scale,
        args.basis_bias_lr_scale => model.basis_bias_lr_scale,
        args.basis_init_gain => model.basis_init_gain,
        args.predrape_secs => train.predrape_secs,
        args.dynamic_basis => model.dynamic_basis,
        args.dynamic_basis_lr_scale => model.dynamic_basis_lr_scale,
        args.augmentation => train.augmentation_fraction,
        args.still_fraction => train.still_fraction,
        args.lr_decay_fraction => train.lr_decay_fraction,
        args.loss_frames => train.loss_frames,
        args.warmup_steps => train.warmup_steps,
        args.precondition => train.precondition_stiffness,
        args.precondition_moving_only => train.precondition_moving_only,
        args.split_batch => train.split_batch,
        args.precondition_dynamic_only => train.precondition_dynamic_only,
        args.weight_average => train.weight_average,
        args.propagate_history => train.history_propagation,
        args.history_adjoint => train.history_adjoint,
        args.fit_physics => train.fit_physics_weight,
        args.momentum_boost => train.momentum_boost,
        args.momentum_boost_steps => train.momentum_boost_steps,
        args.warm_start_steps => train.warm_start_steps,
        args.warm_start_iterations => train.warm_start_iterations,
        args.lr_final_factor => train.lr_final_factor,
        args.dead_limit => train.dead_limit_pct,
    }
    if args.gru_burn_in_random {
        train.gru_burn_in_random = true;
    }
    if let Some(widths) = &args.static_hidden {
        model.static_hidden = widths.clone();
    }
    model.basis_bias = !args.no_basis_bias;
    model.normalise_dynamic_input = args.scale_dynamic_input;
    if args.no_centre_init {
        train.centre_init = false;
    }
    if args.static_from_still {
        train.static_from_still = true;
    }
    if args.keep_posed_bodies {
        train.keep_posed_bodies = true;
    }
    if let Some(which) = args.basis_row_norm {
        train.basis_row_norm = which.into();
    }
    if let Some(dir) = &args.fit_reference {
        train.fit_reference = Some(dir.clone());
        train.mirror_poses = false;
    }
    if let Some(inertia) = args.inertia {
        train.inertia_mode = inertia.into();
    }
    if let Some(b) = args.precondition_final {
        train.precondition_final_stiffness = Some(b);
    }
    if args.skip_fit_check {
        train.fit_check = false;
    }
    if args.no_mirror {
        train.mirror_poses = false;
    }
    if args.warm_start_mirror_frames {
        train.warm_start_mirror_frames = true;
    }
    if let Some(n) = args.mirror_from_step {
        train.mirror_from_step = n;
    }
    if let Some(f) = args.mirror_from {
        train.mirror_from_fraction = f;
    }
    model
}

/// The descriptor settings of a new run: `--rotation-frame`, else the default (a resumed run
/// keeps its own; clap refuses the flag with `--resume`).
pub fn descriptor_config(args: &TrainArgs) -> DescriptorConfig {
    DescriptorConfig {
        rotation_frame: args.rotation_frame.map(Into::into).unwrap_or_default(),
        ..Default::default()
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;
    use neural_cloth::model::RotationFrame;

    /// The `train` arguments alone, parsed as a command line.
    #[derive(Parser)]
    struct Line {
        #[command(flatten)]
        args: TrainArgs,
    }

    #[test]
    fn every_value_flag_lands_in_its_own_field() {
        let line = Line::try_parse_from([
            "train",
            "--checkpoint-every",
            "7",
            "--validate-every",
            "9",
            "--batch",
            "5",
            "--window",
            "0.75",
            "--gru-burn-in",
            "0.25",
            "--seed",
            "11",
            "--learning-rate",
            "0.002",
            "--basis-lr-scale",
            "0.5",
            "--basis-bias-lr-scale",
            "0.25",
            "--basis-init-gain",
            "1.5",
            "--predrape-secs",
            "0.5",
            "--dynamic-basis",
            "false",
            "--dynamic-basis-lr-scale",
            "0.125",
            "--augmentation",
            "0.1",
            "--still-fraction",
            "0",
            "--lr-decay-fraction",
            "0.3",
            "--loss-frames",
            "3",
            "--warmup-steps",
            "13",
            "--precondition",
            "0.2",
            "--precondition-moving-only",
            "false",
            "--precondition-dynamic-only",
            "--weight-average",
            "0.99",
            "--propagate-history",
            "0.4",
            "--history-adjoint",
            "0.6",
            "--fit-reference",
            "refs",
            "--fit-physics",
            "2",
            "--lr-final-factor",
            "0.05",
            "--dead-limit",
            "80",
            "--momentum-boost",
            "0.3",
            "--momentum-boost-steps",
            "17",
        ])
        .unwrap();
        let mut train = TrainConfig::default();
        let model = apply_flags(&line.args, &mut train);
        assert_eq!(
            (
                train.checkpoint_every,
                train.validate_every,
                train.batch_size
            ),
            (7, 9, 5)
        );
        assert_eq!((train.window_secs, train.gru_burn_in_secs), (0.75, 0.25));
        assert_eq!((train.seed, train.learning_rate), (11, 0.002));
        assert_eq!(
            (
                model.basis_lr_scale,
                model.basis_bias_lr_scale,
                model.basis_init_gain
            ),
            (0.5, 0.25, 1.5)
        );
        assert_eq!(train.predrape_secs, 0.5);
        assert!(!model.dynamic_basis);
        assert_eq!(model.dynamic_basis_lr_scale, 0.125);
        assert_eq!(
            (train.augmentation_fraction, train.still_fraction),
            (0.1, 0.0)
        );
        assert_eq!(
            (
                train.lr_decay_fraction,
                train.loss_frames,
                train.warmup_steps
            ),
            (0.3, 3, 13)
        );
        assert_eq!(train.precondition_stiffness, 0.2);
        assert!(!train.precondition_moving_only && train.precondition_dynamic_only);
        assert_eq!(
            (
                train.weight_average,
                train.history_propagation,
                train.history_adjoint
            ),
            (0.99, 0.4, 0.6)
        );
        assert_eq!(
            train.fit_reference.as_deref(),
            Some(std::path::Path::new("refs"))
        );
        assert!(!train.mirror_poses, "a fit has no mirrored frames");
        assert_eq!(train.fit_physics_weight, 2.0);
        assert_eq!((train.lr_final_factor, train.dead_limit_pct), (0.05, 80.0));
        assert_eq!(
            (train.momentum_boost, train.momentum_boost_steps),
            (0.3, 17)
        );
        // The warm start: its steps and iterations, never on top of the diagnostic fit.
        let warm = Line::try_parse_from([
            "train",
            "--warm-start-steps",
            "150",
            "--warm-start-iterations",
            "120",
            "--no-mirror",
        ])
        .unwrap();
        let mut train = TrainConfig::default();
        apply_flags(&warm.args, &mut train);
        assert_eq!(
            (train.warm_start_steps, train.warm_start_iterations),
            (150, 120)
        );
        assert!(!train.mirror_poses);
        assert!(!train.warm_start_mirror_frames);
        let later = Line::try_parse_from(["train", "--mirror-from-step", "1100"]).unwrap();
        let mut train = TrainConfig::default();
        apply_flags(&later.args, &mut train);
        assert_eq!((train.mirror_from_step, train.mirror_poses), (1100, true));
        assert!(Line::try_parse_from(["train", "--mirror-from-step", "5", "--no-mirror"]).is_err());
        let half =
            Line::try_parse_from(["train", "--minutes", "6", "--mirror-from", "0.5"]).unwrap();
        let mut train = TrainConfig::default();
        apply_flags(&half.args, &mut train);
        assert_eq!(train.mirror_from_fraction, 0.5);
        assert!(Line::try_parse_from(["train", "--mirror-from", "0.5", "--no-mirror"]).is_err());
        let reflected = Line::try_parse_from([
            "train",
            "--warm-start-steps",
            "150",
            "--warm-start-mirror-frames",
        ])
        .unwrap();
        let mut train = TrainConfig::default();
        apply_flags(&reflected.args, &mut train);
        assert!(train.warm_start_mirror_frames && train.mirror_poses);
        assert!(Line::try_parse_from(["train", "--warm-start-mirror-frames"]).is_err());
        assert!(
            Line::try_parse_from(["train", "--fit-reference", "r", "--warm-start-steps", "5"])
                .is_err()
        );
        // The rotation frame of the descriptors, for new runs only.
        let paper = Line::try_parse_from(["train", "--rotation-frame", "paper"]).unwrap();
        assert_eq!(
            descriptor_config(&paper.args).rotation_frame,
            RotationFrame::Paper
        );
        assert!(
            Line::try_parse_from(["train", "--rotation-frame", "paper", "--resume", "r"]).is_err()
        );
        // Flags not given leave the defaults.
        let bare = Line::try_parse_from(["train"]).unwrap();
        assert_eq!(descriptor_config(&bare.args), DescriptorConfig::default());
        let mut untouched = TrainConfig::default();
        apply_flags(&bare.args, &mut untouched);
        assert_eq!(untouched, TrainConfig::default());
    }
}
