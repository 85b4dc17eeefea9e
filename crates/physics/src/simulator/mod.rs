//! Reference simulator: the paper's "standard simulation" baseline (Eq. 8). Each step finds
//! `x_t = argmin ½(x - x̃)ᵀM(x - x̃) + Δt² E(x)`, `x̃ = 2x_{t-1} - x_{t-2}`, which divided by
//! `Δt²` is exactly the training loss `L_inertia + L_static` — evaluated by the same
//! [`PhysicsTerms`] code with autodiff gradients. The minimiser is a Jacobi-preconditioned
//! L-BFGS whose iteration budget per step is the accuracy knob; nearest-vertex contacts with
//! the moving body are refreshed every few iterations.
//!
//! Without `dynamics` every step is a static solve (`min E`), the PBNS-like formulation.

mod residual;
mod sequence;

use std::sync::Arc;

use burn::tensor::{DType, Device, Tensor, TensorData};
use serde::{Deserialize, Serialize};

use neural_cloth_core::geometry::Vec3;

pub use residual::FrameResidual;
pub use sequence::{SimProgress, Simulation, settle_on_rest_pose, simulate, start_jitter};

use crate::collision::{BodyBatch, Contacts, PosedBody};
use crate::friction::FrictionContacts;
use crate::lbfgs::{self, InitialMetric, LbfgsOptions};
use crate::rest::GarmentRest;
use crate::sparse::EnvelopeCholesky;
use crate::tensors::{positions_tensor, read_f64};
use crate::{Effects, FabricParams, PhysicsError, PhysicsTerms};

/// Simulator settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimOptions {
    /// L-BFGS iterations per step: the accuracy knob. 1..=10000, default 40.
    pub iterations_per_step: usize,
    /// Steps per output frame (`Δt = 1 / (fps · substeps)`). 1..=64, default 1.
    pub substeps: usize,
    /// Iterations between nearest-vertex contact queries. 1..=10000, default 10.
    pub contact_refresh_every: usize,
    /// L-BFGS memory (correction pairs). 1..=64, default 8.
    pub lbfgs_memory: usize,
    /// Stop a step when the largest residual force is below this fraction of the mean vertex
    /// weight `m̄·|g|`. 0..=1, default 1e-3.
    pub tolerance: f64,
    /// Largest vertex displacement per L-BFGS step, in mean rest edge lengths. 0.01..=100,
    /// default 1.
    pub max_step_edges: f64,
    /// Seconds the first pose is held (garment settling) before the motion plays; not output.
    /// 0..=60, default 0.
    pub settle_secs: f32,
    /// Largest change of each coordinate of the settled garment before the motion plays, in
    /// metres: every vertex moves by its own deterministic pseudo-random offset
    /// ([`start_jitter`]), its velocity unchanged. How sensitive a motion's simulation is to
    /// an imperceptible change of its start (`compare --sensitivity`). 0..=0.01, default 0
    /// (none).
    pub start_jitter_m: f64,
}

impl Default for SimOptions {
    fn default() -> Self {
        Self {
            iterations_per_step: 40,
            substeps: 1,
            contact_refresh_every: 10,
            lbfgs_memory: 8,
            tolerance: 1e-3,
            max_step_edges: 1.0,
            settle_secs: 0.0,
            start_jitter_m: 0.0,
        }
    }
}

impl SimOptions {
    /// Checks the documented ranges.
    pub fn validate(&self) -> Result<(), PhysicsError> {
        let bad = |what: &str| Err(PhysicsError::InvalidOptions(what.to_string()));
        if !(1..=10_000).contains(&self.iterations_per_step) {
            return bad("iterations_per_step must be in 1..=10000");
        }
        if !(1..=64).contains(&self.substeps) {
            return bad("substeps must be in 1..=64");
        }
        if !(1..=10_000).contains(&self.contact_refresh_every)
            || !(1..=64).contains(&self.lbfgs_memory)
        {
            return bad("contact_refresh_every must be in 1..=10000 and lbfgs_memory in 1..=64");
        }
        if !(0.0..=1.0).contains(&self.tolerance) || !(0.01..=100.0).contains(&self.max_step_edges)
        {
            return bad("tolerance must be in [0, 1] and max_step_edges in [0.01, 100]");
        }
        if !(0.0..=60.0).contains(&self.settle_secs) {
            return bad("settle_secs must be in [0, 60]");
        }
        if !(0.0..=0.01).contains(&self.start_jitter_m) {
            return bad("start_jitter_m must be in [0, 0.01]");
        }
        Ok(())
    }
}

