//! The neural training session: model, optimiser, data and physics of one run, stepped by the
//! trainer thread ([`super::handle`]).
//!
//! One step (paper §3.4, §4.1): sample `B` windows of `ceil(window·fps)+3` frames, encode
//! them, decode the last `loss_frames + 2` frames and skin them; static losses on each of the
//! last `loss_frames` frames (1, the paper's: the last frame only); inertia of each such `x_t`
//! against the stop-gradient projection `2x_{t-1} - x_{t-2}` of the network's own previous
//! frames (or, in `snug` mode, with gradients into the past frames); motion augmentation
//! replaces the dynamic code of a fraction of the batch by another sample's (encoders
//! detached, static losses only); with the friction effect, the friction dissipation of each
//! loss frame's slip over the body since the network's own previous frame; the physics
//! gradient filtered ([`crate::filter`], `D (D + βK)⁻¹`) on its way to the network; Adam.

use std::path::PathBuf;
use std::sync::Arc;

use burn::module::Module;
use burn::tensor::{Bytes, Device, Tensor, TensorData};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

use neural_cloth_core::scene::{Avatar, Garment};
use neural_cloth_model::activity::{Activity, revive_dead_units, unit_activity};
use neural_cloth_model::{ClothNet, DescriptorConfig, GarmentLbs, InferenceWeights, ModelArtifact};
use neural_cloth_physics::metrics::History;
use neural_cloth_physics::{
    BodyBatch, ClothMetrics, Contacts, FabricParams, FrictionContacts, LossTerms, PhysicsTerms,
};

mod fit;
mod forward;
mod split;
mod step_losses;

use super::TrainError;
use super::adam::TrainOptimiser;
use super::config::{InertiaMode, TrainConfig};
use super::data::{Batch, Dataset};
use super::filter::FilterCache;
use super::fit_reference::FitReference;
use super::handle::Session;
use super::metrics::{MetricHistory, MetricRecord};
use super::run_dir::{CheckpointState, RunDir};

/// Validation windows per pass.
pub const VALIDATION_WINDOWS: usize = 32;
/// Windows of each training batch whose metrics are logged per step.
pub const STEP_METRIC_WINDOWS: usize = 4;

/// Everything one run trains with.
pub struct NeuralSession {
    device: Device,
    model: ClothNet,
    optim: TrainOptimiser,
    learning_rate: f64,
    /// Factor of the learning-rate schedule on `learning_rate` (checkpoints keep the latter).
    schedule_factor: f64,
    /// Fraction of the run's budget spent (`None`: open-ended), from the loop.
    run_progress: Option<f64>,
    /// Whether the last step's batch could hold the mirrored copies (`None` before this
    /// session's first step), for the one note when they join.
    mirrored_in: Option<bool>,
    /// What the last step changed on the run's schedule, for [`Session::take_note`].
    note: Option<String>,
    config: TrainConfig,
    /// Training frame rate (the scene's), frames per second.
    fps: f32,
    descriptors: DescriptorConfig,
    terms: PhysicsTerms,
    lbs: GarmentLbs,
    avatar: Arc<Avatar>,
    garment: Arc<Garment>,
    train: Dataset,
    validation: Dataset,
    rng: StdRng,
    run: RunDir,
    /// Unit activity of the last validation pass.
    activity: Option<Activity>,
    /// Standard deviation of fresh weights when dead units are revived.
    init_std: f64,
    /// The gradient filter of [`TrainConfig::precondition_stiffness`].
    filter: FilterCache,
    /// Frames of [`TrainConfig::fit_reference`], loaded when the run is prepared, or of the
    /// warm start ([`TrainConfig::warm_start_steps`]) until its steps are done.
    reference: Option<FitReference>,
}

