//! A fused Adam: one pass over each parameter and its two moments on the host.
//!
//! burn's [`AdamConfig`] runs Adam as a chain of tensor operations (two for each moment, a
//! square, a square root, scalings, a division and the subtraction), each a full pass over the
//! parameter that allocates a new tensor: on the default network (about 10 M parameters, the
//! decoder basis and the dynamic basis `[512, V·3]` each) that was the largest share of a
//! training step after the network itself. [`FusedAdam`] does the same arithmetic, in the same
//! order and precision (so the same numbers), in one pass over `(θ, g, m, v)` in place, rayon
//! chunks over the host `f32` buffers of the CPU backend.
//!
//! The state is saved in burn's own optimiser record (burnpack tensors
//! `"{param id}.momentum.moment_1"` and `".moment_2"`, scalars `".momentum.time"` and
//! `".__rank"`), so a checkpoint written by either optimiser resumes with the other.
//! [`TrainOptimiser`] picks one: fused on the CPU backend, burn's where parameters do not live
//! on the host (`--backend wgpu`) or when [`super::TrainConfig::fused_adam`] is off.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use burn::module::{Module, ModuleMapper, Param, ParamId};
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Bytes, DType, Tensor, TensorData};
use burn_pack::{Reader, Scalar, Writer};

use super::config::{BackendKind, BasisRowNorm, TrainConfig};

#[path = "adam_kernels.rs"]
mod kernels;
use kernels::{update_all, update_rows};

/// Adam's first-moment decay (burn's default, [`AdamConfig::new`]).
pub const BETA_1: f32 = 0.9;
/// Adam's second-moment decay (burn's default).
pub const BETA_2: f32 = 0.999;
/// Adam's epsilon (burn's default; burn scales it by the bias correction, see
/// [`Coefficients`]).
pub const EPSILON: f32 = 1e-5;

/// Values per rayon task of the update (a quarter of a megabyte of each of the four buffers).
const CHUNK: usize = 1 << 16;

/// Errors of the fused optimiser.
#[derive(Debug, thiserror::Error)]
pub enum AdamError {
    /// A parameter or gradient is not `f32` (the fused update is single precision only).
    #[error("the fused Adam updates f32 parameters only; parameter {id} is {dtype:?}")]
    DType {
        /// Parameter id.
        id: u64,
        /// Its element type.
        dtype: DType,
    },
    /// The saved moments of a parameter do not match it.
    #[error(
        "optimiser state of parameter {id} ({path}) holds {found} values, the parameter {expected}: \
         the checkpoint's optimiser state belongs to another network"
    )]
    StateSize {
        /// Parameter id.
        id: u64,
        /// Parameter path in the module.
        path: String,
        /// Values of the parameter.
        expected: usize,
        /// Values of the saved moments.
        found: usize,
    },
    /// A parameter's values could not be read or written on the host.
    #[error("parameter {id}: {reason}")]
    Host {
        /// Parameter id.
        id: u64,
        /// What failed.
        reason: String,
    },
    /// The saved optimiser state is not an Adam record this program can read.
    #[error("optimiser state: {0}")]
    Record(String),
}

/// The moments of one parameter.
#[derive(Clone, Debug)]
struct Moments {
    /// Steps taken (burn's `time`; the bias correction uses it).
    time: usize,
    /// First moment, as many values as the parameter (shared with a record being written,
    /// which copies one moment at a time; [`Arc::make_mut`] copies only while one is).
    m: Arc<Vec<f32>>,
    /// Second moment.
    v: Arc<Vec<f32>>,
    /// Shape of the parameter (the record stores the moments with it).
    shape: Vec<usize>,
    /// Path of the parameter in the module (kept in the record, as burn does).
    path: Option<String>,
    /// Moving average of the parameter ([`FusedAdam::with_weight_average`]); not in the
    /// record (a checkpoint holds the average as its weights).
    average: Option<Vec<f32>>,
}