/// What one step (or output frame) of the simulation did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameReport {
    /// Objective `L_inertia + E` at the solution, joules.
    pub objective_j: f64,
    /// Largest residual force relative to the mean vertex weight (0 = exact equilibrium).
    pub residual: f64,
    /// L-BFGS iterations.
    pub iterations: usize,
    /// Objective evaluations (forward + backward passes).
    pub evaluations: usize,
    /// Potential energy `E` (cloth, bending, collision, gravity, pinning), joules.
    pub potential_j: f64,
    /// Kinetic energy `½ Σ m |x_t - x_{t-1}|² / Δt²`, joules.
    pub kinetic_j: f64,
}

/// Inputs of one step: the posed body (when collision is on), pinning targets (all
/// vertices; only pinned rows are used) and the skinned template that carries a quasi-static
/// solve along with the body.
#[derive(Clone, Debug, Default)]
pub struct StepInput {
    /// Body at the end of the step.
    pub body: Option<Arc<PosedBody>>,
    /// Body at the start of the step, for friction (the body's motion at the contacts). None:
    /// the body of the stepper's previous step ([`Stepper::step`]), or a body at rest
    /// ([`Stepper::residual_at`]).
    pub body_before: Option<Arc<PosedBody>>,
    /// Pinning targets at the end of the step.
    pub pin_targets: Option<Vec<Vec3>>,
    /// The garment template skinned to the pose at the end of the step. Without dynamics a
    /// step starts from the previous solution moved by the template's displacement since the
    /// previous step (where both steps had one), so the garment rides along with the body
    /// instead of being left behind where the body moved through it: a frictionless garment
    /// on a turning body otherwise lags, and fast turns pass the body through it (the dress
    /// on the spin, docs/TRAINING.md). Ignored with dynamics, whose inertia carries it.
    pub skinned: Option<Vec<Vec3>>,
}

/// Advances one garment step by step (batch of one) on an autodiff device.
#[derive(Debug)]
pub struct Stepper {
    terms: PhysicsTerms,
    /// Factor of `M/Δt² + K + pins` (no contacts).
    metric: Arc<EnvelopeCholesky>,
    /// Its triplets, to add contact stiffness for the vertices near the body.
    base_triplets: Vec<(usize, usize, f64)>,
    /// `2 k_c`, the Hessian of the collision penalty along the normal (0 without collision).
    contact_k: f64,
    /// Vertices closer than this to the body get `contact_k` in the metric, metres.
    contact_range_m: f64,
    /// The last metric with contact stiffness and the vertices it was built for: the same
    /// vertices give the same matrix, so its factor is reused (within a step and across
    /// steps) instead of computed again.
    contact_metric: Option<(Vec<usize>, Arc<EnvelopeCholesky>)>,
    x_t1: Vec<f64>,
    x_t2: Vec<f64>,
    /// The skinned template of the previous step, flattened (see [`StepInput::skinned`]).
    skinned_t1: Option<Vec<f64>>,
    /// The body of the previous step (friction's start of the step).
    body_t1: Option<Arc<PosedBody>>,
    dt_secs: f32,
    options: SimOptions,
    force_scale: f64,
    max_step_m: f64,
    value_noise: f64,
}

