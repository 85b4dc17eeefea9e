//! Metrics of paper §4.2, computed by the same tensor code as the losses: in-plane deformation
//! (edge elongation and strain, Baraff-Witkin stretch/shear, Green strain), mean dihedral
//! error, percentage of vertices inside the body, gravity potential and inertia; with the body's
//! motion, the cloth's slip over the skin and the friction dissipation.
//!
//! They are pure functions of meshes: [`PhysicsTerms::metrics`] takes a `[B, V, 3]` batch (e.g.
//! network output) and [`sequence_metrics`] any sequence of garment frames.
//!
//! Beside our own bending and stretch, [`ClothMetrics`] carries the official code's definitions
//! of both (`paper_bending_rad`, `paper_stretch`, computed by [`super::paper_metrics`]).

use std::sync::Arc;

use burn::tensor::Tensor;

use neural_cloth_core::geometry::Vec3;

use super::collision::{self, BodyBatch, Contacts, PosedBody};
use super::energies;
use super::friction::{self, FrictionContacts};
use super::paper_metrics;
use super::tensors::{per_sample, positions_tensor, read_f32, read_f64};
use super::{PhysicsError, PhysicsTerms, Term};

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
    /// Bending as the official code defines it: plain mean over every pair of faces sharing an
    /// edge of `|θ - θ̄|`, `θ = atan2(|n0 × n1|, n0 · n1)` the *unsigned* angle between the
    /// two face normals, radians (see [`super::paper_metrics`]).
    #[serde(default)]
    pub paper_bending_rad: f64,
    /// Baraff-Witkin stretch as the official code defines it: `Σ_f |c_f| (|s_u| + |s_v|) /
    /// Σ_f |c_f|`, `s = |w| - 1` on rest frames obtained by rotating each rest normal onto
    /// `+Z` (the *sum* of the two directions, so ≈ 2 × [`Self::stretch`]), unitless (see
    /// [`super::paper_metrics`]).
    #[serde(default)]
    pub paper_stretch: f64,
    /// Friction dissipation of the step (see [`super::friction`]), joules, when the history
    /// holds friction contacts and the friction effect is on.
    #[serde(default)]
    pub friction_j: Option<f64>,
    /// Mean tangential slip over the body of the vertices in contact, metres per frame, when
    /// the history holds friction contacts (whatever the effects: how far the cloth slides
    /// over the skin).
    #[serde(default)]
    pub slip_m: Option<f64>,
    /// The static objective the trainer minimises for this frame: the sum of the scene's
    /// static energies (cloth, bending, collision, gravity, as enabled), joules; filled by
    /// [`sequence_metrics`] (when collision is off or bodies were given), not by
    /// [`PhysicsTerms::metrics`]. Comparing it between two drapes of the same pose says which
    /// one is the lower minimum of the training loss. It leaves out pinning (its targets are
    /// the skinned template, not known here).
    #[serde(default)]
    pub static_energy_j: Option<f64>,
    /// [`Self::static_energy_j`] term by term; filled with it by [`sequence_metrics`].
    #[serde(default)]
    pub static_terms: Option<StaticTerms>,
}

/// The static objective of one frame (or a mean over frames) term by term, joules; a term the
/// scene leaves out is 0.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StaticTerms {
    /// In-plane energy: stretch, plus shear for Baraff-Witkin.
    pub cloth_j: f64,
    /// Bending energy.
    pub bending_j: f64,
    /// Body collision energy.
    pub collision_j: f64,
    /// Gravity potential.
    pub gravity_j: f64,
}

impl StaticTerms {
    /// The sum of the terms: the static objective.
    pub fn total(&self) -> f64 {
        self.cloth_j + self.bending_j + self.collision_j + self.gravity_j
    }