/// The parts a session is built from.
pub struct SessionParts {
    /// Autodiff device.
    pub device: Device,
    /// Initial (or restored) network.
    pub model: ClothNet,
    /// Training settings.
    pub config: TrainConfig,
    /// Training frame rate, frames per second: the scene's `training_fps` (the rate the data
    /// were resampled to), in the trainer's range 5..=240.
    pub fps: f32,
    /// Descriptor settings of the training data (travel with the weight snapshots).
    pub descriptors: DescriptorConfig,
    /// Physics terms of the garment.
    pub terms: PhysicsTerms,
    /// Garment skinning.
    pub lbs: GarmentLbs,
    /// The avatar (bodies for collisions).
    pub avatar: Arc<Avatar>,
    /// The garment (physics rebuilt from it when the fabric changes).
    pub garment: Arc<Garment>,
    /// Training data.
    pub train: Dataset,
    /// Validation data (may be empty: then the training motions validate).
    pub validation: Dataset,
    /// Run directory.
    pub run: RunDir,
    /// Standard deviation of fresh FC weights (the model's `init_std`), for reviving units.
    pub init_std: f64,
}

impl NeuralSession {
    /// Assembles a session with a fresh Adam optimiser.
    pub fn new(parts: SessionParts) -> Self {
        let optim = TrainOptimiser::for_config(&parts.config);
        let seed = parts.config.seed;
        Self {
            device: parts.device,
            model: parts.model,
            optim,
            learning_rate: parts.config.learning_rate,
            schedule_factor: 1.0,
            run_progress: None,
            mirrored_in: None,
            note: None,
            config: parts.config,
            fps: parts.fps,
            descriptors: parts.descriptors,
            terms: parts.terms,
            lbs: parts.lbs,
            avatar: parts.avatar,
            garment: parts.garment,
            train: parts.train,
            validation: parts.validation,
            rng: StdRng::seed_from_u64(seed ^ 0x5eed),
            run: parts.run,
            activity: None,
            init_std: parts.init_std,
            filter: FilterCache::default(),
            reference: None,
        }
    }

    /// Restores model, optimiser and learning rate from checkpoint `step`.
    pub fn load_checkpoint(&mut self, step: u64) -> Result<CheckpointState, TrainError> {
        let (model_bytes, optim_bytes, state) = self.run.read_checkpoint(step)?;
        let record = burn::store::ModuleRecord::from_bytes(Bytes::from_bytes_vec(model_bytes))
            .map_err(|e| TrainError::Checkpoint(e.to_string()))?;
        self.model = self
            .model
            .clone()
            .try_load_record(record)
            .map_err(|e| TrainError::Checkpoint(e.to_string()))?;
        self.optim = self
            .optim
            .load_bytes(Bytes::from_bytes_vec(optim_bytes))
            .map_err(|e| TrainError::Checkpoint(e.to_string()))?;
        self.learning_rate = state.learning_rate;
        self.filter.restore(state.step);
        Ok(state)
    }

    /// The current network.
    pub fn model(&self) -> &ClothNet {
        &self.model
    }

    /// Centres the biases of the network on the probe windows (data-dependent initialisation,
    /// [`neural_cloth_model::activity::centre_biases`]); call before the first step.
    pub fn centre_biases(&mut self) -> Result<(), TrainError> {
        let (statics, dynamics) = self.probe_descriptors();
        neural_cloth_model::activity::centre_biases(&mut self.model, statics, dynamics)?;
        Ok(())
    }

    /// Replaces the network (e.g. a warm start); the optimiser state is kept.
    pub fn set_model(&mut self, model: ClothNet) {
        self.model = model;
    }

    /// The run directory.
    pub fn run_dir(&self) -> &RunDir {
        &self.run
    }

    fn tensor4(&self, data: Vec<f32>, shape: [usize; 4]) -> Tensor<4> {
        Tensor::from_data(TensorData::new(data, shape), &self.device)
    }

    /// Body contacts (when collision is on) and static losses of `x_t`, the predicted frames
    /// `first..K` of `batch` stacked frame by frame ([`stack_frames`]).
    fn static_losses(
        &self,
        data: &Dataset,
        batch: &Batch,
        blended: &Tensor<4>,
        first: usize,
        x_t: &Tensor<3>,
    ) -> Result<(Option<Contacts>, LossTerms), TrainError> {
        let bodies = self.bodies(data, batch, first)?;
        let contacts = match &bodies {
            Some(bodies) => Some(self.terms.contacts(x_t, bodies)?),
            None => None,
        };
        let mut losses = self.terms.static_losses_with(x_t, contacts.as_ref())?;
        if let Some(pinning) = self
            .pin_target(batch, blended, first)
            .and_then(|target| self.terms.pinning(x_t, &target))
        {
            losses.push(neural_cloth_physics::Term::Pinning, pinning);
        }
        Ok((contacts, losses))
    }

