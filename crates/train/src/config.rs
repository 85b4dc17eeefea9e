//! Training configuration: batch, temporal window, optimiser and schedule. The frame rate is
//! the scene's ([`neural_cloth_core::scene::Scene::training_fps`]): the methods that need it
//! take it as an argument.

use serde::{Deserialize, Serialize};

/// How the inertia loss treats past frames (paper §4.5).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InertiaMode {
    /// Ours: the projection `2x_{t-1} - x_{t-2}` is a constant (stop-gradient); only `x_t` learns.
    #[default]
    Ours,
    /// SNUG-style: gradients also flow into the past frames.
    Snug,
}

/// Which decoder bases Adam normalises by rows ([`TrainConfig::basis_row_norm`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BasisRowNorm {
    /// Every parameter value has its own second moment (burn's Adam).
    #[default]
    Off,
    /// The dynamic basis's rows (trained by the moving windows' filtered gradient only).
    Dynamic,
    /// The shared basis's rows and the dynamic basis's.
    Both,
}

/// Which compute backend trains the model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BackendKind {
    /// burn's `flex` CPU backend (default; fastest CPU backend measured on our step).
    #[default]
    Cpu,
    /// burn-wgpu on the first GPU adapter.
    Wgpu,
}

/// Default stiffness scale of the training gradient filter
/// ([`TrainConfig::precondition_stiffness`]).
pub const DEFAULT_PRECONDITION_STIFFNESS: f64 = 0.01;

/// The training window of runs saved before the default became 1 s (docs/TRAINING.md
/// round 12), seconds: what a run folder that does not name its window trained with.
pub const PRE_ROUND_12_WINDOW_SECS: f32 = 0.5;