    /// Adds the batch mean `value` of `term` (pinning and the dynamic terms are not static
    /// terms here and are ignored).
    fn add(&mut self, term: Term, value: f64) {
        match term {
            Term::Stretch | Term::Shear => self.cloth_j += value,
            Term::Bending => self.bending_j += value,
            Term::Collision => self.collision_j += value,
            Term::Gravity => self.gravity_j += value,
            Term::Pinning | Term::Inertia | Term::Friction => {}
        }
    }
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
    /// Contacts of `x` with the body's motion since `x_{t-1}`, for the friction and slip
    /// metrics (None: not measured).
    pub friction: Option<FrictionContacts>,
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
        let paper = paper_metrics::paper_metrics(rest, &read_f32(x.clone())?, b)?;
        m.paper_bending_rad = paper.bending_rad;
        m.paper_stretch = paper.stretch;
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
            if let Some(fc) = h.friction.as_ref().filter(|f| f.weight.dims()[0] == b) {
                m.slip_m = friction::mean_slip_m(&x, &h.x_t1, fc)?;
                if self.friction_on() {
                    m.friction_j = Some(mean(friction::friction(&x, &h.x_t1, fc))?);
                }
            }
        }
        Ok(m)
    }

    /// The static objective of the batch `x` (`[B, V, 3]`), batch mean: the sum of the
    /// scene's static energies as the trainer takes them, joules; `None` when collision is on
    /// and `contacts` of the same shape are missing. Not part of [`Self::metrics`], which a
    /// training step calls: [`sequence_metrics`] fills [`ClothMetrics::static_energy_j`].
    pub fn static_objective_j(
        &self,
        x: &Tensor<3>,
        contacts: Option<&Contacts>,
    ) -> Result<Option<f64>, PhysicsError> {
        Ok(self.static_terms_j(x, contacts)?.map(|t| t.total()))
    }

    /// [`Self::static_objective_j`] term by term (batch means).
    pub fn static_terms_j(
        &self,
        x: &Tensor<3>,
        contacts: Option<&Contacts>,
    ) -> Result<Option<StaticTerms>, PhysicsError> {
        let contacts = contacts.filter(|c| c.points.dims() == x.dims());
        if self.effects().collision && contacts.is_none() {
            return Ok(None);
        }
        let mut terms = StaticTerms::default();
        for (term, value) in self
            .static_losses_with(&x.clone().detach(), contacts)?
            .terms
        {
            terms.add(term, read_f64(value)?.first().copied().unwrap_or(0.0));
        }
        Ok(Some(terms))
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
                indices: c
                    .indices
                    .get((k - start) * v..(k - start + 1) * v)
                    .map(<[u32]>::to_vec)
                    .unwrap_or_default(),
            });
            let history = if k >= 2 {
                let prev = |i: usize| positions_tensor(&[frames[i].as_slice()], &device, dtype);
                let friction = match (&ck, bodies) {
                    (Some(c), Some(b)) => Some(FrictionContacts::new(
                        c,
                        &BodyBatch::new(vec![b[k].clone()]),
                        &BodyBatch::new(vec![b[k - 1].clone()]),
                        &[],
                        terms.rest(),
                        terms.fabric(),
                    )?),
                    _ => None,
                };
                Some(History {
                    x_t1: prev(k - 1)?,
                    x_t2: prev(k - 2)?,
                    dt_secs,
                    friction,
                })
            } else {
                None
            };
            let mut m = terms.metrics(&xk, ck.as_ref(), history.as_ref())?;
            m.static_terms = terms.static_terms_j(&xk, ck.as_ref())?;
            m.static_energy_j = m.static_terms.map(|t| t.total());
            out.push(m);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use burn::tensor::{DType, Device};

    use super::*;
    use crate::{Effects, FabricParams, GarmentRest};
    use neural_cloth_core::geometry::{Topology, TriMesh};

    /// A 5 x 4 sheet, tilted (normal not along an axis), its rest positions optionally bent.
    fn sheet_terms(corrugate: f32) -> (TriMesh, PhysicsTerms) {
        let mut mesh = crate::shapes::sheet(
            5,
            4,
            Vec3::new(0.1, 0.9, -0.2),
            Vec3::new(0.4, 0.1, 0.05),
            Vec3::new(-0.05, 0.1, 0.3),
        );
        let n = Vec3::new(0.4, 0.1, 0.05)
            .cross(&Vec3::new(-0.05, 0.1, 0.3))
            .normalize();
        for (k, p) in mesh.positions.iter_mut().enumerate() {
            // Alternating bumps: hinges bent both ways at rest.
            *p += n * (corrugate * if k % 2 == 0 { 1.0 } else { -1.0 });
        }
        let topology = Topology::new(&mesh);
        let rest = GarmentRest::new(&mesh, &topology, &[], &[], 0.15).unwrap();
        let effects = Effects {
            gravity: true,
            bending: true,
            collision: false,
            dynamics: false,
            pinning: false,
            friction: false,
        };
        let terms = PhysicsTerms::from_rest(
            Arc::new(rest),
            &FabricParams::default(),
            &effects,
            &Device::flex(),
            DType::F32,
        )
        .unwrap();
        (mesh, terms)
    }

    /// Deterministic pseudo-random displacements in `[-amp, amp]`.
    fn jitter(positions: &[Vec3], amp: f32, seed: u64) -> Vec<Vec3> {
        let mut s = seed;
        let mut next = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 33) as f32 / (1u64 << 31) as f32) * 2.0 - 1.0
        };
        positions
            .iter()
            .map(|p| p + Vec3::new(next(), next(), next()) * amp)
            .collect()
    }

    fn metrics_of(terms: &PhysicsTerms, frames: &[Vec<Vec3>]) -> ClothMetrics {
        let refs: Vec<&[Vec3]> = frames.iter().map(|f| f.as_slice()).collect();
        let x = positions_tensor(&refs, terms.device(), terms.dtype()).unwrap();
        terms.metrics(&x, None, None).unwrap()
    }

    #[test]
    fn the_static_energy_is_the_trainers_static_objective() {
        let (mesh, terms) = sheet_terms(0.0);
        let frames: Vec<Vec<Vec3>> = (0..2).map(|s| jitter(&mesh.positions, 0.01, s)).collect();
        let refs: Vec<&[Vec3]> = frames.iter().map(|f| f.as_slice()).collect();
        let x = positions_tensor(&refs, terms.device(), terms.dtype()).unwrap();
        // The sum of every static energy's batch mean, read term by term.
        let objective: f64 = terms
            .static_energies(&x, None)
            .unwrap()
            .into_iter()
            .map(|(_, t)| read_f64(t).unwrap().iter().sum::<f64>() / 2.0)
            .sum();
        let energy = terms.static_objective_j(&x, None).unwrap().unwrap();
        // sequence_metrics fills it per frame; a training step's metrics do not.
        let per_frame = sequence_metrics(&terms, &frames, None, 1.0 / 30.0).unwrap();
        let mean_of_frames = per_frame
            .iter()
            .map(|m| m.static_energy_j.unwrap())
            .sum::<f64>()
            / 2.0;
        // Per frame in one batch or two: the f32 sums differ in rounding only.
        assert!(
            (mean_of_frames - energy).abs() < 1e-6 * energy.abs().max(1.0),
            "{mean_of_frames} vs {energy}"
        );
        // Term by term, each frame's terms sum to its objective, and each term is the batch
        // mean of that energy alone.
        for m in &per_frame {
            let t = m.static_terms.unwrap();
            assert!((t.total() - m.static_energy_j.unwrap()).abs() < 1e-12);
            assert!(t.cloth_j > 0.0 && t.gravity_j != 0.0, "{t:?}");
        }
        let batch = terms.static_terms_j(&x, None).unwrap().unwrap();
        for (term, value) in terms.static_energies(&x, None).unwrap() {
            let mean = read_f64(value).unwrap().iter().sum::<f64>() / 2.0;
            let got = match term {
                Term::Bending => batch.bending_j,
                Term::Gravity => batch.gravity_j,
                Term::Collision => batch.collision_j,
                _ => continue,
            };
            assert!((got - mean).abs() < 1e-6 * mean.abs().max(1.0), "{term:?}");
        }
        assert!(
            terms
                .metrics(&x, None, None)
                .unwrap()
                .static_energy_j
                .is_none()
        );
        assert!(
            (energy - objective).abs() < 1e-6 * objective.abs().max(1.0),
            "{energy} vs {objective}"
        );
        // Lifting the sheet raises it by the gravity potential alone.
        let lifted: Vec<Vec<Vec3>> = frames
            .iter()
            .map(|f| f.iter().map(|p| p + Vec3::new(0.0, 0.01, 0.0)).collect())
            .collect();
        let refs: Vec<&[Vec3]> = lifted.iter().map(|f| f.as_slice()).collect();
        let x = positions_tensor(&refs, terms.device(), terms.dtype()).unwrap();
        let higher = terms.static_objective_j(&x, None).unwrap().unwrap();
        let mass = terms.rest().total_mass_kg;
        let g_y = f64::from(FabricParams::default().gravity_m_per_s2[1]);
        let expected = -mass * g_y * 0.01;
        assert!(expected > 0.0);
        assert!(
            (higher - energy - expected).abs() < 1e-3 * expected,
            "{higher} vs {energy}"
        );
    }

    #[test]
    fn paper_metrics_beside_ours_on_random_meshes() {
        // Flat rest: every rest angle is 0, so unsigned = |signed| and the two bendings agree
        // (every hinge is usable and ours is unweighted too).
        let (mesh, terms) = sheet_terms(0.0);
        let rest = terms.rest();
        assert_eq!(
            rest.hinge_weight.iter().filter(|w| **w > 0.0).count(),
            rest.hinges.len()
        );
        let at_rest = metrics_of(&terms, std::slice::from_ref(&mesh.positions));
        assert!(at_rest.paper_bending_rad < 1e-6 && at_rest.paper_stretch < 1e-6);
        let frames: Vec<Vec<Vec3>> = (0..3).map(|s| jitter(&mesh.positions, 0.02, s)).collect();
        let m = metrics_of(&terms, &frames);
        assert!(m.bending_rad > 0.05, "{m:?}");
        assert!((m.paper_bending_rad - m.bending_rad).abs() < 1e-4, "{m:?}");
        // Batch mean = mean of the per-frame values.
        let per: Vec<ClothMetrics> = frames
            .iter()
            .map(|f| metrics_of(&terms, std::slice::from_ref(f)))
            .collect();
        let mean = |g: fn(&ClothMetrics) -> f64| per.iter().map(g).sum::<f64>() / 3.0;
        assert!((m.paper_bending_rad - mean(|m| m.paper_bending_rad)).abs() < 1e-9);
        assert!((m.paper_stretch - mean(|m| m.paper_stretch)).abs() < 1e-9);
        // Uniform 10 % scaling: frames do not matter; ours averages u and v (0.1), the
        // official sums them (0.2).
        let scaled: Vec<Vec3> = mesh.positions.iter().map(|p| p * 1.1).collect();
        let m = metrics_of(&terms, &[scaled]);
        assert!((m.stretch - 0.1).abs() < 1e-5, "{m:?}");
        assert!((m.paper_stretch - 0.2).abs() < 1e-5, "{m:?}");
        // A random deformation: different rest frames (ours projects +Y, the official rotates
        // the normal onto +Z), so the official stretch is not twice ours.
        let m = metrics_of(&terms, &frames[..1]);
        assert!(m.stretch > 0.01, "{m:?}");
        assert!((m.paper_stretch - 2.0 * m.stretch).abs() > 1e-3, "{m:?}");

        // Bent rest with hinges of both signs, mirrored: signed changes are large, unsigned
        // ones vanish, so ours is large and the official is ~0.
        let (mesh, terms) = sheet_terms(0.02);
        let flat_terms = sheet_terms(0.0).1;
        let rest0 = flat_terms.rest().rest_positions.clone();
        let mirrored: Vec<Vec3> = mesh
            .positions
            .iter()
            .zip(&rest0)
            .map(|(p, q)| q * 2.0 - p)
            .collect();
        let m = metrics_of(&terms, std::slice::from_ref(&mirrored));
        assert!(m.bending_rad > 0.1, "{m:?}");
        assert!(m.paper_bending_rad < 1e-4, "{m:?}");
        // In general the unsigned error never exceeds the signed one; they agree on hinges
        // that keep their sign (the jittered rest) and differ on those that flip.
        for (base, flips) in [(&mesh.positions, false), (&mirrored, true)] {
            let frames: Vec<Vec<Vec3>> = (0..3).map(|s| jitter(base, 0.005, 10 + s)).collect();
            let m = metrics_of(&terms, &frames);
            assert!(m.paper_bending_rad <= m.bending_rad + 1e-6, "{m:?}");
            match flips {
                false => assert!(m.paper_bending_rad > 0.9 * m.bending_rad, "{m:?}"),
                true => assert!(m.paper_bending_rad < 0.5 * m.bending_rad, "{m:?}"),
            }
        }
    }
}
