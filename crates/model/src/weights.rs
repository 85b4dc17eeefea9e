//! Plain `Vec<f32>` copies of a trained [`ClothNet`]'s weights, for the inference engine and
//! for weight snapshots sent from the trainer thread to the UI thread (no burn types inside,
//! so they are `Send`, cheap to clone and independent of the training device).

use burn::nn::{Gru, Linear};
use burn::tensor::Tensor;

use super::ModelError;
use super::descriptors::{DYNAMIC_DIM, STATIC_DIM};
use super::network::{ClothNet, EncoderKind, Mlp, RecurrentEncoder};

/// Rows of the input matrix processed per block in [`DenseWeights::forward_columns`].
const ROW_BLOCK: usize = 64;

/// One fully connected layer `y = x W + b`, `W` stored `[d_in, d_out]` row-major (burn's
/// `Linear` layout), evaluated as a sum of scaled rows so zero inputs (after ReLU) are skipped.
#[derive(Clone, Debug, PartialEq)]
pub struct DenseWeights {
    /// Input width.
    pub d_in: usize,
    /// Output width.
    pub d_out: usize,
    /// Weights `[d_in, d_out]`, row-major.
    pub weight: Vec<f32>,
    /// Bias `[d_out]`, if the layer has one.
    pub bias: Option<Vec<f32>>,
}

fn read<const D: usize>(t: &Tensor<D>, what: &str) -> Result<Vec<f32>, ModelError> {
    t.try_to_vec_as::<f32>()
        .map_err(|e| ModelError::TensorRead {
            what: what.into(),
            reason: e.to_string(),
        })
}

impl DenseWeights {
    /// Copies a burn `Linear` layer.
    pub fn from_linear(layer: &Linear, what: &str) -> Result<Self, ModelError> {
        let w = layer.weight.val();
        let [d_in, d_out] = w.dims();
        let weight = read(&w, what)?;
        let bias = match &layer.bias {
            Some(b) => Some(read(&b.val(), what)?),
            None => None,
        };
        let out = Self {
            d_in,
            d_out,
            weight,
            bias,
        };
        out.validate(what)?;
        Ok(out)
    }

    /// Checks sizes and finiteness.
    pub fn validate(&self, what: &str) -> Result<(), ModelError> {
        if self.weight.len() != self.d_in * self.d_out {
            return Err(ModelError::ShapeMismatch {
                what: format!("{what} weights"),
                expected: self.d_in * self.d_out,
                found: self.weight.len(),
            });
        }
        if let Some(b) = &self.bias
            && b.len() != self.d_out
        {
            return Err(ModelError::ShapeMismatch {
                what: format!("{what} bias"),
                expected: self.d_out,
                found: b.len(),
            });
        }
        if !self
            .weight
            .iter()
            .chain(self.bias.iter().flatten())
            .all(|v| v.is_finite())
        {
            return Err(ModelError::InvalidInput(format!(
                "{what} has non-finite weights"
            )));
        }
        Ok(())
    }

    /// `y = x W + b` (`x` has `d_in` values, `y` has `d_out`).
    pub fn forward(&self, x: &[f32], y: &mut [f32]) {
        match &self.bias {
            Some(b) => y.copy_from_slice(b),
            None => y.fill(0.0),
        }
        for (&xi, row) in x.iter().zip(self.weight.chunks_exact(self.d_out)) {
            if xi != 0.0 {
                for (yo, &wo) in y.iter_mut().zip(row) {
                    *yo += xi * wo;
                }
            }
        }
    }

    /// `relu(x W + b)`.
    pub fn forward_relu(&self, x: &[f32], y: &mut [f32]) {
        self.forward(x, y);
        for v in y.iter_mut() {
            *v = v.max(0.0);
        }
    }

    /// Columns `[col0, col0 + y.len())` of `x W + b`, blocked by rows (the plain reference
    /// form; the inference engine runs [`super::kernels::Matrix::accumulate`]).
    pub fn forward_columns(&self, x: &[f32], col0: usize, y: &mut [f32]) {
        let n = y.len();
        match &self.bias {
            Some(b) => y.copy_from_slice(&b[col0..col0 + n]),
            None => y.fill(0.0),
        }
        for (block, x_block) in x.chunks(ROW_BLOCK).enumerate() {
            for (r, &xi) in x_block.iter().enumerate() {
                if xi != 0.0 {
                    let start = (block * ROW_BLOCK + r) * self.d_out + col0;
                    for (yo, &wo) in y.iter_mut().zip(&self.weight[start..start + n]) {
                        *yo += xi * wo;
                    }
                }
            }
        }
    }
}