    /// With the dynamics effect: the inertia of the first `kept` samples of every loss frame
    /// of `x` (`[B, K, V, 3]`) from the network's own two previous frames, the friction
    /// dissipation of every loss frame `x_t` (stacked, [`stack_frames`]) with the friction
    /// effect, and the friction contacts, for the step's metrics.
    fn dynamic_losses(
        &self,
        x: &Tensor<4>,
        x_t: &Tensor<3>,
        batch: &Batch,
        contacts: Option<&Contacts>,
        kept: usize,
    ) -> Result<DynamicLosses, TrainError> {
        if !self.terms.effects().dynamics {
            return Ok(DynamicLosses::default());
        }
        let (b, predicted) = (batch.size, batch.predicted);
        let (xt, xt1, xt2) = (
            stack_frames(x, 2, predicted, kept),
            stack_frames(x, 1, predicted - 1, kept),
            stack_frames(x, 0, predicted - 2, kept),
        );
        let inertia = match self.config.inertia_mode {
            InertiaMode::Ours => {
                let alpha = self.config.momentum_boost_at(self.filter.steps_taken());
                let xt2 = super::losses::boosted_history(&xt1, xt2, alpha);
                self.terms.inertia(&xt, &xt1, &xt2, self.dt_secs())
            }
            InertiaMode::Snug => {
                super::losses::inertia_through_past(&self.terms, &xt, &xt1, &xt2, self.dt_secs())
            }
        };
        let friction = match (contacts, self.terms.friction_on()) {
            (Some(c), true) => super::losses::friction_contacts(
                &self.terms,
                &self.train,
                &self.avatar,
                batch,
                c,
                kept,
            )?,
            _ => None,
        };
        let dissipation = friction.as_ref().and_then(|fc| {
            let xt1 = stack_frames(x, 1, predicted - 1, b);
            self.terms.friction(x_t, &xt1, fc)
        });
        Ok(DynamicLosses {
            inertia,
            dissipation,
            friction,
        })
    }

    /// Metrics of a training step on its first few windows only ([`STEP_METRIC_WINDOWS`]):
    /// they are a noisy monitor anyway, and the full batch would cost a sizeable share of the
    /// step (validation uses every window). `x` is `[B, K, V, 3]`; `contacts` and `friction`
    /// are stacked over the loss frames.
    fn step_metrics(
        &self,
        x: &Tensor<4>,
        contacts: Option<Contacts>,
        friction: Option<FrictionContacts>,
        b: usize,
        predicted: usize,
    ) -> Result<ClothMetrics, TrainError> {
        let n = b.min(STEP_METRIC_WINDOWS);
        let head = |t: Tensor<3>| t.detach().narrow(0, 0, n);
        let history = History {
            x_t1: head(frame(x, predicted - 2)),
            x_t2: head(frame(x, predicted - 3)),
            dt_secs: self.dt_secs(),
            friction: friction.map(|fc| fc.narrow((predicted - 3) * b, n)),
        };
        // The last frame's block of the stacked contacts.
        let last = (predicted - 3) * b;
        let v = self.garment.vertex_count();
        let contacts = contacts.map(|c| Contacts {
            points: c.points.narrow(0, last, n),
            normals: c.normals.narrow(0, last, n),
            distances_m: c.distances_m[last * v..(last + n) * v].to_vec(),
            indices: c.indices[last * v..(last + n) * v].to_vec(),
        });
        Ok(self.terms.metrics(
            &head(frame(x, predicted - 1)),
            contacts.as_ref(),
            Some(&history),
        )?)
    }

    /// Posed bodies of the predicted frames `first..K` of `batch`, stacked frame by frame.
    fn bodies(
        &self,
        data: &Dataset,
        batch: &Batch,
        first: usize,
    ) -> Result<Option<BodyBatch>, TrainError> {
        if !self.terms.effects().collision {
            return Ok(None);
        }
        let bodies = data.bodies(&self.avatar, &batch.stacked_frames(first))?;
        Ok(Some(BodyBatch::new(bodies)))
    }

