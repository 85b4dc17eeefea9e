//! The viewport's own copy of the cloth model: a plain-Rust [`InferenceEngine`] that predicts
//! the shown frame at the current `w`. It starts from untrained weights (so `w` already changes
//! the garment before training) and switches to each weight snapshot the trainer sends. The
//! recurrent state is rebuilt by replaying a short warm-up before the shown frame whenever the
//! frame is not the successor of the last one.

use std::sync::Arc;

use crate::geometry::Vec3;
use crate::model::network::{ClothNetConfig, EncoderKind};
use crate::model::{DescriptorConfig, InferenceEngine, InferenceOptions, InferenceWeights};
use crate::scene::{Avatar, Garment, Motion};

/// Frames replayed before a jump so that the recurrent state reflects recent motion.
pub const WARMUP_FRAMES: usize = 15;
/// Seed of the untrained preview network.
pub const PREVIEW_SEED: u64 = 7;
/// Target mean garment displacement between `w = 0` and `w = 2` of the untrained preview, m.
pub const UNTRAINED_W_EFFECT_M: f32 = 0.03;

/// Which weights the preview runs.
#[derive(Clone, Debug)]
enum WeightsSource {
    /// Untrained weights made for the current scene.
    Untrained,
    /// A trainer snapshot of this step.
    Snapshot(u64),
}

/// Frame the engine last produced.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Fed {
    motion: usize,
    frame: usize,
    w_bits: u32,
}

/// The preview model.
#[derive(Default)]
pub struct Preview {
    engine: Option<InferenceEngine>,
    source: Option<WeightsSource>,
    pending: Option<(u64, Arc<InferenceWeights>)>,
    fed: Option<Fed>,
    /// Why the preview fell back to the skinned template, if it did.
    pub error: Option<String>,
    failed_for_scene: bool,
}

impl std::fmt::Debug for Preview {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Preview").field("source", &self.source).field("fed", &self.fed).field("error", &self.error).finish()
    }
}

impl Preview {
    /// Forgets the engine (the scene changed); the next frame builds a new one.
    pub fn reset_scene(&mut self) {
        self.engine = None;
        self.source = None;
        self.pending = None;
        self.fed = None;
        self.error = None;
        self.failed_for_scene = false;
    }

    /// Offers trainer weights of `step`; used from the next frame if they fit the scene.
    pub fn offer_weights(&mut self, step: u64, weights: Arc<InferenceWeights>) {
        let current = match self.source {
            Some(WeightsSource::Snapshot(s)) => Some(s),
            _ => None,
        };
        let pending = self.pending.as_ref().map(|(s, _)| *s);
        if current != Some(step) && pending != Some(step) {
            self.pending = Some((step, weights));
        }
    }

    /// Step of the trainer snapshot in use (None: untrained weights or no engine).
    pub fn weights_step(&self) -> Option<u64> {
        match (&self.source, &self.pending) {
            (_, Some((s, _))) => Some(*s),
            (Some(WeightsSource::Snapshot(s)), None) => Some(*s),
            _ => None,
        }
    }

    /// True when the shown garment comes from the network (untrained or trained).
    pub fn is_active(&self) -> bool {
        self.engine.is_some()
    }

    /// Short description for the UI.
    pub fn describe(&self) -> String {
        match (&self.source, &self.error) {
            (_, Some(e)) => format!("skinned template ({e})"),
            (Some(WeightsSource::Snapshot(s)), _) => format!("model at step {s}"),
            (Some(WeightsSource::Untrained), _) => "untrained model".into(),
            (None, _) => "skinned template".into(),
        }
    }

    /// Builds the engine with untrained weights for the scene, if not done yet.
    fn ensure_engine(&mut self, avatar: &Avatar, garment: &Garment, motion: Option<&Motion>, fps: f32, dynamics: bool) {
        if self.engine.is_some() || self.failed_for_scene {
            return;
        }
        match untrained_engine(avatar, garment, motion, fps, dynamics) {
            Ok(engine) => {
                self.engine = Some(engine);
                self.source = Some(WeightsSource::Untrained);
            }
            Err(e) => {
                self.error = Some(e);
                self.failed_for_scene = true;
            }
        }
    }

    /// Garment positions at `time_secs` of `motion` (index `motion_index`) with weight `w`,
    /// or None when the network cannot run (the caller shows the skinned template).
    #[allow(clippy::too_many_arguments)]
    pub fn garment_positions(
        &mut self,
        avatar: &Avatar,
        garment: &Garment,
        motion_index: usize,
        motion: &Motion,
        time_secs: f32,
        w: f32,
        fps: f32,
        dynamics: bool,
    ) -> Option<Vec<Vec3>> {
        self.ensure_engine(avatar, garment, Some(motion), fps, dynamics);
        let engine = self.engine.as_mut()?;
        if let Some((step, weights)) = self.pending.take() {
            match engine.set_weights((*weights).clone()) {
                Ok(()) => {
                    self.source = Some(WeightsSource::Snapshot(step));
                    self.fed = None;
                }
                Err(e) => self.error = Some(format!("snapshot of step {step} does not fit the scene: {e}")),
            }
        }
        let frame = if fps > 0.0 && time_secs.is_finite() { (time_secs.max(0.0) * fps).round() as usize } else { 0 };
        let target = Fed { motion: motion_index, frame, w_bits: w.to_bits() };
        let start = match self.fed {
            Some(f) if f == target => return Some(engine.garment_positions().to_vec()),
            Some(f) if f.motion == target.motion && f.w_bits == target.w_bits && f.frame + 1 == frame => frame,
            _ => {
                engine.reset();
                frame.saturating_sub(WARMUP_FRAMES)
            }
        };
        for k in start..=frame {
            let pose = motion.sample(k as f32 / fps);
            if let Err(e) = engine.step(&pose, w) {
                self.error = Some(e.to_string());
                self.fed = None;
                return None;
            }
        }
        self.fed = Some(target);
        self.error = None;
        Some(engine.garment_positions().to_vec())
    }
}