/// A fully connected layer `y = x W + b` as [`super::gru::gru_step`] evaluates it: the plain
/// f32 [`DenseWeights`] here, or the inference engine's [`super::compiled::Dense`] (f32 or f16
/// storage, SIMD kernels).
pub trait LinearLayer {
    /// Columns `[col0, col0 + y.len())` of `x W + b` into `y`.
    fn forward_columns(&self, x: &[f32], col0: usize, y: &mut [f32]);

    /// `y = x W + b` over all columns.
    fn forward(&self, x: &[f32], y: &mut [f32]) {
        self.forward_columns(x, 0, y);
    }
}

impl LinearLayer for DenseWeights {
    fn forward_columns(&self, x: &[f32], col0: usize, y: &mut [f32]) {
        DenseWeights::forward_columns(self, x, col0, y);
    }

    fn forward(&self, x: &[f32], y: &mut [f32]) {
        DenseWeights::forward(self, x, y);
    }
}

/// GRU weights with the three gates side by side: columns `[update | reset | new]`. The layer
/// type `L` is [`DenseWeights`] except inside the inference engine.
#[derive(Clone, Debug, PartialEq)]
pub struct GruWeights<L = DenseWeights> {
    /// Input width.
    pub d_in: usize,
    /// Hidden width `H`.
    pub d_hidden: usize,
    /// Input transform `[d_in, 3H]` with optional bias `[3H]`.
    pub input: L,
    /// Hidden transform `[H, 3H]` with optional bias `[3H]`.
    pub hidden: L,
    /// Reset gate applied after the hidden product (burn's default, PyTorch and Keras v2 style).
    pub reset_after: bool,
    /// Optional clipping of the state to `[-clip, clip]`.
    pub clip: Option<f32>,
}

fn concat_gates(gates: [DenseWeights; 3]) -> DenseWeights {
    let (d_in, h) = (gates[0].d_in, gates[0].d_out);
    let mut weight = Vec::with_capacity(d_in * 3 * h);
    for r in 0..d_in {
        for g in &gates {
            weight.extend_from_slice(&g.weight[r * h..(r + 1) * h]);
        }
    }
    let bias = if gates.iter().all(|g| g.bias.is_some()) {
        Some(
            gates
                .iter()
                .flat_map(|g| g.bias.iter().flatten().copied())
                .collect(),
        )
    } else {
        None
    };
    DenseWeights {
        d_in,
        d_out: 3 * h,
        weight,
        bias,
    }
}

impl<L> GruWeights<L> {
    /// The same GRU with its two transforms converted by `f` (input first).
    pub fn map_layers<M>(self, mut f: impl FnMut(L) -> M) -> GruWeights<M> {
        GruWeights {
            d_in: self.d_in,
            d_hidden: self.d_hidden,
            input: f(self.input),
            hidden: f(self.hidden),
            reset_after: self.reset_after,
            clip: self.clip,
        }
    }
}

impl GruWeights {
    /// Copies burn's `Gru`; only the standard activations (sigmoid gates, tanh candidate) are
    /// supported, which is what [`burn::nn::GruConfig`] builds by default.
    pub fn from_gru(gru: &Gru, what: &str) -> Result<Self, ModelError> {
        let gates = [&gru.update_gate, &gru.reset_gate, &gru.new_gate];
        let names = ["update", "reset", "new"];
        let mut input = Vec::with_capacity(3);
        let mut hidden = Vec::with_capacity(3);
        for (g, n) in gates.iter().zip(names) {
            input.push(DenseWeights::from_linear(
                &g.input_transform,
                &format!("{what} {n} gate input"),
            )?);
            hidden.push(DenseWeights::from_linear(
                &g.hidden_transform,
                &format!("{what} {n} gate hidden"),
            )?);
        }
        let to_array = |v: Vec<DenseWeights>| -> Result<[DenseWeights; 3], ModelError> {
            v.try_into()
                .map_err(|_| ModelError::InvalidConfig(format!("{what}: GRU needs three gates")))
        };
        let (input, hidden) = (to_array(input)?, to_array(hidden)?);
        let (d_in, h) = (input[0].d_in, gru.d_hidden);
        for d in input.iter().chain(&hidden) {
            if d.d_out != h || (d.d_in != d_in && d.d_in != h) {
                return Err(ModelError::ShapeMismatch {
                    what: format!("{what} gate width"),
                    expected: h,
                    found: d.d_out,
                });
            }
        }
        let out = Self {
            d_in,
            d_hidden: h,
            input: concat_gates(input),
            hidden: concat_gates(hidden),
            reset_after: gru.reset_after,
            clip: gru.clip.map(|c| c as f32),
        };
        out.validate(what)?;
        Ok(out)
    }