/// Everything that decides how a model is trained. Units in field names.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainConfig {
    /// Windows per batch; 1..=256, default 16 (the paper uses up to 32).
    pub batch_size: usize,
    /// Temporal window in seconds; 0.05..=4, default 1 (the paper: 0.5, looser garments up
    /// to 2 s; with 1 s the skirt keeps its lag behind a spinning body and the GRU's state
    /// does not drift on long t-shirt runs: docs/TRAINING.md round 12). Runs saved without
    /// the field keep 0.5 ([`PRE_ROUND_12_WINDOW_SECS`]).
    pub window_secs: f32,
    /// Seconds of motion before each training window over which the dynamic encoder's GRU
    /// runs without gradient, so that the window starts from the state inference would carry
    /// in (inference plays whole motions; a window from a zero state never shows the GRU the
    /// states it drifts to over seconds of slow motion, docs/TRAINING.md round 10). Frames
    /// before a motion's start are still frames (a zero state stays zero). 0..=10, default 0
    /// (every window from a zero state, the paper's training). Measured in docs/TRAINING.md
    /// round 11: 1.5 s removes the drift (the t-shirt's carried state within 0.3 mm of its
    /// windows after 5000 steps, 5.5 mm without) but makes the skirt's lag depend on the
    /// seed; each step costs about 1.25× as much.
    pub gru_burn_in_secs: f32,
    /// Draw each step's burn-in length uniformly from none to [`Self::gru_burn_in_secs`]
    /// (validation keeps the whole), so that training sees windows from a zero state and
    /// from a carried one alike. Default false.
    #[serde(default)]
    pub gru_burn_in_random: bool,
    /// Adam learning rate; (0, 1], default 1e-3.
    pub learning_rate: f64,
    /// Stop after this many optimiser steps (None = no limit). Default None.
    pub max_steps: Option<u64>,
    /// Stop after this many minutes of wall-clock time (None = no limit). Default None.
    pub max_minutes: Option<f64>,
    /// Validate every this many steps; >= 1, default 50.
    pub validate_every: u64,
    /// Send a weight snapshot for preview every this many steps; >= 1, default 10.
    pub snapshot_every: u64,
    /// Write a checkpoint every this many steps; >= 1, default 200.
    pub checkpoint_every: u64,
    /// Add left/right mirrored copies of the training motions. Default true.
    pub mirror_poses: bool,
    /// Steps trained on the motions alone before their mirrored copies join the batches
    /// (with [`TrainConfig::mirror_poses`]); default 0: with them from the start. With both
    /// turning directions from the start the network learns the direction-dependent part
    /// of a motion (the skirt's twist about the body) hardly at all; learned one way first, it
    /// carries to the other (round 24, docs/TRAINING.md: skirt 1100 + 1100 steps, spin 88.8 /
    /// mirrored 101.0 mm from the simulator resumed, 116.8 / 128.4 from scratch, against
    /// 132.7 / 132.8 with the copies throughout). Default 0: the rule for new runs is
    /// [`TrainConfig::mirror_from_fraction`].
    pub mirror_from_step: u64,
    /// Fraction of a bounded run (by steps or minutes, as the learning-rate schedule counts
    /// it) trained on the motions alone before their mirrored copies join the batches (with
    /// [`TrainConfig::mirror_poses`]); the rule for runs whose step count is not known in
    /// advance. Both this and [`TrainConfig::mirror_from_step`] must be reached. Open-ended
    /// runs (the app without a limit) have the copies from the start. 0..1, default 0.5 for
    /// new runs (round 25, docs/TRAINING.md: the skirt 93.8 / 92.0 mm from the simulator on
    /// the spin / mirrored spin after 1702 steps, 136.7 / 150.5 with the copies throughout;
    /// the t-shirt's held-out spin 2-9 mm closer after 1986-2200 steps, within a millimetre
    /// after 1100, its idle at most 0.2 mm further); runs saved without the field read 0.
    #[serde(default)]
    pub mirror_from_fraction: f64,
    /// Fraction of each batch whose dynamic codes are shuffled (motion augmentation, static
    /// losses only, no encoder gradient); 0..=0.9, default 0 (the paper's 0.2 teaches the
    /// dynamic basis to stay silent: docs/TRAINING.md, round 4).
    pub augmentation_fraction: f32,
    /// Inertia gradient mode; default `ours`.
    pub inertia_mode: InertiaMode,
    /// Compute backend; default `cpu`.
    pub backend: BackendKind,
    /// Seed of every random choice (initialisation, sampling); default 0.
    pub seed: u64,
    /// Warm start: seconds the reference simulator lets the garment settle on the rest pose
    /// before training; the basis bias starts at that drape (see [`super::warm_start`]).
    /// 0 = start from the template; 0..=10, default 1.5.
    pub predrape_secs: f32,
    /// Data-dependent initialisation: centre every biased layer's pre-activations on the
    /// training poses before the first step, so that no unit starts dead for every pose
    /// ([`neural_cloth_model::activity::centre_biases`]). Default true.
    pub centre_init: bool,
    /// Fraction of each batch made of still windows (a training pose held for the whole
    /// window: static losses, zero dynamics), teaching the static branch the quasi-static drape
    /// of every pose; 0..=0.9 (with `augmentation_fraction`, at most 0.95), default 0.25
    /// (measured on the skirt: still hem radius 0.199 m against 0.220 m without, simulator
    /// 0.136 m; docs/TRAINING.md).
    pub still_fraction: f32,
    /// Only the still windows train the static encoder: in moving windows its code is
    /// detached, so the static branch learns the quasi-static drape of each pose and the
    /// dynamic branch carries all motion. Needs `still_fraction > 0` and the disentangled
    /// encoder; default false: on the skirt it changed little (still hem 0.168 against
    /// 0.169 m, swing 49.6 against 45.3 mm), on the t-shirt it cost static accuracy (idle
    /// 3.4 against 2.7 mm after 2200 steps: a quarter of each batch trains the static branch).
    pub static_from_still: bool,
    /// Fraction of a bounded run (by steps or minutes) at its end over which the learning
    /// rate falls along a half cosine to `lr_final_factor` of its value: Adam's steps are
    /// about the rate whatever the gradient, so a constant rate leaves millimetres of noise
    /// in the drape. 0..=1, default 0 (constant rate: resuming the 30-minute t-shirt at a tenth
    /// of the rate for 400 steps left its idle distance at 2.4 mm; 0.25 over a whole
    /// 3771-step t-shirt run brought its held-out spin 1.5-2.5 mm closer on two seeds and
    /// changed nothing over 1656 steps; over a 1702-step skirt run it cost 1-9 mm on two seeds;
    /// docs/TRAINING.md rounds 2, 28 and 29).
    /// Open-ended runs (the app without a limit) always keep the constant rate.
    pub lr_decay_fraction: f64,
    /// The learning-rate factor reached at the end of a bounded run, in (0, 1]; default 0.1.
    pub lr_final_factor: f64,
    /// Evaluate the static energies with the fused kernels (default true) or with the burn
    /// tensor code they are checked against (false: the reference path, about 3× slower per
    /// step on the default scene; kept for checks and benchmarks).
    pub fused_physics: bool,
    /// Update the parameters with the fused Adam ([`super::adam::FusedAdam`]: one host pass
    /// over each parameter and its moments, the same formula and numbers as burn's) when the
    /// backend keeps them on the host (`cpu`); false, or `wgpu`: burn's Adam. Both save the
    /// same checkpoint state. Default true.
    pub fused_adam: bool,
    /// Keep every training frame's posed body (its normals and query tree, about 0.3 MB for
    /// a 6000-vertex avatar) once built, instead of building each step's bodies anew (in
    /// parallel) and dropping them after the step. Keeping them saves the builds (about
    /// 0.65 ms a body, two bodies a window) and costs memory that grows with the frames the
    /// run has visited: towards 0.8 GB on the default scene (615 MB more peak memory after
    /// 300 steps, docs/BENCHMARKS.md). Default false.
    pub keep_posed_bodies: bool,
    /// Still windows skip the dynamic encoder and the GRU: their dynamic descriptors are zero
    /// and the dynamic branch has no bias, so their codes are exactly zero and they add nothing
    /// to its gradient ([`neural_cloth_model::RecurrentEncoder::forward_after_quiet`]); the
    /// other windows are computed as before. False computes every window (the path before,
    /// kept for `bench`). Default true.
    #[serde(default = "skip_still_dynamics_default")]
    pub skip_still_dynamics: bool,
    /// Step each batch as two halves on two threads, each with its own copy of the network's
    /// leaves, their gradients summed (each half's losses weighted by its share of the
    /// batch, so the sum is the whole batch's gradient up to rounding). The step's serial
    /// element-wise work then runs on both cores. The augmented windows take the dynamic code
    /// of a window of their own half. The warm start's fit keeps the batch whole. False: one
    /// batch (the path before, kept for `bench`). Default true.
    #[serde(default = "split_batch_default")]
    pub split_batch: bool,
    /// A validation pass with at least this percentage of dead units in one revivable layer
    /// (decoder, static hidden layers) triggers the stall remedy (revive the dead units); 1..=100, default 75.
    pub dead_limit_pct: f64,
    /// Refuse a garment file that clearly does not fit the avatar (many vertices inside the
    /// body, far outside it, or a size or place that fitting would change a lot; see
    /// [`super::preflight::fit_refusal`]); built-in garments are not checked. Default true.
    pub fit_check: bool,
    /// Trailing frames of each window that get the per-frame loss (inertia from the network's
    /// own two previous frames, plus the static terms): 1 = the paper's (the last frame only);
    /// more gives the dynamics that build up over several frames more signal per step, and
    /// each step that much more physics (measured: no better at equal steps, docs/TRAINING.md).
    /// 1..=16 and at most the window's frames minus 2; default 1.
    pub loss_frames: usize,
    /// Steps over which the learning rate rises linearly to its value at the start of a run
    /// (Adam's first steps move every weight by about the rate whatever its gradient, which
    /// kills most decoder units of a fresh network within 50 steps); 0..=100000, default 0.
    pub warmup_steps: u64,
    /// Stiffness scale β of the gradient filter ([`neural_cloth_physics::GradientFilter`]): the
    /// physics gradient with respect to each loss frame becomes `D (D + βK)⁻¹ g`, `D = M/Δt²`,
    /// `K` the rest membrane stiffness, which shrinks the stiff modes' share of the gradient
    /// so that the smooth modes a garment swings in learn at the rate of the rest. 0 = off
    /// (the plain gradient); 0..=100, default 0.01 (t-shirt, three seeds: swing on the run
    /// 4.5-5.0 → 7.8-10.4 mm of the simulator's 12, idle drape unchanged or better; larger
    /// values slow the static drape, docs/TRAINING.md round 7). Run folders from before the
    /// filter keep 0 (`run_dir`'s version-1 upgrade); settings saved elsewhere without the
    /// field (projects) get the default.
    pub precondition_stiffness: f64,
    /// The gradient filter (when `precondition_stiffness > 0`) leaves the still windows'
    /// gradient plain (they teach the quasi-static drape, whose stiff modes the filter slows
    /// down) and filters the moving windows only; without the dynamics effect there are no
    /// still windows and every row is filtered. Default true since docs/TRAINING.md round 12
    /// (with the wide static encoder and the 1 s window: the skirt's spin 83.5 mm from the
    /// simulator on average over four seeds, against 131-139 mm with round 9's defaults; the
    /// t-shirt's idle 1.6 mm). Alone, with round 8's narrow encoder, it cost the skirt's
    /// hem its opening (49 % as far as the simulator's; rounds 7 and 8). Runs saved without
    /// the field keep false.
    pub precondition_moving_only: bool,
    /// With a step limit, the filter's stiffness scale falls (or rises) geometrically from
    /// `precondition_stiffness` to this value over the run's `max_steps` (a resume with another
    /// limit moves the schedule with it; the filter is refactored when β has moved by 10 %);
    /// `None` (default) keeps it constant. In (0, 100]; measured not better than a constant
    /// 0.01 (docs/TRAINING.md round 7).
    pub precondition_final_stiffness: Option<f64>,
    /// The gradient filter (when `precondition_stiffness > 0` and the scene has the dynamics
    /// effect) acts on the gradient of the dynamic terms (inertia, friction) only; the static
    /// terms' gradient stays plain (with `precondition_moving_only` too, the still windows'
    /// dynamic gradient also stays plain). Default false: on the t-shirt with the twirl (seeds
    /// 1 and 9) it keeps the `w = 0` drape within 1.1-1.7 mm of the simulator's height where
    /// the full filter lifts it 4.8-5.6 mm, and loses most of the swing (run 3.8-4.7 mm of the
    /// simulator's 12.0; docs/TRAINING.md round 8).
    pub precondition_dynamic_only: bool,
    /// Adam normalises each row of the decoder's bases (one latent direction's pattern over
    /// every vertex coordinate) by one second moment, the mean of the row's, instead of each
    /// value by its own ([`super::adam::FusedAdam::with_basis_row_norm`]): per-value Adam moves
    /// every vertex coordinate of a row by about the rate whatever its gradient, which turns
    /// the smooth field of the (filtered) physics gradient into a field of equal steps; with
    /// one moment per row the row moves along the gradient's own shape. Needs the fused Adam
    /// (the CPU backend). Default `off`.
    pub basis_row_norm: BasisRowNorm,
    /// Decay of an exponential moving average of the weights kept beside them, in [0, 0.9999]
    /// (0, the default: none). With a decay `d` the checkpoints (and so every bake, compare
    /// and export of the run) hold the average over about the last `1 / (1 - d)` steps
    /// instead of the last step's weights, which averages out the noise of the optimiser's
    /// steps; training itself, its validation and the app's preview go on with the
    /// optimiser's own weights. Early on the decay is `min(d, (1 + t) / (10 + t))` at step
    /// `t` (the average starts from the first weights). A run resumed or rolled back goes on
    /// from the checkpoint's (averaged) weights; the best checkpoint is chosen by the
    /// optimiser's own weights' validation. Needs the fused Adam (the CPU backend). Measured
    /// in docs/TRAINING.md round 16: not better than the last step's weights.
    pub weight_average: f32,
    /// Stiffness scale β' of the history propagation, in [0, 100] (0, the default: off).
    /// With it, the (filtered) gradient of each moving window's loss frames is carried
    /// forward in time, `G_k = g_k + P (2 G_{k-1} - G_{k-2})` with `P = D (D + β'K)⁻¹`, the
    /// linearised effect of moving frame `k - 1` and `k - 2` on frame `k`'s own physics step:
    /// a correction of an early loss frame moves the later ones with it (the soft modes
    /// ballistically, the stiff ones damped by `P`), so a window's frames are corrected
    /// together instead of one frame per refit. The fixed point is unchanged (all `G = 0`
    /// exactly where every `g = 0`). Needs the gradient filter on
    /// (`precondition_stiffness > 0`) and acts only with more than one loss frame
    /// (`loss_frames`). Measured in docs/TRAINING.md round 17 (t-shirt, seed 43, 1100 steps):
    /// with 6 loss frames and β' = 1 the swing grows but the distance to the simulator is
    /// unchanged; with 12 the carried gradient (up to 78 times a constant residual) shreds
    /// the garment. Experimental; keep the loss frames few.
    pub history_propagation: f64,
    /// Stiffness scale β'' of the history adjoint, in [0, 100] (0, the default: off). With
    /// it, each moving window's (filtered) loss-frame gradient `g_k` is also handed to the
    /// two frames its physics step starts from, `g_{k-1} -= 2 P g_k` and `g_{k-2} += P g_k`
    /// with `P = D (D + β''K)⁻¹`: the gradient of the least-squares residual of every frame's
    /// physics step instead of the stop-gradient loss's, with the same fixed point. The
    /// stop-gradient descent is unstable for the soft modes a motion drives faster than
    /// their natural frequency (the swing and the slip) once the network's frames share
    /// parameters; this one is not (a toy shows both, docs/TRAINING.md round 18). Measured
    /// there on the t-shirt (seed 43, 1100 steps, β'' = 1): no closer to the simulator
    /// (held-out spin 31.1 against 30.0 mm, idle 4.5 against 2.7, less swing), nor from a
    /// start near the simulator (round 19: twirl 19.6 against 19.1 mm); experimental.
    /// Needs the gradient filter on (`precondition_stiffness > 0`).
    pub history_adjoint: f64,
    /// A diagnostic, not the method (default None): a folder of our own simulator's frames
    /// of every training motion (the PC2 caches `compare` writes in a run's `reference/`
    /// folder) that the network is fitted to directly, with the mass-weighted squared
    /// distance `Σ m |x - x_sim|² / (2Δt²)` in place of the physics loss's gradient (a
    /// training step's logged loss is then this fit's; validation stays the physics'). It shows how close the architecture
    /// can come to the simulator at all ([`crate::fit_reference`]). Needs `still_fraction`
    /// and `augmentation_fraction` 0 and `mirror_poses` off (their frames have no simulated
    /// counterpart).
    pub fit_reference: Option<std::path::PathBuf>,
    /// Weight of the physics loss added to the fit of [`TrainConfig::fit_reference`], in
    /// [0, 100] (0, the default: the fit alone). With 1 the step descends the fit plus the
    /// paper's loss (filtered as configured): the network follows the simulator's frames
    /// while staying a garment physics accepts (the fit alone leaves the t-shirt strained
    /// 12 %, docs/TRAINING.md round 19). A diagnostic, as the fit is; needs `fit_reference`.
    pub fit_physics_weight: f64,
    /// Momentum boost α of the inertia target at the start of a run, in [0, 1] (0, the
    /// default: off): each loss frame's inertia projects `x_{t-1} + (1 + α)(x_{t-1} - x_{t-2})`
    /// instead of `2x_{t-1} - x_{t-2}`, a negative damping that lets a swing grow from the
    /// network's own (damped) history, as a curriculum towards the swinging garment; α falls
    /// linearly to 0 over [`TrainConfig::momentum_boost_steps`] and the paper's loss takes over.
    /// Validation and metrics keep the plain projection. Experimental (docs/TRAINING.md
    /// round 20).
    pub momentum_boost: f64,
    /// Steps over which [`TrainConfig::momentum_boost`] falls linearly to 0 (counted from the
    /// run's first step, so a resume goes on along the same schedule); 1..=1000000 when the
    /// boost is on, default 0.
    pub momentum_boost_steps: u64,
    /// Steps at the start of a run that also fit the network to our own simulator's frames of
    /// every training motion (0, the default: off). Before the first step the reference
    /// simulator runs each training motion once at [`TrainConfig::warm_start_iterations`]
    /// (cached in the run's `reference/` folder, where `compare` finds them); for these steps
    /// the network descends the mass-weighted distance to them plus the paper's loss, then the
    /// paper's loss alone. The paper's loss keeps a network at the simulator's dynamics on a
    /// motion it trains on, but does not find them from the template (docs/TRAINING.md rounds
    /// 21 and 22): this is the way in. Still unsupervised (the only data is our simulator's
    /// answer for the training motions), at the price of simulating them. Still, augmented
    /// and mirrored windows keep the paper's loss alone (for the mirrored ones see
    /// [`TrainConfig::warm_start_mirror_frames`]); the mirrored ones then pull the swing back
    /// (the spin alone: 17.8 mm from the simulator with [`TrainConfig::mirror_poses`], 9.1
    /// without, round 22). 0..=1000000.
    pub warm_start_steps: u64,
    /// L-BFGS iterations per frame of the warm start's simulation, 10..=1000, default 200
    /// (fewer can settle a fast motion on another branch: at 40 and 100 iterations the
    /// t-shirt's spin whirls the other way, docs/TRAINING.md round 21).
    pub warm_start_iterations: usize,
    /// Experimental, default false: the warm start also fits the mirrored copies of the
    /// training motions, to the mirror image of their motion's simulation where the garment
    /// and body are symmetric ([`crate::warm_start_mirror`]), else to a simulation of their
    /// own. Measured worse (docs/TRAINING.md round 23: the spin alone 26.8 mm from the
    /// simulator against 17.8 without it; after a 450-step fit the network is still 26.0 mm
    /// from the frames it fits), so off. Needs `mirror_poses`.
    pub warm_start_mirror_frames: bool,
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            batch_size: 16,
            window_secs: 1.0,
            gru_burn_in_secs: 0.0,
            gru_burn_in_random: false,
            learning_rate: 1e-3,
            max_steps: None,
            max_minutes: None,
            validate_every: 50,
            snapshot_every: 10,
            checkpoint_every: 200,
            mirror_poses: true,
            mirror_from_step: 0,
            mirror_from_fraction: 0.5,
            augmentation_fraction: 0.0,
            inertia_mode: InertiaMode::Ours,
            backend: BackendKind::Cpu,
            seed: 0,
            predrape_secs: 1.5,
            centre_init: true,
            still_fraction: 0.25,
            static_from_still: false,
            dead_limit_pct: 75.0,
            lr_decay_fraction: 0.0,
            lr_final_factor: 0.1,
            fused_physics: true,
            fused_adam: true,
            keep_posed_bodies: false,
            skip_still_dynamics: true,
            split_batch: true,
            fit_check: true,
            loss_frames: 1,
            warmup_steps: 0,
            precondition_stiffness: DEFAULT_PRECONDITION_STIFFNESS,
            precondition_moving_only: true,
            precondition_final_stiffness: None,
            precondition_dynamic_only: false,
            basis_row_norm: BasisRowNorm::Off,
            weight_average: 0.0,
            history_propagation: 0.0,
            history_adjoint: 0.0,
            fit_reference: None,
            fit_physics_weight: 0.0,
            momentum_boost: 0.0,
            momentum_boost_steps: 0,
            warm_start_steps: 0,
            warm_start_iterations: 200,
            warm_start_mirror_frames: false,
        }
    }
}

