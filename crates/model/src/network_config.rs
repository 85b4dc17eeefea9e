//! The architecture settings of [`super::network::ClothNet`] ([`ClothNetConfig`], with its
//! validation and the builder that initialises a network as the official code does).

use burn::module::{Module, ModuleMapper, Param};
use burn::nn::{GruConfig, Initializer, Linear};
use burn::tensor::{Device, Tensor};
use serde::{Deserialize, Serialize};

use super::ModelError;
use super::descriptors::{DYNAMIC_DIM, STATIC_DIM};
use super::network::{ClothNet, Decoder, Mlp, RecurrentEncoder};

/// How the body motion is encoded.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EncoderKind {
    /// Separate static and (bias-free, recurrent) dynamic encoders, `z = z_S + w z_D` (paper).
    #[default]
    Disentangled,
    /// One recurrent encoder with biases fed static and dynamic descriptors together
    /// (ablation, paper Table 2); `w` has no effect.
    Entangled,
    /// Static encoder only, no dynamic branch (PBNS-like; scenes without dynamics).
    StaticOnly,
}

/// Architecture of [`ClothNet`]; the input joint count and vertex count come from the scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ClothNetConfig {
    /// Encoder layout; default `disentangled`.
    pub encoder: EncoderKind,
    /// Hidden widths of the static encoder before its final `latent` layer; each 1..=8192,
    /// default `[512, 512, 512]` (the paper's `[64, 128, 256]` leaves the skirt's spin 50 mm
    /// further from the simulator: docs/TRAINING.md rounds 10 and 12; runs saved without the
    /// field keep the paper's, [`PAPER_STATIC_HIDDEN`]).
    pub static_hidden: Vec<usize>,
    /// Widths of the per-joint layers of the dynamic (or entangled) encoder; at least one,
    /// each 1..=8192, default `[32, 32]`.
    pub joint_hidden: Vec<usize>,
    /// Widths of the FC layers between the flattened joint features and the GRU; each
    /// 1..=8192, default `[512, 512]`.
    pub dynamic_hidden: Vec<usize>,
    /// Latent size (static encoder output, GRU state, decoder input); 1..=8192, default 512.
    pub latent: usize,
    /// Hidden widths of the decoder before the basis; each 1..=8192, default `[512, 512, 512]`.
    pub decoder_hidden: Vec<usize>,
    /// Standard deviation of the normal initialisation of FC weights; > 0, default 0.05
    /// (Keras `random_normal`, official code). Biases start at zero.
    pub init_std: f64,
    /// Gain of the glorot-normal basis initialisation (std = gain * sqrt(2 / (latent * (V + 3))),
    /// Keras fans of a `[latent, V, 3]` kernel); >= 0, default 1.
    pub basis_init_gain: f64,
    /// Learning-rate factor of the basis, in (0, 1]; default [`DEFAULT_BASIS_LR_SCALE`], 4/512
    /// since round 26 of docs/TRAINING.md (1/512 before; runs saved before the field existed
    /// read 1). The basis is stored as `B̂` with `B = s·B̂`, which under Adam moves
    /// `B` `s` times slower than the other weights while its effective initialisation stays
    /// the glorot one above. Without it one Adam step moves a vertex by up to
    /// `lr·Σ_k h_k` (hundreds of mm with 512 active units): the offsets overshoot, every
    /// basis row learns the same correction, and the next overshoot pushes all decoder units
    /// below zero at once (the dead skirt of issue 11). See docs/TRAINING.md.
    #[serde(default = "unit_scale")]
    pub basis_lr_scale: f64,
    /// Give the basis a learned per-vertex bias: the mean offset over all poses, which a
    /// warm start sets to a simulated drape (see `TrainConfig::predrape_secs`). It learns at
    /// the rate set by [`ClothNetConfig::basis_bias_lr_scale`] and, unlike the decoder units,
    /// cannot die. Default true (runs saved before it existed read false).
    #[serde(default)]
    pub basis_bias: bool,
    /// Learning-rate factor of the basis bias, in (0, 1]; default
    /// [`DEFAULT_BASIS_BIAS_LR_SCALE`] (runs saved before it existed read 1). Stored as `b̂`
    /// with `b = s_b·b̂`: at the plain rate Adam moves every vertex about 1 mm per step
    /// whatever its gradient, a noise that smears the warm-start folds.
    #[serde(default = "unit_scale")]
    pub basis_bias_lr_scale: f64,
    /// Divisors of the 12 dynamic descriptor channels (shared by all joints) applied before
    /// the dynamic encoder, or empty for none (the default). A new training run with
    /// [`ClothNetConfig::normalise_dynamic_input`] sets each to the channel's RMS over its
    /// training motions. Exported weights fold it into the first per-joint layer, so
    /// inference takes raw descriptors. Each finite and > 0. Measured harmful with the
    /// official initialisation (docs/TRAINING.md, round 3): inputs of order one make the
    /// initial dynamic code about twenty times smaller, and the skirt's dynamic branch then
    /// never wakes up (swing 0 against 52 mm unscaled).
    #[serde(default)]
    pub dynamic_input_scale: Vec<f32>,
    /// Set [`ClothNetConfig::dynamic_input_scale`] from the training motions when a run
    /// starts; default false (see there why).
    #[serde(default)]
    pub normalise_dynamic_input: bool,
    /// Give the dynamic code its own linear path to the offsets: `B h(z_S + w z_D) + w B_D
    /// z_D`, with `B_D` (`[latent, V * 3]`) starting at zero and learning at the rate set by
    /// [`ClothNetConfig::dynamic_basis_lr_scale`]. The shared decoder alone, fitted to the static
    /// drape first, leaves the dynamic code almost without effect (docs/TRAINING.md, round 3:
    /// w = 1 and w = 0 differ by 0.3 mm where the simulator swings 24 mm); the direct path
    /// gives every dynamic code a gradient to the offsets from the first step. Exported
    /// weights append `B_D` to the basis rows (basis input `[h, w z_D]`). Disentangled
    /// encoder only; default true (runs saved before it existed read false).
    #[serde(default)]
    pub dynamic_basis: bool,
    /// Learning-rate factor of the dynamic basis, in (0, 1] (stored as `B̂_D` with `B_D =
    /// s_D·B̂_D`, as the basis); default [`DEFAULT_DYNAMIC_BASIS_LR_SCALE`] (runs saved
    /// without the field read [`LEGACY_BASIS_LR_SCALE`], the rate they trained at).
    #[serde(default = "legacy_basis_lr_scale")]
    pub dynamic_basis_lr_scale: f64,
}