    /// Checks sizes.
    pub fn validate(&self, what: &str) -> Result<(), ModelError> {
        self.input.validate(&format!("{what} input"))?;
        self.hidden.validate(&format!("{what} hidden"))?;
        let h3 = 3 * self.d_hidden;
        if self.input.d_in != self.d_in
            || self.input.d_out != h3
            || self.hidden.d_in != self.d_hidden
            || self.hidden.d_out != h3
        {
            return Err(ModelError::ShapeMismatch {
                what: format!("{what} GRU gate matrices"),
                expected: h3,
                found: self.input.d_out,
            });
        }
        Ok(())
    }
}

/// Weights of a recurrent encoder: per-joint layers, FC layers, GRU.
#[derive(Clone, Debug, PartialEq)]
pub struct RecurrentWeights {
    /// Per-joint layers (shared by all joints), ReLU after each.
    pub joint_layers: Vec<DenseWeights>,
    /// Layers on the flattened joint features, ReLU after each.
    pub layers: Vec<DenseWeights>,
    /// The GRU.
    pub gru: GruWeights,
}

impl RecurrentWeights {
    /// The encoder's weights with its input scale folded into the first per-joint layer
    /// (`W' = diag(1/s) W`), so the plain matrices take unscaled descriptors.
    fn from_encoder(enc: &RecurrentEncoder, what: &str) -> Result<Self, ModelError> {
        let mut joint_layers = dense_layers(&enc.joint_mlp, &format!("{what} joint"))?;
        let factors = &enc.input_inv_scale;
        if let Some(first) = joint_layers.first_mut()
            && factors.len() == first.d_in
        {
            for (row, f) in first.weight.chunks_exact_mut(first.d_out).zip(factors) {
                row.iter_mut().for_each(|w| *w *= f);
            }
        }
        Ok(Self {
            joint_layers,
            layers: dense_layers(&enc.mlp, what)?,
            gru: GruWeights::from_gru(&enc.gru, &format!("{what} GRU"))?,
        })
    }

    /// True when no layer has a bias (zero input and state then give a zero code).
    pub fn is_bias_free(&self) -> bool {
        self.joint_layers
            .iter()
            .chain(&self.layers)
            .chain([&self.gru.input, &self.gru.hidden])
            .all(|l| l.bias.is_none())
    }
}

fn dense_layers(mlp: &Mlp, what: &str) -> Result<Vec<DenseWeights>, ModelError> {
    mlp.layers
        .iter()
        .enumerate()
        .map(|(i, l)| DenseWeights::from_linear(l, &format!("{what} layer {i}")))
        .collect()
}

/// All weights of a [`ClothNet`] as plain matrices.
#[derive(Clone, Debug, PartialEq)]
pub struct InferenceWeights {
    /// Which encoder layout the weights belong to.
    pub kind: EncoderKind,
    /// Number of input joints `J`.
    pub input_joints: usize,
    /// Number of garment vertices `V`.
    pub vertices: usize,
    /// Latent size.
    pub latent: usize,
    /// Static encoder layers (empty for the entangled variant), ReLU after each.
    pub static_layers: Vec<DenseWeights>,
    /// The dynamic (disentangled) or single (entangled) recurrent encoder.
    pub recurrent: Option<RecurrentWeights>,
    /// Decoder layers, ReLU after each.
    pub decoder_layers: Vec<DenseWeights>,
    /// Linear basis `[latent' + dynamic rows, V * 3]`, no activation; the rows after the
    /// decoder's width (`dynamic_basis_rows` of them) take `w z_D`.
    pub basis: DenseWeights,
    /// Rows of the basis that take the weighted dynamic code `w z_D` (the network's dynamic
    /// basis, [`crate::ClothNetConfig::dynamic_basis`]): 0 or the latent size.
    pub dynamic_basis_rows: usize,
}

