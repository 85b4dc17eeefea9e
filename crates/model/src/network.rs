//! The recurrent encoder-decoder of paper §3.3 as a burn module.
//!
//! * Static encoder: flatten `[J, 9]` -> FC 512, 512, 512 by default (the paper: 64, 128,
//!   256), latent (ReLU, bias).
//! * Dynamic encoder, no bias anywhere: per-joint FC 12 -> 32 -> 32 (weights shared by all
//!   joints: a `Linear` on `[B, T, J, 12]` acts per joint), flatten `[J, 32]` -> FC 512 ->
//!   FC 512 -> GRU(latent). ReLU follows every FC layer, as in the authors' official code
//!   (`ncs/model/ncs.py`); with no bias, zero descriptors and a zero state give `z_D = 0`
//!   exactly.
//! * `z = z_S + w z_D`, `w` in `[0, 2]` (1 = trained behaviour, paper §4.6).
//! * Decoder: three FC 512 (ReLU, bias) then a bias-free linear basis `latent -> V * 3`
//!   giving rest-space offsets `[B, T, V, 3]`; with a dynamic basis (default) a second,
//!   zero-initialised linear map adds `w B_D z_D` to them (not in the paper; see
//!   [`ClothNetConfig::dynamic_basis`]).
//!
//! Variants (ablation and scene effects): [`EncoderKind::Entangled`] feeds one recurrent
//! encoder (with biases) the concatenated 21-d descriptors; [`EncoderKind::StaticOnly`] has
//! no dynamic branch at all (the static, PBNS-like formulation).
//!
//! Initialisation follows the official code: FC weights `N(0, 0.05²)`, FC biases zero, the
//! basis glorot-normal with Keras' fan convention for a `[latent, V, 3]` kernel, the GRU
//! burn's default (Xavier normal).

use burn::module::Module;
use burn::nn::{Gru, Linear};
use burn::tensor::Tensor;
use burn::tensor::activation::relu;
use burn::tensor::module::linear as dense;

use super::descriptors::DYNAMIC_DIM;

pub use super::network_config::{
    ClothNetConfig, DEFAULT_BASIS_BIAS_LR_SCALE, DEFAULT_BASIS_LR_SCALE,
    DEFAULT_DYNAMIC_BASIS_LR_SCALE, EncoderKind, LEGACY_BASIS_LR_SCALE, MAX_WIDTH,
};

/// A stack of linear layers, each followed by ReLU.
#[derive(Module, Debug)]
pub struct Mlp {
    /// The layers, input first.
    pub layers: Vec<Linear>,
}

impl Mlp {
    /// Applies every layer and ReLU to the last axis of `x`.
    pub fn forward<const D: usize>(&self, x: Tensor<D>) -> Tensor<D> {
        self.layers.iter().fold(x, |x, l| relu(l.forward(x)))
    }
}

/// Per-joint layers, flatten, FC layers and a GRU (the dynamic or the entangled encoder).
#[derive(Module, Debug)]
pub struct RecurrentEncoder {
    /// Layers applied to each joint's descriptor with shared weights.
    pub joint_mlp: Mlp,
    /// Layers applied to the flattened joint features.
    pub mlp: Mlp,
    /// The recurrent unit (burn's GRU, `reset_after = true`).
    pub gru: Gru,
    /// Factors applied to each descriptor channel before the per-joint layers
    /// (`1 / ClothNetConfig::dynamic_input_scale`); empty for none. Not a parameter: it
    /// comes from the config the network is built from.
    #[module(skip)]
    pub input_inv_scale: Vec<f32>,
}

impl RecurrentEncoder {
    /// `[B, T, J, C]` descriptors -> `[B, T, latent]` codes, from `state` (`[B, latent]`) or zero.
    pub fn forward(&self, desc: Tensor<4>, state: Option<Tensor<2>>) -> Tensor<3> {
        let [b, t, _, c] = desc.dims();
        let desc = if self.input_inv_scale.len() == c {
            let factors = Tensor::<1>::from_floats(self.input_inv_scale.as_slice(), &desc.device());
            desc * factors.reshape([1, 1, 1, c])
        } else {
            desc
        };
        let x = self.joint_mlp.forward(desc);
        let [_, _, j, c] = x.dims();
        let x = self.mlp.forward(x.reshape([b, t, j * c]));
        super::gru_unroll::unroll(&self.gru, x, state)
    }