    /// Descriptors `[B, T, J, 9]` and `[B, T, J, 12]` of the probe windows that decide whether
    /// a unit is dead: [`VALIDATION_WINDOWS`] windows spread evenly over the validation motions
    /// and as many over the training motions (a validation split of one motion, e.g. a turn,
    /// shows nearly one pose: half of any layer would look dead on it alone).
    fn probe_descriptors(&self) -> (Tensor<4>, Option<Tensor<4>>) {
        let frames = self.window_frames();
        let (mut statics, mut dynamics) = (Vec::new(), Vec::new());
        let mut size = 0;
        for data in [&self.train, &self.validation] {
            let windows = data.even_windows(VALIDATION_WINDOWS);
            size += windows.len();
            data.append_descriptors(&windows, frames, &mut statics, &mut dynamics);
        }
        let j = self.train.input_joints;
        let statics = self.tensor4(statics, [size, frames, j, 9]);
        let dynamics = (self.model.kind() != neural_cloth_model::EncoderKind::StaticOnly)
            .then(|| self.tensor4(dynamics, [size, frames, j, 12]));
        (statics, dynamics)
    }

    /// Per-layer unit activity of the network on the probe windows.
    fn activity(&self) -> Result<Activity, TrainError> {
        let (statics, dynamics) = self.probe_descriptors();
        Ok(unit_activity(&self.model, statics, dynamics)?)
    }

    fn record(&self, metrics: &ClothMetrics, loss: f64) -> MetricRecord {
        MetricRecord::from_metrics(self.terms.fabric().cloth_model, metrics, loss)
    }

    /// Frames of the configured window at the training rate.
    fn window_frames(&self) -> usize {
        self.config.window_frames(self.fps)
    }

    /// Frames of a training step's batch: [`Self::batch_frames`], or with
    /// [`TrainConfig::gru_burn_in_random`] the window and a burn-in whose length is drawn
    /// for the step, uniformly from none to the configured one.
    fn step_batch_frames(&mut self) -> usize {
        let most = self.config.burn_in_frames(self.fps);
        let burn = match self.config.gru_burn_in_random && most > 0 {
            true => self.rng.random_range(0..=most),
            false => most,
        };
        self.window_frames() + burn
    }

    /// Frames of a batch: the window and the GRU burn-in before it.
    fn batch_frames(&self) -> usize {
        self.window_frames() + self.config.burn_in_frames(self.fps)
    }

    /// Time step between frames at the training rate, seconds.
    fn dt_secs(&self) -> f32 {
        1.0 / self.fps
    }
}

/// What [`NeuralSession::dynamic_losses`] returns (nothing without the dynamics effect).
#[derive(Default)]
struct DynamicLosses {
    /// Inertia (batch mean over the kept samples).
    inertia: Option<Tensor<1>>,
    /// Friction dissipation (batch mean over every sample).
    dissipation: Option<Tensor<1>>,
    /// Friction contacts of the loss frames.
    friction: Option<FrictionContacts>,
}

/// Whether the mirrored copies of the training motions are in the batches at step `steps`
/// of a run `progress` through its budget: both [`TrainConfig::mirror_from_step`] and
/// [`TrainConfig::mirror_from_fraction`] reached (an open-ended run reaches any fraction).
fn mirrored_joined(config: &TrainConfig, steps: u64, progress: Option<f64>) -> bool {
    steps >= config.mirror_from_step && progress.is_none_or(|p| p >= config.mirror_from_fraction)
}

/// `x[:, k]` as `[B, V, 3]`.
fn frame(x: &Tensor<4>, k: usize) -> Tensor<3> {
    let [b, _, v, c] = x.dims();
    x.clone().narrow(1, k, 1).reshape([b, v, c])
}

