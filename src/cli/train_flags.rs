//! The `train` command's flags applied to the settings they override: each given flag
//! replaces the scene's default (or a resumed run's own value) in [`TrainConfig`] or the
//! network's [`ClothNetConfig`].

use neural_cloth::model::ClothNetConfig;
use neural_cloth::train::{BackendKind, TrainConfig};

use super::train::{Backend, TrainArgs};

/// Applies every training and network flag of `args` to `train`, and returns the network
/// settings with theirs (the defaults otherwise).
pub fn apply_flags(args: &TrainArgs, train: &mut TrainConfig) -> ClothNetConfig {
    let mut model = ClothNetConfig::default();
    match args.backend {
        Some(Backend::Cpu) => train.backend = BackendKind::Cpu,
        Some(Backend::Wgpu) => train.backend = BackendKind::Wgpu,
        None => {}
    }
    if let Some(n) = args.checkpoint_every {
        train.checkpoint_every = n;
    }
    if let Some(n) = args.validate_every {
        train.validate_every = n;
    }
    if let Some(b) = args.batch {
        train.batch_size = b;
    }
    if let Some(w) = args.window {
        train.window_secs = w;
    }
    if let Some(secs) = args.gru_burn_in {
        train.gru_burn_in_secs = secs;
    }
    if args.gru_burn_in_random {
        train.gru_burn_in_random = true;
    }
    if let Some(s) = args.seed {
        train.seed = s;
    }
    if let Some(lr) = args.learning_rate {
        train.learning_rate = lr;
    }
    if let Some(s) = args.basis_lr_scale {
        model.basis_lr_scale = s;
    }
    if let Some(s) = args.basis_bias_lr_scale {
        model.basis_bias_lr_scale = s;
    }
    if let Some(g) = args.basis_init_gain {
        model.basis_init_gain = g;
    }
    if let Some(widths) = &args.static_hidden {
        model.static_hidden = widths.clone();
    }
    if let Some(p) = args.predrape_secs {
        train.predrape_secs = p;
    }
    model.basis_bias = !args.no_basis_bias;
    model.normalise_dynamic_input = args.scale_dynamic_input;
    if let Some(on) = args.dynamic_basis {
        model.dynamic_basis = on;
    }
    if let Some(s) = args.dynamic_basis_lr_scale {
        model.dynamic_basis_lr_scale = s;
    }
    if args.no_centre_init {
        train.centre_init = false;
    }
    if args.static_from_still {
        train.static_from_still = true;
    }
    if args.keep_posed_bodies {
        train.keep_posed_bodies = true;
    }
    if let Some(f) = args.augmentation {
        train.augmentation_fraction = f;
    }
    if let Some(f) = args.still_fraction {
        train.still_fraction = f;
    }
    if let Some(f) = args.lr_decay_fraction {
        train.lr_decay_fraction = f;
    }
    if let Some(k) = args.loss_frames {
        train.loss_frames = k;
    }
    if let Some(n) = args.warmup_steps {
        train.warmup_steps = n;
    }
    if let Some(b) = args.precondition {
        train.precondition_stiffness = b;
    }
    if let Some(moving_only) = args.precondition_moving_only {
        train.precondition_moving_only = moving_only;
    }
    if let Some(dynamic_only) = args.precondition_dynamic_only {
        train.precondition_dynamic_only = dynamic_only;
    }
    if let Some(which) = args.basis_row_norm {
        train.basis_row_norm = which.into();
    }
    if let Some(decay) = args.weight_average {
        train.weight_average = decay;
    }
    if let Some(beta) = args.propagate_history {
        train.history_propagation = beta;
    }
    if let Some(beta) = args.history_adjoint {
        train.history_adjoint = beta;
    }
    if let Some(dir) = &args.fit_reference {
        train.fit_reference = Some(dir.clone());
        train.mirror_poses = false;
    }
    if let Some(weight) = args.fit_physics {
        train.fit_physics_weight = weight;
    }
    if let Some(inertia) = args.inertia {
        train.inertia_mode = inertia.into();
    }
    if let Some(b) = args.precondition_final {
        train.precondition_final_stiffness = Some(b);
    }
    if let Some(f) = args.lr_final_factor {
        train.lr_final_factor = f;
    }
    if let Some(d) = args.dead_limit {
        train.dead_limit_pct = d;
    }
    if args.skip_fit_check {
        train.fit_check = false;
    }
    model
}