    /// True when no layer of the encoder (per-joint, FC, GRU) has a bias: then all-zero
    /// descriptors from a zero state give exactly zero codes.
    pub fn bias_free(&self) -> bool {
        let gru = &self.gru;
        let gates = [&gru.update_gate, &gru.reset_gate, &gru.new_gate];
        self.joint_mlp
            .layers
            .iter()
            .chain(&self.mlp.layers)
            .all(|l| l.bias.is_none())
            && gates
                .iter()
                .all(|g| g.input_transform.bias.is_none() && g.hidden_transform.bias.is_none())
    }

    /// [`Self::forward`] when the first `quiet` rows of `desc` are all zero and start from a
    /// zero state (still training windows): for a [`Self::bias_free`] encoder their codes are
    /// exactly zero, so only the other rows are computed (their gradient is unchanged: a zero
    /// input row adds nothing to any weight's gradient). Rows of `state`, when given, must be
    /// zero for the quiet rows too. Other encoders compute every row.
    pub fn forward_after_quiet(
        &self,
        desc: Tensor<4>,
        state: Option<Tensor<2>>,
        quiet: usize,
    ) -> Tensor<3> {
        let [b, t, _, _] = desc.dims();
        let quiet = quiet.min(b);
        if quiet == 0 || !self.bias_free() {
            return self.forward(desc, state);
        }
        let device = desc.device();
        let zeros = Tensor::zeros([quiet, t, self.gru.d_hidden], &device);
        if quiet == b {
            return zeros;
        }
        let moving = self.forward(
            desc.narrow(0, quiet, b - quiet),
            state.map(|s| s.narrow(0, quiet, b - quiet)),
        );
        Tensor::cat(vec![zeros, moving], 0)
    }
}

/// Decoder MLP and the linear basis of rest-space offsets.
#[derive(Module, Debug)]
pub struct Decoder {
    /// FC layers with bias and ReLU.
    pub mlp: Mlp,
    /// Bias-free basis `[latent, V * 3]`, stored divided by `basis_scale`.
    pub basis: Linear,
    /// Bias-free dynamic basis `[latent, V * 3]` applied to `w z_D`, stored divided by
    /// `dynamic_scale` ([`ClothNetConfig::dynamic_basis`]).
    pub dynamic_basis: Option<Linear>,
    /// The effective dynamic basis is `dynamic_scale · dynamic_basis`
    /// ([`ClothNetConfig::dynamic_basis_lr_scale`]).
    pub dynamic_scale: f64,
    /// The effective basis is `basis_scale · basis` ([`ClothNetConfig::basis_lr_scale`]).
    pub basis_scale: f64,
    /// The effective bias is `bias_scale · basis.bias` ([`ClothNetConfig::basis_bias_lr_scale`]).
    pub bias_scale: f64,
}

impl Decoder {
    /// The effective basis weight `[latent, V * 3]` (`basis_scale · B̂`).
    pub fn basis_weight(&self) -> Tensor<2> {
        self.basis.weight.val().mul_scalar(self.basis_scale)
    }

    /// The effective dynamic basis `[latent, V * 3]`, when the network has one.
    pub fn dynamic_basis_weight(&self) -> Option<Tensor<2>> {
        let b = self.dynamic_basis.as_ref()?;
        Some(b.weight.val().mul_scalar(self.dynamic_scale))
    }
}

/// The cloth network: descriptors -> latent code -> rest-space garment offsets.
#[derive(Module, Debug)]
pub struct ClothNet {
    /// Static encoder (absent in the entangled variant).
    pub static_encoder: Option<Mlp>,
    /// Bias-free dynamic encoder (disentangled variant only).
    pub dynamic_encoder: Option<RecurrentEncoder>,
    /// Single encoder of the entangled variant.
    pub entangled_encoder: Option<RecurrentEncoder>,
    /// Decoder and basis.
    pub decoder: Decoder,
    /// Number of input joints `J`.
    pub input_joints: usize,
    /// Number of garment vertices `V`.
    pub vertices: usize,
    /// Latent size.
    pub latent: usize,
}

impl ClothNet {
    /// Which variant this network is.
    pub fn kind(&self) -> EncoderKind {
        match (&self.entangled_encoder, &self.dynamic_encoder) {
            (Some(_), _) => EncoderKind::Entangled,
            (None, Some(_)) => EncoderKind::Disentangled,
            (None, None) => EncoderKind::StaticOnly,
        }
    }