/// The first `rows` samples of frames `from..to` of `x` (`[B, K, V, 3]`), stacked frame by
/// frame: `[(to - from)·rows, V, 3]`, row `(k - from)·rows + s` holding sample `s` of frame `k`.
fn stack_frames(x: &Tensor<4>, from: usize, to: usize, rows: usize) -> Tensor<3> {
    let frames: Vec<Tensor<3>> = (from..to).map(|k| frame(x, k).narrow(0, 0, rows)).collect();
    Tensor::cat(frames, 0)
}

impl Session for NeuralSession {
    fn step(&mut self) -> Result<MetricRecord, TrainError> {
        let b = self.config.batch_size;
        let with_mirrored =
            mirrored_joined(&self.config, self.filter.steps_taken(), self.run_progress);
        // Noted when they join during this session, not when a resumed run has them already.
        if with_mirrored && self.mirrored_in == Some(false) && self.train.has_mirrored() {
            self.note = Some(format!(
                "from step {}, the mirrored copies of the training motions join the batches",
                self.filter.steps_taken() + 1
            ));
        }
        self.mirrored_in = Some(with_mirrored);
        let windows = self.train.sample_windows(b, with_mirrored, &mut self.rng);
        // Still windows come first, augmented ones last.
        let dynamics = self.terms.effects().dynamics;
        let augment = self.config.augmented_windows(b, dynamics);
        let still = self.config.still_windows(b, dynamics);
        let predicted = self.config.loss_frames + 2;
        let frames = self.step_batch_frames();
        // The fit to reference frames (warm start, diagnostic) keeps the batch whole.
        let split = self.config.split_batch && !self.fitting();
        let mut parts = Vec::new();
        for part in split::parts(b, still, augment, split) {
            let picks = match self.model.has_dynamic_branch() {
                true => forward::augmentation_picks(&mut self.rng, part.size(), part.augment),
                false => Vec::new(),
            };
            parts.push(self.part_batch(&windows, part, frames, predicted, picks));
        }
        let filters = self.step_filters()?;
        let outcomes = match parts.as_slice() {
            [whole] => vec![self.descend(&self.model, whole, &filters)?],
            [first, second] => {
                let (a, b) = (
                    split::fresh_leaves(&self.model),
                    split::fresh_leaves(&self.model),
                );
                let (a, b) = rayon::join(
                    || self.descend(&a, first, &filters),
                    || self.descend(&b, second, &filters),
                );
                vec![a?, b?]
            }
            _ => return Err(TrainError::Data("a step has one or two parts".into())),
        };
        let loss = outcomes.iter().map(|o| o.loss).sum::<f64>();
        let mut outcomes = outcomes.into_iter();
        let Some(head) = outcomes.next() else {
            return Err(TrainError::Data("a step has one or two parts".into()));
        };
        let grads = std::iter::once(head.grads)
            .chain(outcomes.map(|o| o.grads))
            .collect();
        let grads = split::sum_gradients(&self.model, grads);
        self.optim.step(
            self.learning_rate * self.schedule_factor,
            &mut self.model,
            grads,
        )?;
        self.filter.count_step();
        self.end_warm_start();
        // The metrics of the first windows, all in the first part.
        let metrics =
            self.step_metrics(&head.x, head.contacts, head.friction, head.size, predicted)?;
        if !self.config.keep_posed_bodies {
            self.train.forget_bodies();
        }
        Ok(self.record(&metrics, loss))
    }