impl InferenceWeights {
    /// Copies every parameter of `model` (reads tensors back from its device).
    pub fn from_module(model: &ClothNet) -> Result<Self, ModelError> {
        let kind = model.kind();
        let static_layers = match &model.static_encoder {
            Some(m) => dense_layers(m, "static encoder")?,
            None => Vec::new(),
        };
        let recurrent = match (&model.dynamic_encoder, &model.entangled_encoder) {
            (Some(e), _) => Some(RecurrentWeights::from_encoder(e, "dynamic encoder")?),
            (None, Some(e)) => Some(RecurrentWeights::from_encoder(e, "entangled encoder")?),
            (None, None) => None,
        };
        let out = Self {
            kind,
            input_joints: model.input_joints,
            vertices: model.vertices,
            latent: model.latent,
            static_layers,
            recurrent,
            decoder_layers: dense_layers(&model.decoder.mlp, "decoder")?,
            basis: effective_basis(&model.decoder)?,
            dynamic_basis_rows: model
                .decoder
                .dynamic_basis
                .as_ref()
                .map_or(0, |_| model.latent),
        };
        out.validate()?;
        Ok(out)
    }

    /// Checks that consecutive layers fit together and match `J`, `V` and the latent size.
    pub fn validate(&self) -> Result<(), ModelError> {
        let mismatch = |what: &str, expected: usize, found: usize| {
            Err(ModelError::ShapeMismatch {
                what: what.to_string(),
                expected,
                found,
            })
        };
        let chain =
            |layers: &[DenseWeights], d_in: usize, what: &str| -> Result<usize, ModelError> {
                let mut d = d_in;
                for (i, l) in layers.iter().enumerate() {
                    l.validate(&format!("{what} layer {i}"))?;
                    if l.d_in != d {
                        return Err(ModelError::ShapeMismatch {
                            what: format!("{what} layer {i} input width"),
                            expected: d,
                            found: l.d_in,
                        });
                    }
                    d = l.d_out;
                }
                Ok(d)
            };
        match (self.kind, &self.recurrent) {
            (EncoderKind::StaticOnly, Some(_)) => {
                return mismatch("recurrent encoders of a static-only model", 0, 1);
            }
            (EncoderKind::Disentangled | EncoderKind::Entangled, None) => {
                return mismatch("recurrent encoders", 1, 0);
            }
            _ => {}
        }
        if self.kind != EncoderKind::Entangled {
            let d = chain(
                &self.static_layers,
                self.input_joints * STATIC_DIM,
                "static encoder",
            )?;
            if d != self.latent {
                return mismatch("static encoder output width", self.latent, d);
            }
        }
        if let Some(r) = &self.recurrent {
            let joint_in = if self.kind == EncoderKind::Entangled {
                STATIC_DIM + DYNAMIC_DIM
            } else {
                DYNAMIC_DIM
            };
            let jd = chain(&r.joint_layers, joint_in, "joint encoder")?;
            let d = chain(&r.layers, self.input_joints * jd, "recurrent encoder")?;
            r.gru.validate("GRU")?;
            if r.gru.d_in != d {
                return mismatch("GRU input width", d, r.gru.d_in);
            }
            if r.gru.d_hidden != self.latent {
                return mismatch("GRU state width", self.latent, r.gru.d_hidden);
            }
            if self.kind == EncoderKind::Disentangled && !r.is_bias_free() {
                return Err(ModelError::InvalidConfig(
                    "the dynamic encoder must have no bias".into(),
                ));
            }
        }
        let d = chain(&self.decoder_layers, self.latent, "decoder")?;
        self.basis.validate("basis")?;
        if self.dynamic_basis_rows != 0
            && (self.dynamic_basis_rows != self.latent || self.kind != EncoderKind::Disentangled)
        {
            return mismatch(
                "dynamic basis rows (the latent size, disentangled only)",
                self.latent,
                self.dynamic_basis_rows,
            );
        }
        if self.basis.d_in != d + self.dynamic_basis_rows {
            return mismatch(
                "basis input width",
                d + self.dynamic_basis_rows,
                self.basis.d_in,
            );
        }
        if self.basis.d_out != self.vertices * 3 {
            return mismatch(
                "basis outputs (3 per vertex)",
                self.vertices * 3,
                self.basis.d_out,
            );
        }
        Ok(())
    }