    /// True when the network has a (separate, bias-free) dynamic branch.
    pub fn has_dynamic_branch(&self) -> bool {
        self.dynamic_encoder.is_some()
    }

    /// Static code `z_S` `[B, T, latent]` of static descriptors `[B, T, J, 9]`; `None` for the
    /// entangled variant.
    pub fn encode_static(&self, static_desc: Tensor<4>) -> Option<Tensor<3>> {
        let enc = self.static_encoder.as_ref()?;
        let [b, t, j, c] = static_desc.dims();
        Some(enc.forward(static_desc.reshape([b, t, j * c])))
    }

    /// Dynamic code `z_D` `[B, T, latent]` of dynamic descriptors `[B, T, J, 12]` with the GRU
    /// started from `state` (`[B, latent]`, zero when `None`); `None` without a dynamic branch.
    pub fn encode_dynamic(
        &self,
        dynamic_desc: Tensor<4>,
        state: Option<Tensor<2>>,
    ) -> Option<Tensor<3>> {
        Some(self.dynamic_encoder.as_ref()?.forward(dynamic_desc, state))
    }

    /// Latent code `z` `[B, T, latent]` of all `T` frames.
    ///
    /// Disentangled: `z_S + w z_D` (`z_D` skipped when `dynamic_desc` is `None` or `w == 0`);
    /// static-only: `z_S`; entangled: the single encoder's code (zero dynamics when `None`).
    pub fn latent_code(
        &self,
        static_desc: Tensor<4>,
        dynamic_desc: Option<Tensor<4>>,
        w: f32,
    ) -> Tensor<3> {
        self.codes(static_desc, dynamic_desc, w).0
    }

    /// `(z, w z_D)`: the latent code of [`ClothNet::latent_code`] and the weighted dynamic
    /// code (`None` when it is skipped or the variant has none), each `[B, T, latent]`.
    pub fn codes(
        &self,
        static_desc: Tensor<4>,
        dynamic_desc: Option<Tensor<4>>,
        w: f32,
    ) -> (Tensor<3>, Option<Tensor<3>>) {
        if let Some(enc) = &self.entangled_encoder {
            let dynamic = dynamic_desc.unwrap_or_else(|| zeros_like_dynamic(&static_desc));
            return (
                enc.forward(Tensor::cat(vec![static_desc, dynamic], 3), None),
                None,
            );
        }
        let [b, t, _, _] = static_desc.dims();
        let device = static_desc.device();
        let z_s = self
            .encode_static(static_desc)
            .unwrap_or_else(|| Tensor::zeros([b, t, self.latent], &device));
        match (dynamic_desc, &self.dynamic_encoder) {
            (Some(d), Some(enc)) if w != 0.0 => {
                let z_d = enc.forward(d, None).mul_scalar(w);
                (z_s + z_d.clone(), Some(z_d))
            }
            _ => (z_s, None),
        }
    }

    /// Rest-space offsets `[B, T, V, 3]` of latent codes `[B, T, latent]` (no dynamic basis
    /// term: see [`ClothNet::decode_with`]).
    pub fn decode(&self, z: Tensor<3>) -> Tensor<4> {
        self.decode_with(z, None)
    }

    /// Rest-space offsets `[B, T, V, 3]` of latent codes `z` plus, when the network has a
    /// dynamic basis, its product with the weighted dynamic codes `w z_D` (each `[B, T, latent]`).
    pub fn decode_with(&self, z: Tensor<3>, weighted_dynamic: Option<Tensor<3>>) -> Tensor<4> {
        let [b, t, _] = z.dims();
        let h = self
            .decoder
            .mlp
            .forward(z)
            .mul_scalar(self.decoder.basis_scale);
        let bias = self
            .decoder
            .basis
            .bias
            .as_ref()
            .map(|b| b.val().mul_scalar(self.decoder.bias_scale));
        let offsets = dense(h, self.decoder.basis.weight.val(), bias);
        let offsets = match (weighted_dynamic, &self.decoder.dynamic_basis) {
            (Some(z_d), Some(basis)) => {
                offsets
                    + dense(
                        z_d.mul_scalar(self.decoder.dynamic_scale),
                        basis.weight.val(),
                        None,
                    )
            }
            _ => offsets,
        };
        offsets.reshape([b, t, self.vertices, 3])
    }