/// The moments of one parameter as read from a record, before both are checked present.
struct SavedMoments {
    m: Option<Vec<f32>>,
    v: Option<Vec<f32>>,
    shape: Vec<usize>,
}

/// The per-step scalars of burn's Adam, computed as burn computes them (all `f32`).
#[derive(Clone, Copy, Debug)]
struct Coefficients {
    beta_1: f32,
    one_minus_beta_1: f32,
    beta_2: f32,
    one_minus_beta_2: f32,
    /// `sqrt(1 - β₂ᵗ) / (1 - β₁ᵗ)`.
    combined: f32,
    /// `ε · sqrt(1 - β₂ᵗ)`.
    epsilon: f32,
    /// The learning rate as the tensor scalar burn multiplies by.
    lr: f32,
}

impl Coefficients {
    fn new(beta_1: f32, beta_2: f32, epsilon: f32, time: usize, lr: f64) -> Self {
        let t = time as i32;
        let bias_correction2_sqrt = (1.0 - beta_2.powi(t)).sqrt();
        Self {
            beta_1,
            one_minus_beta_1: 1.0 - beta_1,
            beta_2,
            one_minus_beta_2: 1.0 - beta_2,
            combined: bias_correction2_sqrt / (1.0 - beta_1.powi(t)),
            epsilon: epsilon * bias_correction2_sqrt,
            lr: lr as f32,
        }
    }
}

/// Adam with burn's formula and defaults, updating every parameter in one fused host pass.
#[derive(Clone, Debug)]
pub struct FusedAdam {
    beta_1: f32,
    beta_2: f32,
    epsilon: f32,
    /// Which decoder bases have each row normalised by one second moment
    /// ([`super::TrainConfig::basis_row_norm`]).
    basis_row_norm: BasisRowNorm,
    /// Decay of the weights' moving average ([`super::TrainConfig::weight_average`]; 0: none).
    average_decay: f32,
    states: HashMap<ParamId, Moments>,
}

impl Default for FusedAdam {
    fn default() -> Self {
        Self {
            beta_1: BETA_1,
            beta_2: BETA_2,
            epsilon: EPSILON,
            basis_row_norm: BasisRowNorm::Off,
            average_decay: 0.0,
            states: HashMap::new(),
        }
    }
}

impl FusedAdam {
    /// A fresh optimiser with burn's defaults (`AdamConfig::new()`).
    pub fn new() -> Self {
        Self::default()
    }

    /// The same optimiser, normalising each row of the decoder bases that `which` names
    /// (`[latent, V·3]` weights at module path `…basis` or `…dynamic_basis`) by one second
    /// moment shared by the row's entries ([`super::TrainConfig::basis_row_norm`]); every
    /// other parameter keeps burn's per-value Adam. The saved record keeps its format: the
    /// shared moment is stored in every entry of its row.
    pub fn with_basis_row_norm(mut self, which: BasisRowNorm) -> Self {
        self.basis_row_norm = which;
        self
    }

    /// The same optimiser, keeping beside each parameter its exponential moving average with
    /// decay `decay` (0: none), `min(decay, (1 + t) / (10 + t))` at the parameter's step `t`
    /// ([`super::TrainConfig::weight_average`]); [`FusedAdam::averaged`] reads it.
    pub fn with_weight_average(mut self, decay: f32) -> Self {
        self.average_decay = decay;
        self
    }

    /// `module` with each parameter that has a moving average replaced by it (the others
    /// as they are); `module` itself without an average.
    pub fn averaged<M: Module>(&self, module: M) -> M {
        if self.average_decay <= 0.0 {
            return module;
        }
        module.map(&mut AverageMapper { adam: self })
    }