fn legacy_basis_lr_scale() -> f64 {
    LEGACY_BASIS_LR_SCALE
}

fn unit_scale() -> f64 {
    1.0
}

/// The paper's static encoder widths, the default before docs/TRAINING.md round 12 (what a
/// run folder that does not name its widths was trained with).
pub const PAPER_STATIC_HIDDEN: [usize; 3] = [64, 128, 256];

/// Default [`ClothNetConfig::basis_lr_scale`]: four over the default decoder width. At
/// [`LEGACY_BASIS_LR_SCALE`] the basis was the slowest part of the t-shirt's learning: at
/// four times that rate the default t-shirt after 1100 steps is closer to the simulator on
/// every motion checked (seed 43: held-out spin 24.5 against 31.6 mm, its mirror image 18.1
/// against 29.6, run 11.9 against 14.6, idle 2.5 against 2.8; docs/TRAINING.md, round 26).
pub const DEFAULT_BASIS_LR_SCALE: f64 = 4.0 / 512.0;

/// The basis learning-rate factor before round 26 (one over the default decoder width), what
/// runs saved without [`ClothNetConfig::dynamic_basis_lr_scale`] trained their dynamic basis at.
pub const LEGACY_BASIS_LR_SCALE: f64 = 1.0 / 512.0;

/// Default learning-rate factor of the dynamic basis: twice [`DEFAULT_BASIS_LR_SCALE`], eight
/// over the default decoder width (2/512 before round 27). With the basis at 4/512 it brought
/// the default t-shirt after 1100 steps closer to the simulator on every motion of all three
/// seeds checked (seed 53: held-out spin 21.2 against 24.4 mm, run 9.5 against 12.1, idle
/// 2.1 against 2.6) and the skirt after 1702 steps from 98.0 to 63.1 mm on the spin (seed
/// 101) with its hem within 7 % of the simulator's when still (docs/TRAINING.md, rounds 26
/// and 27).
pub const DEFAULT_DYNAMIC_BASIS_LR_SCALE: f64 = 8.0 / 512.0;

