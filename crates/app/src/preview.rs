//! The viewport's own copy of the cloth model: a plain-Rust [`InferenceEngine`] that predicts
//! the shown frame at the current `w`. It starts from untrained weights (so `w` already changes
//! the garment before training) and switches to each weight snapshot the trainer sends. The
//! recurrent state is rebuilt by replaying a short warm-up before the shown frame whenever the
//! frame is not the successor of the last one.

use std::sync::Arc;

use neural_cloth_core::geometry::Vec3;
use neural_cloth_core::scene::{Avatar, Garment, Motion};
use neural_cloth_model::network::{ClothNetConfig, EncoderKind};
use neural_cloth_model::{
    DescriptorConfig, InferenceEngine, InferenceOptions, InferenceWeights, ModelArtifact,
    ModelError,
};

use super::error::AppError;

/// Frames replayed before a jump so that the recurrent state reflects recent motion.
pub const WARMUP_FRAMES: usize = 15;
/// Seed of the untrained preview network.
pub const PREVIEW_SEED: u64 = 7;
/// Target mean garment displacement between `w = 0` and `w = 2` of the untrained preview, m.
pub const UNTRAINED_W_EFFECT_M: f32 = 0.04;
/// Largest mean offset from the template of the untrained preview at `w = 0`, m.
pub const UNTRAINED_STATIC_M: f32 = 0.005;

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

/// A build of the untrained engine running on a helper thread.
type Building = std::sync::mpsc::Receiver<Result<InferenceEngine, ModelError>>;

/// The preview model. Its untrained engine is built on a helper thread (about a second), so
/// the UI shows the skinned template meanwhile and never waits.
#[derive(Default)]
pub struct Preview {
    engine: Option<InferenceEngine>,
    building: Option<Building>,
    /// Incremented whenever the engine or its weights change (part of the frame cache key).
    generation: u64,
    /// Called when a background build finishes (requests a repaint).
    notify: Option<Arc<dyn Fn() + Send + Sync>>,
    source: Option<WeightsSource>,
    pending: Option<(u64, Arc<ModelArtifact>)>,
    fed: Option<Fed>,
    /// Why the preview fell back to the skinned template, if it did (shown as text by
    /// [`Self::describe`]).
    pub error: Option<AppError>,
    failed_for_scene: bool,
}

impl std::fmt::Debug for Preview {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Preview")
            .field("source", &self.source)
            .field("fed", &self.fed)
            .field("error", &self.error)
            .finish()
    }
}

impl Preview {
    /// Sets the callback run when a background build finishes (the app requests a repaint).
    pub fn set_notify(&mut self, notify: Arc<dyn Fn() + Send + Sync>) {
        self.notify = Some(notify);
    }

    /// True while the untrained engine is being built.
    pub fn is_building(&self) -> bool {
        self.building.is_some()
    }

    /// Changes whenever the network's output may have changed (new engine or weights).
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// Forgets the engine (the scene changed); the next frame builds a new one.
    pub fn reset_scene(&mut self) {
        self.engine = None;
        self.building = None;
        self.generation += 1;
        self.source = None;
        self.pending = None;
        self.fed = None;
        self.error = None;
        self.failed_for_scene = false;
    }