    /// Updates every parameter of `module` that has a gradient in `grads` with learning rate
    /// `lr`; parameters without one keep their value and state (as burn's does).
    ///
    /// The module is taken out of `module` for the update (a hollow copy with empty tensors
    /// stands in meanwhile), so that its parameter buffers are not shared and are updated in
    /// place. On an error the parameters already updated stay updated; a parameter whose
    /// buffers could not be read is left as zeros (a session then rolls back or stops).
    pub fn step<M: Module + Clone>(
        &mut self,
        lr: f64,
        module: &mut M,
        grads: GradientsParams,
    ) -> Result<(), AdamError> {
        let hollow = module.clone().map(&mut Hollow);
        let owned = std::mem::replace(module, hollow);
        let mut mapper = StepMapper {
            adam: self,
            grads,
            lr,
            path: Vec::new(),
            error: None,
        };
        *module = owned.map(&mut mapper);
        match mapper.error {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// Checks that `value` and `grad` can be updated (f32, moments of the right size).
    fn check<const D: usize>(
        &self,
        id: ParamId,
        path: &str,
        value: &Tensor<D>,
        grad: &Tensor<D>,
    ) -> Result<(), AdamError> {
        for dtype in [value.dtype(), grad.dtype()] {
            if dtype != DType::F32 {
                return Err(AdamError::DType {
                    id: id.val(),
                    dtype,
                });
            }
        }
        let n = value.shape().num_elements();
        match self.states.get(&id) {
            Some(s) if s.m.len() != n || s.v.len() != n => Err(AdamError::StateSize {
                id: id.val(),
                path: path.to_string(),
                expected: n,
                found: s.m.len().min(s.v.len()),
            }),
            _ if grad.shape().num_elements() != n => Err(AdamError::Host {
                id: id.val(),
                reason: format!("gradient of {} values", grad.shape().num_elements()),
            }),
            _ => Ok(()),
        }
    }

    /// One parameter ([`FusedAdam::check`]ed): host buffers of value and gradient, the value
    /// and the moments updated in place.
    fn update<const D: usize>(
        &mut self,
        id: ParamId,
        path: String,
        value: Tensor<D>,
        grad: Tensor<D>,
        lr: f64,
    ) -> Result<Tensor<D>, AdamError> {
        let device = value.device();
        let shape = value.dims().to_vec();
        let host = |e: String| AdamError::Host {
            id: id.val(),
            reason: e,
        };
        let mut data = value.try_into_data().map_err(|e| host(e.to_string()))?;
        let grad = grad.try_into_data().map_err(|e| host(e.to_string()))?;
        let g = grad.as_slice::<f32>().map_err(|e| host(format!("{e:?}")))?;
        let p = data
            .as_mut_slice::<f32>()
            .map_err(|e| host(format!("{e:?}")))?;
        let n = p.len();
        let moments = self.states.entry(id).or_insert_with(|| Moments {
            time: 0,
            m: Arc::new(vec![0.0; n]),
            v: Arc::new(vec![0.0; n]),
            shape: shape.clone(),
            path: Some(path),
            average: None,
        });
        moments.time += 1;
        moments.shape = shape;
        let k = Coefficients::new(self.beta_1, self.beta_2, self.epsilon, moments.time, lr);
        let row_len = self
            .basis_row_norm
            .covers(moments.path.as_deref(), &moments.shape)
            .then(|| moments.shape[1]);
        let (m, v) = (Arc::make_mut(&mut moments.m), Arc::make_mut(&mut moments.v));
        match row_len {
            Some(row_len) => update_rows(p, g, m, v, row_len, &k),
            None => update_all(p, g, m, v, &k),
        }
        if self.average_decay > 0.0 {
            let t = moments.time as f32;
            let decay = self.average_decay.min((1.0 + t) / (10.0 + t));
            match &mut moments.average {
                Some(a) if a.len() == p.len() => update_average(a, p, decay),
                average => *average = Some(p.to_vec()),
            }
        }
        Ok(Tensor::from_data(data, &device))
    }

    /// The state as burn's Adam record (burnpack bytes, the `optimizer.bpk` of a checkpoint).
    pub fn to_bytes(&self) -> Result<Bytes, AdamError> {
        self.record_writer()
            .into_bytes()
            .map_err(|e| AdamError::Record(e.to_string()))
    }

    /// Writes [`Self::to_bytes`]'s record to `path` (replacing it atomically, synced), one
    /// moment at a time: the largest moment is the only copy held (21 MB on the default scene,
    /// against the 216 MB of copied and packed moments that the bytes cost).
    pub fn write_file(&self, path: &Path) -> Result<(), AdamError> {
        self.record_writer()
            .auto_extension(false)
            .write_to_file(path)
            .map_err(|e| AdamError::Record(format!("{e}: {}", path.display())))
    }

    /// The record's layout, each moment a deferred tensor copied when the writer reaches it.
    fn record_writer(&self) -> Writer {
        let mut tensors = Vec::with_capacity(2 * self.states.len());
        let mut scalars = Vec::with_capacity(2 * self.states.len());
        let mut paths = Vec::new();
        for (id, s) in &self.states {
            let prefix = id.val().to_string();
            for (leaf, values) in [("moment_1", &s.m), ("moment_2", &s.v)] {
                let values = Arc::clone(values);
                let shape = s.shape.clone();
                tensors.push(burn_pack::Tensor::deferred(
                    format!("{prefix}.momentum.{leaf}"),
                    DType::F32,
                    shape.clone(),
                    Some(id.val()),
                    std::mem::size_of_val(values.as_slice()),
                    move || {
                        Ok(TensorData::new(values.as_ref().clone(), shape.clone())
                            .into_parts()
                            .0)
                    },
                ));
            }
            scalars.push((format!("{prefix}.momentum.time"), Scalar::from(s.time)));
            scalars.push((format!("{prefix}.__rank"), Scalar::from(s.shape.len())));
            if let Some(path) = &s.path {
                paths.push((prefix, path.clone()));
            }
        }
        let mut writer = Writer::new(tensors);
        for (key, value) in scalars {
            writer = writer.with_scalar(&key, value);
        }
        for (key, value) in paths {
            writer = writer.with_metadata(&key, &value);
        }
        writer
    }

    /// Reads a state written by [`FusedAdam::to_bytes`] or by burn's `ModuleOptimizer` for
    /// Adam; a record of another optimiser (no Adam moments) or with AMSGrad is refused.
    pub fn from_bytes(bytes: Bytes) -> Result<Self, AdamError> {
        let record = |e: String| AdamError::Record(e);
        let reader = Reader::from_bytes(bytes).map_err(|e| record(e.to_string()))?;
        let scalars = reader.scalars().clone();
        let paths = reader.metadata().clone();
        let mut moments: HashMap<u64, SavedMoments> = HashMap::new();
        for tensor in reader.into_tensors().map_err(|e| record(e.to_string()))? {
            let (name, dtype, shape, param_id, bytes) =
                tensor.into_parts().map_err(|e| record(e.to_string()))?;
            let values = TensorData::from_bytes(bytes, shape.clone(), dtype)
                .convert::<f32>()
                .try_into_vec::<f32>()
                .map_err(|e| record(format!("{name}: {e:?}")))?;
            let id = param_id.ok_or_else(|| record(format!("tensor {name} has no parameter")))?;
            let slot = moments.entry(id).or_insert_with(|| SavedMoments {
                m: None,
                v: None,
                shape: shape.to_vec(),
            });
            match name.rsplit_once('.').map(|(_, leaf)| leaf) {
                Some("moment_1") => slot.m = Some(values),
                Some("moment_2") => slot.v = Some(values),
                _ => {
                    return Err(record(format!(
                        "tensor {name} is not an Adam moment (another optimiser, or AMSGrad)"
                    )));
                }
            }
        }
        let mut adam = Self::default();
        for (id, SavedMoments { m, v, shape }) in moments {
            let (Some(m), Some(v)) = (m, v) else {
                return Err(record(format!("parameter {id} lacks one of its moments")));
            };
            let time = scalars
                .get(&format!("{id}.momentum.time"))
                .and_then(|s| usize::try_from(*s).ok())
                .ok_or_else(|| record(format!("parameter {id} has no step count")))?;
            let path = paths.get(&id.to_string()).cloned();
            let state = Moments {
                time,
                m: Arc::new(m),
                v: Arc::new(v),
                shape,
                path,
                average: None,
            };
            adam.states.insert(ParamId::from(id), state);
        }
        Ok(adam)
    }
}

/// Walks the module like burn's optimiser mapper: each float parameter with a gradient is
/// updated on the inner (non-autodiff) backend and put back with its autodiff settings.
struct StepMapper<'a> {
    adam: &'a mut FusedAdam,
    grads: GradientsParams,
    lr: f64,
    path: Vec<String>,
    error: Option<AdamError>,
}

impl ModuleMapper for StepMapper<'_> {
    fn enter_module(&mut self, name: &str, _container_type: &str) {
        self.path.push(name.to_string());
    }

