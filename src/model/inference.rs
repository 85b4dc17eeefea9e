//! Fast inference without burn: raw poses in, garment and body meshes out, one frame at a
//! time with the GRU state carried over (the paper's §4.5 measure, from raw pose data to final
//! meshes).
//!
//! Per frame: descriptors -> encoders -> `z = z_S + w z_D` -> decoder -> basis product ->
//! template + offsets -> LBS of the garment, and LBS of the body with the avatar's skin. Every
//! buffer is allocated when the engine is built, so [`InferenceEngine::step`] allocates
//! nothing. The bias-free dynamic branch is skipped exactly when its input and state are zero
//! (a still body from rest), which gives the same result as running it. The basis product is
//! one pass over the `[latent, V * 3]` row-major basis, blocked by output columns and
//! optionally spread over a rayon pool, as is the skinning.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::geometry::{Mat4, SkinWeights, Vec3};
use crate::scene::{Avatar, Garment, Pose, Skeleton};

use super::ModelError;
use super::descriptors::{DYNAMIC_DIM, DescriptorConfig, DescriptorStream, STATIC_DIM};
use super::gru::{GruScratch, gru_step};
use super::network::EncoderKind;
use super::skinning::{MATRIX_FLOATS, SkinMatrixBuilder, skin_positions_into, write_matrices_3x4};
use super::weights::{DenseWeights, InferenceWeights};

/// Output columns per block of the basis product (and vertices per skinning chunk × 3).
const COLUMN_BLOCK: usize = 2048;

/// Threading and output options of the engine.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct InferenceOptions {
    /// Worker threads for the basis product and skinning: 1 = the calling thread only
    /// (default), 0 = one per core, otherwise 2..=256.
    pub threads: usize,
    /// Garments with fewer output values (`V * 3`) than this stay on the calling thread even
    /// with `threads != 1`; default 30 000 (10K vertices).
    pub parallel_min_values: usize,
    /// Also skin the body mesh every frame; default true.
    pub skin_body: bool,
}

impl Default for InferenceOptions {
    fn default() -> Self {
        Self { threads: 1, parallel_min_values: 30_000, skin_body: true }
    }
}

/// What the engine needs of the scene: skeleton, garment template and skin, optional body.
#[derive(Clone, Copy, Debug)]
pub struct InferenceScene<'a> {
    /// The avatar's skeleton (defines the rest space of the template).
    pub skeleton: &'a Skeleton,
    /// Garment template in the skeleton's world rest pose.
    pub template: &'a [Vec3],
    /// Garment skin weights over the skeleton's joints.
    pub garment_skin: &'a SkinWeights,
    /// Body bind-space positions and skin weights, if the body is to be posed too.
    pub body: Option<(&'a [Vec3], &'a SkinWeights)>,
}

impl<'a> InferenceScene<'a> {
    /// The scene of `garment` on `avatar` (body included).
    pub fn new(avatar: &'a Avatar, garment: &'a Garment) -> Self {
        Self {
            skeleton: &avatar.skeleton,
            template: &garment.mesh.positions,
            garment_skin: &garment.skin,
            body: Some((&avatar.bind_mesh.positions, &avatar.skin)),
        }
    }
}

/// Preallocated per-frame buffers.
#[derive(Clone, Debug)]
struct Buffers {
    a: Vec<f32>,
    b: Vec<f32>,
    joint_in: Vec<f32>,
    joint_a: Vec<f32>,
    joint_b: Vec<f32>,
    joint_feat: Vec<f32>,
    gru_in: Vec<f32>,
    gru: GruScratch,
    z_s: Vec<f32>,
    z: Vec<f32>,
    offsets: Vec<f32>,
    rest: Vec<f32>,
    garment_mats: Vec<f32>,
    body_mats: Vec<f32>,
}