impl Stepper {
    /// A stepper starting at rest at `initial` positions. Uses `f64` tensors where `device`
    /// supports them (else `f32`), with autodiff enabled.
    pub fn new(
        rest: Arc<GarmentRest>,
        fabric: &FabricParams,
        effects: &Effects,
        initial: &[Vec3],
        dt_secs: f32,
        options: &SimOptions,
        device: &Device,
    ) -> Result<Self, PhysicsError> {
        options.validate()?;
        if !(dt_secs.is_finite() && dt_secs > 0.0 && dt_secs <= 1.0) {
            return Err(PhysicsError::InvalidOptions(format!(
                "time step {dt_secs} s is not in (0, 1]"
            )));
        }
        if initial.len() != rest.vertex_count()
            || initial.iter().any(|p| !p.iter().all(|v| v.is_finite()))
        {
            return Err(PhysicsError::InvalidGarment(format!(
                "initial state has {} (finite?) positions for {} vertices",
                initial.len(),
                rest.vertex_count()
            )));
        }
        let device = device.clone().autodiff();
        let f64_ok = device.supports_dtype(DType::F64);
        let dtype = if f64_ok { DType::F64 } else { DType::F32 };
        let dt2 = f64::from(dt_secs).powi(2);
        let mean_mass = rest.total_mass_kg / rest.vertex_count().max(1) as f64;
        // Initial L-BFGS metric: (M/Δt² + K + pins)⁻¹ with K the rest membrane stiffness.
        let mut triplets = rest.membrane_stiffness_triplets(fabric);
        let k_scale = triplets
            .iter()
            .filter(|(i, j, _)| i == j)
            .map(|t| t.2)
            .sum::<f64>()
            / rest.vertex_count().max(1) as f64;
        let regulariser = 1e-6 * k_scale + 1e-3 * mean_mass / dt2 + 1e-12;
        let pin_k = if effects.pinning {
            2.0 * f64::from(fabric.pinning_stiffness)
        } else {
            0.0
        };
        let mut pinned = vec![false; rest.vertex_count()];
        rest.pinned.iter().for_each(|&i| pinned[i as usize] = true);
        for (v, m) in rest.mass_kg.iter().enumerate() {
            let inertial = if effects.dynamics { m / dt2 } else { 0.0 };
            triplets.push((
                v,
                v,
                inertial + regulariser + if pinned[v] { pin_k } else { 0.0 },
            ));
        }
        let metric = Arc::new(EnvelopeCholesky::factor(rest.vertex_count(), &triplets)?);
        let contact_k = if effects.collision {
            2.0 * f64::from(fabric.collision_stiffness)
        } else {
            0.0
        };
        let g = f64::from(fabric.gravity().norm()).max(1.0);
        let x0 = flatten(initial);
        let terms = PhysicsTerms::from_rest(rest.clone(), fabric, effects, &device, dtype)?;
        Ok(Self {
            metric,
            base_triplets: triplets,
            contact_k,
            contact_range_m: 2.0 * f64::from(fabric.collision_threshold_m)
                + options.max_step_edges * rest.mean_edge_m,
            contact_metric: None,
            x_t1: x0.clone(),
            x_t2: x0,
            skinned_t1: None,
            body_t1: None,
            dt_secs,
            force_scale: (mean_mass * g).max(1e-30),
            max_step_m: options.max_step_edges * rest.mean_edge_m.max(1e-6),
            value_noise: if f64_ok { 1e-12 } else { 1e-6 },
            options: options.clone(),
            terms,
        })
    }

    /// Current positions (the last solved step).
    pub fn positions(&self) -> Vec<Vec3> {
        to_vec3(&self.x_t1)
    }

    /// Sets the two previous frames the next step starts from (`x_t2` before `x_t1`): a step
    /// taken from any trajectory's own history (the network's, in `compare`'s one-step
    /// check). Only the positions are set: the previous step's body (friction's start, see
    /// [`StepInput::body_before`]) and skinned template (static solves) stay the stepper's
    /// own, so give `body_before` with the next step. Refused unless both have a finite
    /// position per vertex.
    pub fn set_history(&mut self, x_t2: &[Vec3], x_t1: &[Vec3]) -> Result<(), PhysicsError> {
        let v = self.terms.rest().vertex_count();
        if x_t2.len() != v || x_t1.len() != v {
            return Err(PhysicsError::ShapeMismatch {
                what: "history frames".into(),
                expected: format!("{v} vertices"),
                found: format!("{}, {}", x_t2.len(), x_t1.len()),
            });
        }
        if [x_t2, x_t1]
            .iter()
            .any(|f| f.iter().any(|p| !p.iter().all(|c| c.is_finite())))
        {
            return Err(PhysicsError::NonFinite("history frames".into()));
        }
        self.x_t2 = flatten(x_t2);
        self.x_t1 = flatten(x_t1);
        Ok(())
    }

    /// Moves the garment by `offsets` (one per vertex) in both history frames, so that its
    /// velocity is unchanged. Refused unless there is a finite offset per vertex.
    pub fn displace(&mut self, offsets: &[Vec3]) -> Result<(), PhysicsError> {
        let v = self.terms.rest().vertex_count();
        if offsets.len() != v {
            return Err(PhysicsError::ShapeMismatch {
                what: "displacement".into(),
                expected: format!("{v} vertices"),
                found: offsets.len().to_string(),
            });
        }
        if offsets.iter().any(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(PhysicsError::NonFinite("displacement".into()));
        }
        for frame in [&mut self.x_t1, &mut self.x_t2] {
            for (x, d) in frame.chunks_exact_mut(3).zip(offsets) {
                x.iter_mut()
                    .zip(d.iter())
                    .for_each(|(x, d)| *x += f64::from(*d));
            }
        }
        Ok(())
    }