    fn exit_module(&mut self, _name: &str, _container_type: &str) {
        self.path.pop();
    }

    fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
        let (id, tensor, mapper) = param.consume();
        let grad = match (self.error.is_none(), self.grads.remove::<D>(id)) {
            (true, Some(grad)) => grad.inner(),
            _ => return Param::from_mapped_value(id, tensor, mapper),
        };
        let path = self.path.join(".");
        if let Err(e) = self.adam.check(id, &path, &tensor, &grad) {
            self.error = Some(e);
            return Param::from_mapped_value(id, tensor, mapper);
        }
        let require_grad = tensor.is_require_grad();
        let checkpointing = tensor.gradient_checkpointing_strategy();
        let autodiff = tensor.is_autodiff();
        let device = tensor.device();
        let shape = tensor.shape();
        let updated = match self.adam.update(id, path, tensor.inner(), grad, self.lr) {
            Ok(t) => t,
            Err(e) => {
                self.error = Some(e);
                Tensor::zeros(shape, &device).inner()
            }
        };
        let mut updated = if autodiff {
            Tensor::from_inner(updated)
        } else {
            updated
        };
        if let (true, Some(strategy)) = (autodiff, checkpointing) {
            updated = updated.with_gradient_checkpointing_strategy(strategy);
        }
        if require_grad {
            updated = updated.require_grad();
        }
        Param::from_mapped_value(id, updated, mapper)
    }
}