/// [`TrainConfig::skip_still_dynamics`] of configurations saved without it.
fn skip_still_dynamics_default() -> bool {
    true
}

/// [`TrainConfig::split_batch`] of configurations saved without it.
fn split_batch_default() -> bool {
    true
}

/// A configuration value outside its documented range.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("training setting `{field}` = {value} is outside {range}")]
pub struct ConfigError {
    /// Field name.
    pub field: &'static str,
    /// Offending value, formatted.
    pub value: String,
    /// Allowed range, formatted.
    pub range: &'static str,
}

/// The training frame rates the trainer takes, frames per second ([`TrainConfig::validate`]).
pub const TRAINING_FPS_RANGE: std::ops::RangeInclusive<f32> = 5.0..=240.0;
/// [`TRAINING_FPS_RANGE`] as its error messages print it (keep the two together).
const TRAINING_FPS_RANGE_TEXT: &str = "5..=240";

impl TrainConfig {
    /// The momentum boost α before step `step` (0-based): [`Self::momentum_boost`] falling
    /// linearly to 0 at [`Self::momentum_boost_steps`], 0 after (and when off).
    pub fn momentum_boost_at(&self, step: u64) -> f64 {
        if self.momentum_boost == 0.0 || step >= self.momentum_boost_steps {
            return 0.0;
        }
        self.momentum_boost * (1.0 - step as f64 / self.momentum_boost_steps as f64)
    }