impl Buffers {
    fn new(w: &InferenceWeights, joints_all: usize) -> Self {
        let width = w.max_width();
        let (joint_width, joint_out, gru_in, hidden) = match &w.recurrent {
            Some(r) => {
                let jw = r.joint_layers.iter().map(|l| l.d_out).chain([STATIC_DIM + DYNAMIC_DIM]).max().unwrap_or(0);
                let joint_in = if w.kind == EncoderKind::Entangled { STATIC_DIM + DYNAMIC_DIM } else { DYNAMIC_DIM };
                let jo = r.joint_layers.last().map_or(joint_in, |l| l.d_out);
                (jw, jo, r.gru.d_in, r.gru.d_hidden)
            }
            None => (0, 0, 0, 0),
        };
        Self {
            a: vec![0.0; width],
            b: vec![0.0; width],
            joint_in: vec![0.0; STATIC_DIM + DYNAMIC_DIM],
            joint_a: vec![0.0; joint_width],
            joint_b: vec![0.0; joint_width],
            joint_feat: vec![0.0; w.input_joints * joint_out],
            gru_in: vec![0.0; gru_in],
            gru: GruScratch::new(hidden),
            z_s: vec![0.0; w.latent],
            z: vec![0.0; w.latent],
            offsets: vec![0.0; w.vertices * 3],
            rest: vec![0.0; w.vertices * 3],
            garment_mats: vec![0.0; joints_all * MATRIX_FLOATS],
            body_mats: vec![0.0; joints_all * MATRIX_FLOATS],
        }
    }
}

/// Runs ReLU layers from `x`, ping-ponging between `a` and `b`, and copies the result into
/// `out` (which must have the last layer's width, or `x`'s without layers).
fn relu_chain_into(layers: &[DenseWeights], x: &[f32], a: &mut [f32], b: &mut [f32], out: &mut [f32]) {
    let mut width = x.len();
    let mut in_a = None;
    for l in layers {
        match in_a {
            None => l.forward_relu(x, &mut a[..l.d_out]),
            Some(true) => l.forward_relu(&a[..width], &mut b[..l.d_out]),
            Some(false) => l.forward_relu(&b[..width], &mut a[..l.d_out]),
        }
        in_a = Some(!matches!(in_a, Some(true)));
        width = l.d_out;
    }
    match in_a {
        None => out.copy_from_slice(x),
        Some(true) => out.copy_from_slice(&a[..width]),
        Some(false) => out.copy_from_slice(&b[..width]),
    }
}

/// The plain-Rust cloth model: feed poses at the training frame rate with
/// [`InferenceEngine::step`], read meshes with [`InferenceEngine::garment_positions`] and
/// [`InferenceEngine::body_positions`].
pub struct InferenceEngine {
    weights: InferenceWeights,
    options: InferenceOptions,
    pool: Option<rayon::ThreadPool>,
    stream: DescriptorStream,
    template: Vec<f32>,
    garment_skin: SkinWeights,
    rest_from_world: Vec<Mat4>,
    body_bind: Vec<f32>,
    body_skin: SkinWeights,
    hidden: Vec<f32>,
    hidden_is_zero: bool,
    dynamic_skipped: bool,
    bufs: Buffers,
    garment: Vec<Vec3>,
    body: Vec<Vec3>,
}

impl std::fmt::Debug for InferenceEngine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("InferenceEngine")
            .field("kind", &self.weights.kind)
            .field("input_joints", &self.weights.input_joints)
            .field("vertices", &self.weights.vertices)
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

fn flatten(points: &[Vec3]) -> Vec<f32> {
    points.iter().flat_map(|p| [p.x, p.y, p.z]).collect()
}

impl InferenceEngine {
    /// An engine for `garment` on `avatar`, with input joints chosen by `descriptors` and
    /// poses fed at `fps` (the training frame rate).
    pub fn from_scene(
        weights: InferenceWeights,
        avatar: &Avatar,
        garment: &Garment,
        descriptors: &DescriptorConfig,
        fps: f32,
        options: InferenceOptions,
    ) -> Result<Self, ModelError> {
        Self::new(weights, InferenceScene::new(avatar, garment), descriptors, fps, options)
    }