/// `a ← d·a + (1 - d)·p` over the values, in parallel chunks.
fn update_average(a: &mut [f32], p: &[f32], decay: f32) {
    use rayon::prelude::*;
    a.par_chunks_mut(CHUNK)
        .zip(p.par_chunks(CHUNK))
        .for_each(|(a, p)| {
            for (a, &p) in a.iter_mut().zip(p) {
                *a = decay * *a + (1.0 - decay) * p;
            }
        });
}

/// Replaces each float parameter that has a moving average by it ([`FusedAdam::averaged`]),
/// keeping the parameter's id and settings.
struct AverageMapper<'a> {
    adam: &'a FusedAdam,
}

impl ModuleMapper for AverageMapper<'_> {
    fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
        let (id, tensor, mapper) = param.consume();
        let Some(average) = self
            .adam
            .states
            .get(&id)
            .and_then(|s| s.average.as_ref())
            .filter(|a| a.len() == tensor.shape().num_elements())
        else {
            return Param::from_mapped_value(id, tensor, mapper);
        };
        let require_grad = tensor.is_require_grad();
        let data = TensorData::new(average.clone(), tensor.shape());
        let mut averaged = Tensor::from_data(data, &tensor.device());
        if require_grad {
            averaged = averaged.require_grad();
        }
        Param::from_mapped_value(id, averaged, mapper)
    }
}

/// Maps every float parameter to an empty tensor: the stand-in of [`FusedAdam::step`] (so the
/// real parameters are owned by the step alone).
struct Hollow;

impl ModuleMapper for Hollow {
    fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
        let (id, tensor, mapper) = param.consume();
        let empty = Tensor::empty([0; D], &tensor.device());
        Param::from_mapped_value(id, empty, mapper)
    }
}