    /// Frames per training window at `fps` (the scene's training rate, frames per second):
    /// `ceil(window_secs * fps) + 3` (the last 3 are predicted).
    pub fn window_frames(&self, fps: f32) -> usize {
        (self.window_secs * fps).ceil().max(0.0) as usize + 3
    }

    /// Windows of a batch of `batch` whose dynamic codes are shuffled
    /// ([`Self::augmentation_fraction`]); none without `dynamics` (the scene's effect) and at
    /// least one window left unshuffled.
    pub fn augmented_windows(&self, batch: usize, dynamics: bool) -> usize {
        if dynamics && batch >= 2 {
            ((self.augmentation_fraction * batch as f32).round() as usize).min(batch - 1)
        } else {
            0
        }
    }

    /// Still windows of a batch of `batch` ([`Self::still_fraction`]), at most the windows left
    /// by [`Self::augmented_windows`]; none without `dynamics` (every window is then already
    /// quasi-static).
    pub fn still_windows(&self, batch: usize, dynamics: bool) -> usize {
        if dynamics {
            ((self.still_fraction * batch as f32).round() as usize)
                .min(batch - self.augmented_windows(batch, dynamics))
        } else {
            0
        }
    }

    /// Frames before each window that only set its GRU state ([`TrainConfig::gru_burn_in_secs`]
    /// at `fps`).
    pub fn burn_in_frames(&self, fps: f32) -> usize {
        (self.gru_burn_in_secs * fps).round().max(0.0) as usize
    }

