//! The inference engine's own form of the network: an [`InferenceWeights`] taken by value and
//! turned into [`Dense`] layers over [`Matrix`] storage (f32 or f16, converted in place, so
//! building an engine never holds two copies of the basis).

use super::descriptors::{DYNAMIC_DIM, STATIC_DIM};
use super::kernels::{Matrix, Precision};
use super::network::EncoderKind;
use super::weights::{DenseWeights, GruWeights, InferenceWeights, LinearLayer};

/// A fully connected layer `y = x W + b` with `W` in a [`Matrix`]; zero inputs are skipped.
#[derive(Clone, Debug, PartialEq)]
pub struct Dense {
    /// Weights `[d_in, d_out]`.
    pub matrix: Matrix,
    /// Bias `[d_out]`, if the layer has one (always f32).
    pub bias: Option<Vec<f32>>,
}

impl Dense {
    /// Takes the weights of `layer` (no copy at f32, converted in place at f16).
    pub fn new(layer: DenseWeights, precision: Precision) -> Self {
        Self {
            matrix: Matrix::new(layer.d_in, layer.d_out, layer.weight, precision),
            bias: layer.bias,
        }
    }

    /// Input width.
    pub fn d_in(&self) -> usize {
        self.matrix.rows()
    }

    /// Output width.
    pub fn d_out(&self) -> usize {
        self.matrix.cols()
    }

    /// `relu(x W + b)`.
    pub fn forward_relu(&self, x: &[f32], y: &mut [f32]) {
        self.forward(x, y);
        for v in y.iter_mut() {
            *v = v.max(0.0);
        }
    }
}

impl LinearLayer for Dense {
    fn forward_columns(&self, x: &[f32], col0: usize, y: &mut [f32]) {
        match self.bias.as_ref().and_then(|b| b.get(col0..col0 + y.len())) {
            Some(b) => y.copy_from_slice(b),
            None => y.fill(0.0),
        }
        self.matrix.accumulate(x, col0, y);
    }
}

/// Layers of a recurrent encoder.
#[derive(Clone, Debug, PartialEq)]
pub struct RecurrentLayers {
    /// Per-joint layers (shared by all joints), ReLU after each.
    pub joint_layers: Vec<Dense>,
    /// Layers on the flattened joint features, ReLU after each.
    pub layers: Vec<Dense>,
    /// The GRU.
    pub gru: GruWeights<Dense>,
}

/// The whole network, ready to run.
#[derive(Clone, Debug, PartialEq)]
pub struct CompiledNet {
    /// Encoder layout.
    pub kind: EncoderKind,
    /// Number of input joints `J`.
    pub input_joints: usize,
    /// Number of garment vertices `V`.
    pub vertices: usize,
    /// Latent size.
    pub latent: usize,
    /// Static encoder (empty when entangled), ReLU after each layer.
    pub static_layers: Vec<Dense>,
    /// Dynamic or entangled recurrent encoder.
    pub recurrent: Option<RecurrentLayers>,
    /// Decoder MLP, ReLU after each layer.
    pub decoder_layers: Vec<Dense>,
    /// Linear basis `[decoder width, V * 3]`.
    pub basis: Matrix,
    /// Per-value bias of the basis `[V * 3]` (the learned mean offset), when the network has one.
    pub basis_bias: Option<Vec<f32>>,
    /// The last rows of the basis that take `w z_D` (0 or the latent size; see
    /// [`InferenceWeights::dynamic_basis_rows`]).
    pub dynamic_basis_rows: usize,
}

fn dense_all(layers: Vec<DenseWeights>, precision: Precision) -> Vec<Dense> {
    layers
        .into_iter()
        .map(|l| Dense::new(l, precision))
        .collect()
}

impl CompiledNet {
    /// Takes validated `weights` and stores the basis at `basis` precision and every other
    /// matrix at `layers` precision.
    pub fn new(weights: InferenceWeights, basis: Precision, layers: Precision) -> Self {
        let recurrent = weights.recurrent.map(|r| RecurrentLayers {
            joint_layers: dense_all(r.joint_layers, layers),
            layers: dense_all(r.layers, layers),
            gru: r.gru.map_layers(|l| Dense::new(l, layers)),
        });
        Self {
            kind: weights.kind,
            input_joints: weights.input_joints,
            vertices: weights.vertices,
            latent: weights.latent,
            static_layers: dense_all(weights.static_layers, layers),
            recurrent,
            decoder_layers: dense_all(weights.decoder_layers, layers),
            basis: Matrix::new(
                weights.basis.d_in,
                weights.basis.d_out,
                weights.basis.weight,
                basis,
            ),
            basis_bias: weights.basis.bias,
            dynamic_basis_rows: weights.dynamic_basis_rows,
        }
    }

    fn all_layers(&self) -> impl Iterator<Item = &Dense> {
        let recurrent = self.recurrent.iter().flat_map(|r| {
            r.joint_layers
                .iter()
                .chain(&r.layers)
                .chain([&r.gru.input, &r.gru.hidden])
        });
        self.static_layers
            .iter()
            .chain(&self.decoder_layers)
            .chain(recurrent)
    }

    /// Bytes of weight storage (matrices at their precision, biases f32).
    pub fn weight_bytes(&self) -> usize {
        self.basis.bytes()
            + self
                .all_layers()
                .map(|l| l.matrix.bytes() + 4 * l.bias.as_ref().map_or(0, Vec::len))
                .sum::<usize>()
    }

    /// Widest activation of the encoders and the decoder MLP (scratch buffer size).
    pub fn max_width(&self) -> usize {
        let mut w = self
            .latent
            .max(self.input_joints * (STATIC_DIM + DYNAMIC_DIM))
            .max(self.basis.rows());
        for l in self.static_layers.iter().chain(&self.decoder_layers) {
            w = w.max(l.d_out()).max(l.d_in());
        }
        if let Some(r) = &self.recurrent {
            for l in r.joint_layers.iter().chain(&r.layers) {
                w = w.max(l.d_out()).max(l.d_in());
            }
        }
        w
    }
}

/// Runs ReLU layers from `x`, ping-ponging between `a` and `b`, and copies the result into
/// `out` (which must have the last layer's width, or `x`'s without layers).
pub fn relu_chain_into(layers: &[Dense], x: &[f32], a: &mut [f32], b: &mut [f32], out: &mut [f32]) {
    let mut width = x.len();
    let mut in_a = None;
    for l in layers {
        let d = l.d_out();
        match in_a {
            None => l.forward_relu(x, &mut a[..d]),
            Some(true) => l.forward_relu(&a[..width], &mut b[..d]),
            Some(false) => l.forward_relu(&b[..width], &mut a[..d]),
        }
        in_a = Some(!matches!(in_a, Some(true)));
        width = d;
    }
    match in_a {
        None => out.copy_from_slice(x),
        Some(true) => out.copy_from_slice(&a[..width]),
        Some(false) => out.copy_from_slice(&b[..width]),
    }
}
