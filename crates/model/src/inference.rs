//! Fast inference without burn: raw poses in, garment and body meshes out, one frame at a
//! time with the GRU state carried over (the paper's §4.5 measure, from raw pose data to final
//! meshes).
//!
//! Per frame: descriptors -> encoders -> `z = z_S + w z_D` -> decoder -> basis product ->
//! template + offsets -> LBS of the garment, and LBS of the body with the avatar's skin. Every
//! buffer is allocated when the engine is built, so [`InferenceEngine::step`] allocates
//! nothing. The engine takes the weights by value and keeps them as [`CompiledNet`] (f32, or
//! f16 converted in place: [`InferenceOptions::basis_precision`]). The bias-free dynamic
//! branch is skipped exactly when its input and state are zero (a still body from rest),
//! which gives the same result as running it. The basis product is one pass over the
//! `[latent, V * 3]` row-major basis, reading only the rows of nonzero decoder outputs, fused
//! with the template addition and the garment skinning per chunk of vertices (the chunk stays
//! in L1), and optionally spread over a rayon pool.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use neural_cloth_core::geometry::{Mat4, SkinWeights, Vec3};
use neural_cloth_core::scene::{Avatar, Garment, Pose, Skeleton};

use super::ModelError;
use super::compiled::{CompiledNet, relu_chain_into};
use super::descriptors::{DYNAMIC_DIM, DescriptorConfig, DescriptorStream, STATIC_DIM};
use super::gru::{GruScratch, gru_step};
use super::kernels::{GarmentChunk, Precision, skin_into};
use super::network::EncoderKind;
use super::skinning::{MATRIX_FLOATS, SkinMatrixBuilder, write_matrices_3x4};
use super::weights::InferenceWeights;

/// Garment vertices per chunk of the fused basis product + skinning (1536 output columns:
/// 6 KiB of offsets, rest and posed positions each, all L1-resident).
const VERTEX_CHUNK: usize = 512;

/// Threading, output and weight-precision options of the engine.
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
    /// Storage of the decoder basis `[latent, V * 3]`, the bulk of the weights and of the
    /// bytes read per frame: `f16` (default; each row scaled by a power of two, f32
    /// arithmetic) halves them. Measured by `neural-cloth bench`: the offsets move by about
    /// 2·10⁻⁴ of the largest offset (0.01 mm for offsets of 5 cm).
    pub basis_precision: Precision,
    /// Storage of the other matrices (encoders, GRU, decoder MLP): default `f16`. With the
    /// basis also in f16 the offsets move by up to about 8·10⁻⁴ of the largest offset
    /// (0.04 mm for offsets of 5 cm); it is what brings 10K DoF past 2,000 fps on one core.
    pub layer_precision: Precision,
}

impl Default for InferenceOptions {
    fn default() -> Self {
        Self {
            threads: 1,
            parallel_min_values: 30_000,
            skin_body: true,
            basis_precision: Precision::F16,
            layer_precision: Precision::F16,
        }
    }
}