    /// Checks every field against its documented range, for training at `fps` (the scene's
    /// training rate, frames per second): the rate itself must lie in [`TRAINING_FPS_RANGE`]
    /// and the window at that rate must hold the loss frames.
    pub fn validate(&self, fps: f32) -> Result<(), ConfigError> {
        fn check(
            ok: bool,
            field: &'static str,
            value: impl ToString,
            range: &'static str,
        ) -> Result<(), ConfigError> {
            if ok {
                Ok(())
            } else {
                Err(ConfigError {
                    field,
                    value: value.to_string(),
                    range,
                })
            }
        }
        check(
            (1..=256).contains(&self.batch_size),
            "batch_size",
            self.batch_size,
            "1..=256",
        )?;
        check(
            (0.05..=4.0).contains(&self.window_secs),
            "window_secs",
            self.window_secs,
            "0.05..=4 s",
        )?;
        check(
            (0.0..=10.0).contains(&self.gru_burn_in_secs),
            "gru_burn_in_secs",
            self.gru_burn_in_secs,
            "0..=10 s",
        )?;
        check(
            TRAINING_FPS_RANGE.contains(&fps),
            "training_fps",
            fps,
            TRAINING_FPS_RANGE_TEXT,
        )?;
        check(
            self.learning_rate > 0.0 && self.learning_rate <= 1.0,
            "learning_rate",
            self.learning_rate,
            "(0, 1]",
        )?;
        check(
            self.validate_every >= 1,
            "validate_every",
            self.validate_every,
            ">= 1",
        )?;
        check(
            self.snapshot_every >= 1,
            "snapshot_every",
            self.snapshot_every,
            ">= 1",
        )?;
        check(
            self.checkpoint_every >= 1,
            "checkpoint_every",
            self.checkpoint_every,
            ">= 1",
        )?;
        check(
            (0.0..=0.9).contains(&self.augmentation_fraction),
            "augmentation_fraction",
            self.augmentation_fraction,
            "0..=0.9",
        )?;
        check(
            (0.0..=10.0).contains(&self.predrape_secs),
            "predrape_secs",
            self.predrape_secs,
            "0..=10 s",
        )?;
        check(
            (0.0..=0.9).contains(&self.still_fraction)
                && self.still_fraction + self.augmentation_fraction <= 0.95,
            "still_fraction",
            self.still_fraction,
            "0..=0.9, with augmentation_fraction at most 0.95",
        )?;
        check(
            (1.0..=100.0).contains(&self.dead_limit_pct),
            "dead_limit_pct",
            self.dead_limit_pct,
            "1..=100 %",
        )?;
        check(
            (0.0..=1.0).contains(&self.lr_decay_fraction),
            "lr_decay_fraction",
            self.lr_decay_fraction,
            "0..=1",
        )?;
        check(
            self.lr_final_factor > 0.0 && self.lr_final_factor <= 1.0,
            "lr_final_factor",
            self.lr_final_factor,
            "(0, 1]",
        )?;
        check(
            (1..=16).contains(&self.loss_frames) && self.loss_frames + 2 <= self.window_frames(fps),
            "loss_frames",
            self.loss_frames,
            "1..=16 and at most the window's frames minus 2",
        )?;
        check(
            self.warmup_steps <= 100_000,
            "warmup_steps",
            self.warmup_steps,
            "0..=100000",
        )?;
        check(
            (0.0..=100.0).contains(&self.precondition_stiffness),
            "precondition_stiffness",
            self.precondition_stiffness,
            "0..=100",
        )?;
        if let Some(b) = self.precondition_final_stiffness {
            check(
                b > 0.0 && b <= 100.0,
                "precondition_final_stiffness",
                b,
                "(0, 100]",
            )?;
        }
        check(
            self.basis_row_norm == BasisRowNorm::Off
                || (self.fused_adam && self.backend == BackendKind::Cpu),
            "basis_row_norm",
            format!("{:?}", self.basis_row_norm),
            "false unless the fused Adam of the CPU backend trains",
        )?;
        check(
            (0.0..=0.9999).contains(&self.weight_average),
            "weight_average",
            self.weight_average,
            "[0, 0.9999]",
        )?;
        check(
            self.weight_average == 0.0 || (self.fused_adam && self.backend == BackendKind::Cpu),
            "weight_average",
            self.weight_average,
            "0 unless the fused Adam of the CPU backend trains",
        )?;
        check(
            (0.0..=100.0).contains(&self.history_propagation),
            "history_propagation",
            self.history_propagation,
            "[0, 100]",
        )?;
        check(
            self.history_propagation == 0.0 || self.precondition_stiffness > 0.0,
            "history_propagation",
            self.history_propagation,
            "0 unless the gradient filter is on (precondition_stiffness > 0)",
        )?;
        check(
            (0.0..=100.0).contains(&self.history_adjoint),
            "history_adjoint",
            self.history_adjoint,
            "[0, 100]",
        )?;
        check(
            self.history_adjoint == 0.0 || self.precondition_stiffness > 0.0,
            "history_adjoint",
            self.history_adjoint,
            "0 unless the gradient filter is on (precondition_stiffness > 0)",
        )?;
        check(
            (0.0..=100.0).contains(&self.fit_physics_weight),
            "fit_physics_weight",
            self.fit_physics_weight,
            "[0, 100]",
        )?;
        check(
            self.fit_physics_weight == 0.0 || self.fit_reference.is_some(),
            "fit_physics_weight",
            self.fit_physics_weight,
            "0 unless fitting to reference frames (fit_reference)",
        )?;
        check(
            (0.0..=1.0).contains(&self.momentum_boost),
            "momentum_boost",
            self.momentum_boost,
            "[0, 1]",
        )?;
        check(
            self.momentum_boost == 0.0 || (1..=1_000_000).contains(&self.momentum_boost_steps),
            "momentum_boost_steps",
            self.momentum_boost_steps,
            "1..=1000000 when the momentum boost is on",
        )?;
        check(
            self.warm_start_steps <= 1_000_000,
            "warm_start_steps",
            self.warm_start_steps,
            "0..=1000000",
        )?;
        check(
            (10..=1000).contains(&self.warm_start_iterations),
            "warm_start_iterations",
            self.warm_start_iterations,
            "10..=1000",
        )?;
        check(
            !self.warm_start_mirror_frames || (self.warm_start_steps > 0 && self.mirror_poses),
            "warm_start_mirror_frames",
            self.warm_start_mirror_frames,
            "false unless there is a warm start and mirrored copies (mirror_poses)",
        )?;
        check(
            self.mirror_from_step == 0 || self.mirror_poses,
            "mirror_from_step",
            self.mirror_from_step,
            "0 without mirrored copies (mirror_poses)",
        )?;
        check(
            (0.0..1.0).contains(&self.mirror_from_fraction),
            "mirror_from_fraction",
            self.mirror_from_fraction,
            "0..1",
        )?;
        check(
            self.warm_start_steps == 0 || self.fit_reference.is_none(),
            "warm_start_steps",
            self.warm_start_steps,
            "0 when fitting to reference frames (fit_reference)",
        )?;
        if self.fit_reference.is_some() {
            check(
                self.still_fraction == 0.0 && self.augmentation_fraction == 0.0,
                "still_fraction",
                self.still_fraction,
                "0 (and augmentation_fraction 0) when fitting to reference frames",
            )?;
            check(
                !self.mirror_poses,
                "mirror_poses",
                self.mirror_poses,
                "false when fitting to reference frames",
            )?;
        }
        if let Some(m) = self.max_minutes {
            check(m.is_finite() && m > 0.0, "max_minutes", m, "> 0")?;
        }
        Ok(())
    }
}

