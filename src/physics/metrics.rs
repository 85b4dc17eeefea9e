//! Metrics of paper §4.2, computed by the same tensor code as the losses: in-plane deformation
//! (edge elongation and strain, Baraff-Witkin stretch/shear, Green strain), mean dihedral
//! error, percentage of vertices inside the body, gravity potential and inertia.
//!
//! They are pure functions of meshes: [`PhysicsTerms::metrics`] takes a `[B, V, 3]` batch (e.g.
//! network output) and [`sequence_metrics`] any sequence of garment frames.

use std::sync::Arc;

use burn::tensor::Tensor;

use crate::geometry::Vec3;

use super::collision::{self, BodyBatch, Contacts, PosedBody};
use super::energies;
use super::tensors::{per_sample, positions_tensor, read_f64};
use super::{PhysicsError, PhysicsTerms};

/// Batch-averaged metrics. Lower is not always better (see paper §4.2): only strain and
/// collisions have an obvious goal.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ClothMetrics {
    /// Mean absolute edge elongation `|l - l̄|`, metres (the mass-spring "edge" metric).
    pub edge_elongation_m: f64,
    /// Mean relative edge strain `(l - l̄)/l̄` (positive: stretched), unitless.
    pub edge_strain: f64,
    /// Area-weighted mean Baraff-Witkin stretch `(|s_u| + |s_v|)/2`, unitless.
    pub stretch: f64,
    /// Area-weighted mean absolute Baraff-Witkin shear `|w_u·w_v|`, unitless.
    pub shear: f64,
    /// Area-weighted mean Frobenius norm of the Green strain, unitless (the StVK "strain").
    pub green_strain: f64,
    /// Mean absolute dihedral change w.r.t. rest over usable hinges, radians.
    pub bending_rad: f64,
    /// Percentage of colliding vertices inside the body (`d < 0`), when a body was given.
    pub collision_pct: Option<f64>,
    /// Gravity potential `-Σ m x·g`, joules (relative to the origin).
    pub gravity_j: f64,
    /// Inertia energy `Σ m |x - x̃|² / (2Δt²)`, joules, when two previous frames were given.
    pub inertia_j: Option<f64>,
    /// Mass-weighted mean distance `|x - x̃|`, metres, when two previous frames were given.
    pub inertia_m: Option<f64>,
}

/// Two previous frames and the time step, for the inertia metric.
#[derive(Clone, Debug)]
pub struct History {
    /// `x_{t-1}`, `[B, V, 3]`.
    pub x_t1: Tensor<3>,
    /// `x_{t-2}`, `[B, V, 3]`.
    pub x_t2: Tensor<3>,
    /// Time step in seconds.
    pub dt_secs: f32,
}