    /// Offers trainer weights of `step`; used from the next frame if they fit the scene.
    pub fn offer_weights(&mut self, step: u64, weights: Arc<ModelArtifact>) {
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

    /// Starts building the untrained engine for the scene on a helper thread if there is
    /// none, and picks up a finished build.
    fn ensure_engine(
        &mut self,
        avatar: &Arc<Avatar>,
        garment: &Arc<Garment>,
        fps: f32,
        dynamics: bool,
    ) {
        if self.engine.is_some() || self.failed_for_scene {
            return;
        }
        if self.building.is_some() {
            self.poll_build();
            return;
        }
        let (tx, rx) = std::sync::mpsc::sync_channel(1);
        let (avatar, garment, notify) = (avatar.clone(), garment.clone(), self.notify.clone());
        let spawned = std::thread::Builder::new()
            .name("neural-cloth-preview".into())
            .spawn(move || {
                let result = untrained_engine(&avatar, &garment, &avatar.motions, fps, dynamics);
                let _ = tx.send(result);
                if let Some(n) = notify {
                    n();
                }
            });
        match spawned {
            Ok(_) => self.building = Some(rx),
            Err(e) => {
                self.error = Some(AppError::Thread {
                    name: "neural-cloth-preview".into(),
                    source: e,
                });
                self.failed_for_scene = true;
            }
        }
    }

    /// Takes over a finished background build, if any (never waits).
    pub fn poll_build(&mut self) {
        let Some(rx) = &self.building else { return };
        let result = match rx.try_recv() {
            Ok(result) => result.map_err(AppError::from),
            Err(std::sync::mpsc::TryRecvError::Empty) => return,
            Err(std::sync::mpsc::TryRecvError::Disconnected) => Err(AppError::Panicked {
                name: "neural-cloth-preview".into(),
            }),
        };
        self.finish_build(result);
    }

    fn finish_build(&mut self, result: Result<InferenceEngine, AppError>) {
        self.building = None;
        self.generation += 1;
        match result {
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

    /// Waits (up to `timeout`) for a background build to finish; for tests and tools.
    pub fn wait_until_built(&mut self, timeout: std::time::Duration) -> bool {
        let Some(rx) = self.building.take() else {
            return true;
        };
        match rx.recv_timeout(timeout) {
            Ok(result) => {
                self.finish_build(result.map_err(AppError::from));
                true
            }
            Err(_) => {
                self.building = Some(rx);
                false
            }
        }
    }

    /// Garment positions at `time_secs` of `motion` (index `motion_index`) with weight `w`,
    /// or None when the network cannot run (the caller shows the skinned template).
    #[allow(clippy::too_many_arguments)]
    pub fn garment_positions(
        &mut self,
        avatar: &Arc<Avatar>,
        garment: &Arc<Garment>,
        motion_index: usize,
        motion: &Motion,
        time_secs: f32,
        w: f32,
        fps: f32,
        dynamics: bool,
    ) -> Option<Vec<Vec3>> {
        self.ensure_engine(avatar, garment, fps, dynamics);
        let engine = self.engine.as_mut()?;
        if let Some((step, model)) = self.pending.take() {
            self.generation += 1;
            match model.swap_into(engine, avatar, garment) {
                Ok(()) => {
                    self.source = Some(WeightsSource::Snapshot(step));
                    self.fed = None;
                }
                Err(source) => self.error = Some(AppError::Snapshot { step, source }),
            }
        }
        let fps = engine.fps();
        let frame = if fps > 0.0 && time_secs.is_finite() {
            (time_secs.max(0.0) * fps).round() as usize
        } else {
            0
        };
        let target = Fed {
            motion: motion_index,
            frame,
            w_bits: w.to_bits(),
        };
        let start = match self.fed {
            Some(f) if f == target => return Some(engine.garment_positions().to_vec()),
            // Playing forward (possibly skipping a few frames): continue from the last frame.
            Some(f)
                if f.motion == target.motion
                    && f.w_bits == target.w_bits
                    && f.frame < frame
                    && frame <= f.frame + WARMUP_FRAMES =>
            {
                f.frame + 1
            }
            _ => {
                engine.reset();
                frame.saturating_sub(WARMUP_FRAMES)
            }
        };
        for k in start..=frame {
            let pose = motion.sample(k as f32 / fps);
            if let Err(e) = engine.step(&pose, w) {
                self.error = Some(e.into());
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
    if values.is_empty() {
        0.0
    } else {
        values.iter().map(|v| v.abs()).sum::<f32>() / values.len() as f32
    }
}

/// An engine with freshly initialised weights, adjusted so that `w` has a visible effect.
///
/// An untrained network predicts offsets of a few micrometres, so as a preview it would show
/// the plain template and `w` would do nothing. Before training the preview therefore
/// (1) replaces the random basis by a smooth random one (low-frequency waves over the rest
/// template, so deformations look like cloth folds rather than noise), (2) scales the dynamic
/// encoder's per-joint layer so the recurrent code is of order one on the most dynamic of
/// `motions`, and (3) scales the basis so that on that motion `w = 2` moves the garment by
/// about [`UNTRAINED_W_EFFECT_M`] on average while `w = 0` stays within
/// [`UNTRAINED_STATIC_M`] of the template. None of this reaches training: the trainer's
/// snapshots replace these weights.
pub fn untrained_engine(
    avatar: &Avatar,
    garment: &Garment,
    motions: &[Motion],
    fps: f32,
    dynamics: bool,
) -> Result<InferenceEngine, ModelError> {
    let descriptors = DescriptorConfig::default();
    let joints = neural_cloth_model::DescriptorStream::new(
        &avatar.skeleton,
        &descriptors,
        1.0 / fps.max(1.0),
    )?
    .joint_count();
    let config = ClothNetConfig {
        encoder: if dynamics {
            EncoderKind::Disentangled
        } else {
            EncoderKind::StaticOnly
        },
        ..Default::default()
    };
    // burn builds the layer shapes; the values are then redrawn from our own seeded generator
    // (burn's generator is global and shared with other threads, e.g. a trainer).
    let net = config.init(
        joints,
        garment.vertex_count(),
        &burn::tensor::Device::flex(),
    )?;
    let mut weights = InferenceWeights::from_module(&net)?;
    let mut rng = SplitMix::new(PREVIEW_SEED);
    redraw(&mut weights, config.init_std as f32, &mut rng);
    smooth_basis(&mut weights, &garment.mesh.positions, &mut rng);
    let options = InferenceOptions {
        skin_body: false,
        ..Default::default()
    };
    let mut engine = ModelArtifact::new(weights.clone(), descriptors, fps)
        .into_engine(avatar, garment, options)?;
    // Runs WARMUP_FRAMES + 1 frames from the middle of `motion`; returns the rest-space offsets
    // and the mean magnitude of the dynamic code of the last frame.
    let run = |engine: &mut InferenceEngine,
               motion: &Motion,
               w: f32|
     -> Result<(Vec<f32>, f32), ModelError> {
        engine.reset();
        let count = (motion.duration_secs() * fps).floor().max(0.0) as usize + 1;
        let start = (count / 2).saturating_sub(WARMUP_FRAMES / 2);
        for k in start..(start + WARMUP_FRAMES + 1).min(count.max(start + 1)) {
            engine.step(&motion.sample(k as f32 / fps), w)?;
        }
        Ok((engine.offsets().to_vec(), mean_abs(engine.dynamic_code())))
    };
    // The most dynamic motion calibrates the preview.
    let mut probe: Option<(&Motion, f32)> = None;
    for m in motions.iter().filter(|m| m.frame_count() > 2) {
        let (_, z_d) = run(&mut engine, m, 1.0)?;
        if probe.is_none_or(|(_, best)| z_d > best) {
            probe = Some((m, z_d));
        }
    }
    let Some((motion, z_d)) = probe else {
        return Ok(engine);
    };
    // (2) Make the recurrent code of order one (ReLU layers are positively homogeneous).
    if let Some(rec) = weights.recurrent.as_mut()
        && z_d > 0.0
        && z_d < 0.2
    {
        let gain = (0.3 / z_d).clamp(1.0, 1e4);
        if let Some(first) = rec.joint_layers.first_mut() {
            first.weight.iter_mut().for_each(|v| *v *= gain);
        }
        engine.set_weights(weights.clone())?;
    }
    // (3) Scale the basis to the target effect of w, keeping w = 0 close to the template.
    let norm_mean = |v: &[f32]| {
        v.chunks_exact(3)
            .map(|c| (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt())
            .sum::<f32>()
            / (v.len() / 3).max(1) as f32
    };
    let (at0, _) = run(&mut engine, motion, 0.0)?;
    let (at2, _) = run(&mut engine, motion, 2.0)?;
    let diff: Vec<f32> = at0.iter().zip(&at2).map(|(a, b)| a - b).collect();
    let (effect, static_offset) = (norm_mean(&diff), norm_mean(&at0));
    if effect.is_finite() && effect > 1e-9 {
        let mut scale = UNTRAINED_W_EFFECT_M / effect;
        if static_offset.is_finite() && static_offset > 0.0 {
            scale = scale.min(UNTRAINED_STATIC_M / static_offset);
        }
        let scale = scale.clamp(1e-3, 1e6);
        weights.basis.weight.iter_mut().for_each(|v| *v *= scale);
        engine.set_weights(weights)?;
    }
    engine.reset();
    Ok(engine)
}

/// A small deterministic generator (SplitMix64), so the preview is the same on every run.
struct SplitMix(u64);

impl SplitMix {
    fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15))
    }

    /// Uniform in [0, 1).
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Standard normal (Box-Muller).
    fn normal(&mut self) -> f32 {
        let u = self.next().max(1e-7);
        let v = self.next();
        (-2.0 * u.ln()).sqrt() * (std::f32::consts::TAU * v).cos()
    }
}

/// Redraws every layer as the model initialises it: FC weights `N(0, fc_std²)`, GRU
/// weights Xavier-normal, biases zero (the basis is replaced afterwards).
fn redraw(weights: &mut InferenceWeights, fc_std: f32, rng: &mut SplitMix) {
    let mut fill = |layer: &mut neural_cloth_model::weights::DenseWeights, std: f32| {
        layer
            .weight
            .iter_mut()
            .for_each(|v| *v = std * rng.normal());
        if let Some(b) = layer.bias.as_mut() {
            b.fill(0.0);
        }
    };
    for layer in weights
        .static_layers
        .iter_mut()
        .chain(weights.decoder_layers.iter_mut())
    {
        fill(layer, fc_std);
    }
    if let Some(rec) = weights.recurrent.as_mut() {
        for layer in rec.joint_layers.iter_mut().chain(rec.layers.iter_mut()) {
            fill(layer, fc_std);
        }
        for layer in [&mut rec.gru.input, &mut rec.gru.hidden] {
            let std = (2.0 / (layer.d_in + layer.d_out / 3).max(1) as f32).sqrt();
            fill(layer, std);
        }
    }
}

/// Replaces the basis rows by smooth waves over the rest positions: row `r`, vertex `v`,
/// axis `a` gets `amp[r][a] * sin(k_r · p_v + phase_r)` with wavelengths of 0.3–1 m.
fn smooth_basis(weights: &mut InferenceWeights, rest: &[Vec3], rng: &mut SplitMix) {
    let basis = &mut weights.basis;
    let cols = basis.d_out;
    if cols != rest.len() * 3 {
        return;
    }
    let mut next = || rng.next();
    let norm = 1.0 / (basis.d_in as f32).sqrt();
    for row in basis.weight.chunks_exact_mut(cols) {
        let dir = Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5);
        let dir = neural_cloth_core::geometry::safe_normalize(dir).unwrap_or_else(Vec3::y);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn untrained_preview_is_deterministic_and_w_moves_the_garment() {
        let scene = neural_cloth_core::scene::procedural::default_scene().expect("default scene");
        let mut avatar = scene.avatar.clone();
        avatar
            .motions
            .extend(scene.motions.iter().map(|(m, _)| m.clone()));
        let motion = avatar
            .motions
            .iter()
            .find(|m| m.name == "run")
            .expect("run motion")
            .clone();
        let fps = scene.training_fps;
        let (avatar, garment) = (Arc::new(avatar), Arc::new(scene.garment.clone()));
        let run = |w: f32| {
            let mut p = Preview::default();
            let first = p.garment_positions(&avatar, &garment, 0, &motion, 1.3, w, fps, true);
            assert!(
                first.is_none() && p.is_building(),
                "built in the background"
            );
            assert!(p.wait_until_built(std::time::Duration::from_secs(60)));
            p.garment_positions(&avatar, &garment, 0, &motion, 1.3, w, fps, true)
                .expect("preview runs")
        };
        let (a0, b0, a2) = (run(0.0), run(0.0), run(2.0));
        assert_eq!(a0, b0, "same weights and frame give the same garment");
        let template = scene.garment.pose_vertices(&avatar, &motion.sample(1.3));
        let mean = |x: &[Vec3], y: &[Vec3]| {
            x.iter().zip(y).map(|(p, q)| (p - q).norm()).sum::<f32>() / x.len() as f32
        };
        let effect = mean(&a0, &a2);
        let static_offset = mean(&a0, &template);
        eprintln!(
            "untrained preview: mean |x(w=2) - x(w=0)| = {effect:.4} m, mean |x(w=0) - template| = {static_offset:.4} m"
        );
        assert!(
            effect > 0.2 * UNTRAINED_W_EFFECT_M && effect < 3.0 * UNTRAINED_W_EFFECT_M,
            "{effect}"
        );
        assert!(static_offset < 3.0 * UNTRAINED_STATIC_M, "{static_offset}");
        assert!(
            a0.iter()
                .chain(&a2)
                .all(|p| p.iter().all(|v| v.is_finite()))
        );
    }
}