/// The learning-rate factor of the warm-up before step `step + 1` (0-based `step`):
/// `(step + 1) / warmup_steps` up to 1; always 1 without a warm-up.
pub fn warmup_factor(step: u64, warmup_steps: u64) -> f64 {
    if warmup_steps == 0 {
        1.0
    } else {
        ((step + 1) as f64 / warmup_steps as f64).min(1.0)
    }
}

/// How far a run is through its budget: the larger of `step` of `max_steps` and
/// `trained_secs` of `max_secs`, as a fraction (above 1 once a budget is overspent);
/// `None` for an open-ended run. What the learning-rate schedule and the mirrored copies'
/// start count, and what the app's progress bar shows.
pub fn run_progress(
    step: u64,
    max_steps: Option<u64>,
    trained_secs: f64,
    max_secs: Option<f64>,
) -> Option<f64> {
    let by_steps = max_steps.map(|m| step as f64 / m.max(1) as f64);
    let by_time = max_secs.map(|m| trained_secs / m.max(1e-9));
    match (by_steps, by_time) {
        (Some(a), Some(b)) => Some(a.max(b)),
        (a, b) => a.or(b),
    }
}

/// The learning-rate factor at `progress` (0..=1 of a bounded run): 1 until the last
/// `decay_fraction` of the run, then a half cosine down to `final_factor`.
pub fn lr_schedule_factor(progress: f64, decay_fraction: f64, final_factor: f64) -> f64 {
    if decay_fraction <= 0.0 || !progress.is_finite() {
        return 1.0;
    }
    let t = ((progress - (1.0 - decay_fraction)) / decay_fraction).clamp(0.0, 1.0);
    final_factor + (1.0 - final_factor) * 0.5 * (1.0 + (std::f64::consts::PI * t).cos())
}

#[cfg(test)]
#[path = "config_tests.rs"]
mod tests;