/// Default [`ClothNetConfig::basis_bias_lr_scale`].
pub const DEFAULT_BASIS_BIAS_LR_SCALE: f64 = 1.0 / 16.0;

impl Default for ClothNetConfig {
    fn default() -> Self {
        Self {
            encoder: EncoderKind::Disentangled,
            static_hidden: vec![512, 512, 512],
            joint_hidden: vec![32, 32],
            dynamic_hidden: vec![512, 512],
            latent: 512,
            decoder_hidden: vec![512, 512, 512],
            init_std: 0.05,
            basis_init_gain: 1.0,
            basis_lr_scale: DEFAULT_BASIS_LR_SCALE,
            basis_bias: true,
            basis_bias_lr_scale: DEFAULT_BASIS_BIAS_LR_SCALE,
            dynamic_input_scale: Vec::new(),
            normalise_dynamic_input: false,
            dynamic_basis: true,
            dynamic_basis_lr_scale: DEFAULT_DYNAMIC_BASIS_LR_SCALE,
        }
    }
}

/// Largest layer width accepted by [`ClothNetConfig::validate`].
pub const MAX_WIDTH: usize = 8192;

impl ClothNetConfig {
    /// Checks widths and initialisation scales.
    pub fn validate(&self) -> Result<(), ModelError> {
        let widths = self
            .static_hidden
            .iter()
            .chain(&self.joint_hidden)
            .chain(&self.dynamic_hidden)
            .chain(&self.decoder_hidden)
            .chain(std::iter::once(&self.latent));
        if let Some(w) = widths.into_iter().find(|w| !(1..=MAX_WIDTH).contains(*w)) {
            return Err(ModelError::InvalidConfig(format!(
                "layer width {w} outside 1..={MAX_WIDTH}"
            )));
        }
        if self.encoder != EncoderKind::StaticOnly && self.joint_hidden.is_empty() {
            return Err(ModelError::InvalidConfig(
                "joint_hidden needs at least one layer".into(),
            ));
        }
        if !(self.init_std.is_finite() && self.init_std > 0.0) {
            return Err(ModelError::InvalidConfig(format!(
                "init_std {} is not positive",
                self.init_std
            )));
        }
        for (name, value) in [
            ("basis_lr_scale", self.basis_lr_scale),
            ("dynamic_basis_lr_scale", self.dynamic_basis_lr_scale),
            ("basis_bias_lr_scale", self.basis_bias_lr_scale),
        ] {
            if !(value.is_finite() && value > 0.0 && value <= 1.0) {
                return Err(ModelError::InvalidConfig(format!(
                    "{name} {value} is outside (0, 1]"
                )));
            }
        }
        let scale = &self.dynamic_input_scale;
        if !scale.is_empty()
            && (scale.len() != DYNAMIC_DIM || scale.iter().any(|s| !(s.is_finite() && *s > 0.0)))
        {
            return Err(ModelError::InvalidConfig(format!(
                "dynamic_input_scale {scale:?} is not {DYNAMIC_DIM} positive values"
            )));
        }
        if !(self.basis_init_gain.is_finite() && self.basis_init_gain >= 0.0) {
            return Err(ModelError::InvalidConfig(format!(
                "basis_init_gain {} is negative",
                self.basis_init_gain
            )));
        }
        Ok(())
    }