    /// An engine for an explicit scene description.
    pub fn new(
        weights: InferenceWeights,
        scene: InferenceScene<'_>,
        descriptors: &DescriptorConfig,
        fps: f32,
        options: InferenceOptions,
    ) -> Result<Self, ModelError> {
        if !(fps.is_finite() && fps > 0.0) {
            return Err(ModelError::InvalidInput(format!("frame rate {fps} is not positive")));
        }
        weights.validate()?;
        let stream = DescriptorStream::new(scene.skeleton, descriptors, 1.0 / fps)?;
        if stream.joint_count() != weights.input_joints {
            return Err(ModelError::ShapeMismatch {
                what: "input joints of the skeleton (after exclusions) vs the model".into(),
                expected: weights.input_joints,
                found: stream.joint_count(),
            });
        }
        let v = scene.template.len();
        if v != weights.vertices || scene.garment_skin.len() != v {
            return Err(ModelError::ShapeMismatch {
                what: "garment vertices (template, skin weights) vs the model".into(),
                expected: weights.vertices,
                found: if v != weights.vertices { v } else { scene.garment_skin.len() },
            });
        }
        let joints_all = scene.skeleton.len();
        for (what, skin) in std::iter::once(("garment", scene.garment_skin)).chain(scene.body.map(|(_, s)| ("body", s))) {
            if let Some(j) = skin.max_joint().filter(|&j| j as usize >= joints_all) {
                return Err(ModelError::ShapeMismatch { what: format!("{what} skin joint {j}; joints"), expected: joints_all, found: j as usize + 1 });
            }
        }
        let (body_bind, body_skin) = match scene.body {
            Some((pos, skin)) if skin.len() == pos.len() => (flatten(pos), skin.clone()),
            Some((pos, skin)) => {
                return Err(ModelError::ShapeMismatch { what: "body skin weights (one per vertex)".into(), expected: pos.len(), found: skin.len() });
            }
            None => (Vec::new(), SkinWeights::default()),
        };
        if !scene.template.iter().chain(scene.body.map_or(&[][..], |b| b.0)).all(|p| p.iter().all(|c| c.is_finite())) {
            return Err(ModelError::InvalidInput("template or body has a non-finite vertex".into()));
        }
        let pool = match options.threads {
            1 => None,
            n => Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n.min(256))
                    .thread_name(|i| format!("nc-inference-{i}"))
                    .build()
                    .map_err(|e| ModelError::ThreadPool(e.to_string()))?,
            ),
        };
        let bufs = Buffers::new(&weights, joints_all);
        let body_count = body_bind.len() / 3;
        Ok(Self {
            hidden: vec![0.0; weights.latent],
            hidden_is_zero: true,
            dynamic_skipped: false,
            template: flatten(scene.template),
            garment_skin: scene.garment_skin.clone(),
            rest_from_world: SkinMatrixBuilder::new(scene.skeleton).rest_from_world().to_vec(),
            body_bind,
            body_skin,
            garment: vec![Vec3::zeros(); v],
            body: vec![Vec3::zeros(); body_count],
            bufs,
            stream,
            pool,
            options,
            weights,
        })
    }

    /// Replaces the weights (e.g. a snapshot from the trainer). The layout must describe the
    /// same joints and vertices; the GRU state is kept when the encoder layout is unchanged.
    pub fn set_weights(&mut self, weights: InferenceWeights) -> Result<(), ModelError> {
        weights.validate()?;
        if weights.input_joints != self.weights.input_joints || weights.vertices != self.weights.vertices {
            return Err(ModelError::ShapeMismatch {
                what: "joints × vertices of the new weights".into(),
                expected: self.weights.input_joints * self.weights.vertices,
                found: weights.input_joints * weights.vertices,
            });
        }
        let same_layout = weights.kind == self.weights.kind && weights.latent == self.weights.latent;
        let joints_all = self.bufs.garment_mats.len() / MATRIX_FLOATS;
        self.bufs = Buffers::new(&weights, joints_all);
        self.weights = weights;
        if !same_layout {
            self.hidden = vec![0.0; self.weights.latent];
            self.hidden_is_zero = true;
        }
        Ok(())
    }

    /// Forgets the motion history: zero GRU state, the next pose starts a new sequence.
    pub fn reset(&mut self) {
        self.stream.reset();
        self.hidden.fill(0.0);
        self.hidden_is_zero = true;
        self.dynamic_skipped = false;
    }

    /// Advances one frame with `pose` (sampled at the engine's frame rate) and dynamic weight
    /// `w` (0 = static, 1 = trained, up to 2 exaggerates). Allocates nothing.
    pub fn step(&mut self, pose: &Pose, w: f32) -> Result<(), ModelError> {
        if !w.is_finite() {
            return Err(ModelError::InvalidInput(format!("dynamic weight {w} is not finite")));
        }
        self.stream.push(pose)?;
        self.encode(w);
        self.decode();
        self.skin();
        Ok(())
    }

    fn encode(&mut self, w: f32) {
        let weights = &self.weights;
        let b = &mut self.bufs;
        if weights.kind != EncoderKind::Entangled {
            relu_chain_into(&weights.static_layers, self.stream.static_desc(), &mut b.a, &mut b.b, &mut b.z_s);
        }
        self.dynamic_skipped = false;
        if let Some(r) = &weights.recurrent {
            let entangled = weights.kind == EncoderKind::Entangled;
            if !entangled && self.hidden_is_zero && self.stream.dynamic_is_zero() {
                // Bias-free branch with zero input and zero state: its output is exactly zero.
                self.dynamic_skipped = true;
            } else {
                let jo = b.joint_feat.len() / weights.input_joints.max(1);
                let (s, d) = (self.stream.static_desc(), self.stream.dynamic_desc());
                for k in 0..weights.input_joints {
                    let dk = &d[k * DYNAMIC_DIM..(k + 1) * DYNAMIC_DIM];
                    let x: &[f32] = if entangled {
                        b.joint_in[..STATIC_DIM].copy_from_slice(&s[k * STATIC_DIM..(k + 1) * STATIC_DIM]);
                        b.joint_in[STATIC_DIM..].copy_from_slice(dk);
                        &b.joint_in
                    } else {
                        dk
                    };
                    relu_chain_into(&r.joint_layers, x, &mut b.joint_a, &mut b.joint_b, &mut b.joint_feat[k * jo..(k + 1) * jo]);
                }
                relu_chain_into(&r.layers, &b.joint_feat, &mut b.a, &mut b.b, &mut b.gru_in);
                gru_step(&r.gru, &b.gru_in, &mut self.hidden, &mut b.gru);
                self.hidden_is_zero = self.hidden.iter().all(|v| *v == 0.0);
            }
        }
        match weights.kind {
            EncoderKind::Entangled => b.z.copy_from_slice(&self.hidden),
            EncoderKind::StaticOnly => b.z.copy_from_slice(&b.z_s),
            EncoderKind::Disentangled => {
                if self.dynamic_skipped || w == 0.0 {
                    b.z.copy_from_slice(&b.z_s);
                } else {
                    for ((z, s), h) in b.z.iter_mut().zip(&b.z_s).zip(&self.hidden) {
                        *z = s + w * h;
                    }
                }
            }
        }
    }

    fn decode(&mut self) {
        let b = &mut self.bufs;
        let basis = &self.weights.basis;
        let d = basis.d_in;
        // Decoder MLP, ping-ponging between `a` and `b`; `h` is its output.
        let layers = &self.weights.decoder_layers;
        let mut in_a = None;
        let mut width = b.z.len();
        for l in layers {
            match in_a {
                None => l.forward_relu(&b.z, &mut b.a[..l.d_out]),
                Some(true) => l.forward_relu(&b.a[..width], &mut b.b[..l.d_out]),
                Some(false) => l.forward_relu(&b.b[..width], &mut b.a[..l.d_out]),
            }
            in_a = Some(!matches!(in_a, Some(true)));
            width = l.d_out;
        }
        let h: &[f32] = match in_a {
            None => &b.z,
            Some(true) => &b.a[..d],
            Some(false) => &b.b[..d],
        };
        let offsets = &mut b.offsets;
        match &self.pool {
            Some(pool) if offsets.len() >= self.options.parallel_min_values => pool.install(|| {
                offsets
                    .par_chunks_mut(COLUMN_BLOCK)
                    .enumerate()
                    .for_each(|(c, y)| basis.forward_columns(h, c * COLUMN_BLOCK, y));
            }),
            _ => {
                for (c, y) in offsets.chunks_mut(COLUMN_BLOCK).enumerate() {
                    basis.forward_columns(h, c * COLUMN_BLOCK, y);
                }
            }
        }
        for ((r, t), o) in b.rest.iter_mut().zip(&self.template).zip(offsets.iter()) {
            *r = t + o;
        }
    }

    fn skin(&mut self) {
        let world = self.stream.world_from_joint();
        let b = &mut self.bufs;
        write_matrices_3x4(world, &self.rest_from_world, &mut b.garment_mats);
        let parallel = self.pool.as_ref().filter(|_| b.rest.len() >= self.options.parallel_min_values);
        skin_maybe_parallel(parallel, &b.rest, &self.garment_skin, &b.garment_mats, &mut self.garment);
        if self.options.skin_body && !self.body.is_empty() {
            write_matrices_3x4(world, &self.stream.skeleton().joint_from_bind, &mut b.body_mats);
            let parallel = self.pool.as_ref().filter(|_| self.body_bind.len() >= self.options.parallel_min_values);
            skin_maybe_parallel(parallel, &self.body_bind, &self.body_skin, &b.body_mats, &mut self.body);
        }
    }

    /// Posed garment vertices of the last frame (world space, metres).
    pub fn garment_positions(&self) -> &[Vec3] {
        &self.garment
    }

    /// Posed body vertices of the last frame (empty without a body or with `skin_body` off).
    pub fn body_positions(&self) -> &[Vec3] {
        &self.body
    }

    /// Rest-space offsets of the last frame, `[V * 3]`.
    pub fn offsets(&self) -> &[f32] {
        &self.bufs.offsets
    }

    /// Template plus offsets of the last frame, `[V * 3]` (unposed garment).
    pub fn rest_positions(&self) -> &[f32] {
        &self.bufs.rest
    }

    /// Static code `z_S` of the last frame (zeros for the entangled variant).
    pub fn static_code(&self) -> &[f32] {
        &self.bufs.z_s
    }

    /// GRU state = dynamic code `z_D` of the last frame (the single code when entangled).
    pub fn dynamic_code(&self) -> &[f32] {
        &self.hidden
    }

    /// Latent code `z` that was decoded in the last frame.
    pub fn latent_code(&self) -> &[f32] {
        &self.bufs.z
    }

    /// True when the last frame skipped the dynamic branch (zero input and zero state).
    pub fn dynamic_skipped(&self) -> bool {
        self.dynamic_skipped
    }

    /// The weights in use.
    pub fn weights(&self) -> &InferenceWeights {
        &self.weights
    }

    /// Skeleton indices of the network's input joints.
    pub fn input_joints(&self) -> &[usize] {
        self.stream.input_joints()
    }

    /// Frames stepped since construction or the last [`InferenceEngine::reset`].
    pub fn frames_seen(&self) -> usize {
        self.stream.frames_seen()
    }
}

fn skin_maybe_parallel(pool: Option<&rayon::ThreadPool>, rest: &[f32], skin: &SkinWeights, mats: &[f32], out: &mut [Vec3]) {
    const CHUNK: usize = COLUMN_BLOCK / 3;
    match pool {
        Some(pool) => pool.install(|| {
            rest.par_chunks(3 * CHUNK)
                .zip(skin.joints.par_chunks(CHUNK))
                .zip(skin.weights.par_chunks(CHUNK))
                .zip(out.par_chunks_mut(CHUNK))
                .for_each(|(((r, j), w), o)| skin_positions_into(r, j, w, mats, o));
        }),
        None => skin_positions_into(rest, &skin.joints, &skin.weights, mats, out),
    }
}