impl InferenceOptions {
    /// Full f32 weights: the trained model bit for bit (matches burn to float rounding).
    pub fn exact() -> Self {
        Self {
            basis_precision: Precision::F32,
            layer_precision: Precision::F32,
            ..Self::default()
        }
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
    /// Decoder output: the basis coefficients of the frame.
    h: Vec<f32>,
    offsets: Vec<f32>,
    rest: Vec<f32>,
    garment_mats: Vec<f32>,
    body_mats: Vec<f32>,
}

impl Buffers {
    fn new(net: &CompiledNet, joints_all: usize) -> Self {
        let width = net.max_width();
        let (joint_width, joint_out, gru_in, hidden) = match &net.recurrent {
            Some(r) => {
                let jw = r
                    .joint_layers
                    .iter()
                    .map(|l| l.d_out())
                    .chain([STATIC_DIM + DYNAMIC_DIM])
                    .max()
                    .unwrap_or(0);
                let joint_in = if net.kind == EncoderKind::Entangled {
                    STATIC_DIM + DYNAMIC_DIM
                } else {
                    DYNAMIC_DIM
                };
                let jo = r.joint_layers.last().map_or(joint_in, |l| l.d_out());
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
            joint_feat: vec![0.0; net.input_joints * joint_out],
            gru_in: vec![0.0; gru_in],
            gru: GruScratch::new(hidden),
            z_s: vec![0.0; net.latent],
            z: vec![0.0; net.latent],
            h: vec![0.0; net.basis.rows()],
            offsets: vec![0.0; net.vertices * 3],
            rest: vec![0.0; net.vertices * 3],
            garment_mats: vec![0.0; joints_all * MATRIX_FLOATS],
            body_mats: vec![0.0; joints_all * MATRIX_FLOATS],
        }
    }
}

/// The plain-Rust cloth model: feed poses at the training frame rate with
/// [`InferenceEngine::step`], read meshes with [`InferenceEngine::garment_positions`] and
/// [`InferenceEngine::body_positions`].
pub struct InferenceEngine {
    net: CompiledNet,
    options: InferenceOptions,
    fps: f32,
    descriptors: DescriptorConfig,
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
            .field("kind", &self.net.kind)
            .field("input_joints", &self.net.input_joints)
            .field("vertices", &self.net.vertices)
            .field("options", &self.options)
            .finish_non_exhaustive()
    }
}

fn flatten(points: &[Vec3]) -> Vec<f32> {
    points.iter().flat_map(|p| [p.x, p.y, p.z]).collect()
}

impl InferenceEngine {
    /// An engine for `garment` on `avatar`, with input joints chosen by `descriptors` and
    /// poses fed at `fps` (the training frame rate). The engine keeps `weights` (moved, not
    /// copied; converted in place at f16).
    pub fn from_scene(
        weights: InferenceWeights,
        avatar: &Avatar,
        garment: &Garment,
        descriptors: &DescriptorConfig,
        fps: f32,
        options: InferenceOptions,
    ) -> Result<Self, ModelError> {
        Self::new(
            weights,
            InferenceScene::new(avatar, garment),
            descriptors,
            fps,
            options,
        )
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
            return Err(ModelError::InvalidInput(format!(
                "frame rate {fps} is not positive"
            )));
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
                found: if v != weights.vertices {
                    v
                } else {
                    scene.garment_skin.len()
                },
            });
        }
        let joints_all = scene.skeleton.len();
        for (what, skin) in std::iter::once(("garment", scene.garment_skin))
            .chain(scene.body.map(|(_, s)| ("body", s)))
        {
            if let Some(j) = skin.max_joint().filter(|&j| j as usize >= joints_all) {
                return Err(ModelError::ShapeMismatch {
                    what: format!("{what} skin joint {j}; joints"),
                    expected: joints_all,
                    found: j as usize + 1,
                });
            }
        }
        let (body_bind, body_skin) = match scene.body {
            Some((pos, skin)) if skin.len() == pos.len() => (flatten(pos), skin.clone()),
            Some((pos, skin)) => {
                return Err(ModelError::ShapeMismatch {
                    what: "body skin weights (one per vertex)".into(),
                    expected: pos.len(),
                    found: skin.len(),
                });
            }
            None => (Vec::new(), SkinWeights::default()),
        };
        if !scene
            .template
            .iter()
            .chain(scene.body.map_or(&[][..], |b| b.0))
            .all(|p| p.iter().all(|c| c.is_finite()))
        {
            return Err(ModelError::InvalidInput(
                "template or body has a non-finite vertex".into(),
            ));
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
        let net = CompiledNet::new(weights, options.basis_precision, options.layer_precision);
        let bufs = Buffers::new(&net, joints_all);
        let body_count = body_bind.len() / 3;
        Ok(Self {
            hidden: vec![0.0; net.latent],
            hidden_is_zero: true,
            dynamic_skipped: false,
            template: flatten(scene.template),
            garment_skin: scene.garment_skin.clone(),
            rest_from_world: SkinMatrixBuilder::new(scene.skeleton)
                .rest_from_world()
                .to_vec(),
            body_bind,
            body_skin,
            garment: vec![Vec3::zeros(); v],
            body: vec![Vec3::zeros(); body_count],
            bufs,
            stream,
            pool,
            options,
            fps,
            descriptors: descriptors.clone(),
            net,
        })
    }

    /// Replaces the weights (e.g. a snapshot from the trainer), stored at the engine's
    /// precisions. The layout must describe the same joints and vertices; the GRU state is kept
    /// when the encoder layout is unchanged.
    pub fn set_weights(&mut self, weights: InferenceWeights) -> Result<(), ModelError> {
        weights.validate()?;
        if weights.input_joints != self.net.input_joints || weights.vertices != self.net.vertices {
            return Err(ModelError::ShapeMismatch {
                what: "joints × vertices of the new weights".into(),
                expected: self.net.input_joints * self.net.vertices,
                found: weights.input_joints * weights.vertices,
            });
        }
        let same_layout = weights.kind == self.net.kind && weights.latent == self.net.latent;
        let joints_all = self.bufs.garment_mats.len() / MATRIX_FLOATS;
        self.net = CompiledNet::new(
            weights,
            self.options.basis_precision,
            self.options.layer_precision,
        );
        self.bufs = Buffers::new(&self.net, joints_all);
        if !same_layout {
            self.hidden = vec![0.0; self.net.latent];
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
            return Err(ModelError::InvalidInput(format!(
                "dynamic weight {w} is not finite"
            )));
        }
        self.stream.push(pose)?;
        self.encode(w);
        self.decode(w);
        self.pose_garment();
        self.pose_body();
        Ok(())
    }

    fn encode(&mut self, w: f32) {
        let weights = &self.net;
        let b = &mut self.bufs;
        if weights.kind != EncoderKind::Entangled {
            relu_chain_into(
                &weights.static_layers,
                self.stream.static_desc(),
                &mut b.a,
                &mut b.b,
                &mut b.z_s,
            );
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
                        b.joint_in[..STATIC_DIM]
                            .copy_from_slice(&s[k * STATIC_DIM..(k + 1) * STATIC_DIM]);
                        b.joint_in[STATIC_DIM..].copy_from_slice(dk);
                        &b.joint_in
                    } else {
                        dk
                    };
                    relu_chain_into(
                        &r.joint_layers,
                        x,
                        &mut b.joint_a,
                        &mut b.joint_b,
                        &mut b.joint_feat[k * jo..(k + 1) * jo],
                    );
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

    /// Decoder MLP: `z` -> basis coefficients `h`, followed by `w z_D` for the rows of a
    /// dynamic basis.
    fn decode(&mut self, w: f32) {
        let b = &mut self.bufs;
        let d = b.h.len() - self.net.dynamic_basis_rows;
        let (h, dynamic) = b.h.split_at_mut(d);
        relu_chain_into(&self.net.decoder_layers, &b.z, &mut b.a, &mut b.b, h);
        if self.dynamic_skipped || w == 0.0 {
            dynamic.fill(0.0);
        } else {
            for (out, z_d) in dynamic.iter_mut().zip(&self.hidden) {
                *out = w * z_d;
            }
        }
    }

    /// Basis product, template addition and garment skinning, fused per chunk of vertices.
    fn pose_garment(&mut self) {
        let pool = self
            .pool
            .as_ref()
            .filter(|_| self.bufs.offsets.len() >= self.options.parallel_min_values);
        let garment = &mut self.garment;
        let b = &mut self.bufs;
        write_matrices_3x4(
            self.stream.world_from_joint(),
            &self.rest_from_world,
            &mut b.garment_mats,
        );
        let chunk = GarmentChunk {
            basis: &self.net.basis,
            h: &b.h,
            bias: self.net.basis_bias.as_deref(),
            template: &self.template,
            skin: &self.garment_skin,
            mats: &b.garment_mats,
        };
        let values = 3 * VERTEX_CHUNK;
        match pool {
            Some(pool) => pool.install(|| {
                b.offsets
                    .par_chunks_mut(values)
                    .zip(b.rest.par_chunks_mut(values))
                    .zip(garment.par_chunks_mut(VERTEX_CHUNK))
                    .enumerate()
                    .for_each(|(c, ((o, r), g))| chunk.run(c * VERTEX_CHUNK, o, r, g));
            }),
            None => {
                let chunks = b
                    .offsets
                    .chunks_mut(values)
                    .zip(b.rest.chunks_mut(values))
                    .zip(garment.chunks_mut(VERTEX_CHUNK));
                for (c, ((o, r), g)) in chunks.enumerate() {
                    chunk.run(c * VERTEX_CHUNK, o, r, g);
                }
            }
        }
    }

    fn pose_body(&mut self) {
        if !self.options.skin_body || self.body.is_empty() {
            return;
        }
        let b = &mut self.bufs;
        write_matrices_3x4(
            self.stream.world_from_joint(),
            &self.stream.skeleton().joint_from_bind,
            &mut b.body_mats,
        );
        let (bind, skin, mats) = (&self.body_bind, &self.body_skin, &b.body_mats);
        let pool = self
            .pool
            .as_ref()
            .filter(|_| bind.len() >= self.options.parallel_min_values);
        match pool {
            Some(pool) => pool.install(|| {
                bind.par_chunks(3 * VERTEX_CHUNK)
                    .zip(skin.joints.par_chunks(VERTEX_CHUNK))
                    .zip(skin.weights.par_chunks(VERTEX_CHUNK))
                    .zip(self.body.par_chunks_mut(VERTEX_CHUNK))
                    .for_each(|(((r, j), w), o)| skin_into(r, j, w, mats, o));
            }),
            None => skin_into(bind, &skin.joints, &skin.weights, mats, &mut self.body),
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

    /// Basis coefficients of the last frame: the decoder's output (after ReLU) followed, with
    /// a dynamic basis, by `w z_D` (any sign); the basis rows of its zeros were not read.
    pub fn basis_input(&self) -> &[f32] {
        &self.bufs.h
    }

    /// Storage precision of the basis actually in use (f32 when f16 was asked for but a weight
    /// is out of the f16 range).
    pub fn basis_precision(&self) -> Precision {
        self.net.basis.precision()
    }

    /// Bytes of weight storage of the engine (basis and layers at their precisions).
    pub fn weight_bytes(&self) -> usize {
        self.net.weight_bytes()
    }

    /// Bytes of the stored basis.
    pub fn basis_bytes(&self) -> usize {
        self.net.basis.bytes()
    }

    /// The options the engine was built with.
    pub fn options(&self) -> &InferenceOptions {
        &self.options
    }

    /// Frame rate the engine takes poses at (the model's training rate), frames per second.
    pub fn fps(&self) -> f32 {
        self.fps
    }

    /// The descriptor settings the engine takes poses with.
    pub fn descriptors(&self) -> &DescriptorConfig {
        &self.descriptors
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