    /// Builds the network for `input_joints` joints and a garment of `vertices` vertices.
    pub fn init(
        &self,
        input_joints: usize,
        vertices: usize,
        device: &Device,
    ) -> Result<ClothNet, ModelError> {
        self.validate()?;
        if input_joints == 0 || vertices == 0 {
            return Err(ModelError::InvalidConfig(format!(
                "network needs at least one input joint and one vertex (got {input_joints} joints, {vertices} vertices)"
            )));
        }
        let fc = Initializer::Normal {
            mean: 0.0,
            std: self.init_std,
        };
        let mlp = |d_in: usize, widths: &[usize], bias: bool| -> Mlp {
            let mut layers = Vec::with_capacity(widths.len());
            let mut d = d_in;
            for &w in widths {
                layers.push(linear(d, w, bias, &fc, device));
                d = w;
            }
            Mlp { layers }
        };
        let recurrent = |joint_in: usize, bias: bool, scale: &[f32]| -> RecurrentEncoder {
            let joint_mlp = mlp(joint_in, &self.joint_hidden, bias);
            let joint_out = self.joint_hidden.last().copied().unwrap_or(joint_in);
            let mlp = mlp(input_joints * joint_out, &self.dynamic_hidden, bias);
            let gru_in = self
                .dynamic_hidden
                .last()
                .copied()
                .unwrap_or(input_joints * joint_out);
            RecurrentEncoder {
                joint_mlp,
                mlp,
                gru: GruConfig::new(gru_in, self.latent, bias).init(device),
                input_inv_scale: scale.iter().map(|s| 1.0 / s).collect(),
            }
        };
        let mut static_widths = self.static_hidden.clone();
        static_widths.push(self.latent);
        let (static_encoder, dynamic_encoder, entangled_encoder) = match self.encoder {
            EncoderKind::Disentangled => (
                Some(mlp(input_joints * STATIC_DIM, &static_widths, true)),
                Some(recurrent(DYNAMIC_DIM, false, &self.dynamic_input_scale)),
                None,
            ),
            EncoderKind::StaticOnly => (
                Some(mlp(input_joints * STATIC_DIM, &static_widths, true)),
                None,
                None,
            ),
            EncoderKind::Entangled => (
                None,
                None,
                Some(recurrent(STATIC_DIM + DYNAMIC_DIM, true, &[])),
            ),
        };
        let decoder_mlp = mlp(self.latent, &self.decoder_hidden, true);
        let basis_in = self.decoder_hidden.last().copied().unwrap_or(self.latent);
        // Keras glorot_normal on a [basis_in, V, 3] kernel: fan_in = basis_in * V, fan_out = basis_in * 3.
        // Stored as B̂ = B / s: the effective basis B starts glorot-normal whatever s is.
        let basis_std = self.basis_init_gain
            * (2.0 / (basis_in as f64 * (vertices as f64 + 3.0))).sqrt()
            / self.basis_lr_scale;
        let basis = Linear {
            weight: Initializer::Normal {
                mean: 0.0,
                std: basis_std.max(f64::MIN_POSITIVE),
            }
            .init_with(
                [basis_in, vertices * 3],
                Some(basis_in),
                Some(vertices * 3),
                device,
            ),
            bias: self.basis_bias.then(|| {
                Initializer::Zeros.init_with(
                    [vertices * 3],
                    Some(basis_in),
                    Some(vertices * 3),
                    device,
                )
            }),
        };
        // The dynamic basis starts at zero: the network's first output is unchanged.
        let dynamic_basis =
            (self.dynamic_basis && self.encoder == EncoderKind::Disentangled).then(|| Linear {
                weight: Initializer::Zeros.init_with(
                    [self.latent, vertices * 3],
                    Some(self.latent),
                    Some(vertices * 3),
                    device,
                ),
                bias: None,
            });
        let net = ClothNet {
            static_encoder,
            dynamic_encoder,
            entangled_encoder,
            decoder: Decoder {
                mlp: decoder_mlp,
                basis,
                dynamic_basis,
                dynamic_scale: self.dynamic_basis_lr_scale,
                basis_scale: self.basis_lr_scale,
                bias_scale: self.basis_bias_lr_scale,
            },
            input_joints,
            vertices,
            latent: self.latent,
        };
        // burn draws a parameter's initial values at its first use: draw them all now, in
        // module order, so that the weights depend on the device's seed alone and not on what
        // else drew from it before the first forward pass (two runs prepared with one seed in
        // one process started from different weights).
        Ok(net.map(&mut Materialise))
    }
}

/// Takes each float parameter's value (which draws a lazily initialised one) and puts it back
/// unchanged.
struct Materialise;

impl ModuleMapper for Materialise {
    fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
        let (id, tensor, mapper) = param.consume();
        Param::from_mapped_value(id, tensor, mapper)
    }
}

fn linear(d_in: usize, d_out: usize, bias: bool, init: &Initializer, device: &Device) -> Linear {
    Linear {
        weight: init.init_with([d_in, d_out], Some(d_in), Some(d_out), device),
        bias: bias.then(|| Initializer::Zeros.init_with([d_out], Some(d_in), Some(d_out), device)),
    }
}