    /// Offsets `[B, T, V, 3]` for every frame of the window: static descriptors `[B, T, J, 9]`,
    /// optional dynamic descriptors `[B, T, J, 12]`, dynamic weight `w` (1 = trained).
    pub fn forward(
        &self,
        static_desc: Tensor<4>,
        dynamic_desc: Option<Tensor<4>>,
        w: f32,
    ) -> Tensor<4> {
        let (z, z_d) = self.codes(static_desc, dynamic_desc, w);
        self.decode_with(z, z_d)
    }

    /// The dynamic encoder's GRU state `[B, latent]` after the frames of `dynamic_desc`
    /// (`[B, H, J, 12]`) from a zero state, detached: the state a training window starts from
    /// when the `H` frames before it are played first, as inference carries the state over a
    /// whole motion. `None` without a dynamic branch or when `H = 0`.
    pub fn burn_in_state(&self, dynamic_desc: Tensor<4>) -> Option<Tensor<2>> {
        let enc = self.dynamic_encoder.as_ref()?;
        let [b, h, _, _] = dynamic_desc.dims();
        if h == 0 {
            return None;
        }
        let states = enc.forward(dynamic_desc, None);
        Some(
            states
                .narrow(1, h - 1, 1)
                .reshape([b, self.latent])
                .detach(),
        )
    }

    /// Codes of the last `last` frames (1..=T) for motion augmentation: `(z_S, Some(z_D))` for
    /// the disentangled variant (shuffle / detach `z_D`, then [`ClothNet::decode`]
    /// `z_S + w z_D`), `(z_S, None)` when static-only, `(z, None)` when entangled. Each
    /// `[B, last, latent]`. The dynamic encoder's GRU starts from `state` (zero when `None`);
    /// the first `quiet` rows are still windows ([`RecurrentEncoder::forward_after_quiet`]).
    pub fn encode_last(
        &self,
        static_desc: Tensor<4>,
        dynamic_desc: Option<Tensor<4>>,
        last: usize,
        state: Option<Tensor<2>>,
        quiet: usize,
    ) -> (Tensor<3>, Option<Tensor<3>>) {
        let t = static_desc.dims()[1];
        let last = last.clamp(1, t.max(1));
        let start = t - last;
        if self.entangled_encoder.is_some() {
            return (
                self.latent_code(static_desc, dynamic_desc, 1.0)
                    .narrow(1, start, last),
                None,
            );
        }
        let z_s = self.latent_code(static_desc.narrow(1, start, last), None, 0.0);
        let z_d = match (dynamic_desc, &self.dynamic_encoder) {
            (Some(d), Some(enc)) => Some(
                enc.forward_after_quiet(d, state, quiet)
                    .narrow(1, start, last),
            ),
            _ => None,
        };
        (z_s, z_d)
    }

    /// Offsets `[B, last, V, 3]` of the last `last` frames only (1..=T): the GRU runs over the
    /// whole window from `state` (zero when `None`), the static encoder and the decoder over
    /// the last frames (training takes 3). The first `quiet` rows are still windows (all-zero
    /// dynamic descriptors, zero state: [`RecurrentEncoder::forward_after_quiet`]).
    pub fn forward_last(
        &self,
        static_desc: Tensor<4>,
        dynamic_desc: Option<Tensor<4>>,
        w: f32,
        last: usize,
        state: Option<Tensor<2>>,
        quiet: usize,
    ) -> Tensor<4> {
        let t = static_desc.dims()[1];
        let last = last.clamp(1, t.max(1));
        let start = t - last;
        if self.entangled_encoder.is_some() {
            let z = self.latent_code(static_desc, dynamic_desc, w);
            return self.decode(z.narrow(1, start, last));
        }
        let s_last = static_desc.narrow(1, start, last);
        let z_s = self.latent_code(s_last, None, 0.0);
        match (dynamic_desc, &self.dynamic_encoder) {
            (Some(d), Some(enc)) if w != 0.0 => {
                let z_d = enc
                    .forward_after_quiet(d, state, quiet)
                    .narrow(1, start, last)
                    .mul_scalar(w);
                self.decode_with(z_s + z_d.clone(), Some(z_d))
            }
            _ => self.decode(z_s),
        }
    }
}

fn zeros_like_dynamic(static_desc: &Tensor<4>) -> Tensor<4> {
    let [b, t, j, _] = static_desc.dims();
    Tensor::zeros([b, t, j, DYNAMIC_DIM], &static_desc.device())
}

#[cfg(test)]
#[path = "network_tests.rs"]
mod tests;