/// The optimiser of a training session: burn's Adam or the fused one (same formula, same
/// record format).
#[derive(Clone)]
pub enum TrainOptimiser {
    /// burn's `ModuleOptimizer` with `AdamConfig::new()` (any backend).
    Burn(ModuleOptimizer),
    /// [`FusedAdam`] (parameters on the host: the CPU backend).
    Fused(FusedAdam),
}

impl TrainOptimiser {
    /// A fresh optimiser: fused when `fused` (the caller checks the backend keeps parameters
    /// on the host), else burn's.
    pub fn new(fused: bool) -> Self {
        if fused {
            Self::Fused(FusedAdam::new())
        } else {
            Self::Burn(AdamConfig::new().init())
        }
    }

    /// The optimiser `config` asks for: fused when [`TrainConfig::fused_adam`] is on and the
    /// backend is the CPU one (whose parameters live on the host), burn's otherwise.
    pub fn for_config(config: &TrainConfig) -> Self {
        match Self::new(config.fused_adam && config.backend == BackendKind::Cpu)
            .with_basis_row_norm(config.basis_row_norm)
        {
            Self::Fused(adam) => Self::Fused(adam.with_weight_average(config.weight_average)),
            burn => burn,
        }
    }

    /// The same optimiser with [`FusedAdam::with_basis_row_norm`] set (burn's Adam has no
    /// such mode: [`TrainConfig::validate`] refuses the setting without the fused one).
    pub fn with_basis_row_norm(self, which: BasisRowNorm) -> Self {
        match self {
            Self::Fused(adam) => Self::Fused(adam.with_basis_row_norm(which)),
            burn => burn,
        }
    }

    /// `module` with its parameters replaced by their moving averages where the fused
    /// optimiser keeps them ([`FusedAdam::averaged`]); `module` itself otherwise.
    pub fn averaged<M: Module>(&self, module: M) -> M {
        match self {
            Self::Fused(adam) => adam.averaged(module),
            Self::Burn(_) => module,
        }
    }

    /// True for the fused optimiser.
    pub fn is_fused(&self) -> bool {
        matches!(self, Self::Fused(_))
    }

    /// One Adam step of `module` with `grads` at learning rate `lr`.
    pub fn step<M: Module + Clone>(
        &mut self,
        lr: f64,
        module: &mut M,
        grads: GradientsParams,
    ) -> Result<(), AdamError> {
        match self {
            Self::Burn(optim) => {
                *module = optim.step(lr, module.clone(), grads);
                Ok(())
            }
            Self::Fused(adam) => adam.step(lr, module, grads),
        }
    }

    /// The state as burn's optimiser record (the checkpoint's `optimizer.bpk`).
    pub fn to_bytes(&self) -> Result<Bytes, AdamError> {
        match self {
            Self::Burn(optim) => optim
                .into_bytes()
                .map_err(|e| AdamError::Record(e.to_string())),
            Self::Fused(adam) => adam.to_bytes(),
        }
    }

    /// Writes [`Self::to_bytes`]'s record to `path`, synced; the fused optimiser streams it
    /// ([`FusedAdam::write_file`]).
    pub fn write_file(&self, path: &Path) -> Result<(), AdamError> {
        match self {
            Self::Burn(_) => super::checkpoint::write_synced(path, &self.to_bytes()?, path)
                .map_err(|e| AdamError::Record(e.to_string())),
            Self::Fused(adam) => adam.write_file(path),
        }
    }

    /// The same kind of optimiser with the state of `bytes` (written by either kind).
    pub fn load_bytes(&self, bytes: Bytes) -> Result<Self, AdamError> {
        match self {
            Self::Burn(_) => AdamConfig::new()
                .init()
                .from_bytes(bytes)
                .map(Self::Burn)
                .map_err(|e| AdamError::Record(e.to_string())),
            Self::Fused(adam) => FusedAdam::from_bytes(bytes).map(|loaded| {
                Self::Fused(
                    loaded
                        .with_basis_row_norm(adam.basis_row_norm)
                        .with_weight_average(adam.average_decay),
                )
            }),
        }
    }
}

#[cfg(test)]
#[path = "adam_tests.rs"]
mod tests;