    /// The factor of `M/Δt² + K + pins` plus the contact stiffness at the vertices `near`,
    /// computed only when `near` differs from the last call's.
    fn metric_with_contacts(
        &mut self,
        near: Vec<usize>,
    ) -> Result<Arc<EnvelopeCholesky>, PhysicsError> {
        if let Some((set, metric)) = &self.contact_metric
            && *set == near
        {
            return Ok(metric.clone());
        }
        let mut t = self.base_triplets.clone();
        t.extend(near.iter().map(|&i| (i, i, self.contact_k)));
        let metric = Arc::new(EnvelopeCholesky::factor(self.metric.len(), &t)?);
        self.contact_metric = Some((near, metric.clone()));
        Ok(metric)
    }

    /// The terms the stepper evaluates.
    pub fn terms(&self) -> &PhysicsTerms {
        &self.terms
    }

    /// Solves one step and returns the new positions and what it took.
    pub fn step(&mut self, input: &StepInput) -> Result<(Vec<Vec3>, FrameReport), PhysicsError> {
        let effects = *self.terms.effects();
        let body = match (effects.collision, &input.body) {
            (true, Some(b)) => Some(BodyBatch::new(vec![b.clone()])),
            (true, None) => return Err(PhysicsError::MissingBody),
            (false, _) => None,
        };
        let (device, dtype) = (self.terms.device().clone(), self.terms.dtype());
        let v = self.terms.rest().vertex_count();
        let upload = |x: &[f64]| {
            Tensor::<3>::from_data(TensorData::new(x.to_vec(), [1, v, 3]), (&device, dtype))
        };
        let (x_t1, x_t2) = (upload(&self.x_t1), upload(&self.x_t2));
        let pin_target = match (&input.pin_targets, self.terms.tensors().pinned.is_some()) {
            (Some(t), true) => Some(positions_tensor(&[t.as_slice()], &device, dtype)?),
            _ => None,
        };
        let skinned = input
            .skinned
            .as_deref()
            .map(flatten)
            .filter(|s| s.len() == 3 * v);
        let mut x: Vec<f64> = match (effects.dynamics, &skinned, &self.skinned_t1) {
            (true, _, _) => self
                .x_t1
                .iter()
                .zip(&self.x_t2)
                .map(|(a, b)| 2.0 * a - b)
                .collect(),
            (false, Some(now), Some(before)) => self
                .x_t1
                .iter()
                .zip(now.iter().zip(before))
                .map(|(x, (n, b))| x + (n - b))
                .collect(),
            (false, _, _) => self.x_t1.clone(),
        };
        self.skinned_t1 = skinned;
        let mut report = FrameReport::default();
        let mut spent = 0;
        let lbfgs_opts = LbfgsOptions {
            memory: self.options.lbfgs_memory,
            grad_tolerance: self.options.tolerance * self.force_scale,
            max_step: self.max_step_m,
            value_noise: self.value_noise,
            ..Default::default()
        };
        let before = input
            .body_before
            .clone()
            .or_else(|| self.body_t1.clone())
            .or_else(|| input.body.clone())
            .map(|b| BodyBatch::new(vec![b]));
        let mut last_contacts: Option<Contacts>;
        let mut last_friction: Option<FrictionContacts>;
        let mut memory = lbfgs::Memory::new();
        loop {
            let contacts = match &body {
                Some(b) => {
                    let flat: Vec<f32> = x.iter().map(|&c| c as f32).collect();
                    Some(Contacts::query(b, &flat, v, &device, dtype)?)
                }
                None => None,
            };
            let friction = match (&contacts, &body, &before) {
                (Some(c), Some(now), Some(before)) => {
                    self.terms.friction_contacts(c, now, before, &[])?
                }
                _ => None,
            };
            // The metric with the contact stiffness of the vertices near the body.
            let near: Vec<usize> = contacts.as_ref().map_or_else(Vec::new, |c| {
                c.distances_m
                    .iter()
                    .enumerate()
                    .filter(|(_, d)| f64::from(**d) < self.contact_range_m)
                    .map(|(i, _)| i)
                    .collect()
            });
            let metric = if near.is_empty() || self.contact_k == 0.0 {
                self.metric.clone()
            } else {
                self.metric_with_contacts(near)?
            };
            let apply = |r: &[f64]| -> Vec<f64> {
                let mut columns: Vec<[f64; 3]> =
                    r.chunks_exact(3).map(|x| [x[0], x[1], x[2]]).collect();
                metric.solve3_in_place(&mut columns);
                columns.into_iter().flatten().collect()
            };
            let h0 = InitialMetric::Operator(&apply);
            let budget =
                (self.options.iterations_per_step - spent).min(self.options.contact_refresh_every);
            let opts = LbfgsOptions {
                max_iterations: budget,
                ..lbfgs_opts.clone()
            };
            let r = lbfgs::minimize_with_memory(&mut x, &h0, &opts, &mut memory, |xs| {
                self.objective(
                    &upload(xs),
                    contacts.as_ref(),
                    friction.as_ref(),
                    &x_t1,
                    &x_t2,
                    pin_target.as_ref(),
                    true,
                )
                .map(|(value, _, grad)| (value, grad))
            })?;
            spent += r.iterations;
            report.iterations += r.iterations;
            report.evaluations += r.evaluations;
            report.objective_j = r.value;
            report.residual = r.grad_inf / self.force_scale;
            last_contacts = contacts;
            last_friction = friction;
            let stalled = r.iterations < budget && !r.converged;
            if spent >= self.options.iterations_per_step
                || (r.converged && (r.iterations == 0 || body.is_none()))
                || stalled
            {
                break;
            }
        }
        if x.iter().any(|c| !c.is_finite()) {
            return Err(PhysicsError::NonFinite("simulated positions".into()));
        }
        let (_, potential, _) = self.objective(
            &upload(&x),
            last_contacts.as_ref(),
            last_friction.as_ref(),
            &x_t1,
            &x_t2,
            pin_target.as_ref(),
            false,
        )?;
        report.potential_j = potential;
        let dt2 = f64::from(self.dt_secs).powi(2);
        report.kinetic_j = self
            .terms
            .rest()
            .mass_kg
            .iter()
            .enumerate()
            .map(|(i, m)| {
                let d2: f64 = (0..3)
                    .map(|k| (x[3 * i + k] - self.x_t1[3 * i + k]).powi(2))
                    .sum();
                0.5 * m * d2 / dt2
            })
            .sum();
        self.x_t2 = std::mem::replace(&mut self.x_t1, x);
        self.body_t1 = input.body.clone();
        Ok((self.positions(), report))
    }