    fn validate(&mut self) -> Result<MetricRecord, TrainError> {
        let data = if self.validation.is_empty() {
            &self.train
        } else {
            &self.validation
        };
        let windows = data.even_windows(VALIDATION_WINDOWS);
        if windows.is_empty() {
            return Err(TrainError::NoValidationFrames);
        }
        let batch = data.batch(&windows, self.batch_frames(), 3, &self.garment.skin);
        let (x, blended) = self.predict(&self.model, &batch, 0, &[]);
        let x = x.detach();
        let (x_t, x_t1, x_t2) = (frame(&x, 2), frame(&x, 1), frame(&x, 0));
        let data = if self.validation.is_empty() {
            &self.train
        } else {
            &self.validation
        };
        let (contacts, losses) = self.static_losses(data, &batch, &blended, 2, &x_t)?;
        let mut loss = losses
            .total()
            .map(|t| t.into_scalar::<f64>())
            .unwrap_or(0.0);
        if let Some(i) = self.terms.inertia(&x_t, &x_t1, &x_t2, self.dt_secs()) {
            loss += i.into_scalar::<f64>();
        }
        let friction = match &contacts {
            Some(c) => super::losses::friction_contacts(
                &self.terms,
                data,
                &self.avatar,
                &batch,
                c,
                batch.size,
            )?,
            None => None,
        };
        if let Some(d) = friction
            .as_ref()
            .and_then(|fc| self.terms.friction(&x_t, &x_t1, fc))
        {
            loss += d.into_scalar::<f64>();
        }
        let history = History {
            x_t1,
            x_t2,
            dt_secs: self.dt_secs(),
            friction,
        };
        let metrics = self
            .terms
            .metrics(&x_t, contacts.as_ref(), Some(&history))?;
        let activity = self.activity()?;
        let mut record = self.record(&metrics, loss);
        record.dead_units_pct = activity.worst_revivable_pct();
        self.activity = Some(activity);
        Ok(record)
    }

    fn activity_summary(&self) -> Option<String> {
        self.activity.as_ref().map(Activity::summary)
    }

    fn revive_dead_units(&mut self) -> Result<usize, TrainError> {
        let (statics, dynamics) = self.probe_descriptors();
        let [b, t, j, c] = statics.dims();
        let flat = statics.clone().detach().reshape([b * t, j * c]);
        let z = self.model.latent_code(statics, dynamics, 1.0).detach();
        let latent = z.dims()[2];
        let _rng = crate::device_rng_lock();
        let revived = revive_dead_units(
            &mut self.model,
            flat,
            z.reshape([b * t, latent]),
            self.init_std,
        )?;
        Ok(revived.iter().sum())
    }

    fn weights_finite(&self) -> bool {
        InferenceWeights::from_module(&self.model)
            .map(|w| w.validate().is_ok())
            .unwrap_or(false)
    }

    fn snapshot(&self) -> Result<ModelArtifact, TrainError> {
        let weights = InferenceWeights::from_module(&self.model)?;
        Ok(ModelArtifact::new(
            weights,
            self.descriptors.clone(),
            self.fps,
        ))
    }

    fn checkpoint(&mut self, step: u64, history: &MetricHistory) -> Result<PathBuf, TrainError> {
        let state = CheckpointState {
            step,
            learning_rate: self.learning_rate,
        };
        // With a weight average on, the checkpoint holds the average (what bakes and
        // compares read); training goes on with the optimiser's own weights.
        let model = self.optim.averaged(self.model.clone());
        let optim = &self.optim;
        self.run.write_checkpoint_from(
            state,
            Box::new(move |path| Ok(model.into_record().save(path)?)),
            Box::new(|path| Ok(optim.write_file(path)?)),
            history,
        )
    }

    fn restore_last_checkpoint(&mut self) -> Result<u64, TrainError> {
        let step = self.run.latest_step().ok_or(TrainError::NoCheckpointYet)?;
        self.load_checkpoint(step)?;
        Ok(step)
    }

    fn learning_rate(&self) -> f64 {
        self.learning_rate
    }

    fn set_learning_rate(&mut self, lr: f64) {
        self.learning_rate = lr;
    }

    fn set_schedule_factor(&mut self, factor: f64) {
        self.schedule_factor = factor;
    }

    fn set_run_progress(&mut self, progress: Option<f64>) {
        self.run_progress = progress;
    }

    fn take_note(&mut self) -> Option<String> {
        self.note.take()
    }

    fn set_fabric(&mut self, fabric: FabricParams) -> Result<(), TrainError> {
        let effects = *self.terms.effects();
        self.terms = PhysicsTerms::new(&self.garment, &fabric, &effects, &self.device)?
            .with_fused(self.config.fused_physics);
        self.filter.reset();
        Ok(())
    }

    fn set_window(&mut self, window_secs: f32) -> Result<(), TrainError> {
        let next = TrainConfig {
            window_secs,
            ..self.config.clone()
        };
        next.validate(self.fps)?;
        self.config = next;
        Ok(())
    }
}

#[cfg(test)]
mod tests;