impl PhysicsTerms {
    /// Metrics of the batch `x` (`[B, V, 3]`), averaged over the batch. Every metric is
    /// computed whatever the effects are, except that bending needs the hinges (uploaded with
    /// the bending effect), collision needs `contacts` and inertia `history`, each of the same
    /// shape as `x` (otherwise that metric is left out).
    pub fn metrics(
        &self,
        x: &Tensor<3>,
        contacts: Option<&Contacts>,
        history: Option<&History>,
    ) -> Result<ClothMetrics, PhysicsError> {
        let b = self.tensors().batch_of(x)?;
        let x = x.clone().detach();
        let rt = self.tensors();
        let rest = self.rest();
        let mean = |t: Tensor<1>| -> Result<f64, PhysicsError> {
            Ok(read_f64(t)?.iter().sum::<f64>() / b as f64)
        };
        let mut m = ClothMetrics::default();
        if let (Some(len), Some(rest_len)) = (energies::edge_lengths(&x, rt), rt.edge_rest.as_ref())
        {
            let ne = rest.edges.len().max(1) as f64;
            let d = len - rest_len.clone();
            m.edge_elongation_m = mean(per_sample(d.clone().abs()))? / ne;
            m.edge_strain = mean(per_sample(d / rest_len.clone()))? / ne;
        }
        let total_area2 = 2.0 * rest.total_area_m2;
        if let (Some((su, sv, sh)), Some(area2)) =
            (energies::stretch_and_shear(&x, rt), rt.face_area2.as_ref())
        {
            let w = |t: Tensor<3>| {
                per_sample(t * area2.clone()).div_scalar(total_area2.max(f64::MIN_POSITIVE))
            };
            m.stretch = mean(w((su.abs() + sv.abs()).mul_scalar(0.5)))?;
            m.shear = mean(w(sh.abs()))?;
        }
        if let (Some((g00, g11, g01)), Some(area2)) =
            (energies::green_strain(&x, rt), rt.face_area2.as_ref())
        {
            let frob = (g00.square() + g11.square() + g01.square().mul_scalar(2.0)).sqrt();
            m.green_strain = mean(
                per_sample(frob * area2.clone()).div_scalar(total_area2.max(f64::MIN_POSITIVE)),
            )?;
        }
        if let (Some(delta), Some([weight, ..])) =
            (energies::dihedral_change(&x, rt), rt.hinge_consts.as_ref())
        {
            let usable = rest
                .hinge_weight
                .iter()
                .filter(|w| **w > 0.0)
                .count()
                .max(1) as f64;
            // weight >= 0, so its sign is the 0/1 mask of usable hinges.
            m.bending_rad = mean(per_sample(delta.abs() * weight.clone().sign()))? / usable;
        }
        if let Some(contacts) = contacts.filter(|c| c.points.dims() == x.dims()) {
            let colliding = rest.collide.iter().filter(|c| **c).count();
            if let Some(frac) = collision::inside_fraction(&x, contacts, rt, colliding) {
                m.collision_pct = Some(100.0 * mean(frac)?);
            }
        }
        m.gravity_j = mean(energies::gravity(&x, rt))?;
        if let Some(h) = history.filter(|h| h.x_t1.dims() == x.dims() && h.x_t2.dims() == x.dims())
        {
            m.inertia_j = Some(mean(energies::inertia(
                &x, &h.x_t1, &h.x_t2, rt, h.dt_secs,
            ))?);
            m.inertia_m = Some(mean(energies::inertia_distance(
                &x,
                &h.x_t1,
                &h.x_t2,
                rt,
                rest.total_mass_kg,
            ))?);
        }
        Ok(m)
    }
}

/// Per-frame metrics of a garment sequence `frames` (each `V` positions) with optional posed
/// bodies (one per frame, for the collision metric) and frame time `dt_secs` (inertia from the
/// third frame on). Frames are evaluated in batches of up to 64.
pub fn sequence_metrics(
    terms: &PhysicsTerms,
    frames: &[Vec<Vec3>],
    bodies: Option<&[Arc<PosedBody>]>,
    dt_secs: f32,
) -> Result<Vec<ClothMetrics>, PhysicsError> {
    if let Some(b) = bodies
        && b.len() != frames.len()
    {
        return Err(PhysicsError::ShapeMismatch {
            what: "bodies for sequence metrics".into(),
            expected: format!("{} (one per frame)", frames.len()),
            found: b.len().to_string(),
        });
    }
    let (device, dtype) = (terms.device().clone(), terms.dtype());
    let mut out = Vec::with_capacity(frames.len());
    for start in (0..frames.len()).step_by(64) {
        let end = (start + 64).min(frames.len());
        let refs: Vec<&[Vec3]> = frames[start..end].iter().map(|f| f.as_slice()).collect();
        let x = positions_tensor(&refs, &device, dtype)?;
        let contacts = match bodies {
            Some(b) => Some(terms.contacts(&x, &BodyBatch::new(b[start..end].to_vec()))?),
            None => None,
        };
        for k in start..end {
            let pick = |t: &Tensor<3>, i: usize| t.clone().narrow(0, i, 1);
            let xk = pick(&x, k - start);
            let v = terms.rest().vertex_count();
            let ck = contacts.as_ref().map(|c| Contacts {
                points: pick(&c.points, k - start),
                normals: pick(&c.normals, k - start),
                distances_m: c
                    .distances_m
                    .get((k - start) * v..(k - start + 1) * v)
                    .map(<[f32]>::to_vec)
                    .unwrap_or_default(),
            });
            let history = if k >= 2 {
                let prev = |i: usize| positions_tensor(&[frames[i].as_slice()], &device, dtype);
                Some(History {
                    x_t1: prev(k - 1)?,
                    x_t2: prev(k - 2)?,
                    dt_secs,
                })
            } else {
                None
            };
            out.push(terms.metrics(&xk, ck.as_ref(), history.as_ref())?);
        }
    }
    Ok(out)
}