    /// Total number of scalar parameters.
    pub fn parameter_count(&self) -> usize {
        let dense = |l: &DenseWeights| l.weight.len() + l.bias.as_ref().map_or(0, Vec::len);
        let mut n: usize = self
            .static_layers
            .iter()
            .chain(&self.decoder_layers)
            .chain([&self.basis])
            .map(dense)
            .sum();
        if let Some(r) = &self.recurrent {
            n += r
                .joint_layers
                .iter()
                .chain(&r.layers)
                .chain([&r.gru.input, &r.gru.hidden])
                .map(dense)
                .sum::<usize>();
        }
        n
    }

    /// Widest intermediate activation (for sizing scratch buffers).
    pub fn max_width(&self) -> usize {
        let mut w = self
            .latent
            .max(self.input_joints * (STATIC_DIM + DYNAMIC_DIM));
        let all = self.static_layers.iter().chain(&self.decoder_layers);
        for l in all {
            w = w.max(l.d_out).max(l.d_in);
        }
        if let Some(r) = &self.recurrent {
            for l in r.joint_layers.iter().chain(&r.layers) {
                w = w.max(l.d_out).max(l.d_in);
            }
        }
        w
    }
}

/// The decoder's effective basis and bias (`basis_scale · B̂`, `bias_scale · b̂`, see
/// [`crate::ClothNetConfig`]), with the dynamic basis's rows appended when it has one.
fn effective_basis(decoder: &crate::network::Decoder) -> Result<DenseWeights, ModelError> {
    let mut basis = DenseWeights::from_linear(&decoder.basis, "basis")?;
    let scale = decoder.basis_scale as f32;
    if scale != 1.0 {
        basis.weight.iter_mut().for_each(|v| *v *= scale);
    }
    let bias_scale = decoder.bias_scale as f32;
    if let (Some(bias), true) = (basis.bias.as_mut(), bias_scale != 1.0) {
        bias.iter_mut().for_each(|v| *v *= bias_scale);
    }
    if let Some(dynamic) = &decoder.dynamic_basis {
        let mut dynamic = DenseWeights::from_linear(dynamic, "dynamic basis")?;
        if dynamic.d_out != basis.d_out {
            return Err(ModelError::ShapeMismatch {
                what: "dynamic basis outputs".into(),
                expected: basis.d_out,
                found: dynamic.d_out,
            });
        }
        let scale = decoder.dynamic_scale as f32;
        dynamic.weight.iter_mut().for_each(|v| *v *= scale);
        // Row-major [d_in, d_out]: appending rows appends the data.
        basis.weight.extend_from_slice(&dynamic.weight);
        basis.d_in += dynamic.d_in;
    }
    Ok(basis)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dense_forms_agree() {
        let d = DenseWeights {
            d_in: 3,
            d_out: 5,
            weight: (0..15).map(|v| v as f32 * 0.1 - 0.7).collect(),
            bias: Some(vec![0.5; 5]),
        };
        let x = [1.0, 0.0, -2.0];
        let mut y = [0.0; 5];
        d.forward(&x, &mut y);
        for (o, yo) in y.iter().enumerate() {
            let expected: f32 = 0.5 + (0..3).map(|i| x[i] * d.weight[i * 5 + o]).sum::<f32>();
            assert!((yo - expected).abs() < 1e-6);
        }
        let mut part = [0.0; 3];
        d.forward_columns(&x, 2, &mut part);
        assert_eq!(part, [y[2], y[3], y[4]]);
        let mut r = [0.0; 5];
        d.forward_relu(&x, &mut r);
        assert!(r.iter().zip(&y).all(|(a, b)| *a == b.max(0.0)));
    }

    #[test]
    fn from_module_round_trips_shapes() {
        use crate::network::ClothNetConfig;
        let device = burn::tensor::Device::flex();
        let cfg = ClothNetConfig {
            static_hidden: vec![6],
            joint_hidden: vec![4],
            dynamic_hidden: vec![8],
            latent: 5,
            decoder_hidden: vec![7],
            ..Default::default()
        };
        for kind in [
            EncoderKind::Disentangled,
            EncoderKind::Entangled,
            EncoderKind::StaticOnly,
        ] {
            let net = ClothNetConfig {
                encoder: kind,
                ..cfg.clone()
            }
            .init(2, 4, &device)
            .unwrap();
            let w = InferenceWeights::from_module(&net).unwrap();
            assert_eq!(w.kind, kind);
            assert_eq!(w.basis.d_out, 12);
            let mut broken = w.clone();
            broken.basis.d_out = 9;
            assert!(broken.validate().is_err());
        }
    }
}