    /// `(objective, potential part, gradient)`; the gradient is empty when `grad` is false.
    /// The objective holds friction's dissipation (with `friction`), the potential part not.
    #[allow(clippy::too_many_arguments)]
    fn objective(
        &self,
        x: &Tensor<3>,
        contacts: Option<&Contacts>,
        friction: Option<&FrictionContacts>,
        x_t1: &Tensor<3>,
        x_t2: &Tensor<3>,
        pin_target: Option<&Tensor<3>>,
        grad: bool,
    ) -> Result<(f64, f64, Vec<f64>), PhysicsError> {
        let x = if grad {
            x.clone().require_grad()
        } else {
            x.clone()
        };
        let mut potential = self
            .terms
            .static_energies(&x, contacts)?
            .into_iter()
            .map(|(_, e)| e)
            .reduce(|a, b| a + b);
        if let Some(p) = pin_target.and_then(|target| self.terms.pinning(&x, target)) {
            potential = Some(match potential {
                Some(e) => e + p,
                None => p,
            });
        }
        let potential = potential.unwrap_or_else(|| self.terms.tensors().zeros(1));
        let mut total = match self.terms.inertia(&x, x_t1, x_t2, self.dt_secs) {
            Some(inertia) => potential.clone() + inertia,
            None => potential.clone(),
        };
        if let Some(d) = friction.and_then(|fc| self.terms.friction(&x, x_t1, fc)) {
            total = total + d;
        }
        let value = read_f64(total.clone().detach())?
            .first()
            .copied()
            .unwrap_or(f64::NAN);
        let pot = read_f64(potential.detach())?
            .first()
            .copied()
            .unwrap_or(f64::NAN);
        if !grad {
            return Ok((value, pot, Vec::new()));
        }
        let grads = total.backward();
        let g = x
            .grad(&grads)
            .ok_or_else(|| PhysicsError::Backend("no gradient for positions".into()))?;
        Ok((value, pot, read_f64(g)?))
    }
}

/// `[x0, y0, z0, x1, ...]` in `f64`.
fn flatten(points: &[Vec3]) -> Vec<f64> {
    points
        .iter()
        .flat_map(|p| [f64::from(p.x), f64::from(p.y), f64::from(p.z)])
        .collect()
}

fn to_vec3(x: &[f64]) -> Vec<Vec3> {
    x.chunks_exact(3)
        .map(|c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32))
        .collect()
}