/// Mean absolute value of a slice (0 when empty).
fn mean_abs(values: &[f32]) -> f32 {
    if values.is_empty() { 0.0 } else { values.iter().map(|v| v.abs()).sum::<f32>() / values.len() as f32 }
}

/// An engine with freshly initialised weights, adjusted so that `w` has a visible effect.
///
/// An untrained network predicts offsets of a few micrometres, so as a preview it would show
/// the plain template and `w` would do nothing. Before training the preview therefore
/// (1) replaces the random basis by a smooth random one (low-frequency waves over the rest
/// template, so deformations look like cloth folds rather than noise), (2) scales the dynamic
/// encoder's per-joint layer so the recurrent code is of order one on `motion`, and (3) scales
/// the basis so that `w = 2` moves the garment by about [`UNTRAINED_W_EFFECT_M`] on average.
/// None of this reaches training: the trainer's snapshots replace these weights.
pub fn untrained_engine(avatar: &Avatar, garment: &Garment, motion: Option<&Motion>, fps: f32, dynamics: bool) -> Result<InferenceEngine, String> {
    let descriptors = DescriptorConfig::default();
    let joints = crate::model::DescriptorStream::new(&avatar.skeleton, &descriptors, 1.0 / fps.max(1.0))
        .map_err(|e| e.to_string())?
        .joint_count();
    let config = ClothNetConfig { encoder: if dynamics { EncoderKind::Disentangled } else { EncoderKind::StaticOnly }, ..Default::default() };
    let device = burn::tensor::Device::flex();
    burn::tensor::Device::seed(&device, PREVIEW_SEED);
    let net = config.init(joints, garment.vertex_count(), &device).map_err(|e| e.to_string())?;
    let mut weights = InferenceWeights::from_module(&net).map_err(|e| e.to_string())?;
    smooth_basis(&mut weights, &garment.mesh.positions);
    let options = InferenceOptions { skin_body: false, ..Default::default() };
    let mut engine = InferenceEngine::from_scene(weights.clone(), avatar, garment, &descriptors, fps, options.clone()).map_err(|e| e.to_string())?;
    let Some(motion) = motion.filter(|m| m.frame_count() > 2) else { return Ok(engine) };
    let frames = motion.frame_count().min(WARMUP_FRAMES + 1);
    let run = |engine: &mut InferenceEngine, w: f32| -> Result<(Vec<Vec3>, f32), String> {
        engine.reset();
        for k in 0..frames {
            engine.step(&motion.sample(k as f32 / fps), w).map_err(|e| e.to_string())?;
        }
        Ok((engine.garment_positions().to_vec(), mean_abs(engine.dynamic_code())))
    };
    // (2) Make the recurrent code of order one (ReLU layers are positively homogeneous).
    if let Some(rec) = weights.recurrent.as_mut() {
        let (_, z_d) = run(&mut engine, 1.0)?;
        if z_d > 0.0 && z_d < 0.2 {
            let gain = (0.3 / z_d).clamp(1.0, 1e4);
            if let Some(first) = rec.joint_layers.first_mut() {
                first.weight.iter_mut().for_each(|v| *v *= gain);
            }
            engine.set_weights(weights.clone()).map_err(|e| e.to_string())?;
        }
    }
    // (3) Scale the basis to the target effect of w.
    let (at0, _) = run(&mut engine, 0.0)?;
    let (at2, _) = run(&mut engine, 2.0)?;
    let effect = at0.iter().zip(&at2).map(|(a, b)| (a - b).norm()).sum::<f32>() / at0.len().max(1) as f32;
    if effect.is_finite() && effect > 1e-9 {
        let scale = (UNTRAINED_W_EFFECT_M / effect).clamp(1e-3, 1e6);
        weights.basis.weight.iter_mut().for_each(|v| *v *= scale);
        engine.set_weights(weights).map_err(|e| e.to_string())?;
    }
    engine.reset();
    Ok(engine)
}

/// Replaces the basis rows by smooth waves over the rest positions: row `r`, vertex `v`,
/// axis `a` gets `amp[r][a] * sin(k_r · p_v + phase_r)` with wavelengths of 0.3–1 m.
fn smooth_basis(weights: &mut InferenceWeights, rest: &[Vec3]) {
    let basis = &mut weights.basis;
    let cols = basis.d_out;
    if cols != rest.len() * 3 {
        return;
    }
    // A small deterministic generator (SplitMix64) so the preview is the same every run.
    let mut state = PREVIEW_SEED.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    let mut next = move || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    };
    let norm = 1.0 / (basis.d_in as f32).sqrt();
    for row in basis.weight.chunks_exact_mut(cols) {
        let dir = Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5);
        let dir = crate::geometry::safe_normalize(dir).unwrap_or_else(Vec3::y);
        let wavelength = 0.3 + 0.7 * next();
        let k = dir * (std::f32::consts::TAU / wavelength);
        let phase = next() * std::f32::consts::TAU;
        let amp = [next() - 0.5, next() - 0.5, next() - 0.5].map(|a| a * norm);
        for (v, p) in rest.iter().enumerate() {
            let s = (k.dot(p) + phase).sin();
            for (a, amp_a) in amp.iter().enumerate() {
                if let Some(x) = row.get_mut(v * 3 + a) {
                    *x = amp_a * s;
                }
            }
        }
    }
}
