//! The training side of the gradient filter ([`GradientFilter`], physics layer): which
//! stiffness scale applies at a step, a cache that refactors the filter when it changes, and
//! the surrogate that hands the filtered physics gradient to the network.

use std::sync::Arc;

use burn::tensor::{Tensor, TensorData};
use neural_cloth_physics::{GradientFilter, PhysicsError, PhysicsTerms};

use super::TrainError;
use super::config::TrainConfig;

/// The filter of a session: built on first use, rebuilt when the stiffness scale of the
/// schedule has moved by more than 10 % or the fabric changed ([`Self::reset`]).
#[derive(Default)]
pub struct FilterCache {
    filter: Option<Arc<GradientFilter>>,
    /// The history propagation's `D (D + β'K)⁻¹` ([`TrainConfig::history_propagation`]).
    propagation: Option<Arc<GradientFilter>>,
    /// The history adjoint's `D (D + β''K)⁻¹` ([`TrainConfig::history_adjoint`]).
    adjoint: Option<Arc<GradientFilter>>,
    /// Steps taken (restored with a checkpoint), for the schedule.
    steps_taken: u64,
}

impl FilterCache {
    /// The filter for the next step, `None` when the settings ask for none.
    pub fn next(
        &mut self,
        config: &TrainConfig,
        terms: &PhysicsTerms,
        dt_secs: f32,
    ) -> Result<Option<Arc<GradientFilter>>, TrainError> {
        let beta = precondition_schedule(config, self.steps_taken);
        if beta <= 0.0 {
            return Ok(None);
        }
        let stale = self
            .filter
            .as_ref()
            .is_none_or(|f| (f.stiffness_scale() / beta - 1.0).abs() > 0.1);
        if stale {
            self.filter = Some(Arc::new(GradientFilter::new(
                terms.rest(),
                terms.fabric(),
                dt_secs,
                beta,
            )?));
        }
        Ok(self.filter.clone())
    }

    /// The history propagation's filter, `None` when the settings ask for none.
    pub fn propagation(
        &mut self,
        config: &TrainConfig,
        terms: &PhysicsTerms,
        dt_secs: f32,
    ) -> Result<Option<Arc<GradientFilter>>, TrainError> {
        built_once(
            &mut self.propagation,
            config.history_propagation,
            terms,
            dt_secs,
        )
    }

    /// The history adjoint's filter, `None` when the settings ask for none.
    pub fn adjoint(
        &mut self,
        config: &TrainConfig,
        terms: &PhysicsTerms,
        dt_secs: f32,
    ) -> Result<Option<Arc<GradientFilter>>, TrainError> {
        built_once(&mut self.adjoint, config.history_adjoint, terms, dt_secs)
    }

    /// Steps taken so far in the run (from its first step, resumes included).
    pub fn steps_taken(&self) -> u64 {
        self.steps_taken
    }

    /// Counts a step whose update was made.
    pub fn count_step(&mut self) {
        self.steps_taken += 1;
    }

    /// Continues from checkpoint step `step`.
    pub fn restore(&mut self, step: u64) {
        self.steps_taken = step;
    }

    /// Forgets the filter (the fabric changed); the next step rebuilds it.
    pub fn reset(&mut self) {
        self.filter = None;
        self.propagation = None;
        self.adjoint = None;
    }
}

/// The filter at stiffness scale `beta` kept in `slot` (built on first use), `None` when
/// `beta` is not positive.
fn built_once(
    slot: &mut Option<Arc<GradientFilter>>,
    beta: f64,
    terms: &PhysicsTerms,
    dt_secs: f32,
) -> Result<Option<Arc<GradientFilter>>, TrainError> {
    if beta <= 0.0 {
        return Ok(None);
    }
    if slot.is_none() {
        *slot = Some(Arc::new(GradientFilter::new(
            terms.rest(),
            terms.fabric(),
            dt_secs,
            beta,
        )?));
    }
    Ok(slot.clone())
}

/// The filter's stiffness scale before step `step` (0-based): constant, or, with
/// [`TrainConfig::precondition_final_stiffness`] and a step limit, moving geometrically from the
/// start value to the final one over the run.
pub fn precondition_schedule(config: &TrainConfig, step: u64) -> f64 {
    let start = config.precondition_stiffness;
    match (config.precondition_final_stiffness, config.max_steps) {
        (Some(end), Some(total)) if start > 0.0 && end > 0.0 && total > 0 => {
            let t = (step as f64 / total as f64).min(1.0);
            start * (end / start).powf(t)
        }
        _ => start,
    }
}

/// What a step does with a gradient along each window's frames, over the moving windows
/// `samples` (rows of `[B, K, V, 3]` are sample-major).
pub struct HistoryTerms<'a> {
    /// Carries the gradient forward in time ([`propagate_history`]).
    pub propagation: Option<&'a GradientFilter>,
    /// Hands each loss frame's residual to the two frames before it ([`adjoint_history`]).
    pub adjoint: Option<&'a GradientFilter>,
    /// The samples (windows) both act on.
    pub samples: std::ops::Range<usize>,
}

/// `Σ x_net · sg(F(∂total/∂x) + ∂plain/∂x_plain)`, F the gradient filter: its gradient with
/// respect to the network's output `x_net` is the filtered physics gradient (the first
/// `plain_rows` rows of `[B·K, V, 3]` keep the plain one), plus, when given, the plain
/// gradient of a second loss `plain` taken on its own detached copy `x_plain`. `x` is the
/// detached leaf copy of `x_net` that `total` was computed from. The summed gradient is then
/// handed back to the previous frames ([`adjoint_history`]) and carried forward in time
/// ([`propagate_history`]) over the samples of `history`, where it asks for them.
pub fn filtered_surrogate(
    filter: &GradientFilter,
    x_net: &Tensor<4>,
    x: &Tensor<4>,
    total: Tensor<1>,
    plain_rows: usize,
    plain: Option<(Tensor<4>, Tensor<1>)>,
    history: HistoryTerms<'_>,
) -> Result<Tensor<1>, TrainError> {
    let dims = x.dims();
    let gradient_of = |leaf: &Tensor<4>, loss: Tensor<1>| -> Result<Vec<f32>, TrainError> {
        let grads = loss.backward();
        match leaf.grad(&grads) {
            Some(g) => Ok(g
                .try_into_vec_as::<f32>()
                .map_err(|e| PhysicsError::Backend(e.to_string()))?),
            None => Ok(vec![0.0; dims.iter().product()]),
        }
    };
    let mut g = gradient_of(x, total)?;
    filter.apply_from(&mut g, plain_rows)?;
    if let Some((x_plain, loss)) = plain {
        for (a, b) in g.iter_mut().zip(gradient_of(&x_plain, loss)?) {
            *a += b;
        }
    }
    if let Some(adjoint) = history.adjoint {
        adjoint_history(adjoint, &mut g, dims[1], history.samples.clone())?;
    }
    if let Some(propagation) = history.propagation {
        propagate_history(propagation, &mut g, dims[1], history.samples)?;
    }
    let g = Tensor::<4>::from_data(TensorData::new(g, dims), &x_net.device());
    Ok((x_net.clone() * g).sum())
}

/// Carries the gradient `g` (`[B·K, V, 3]`, sample-major, `K = frames`) forward in time
/// within each sample of `samples`: `G_k = g_k + P (2 G_{k-1} - G_{k-2})` for `k` in `2..K`,
/// `P` the `propagation` filter ([`TrainConfig::history_propagation`]). Frame `k`'s physics
/// step starts from frames `k - 1` and `k - 2` (the inertia's `2x_{k-1} - x_{k-2}`), so a
/// correction of those frames moves frame `k`'s one-step answer by `P` times the same
/// combination of corrections: the recurrence is the linearised forward substitution of a
/// window's frames. Samples outside `samples` are left as they are.
pub fn propagate_history(
    propagation: &GradientFilter,
    g: &mut [f32],
    frames: usize,
    samples: std::ops::Range<usize>,
) -> Result<(), TrainError> {
    let row = propagation.vertex_count() * 3;
    for_each_sample(g, row, frames, samples, "gradient to propagate", |sample| {
        for k in 2..frames {
            let (before, after) = sample.split_at_mut(k * row);
            let mut carry: Vec<f32> = before[(k - 1) * row..]
                .iter()
                .zip(&before[(k - 2) * row..(k - 1) * row])
                .map(|(g1, g2)| 2.0 * g1 - g2)
                .collect();
            propagation.apply(&mut carry)?;
            for (out, c) in after[..row].iter_mut().zip(&carry) {
                *out += c;
            }
        }
        Ok(())
    })
}

/// Hands each loss frame's gradient `g_k` (`[B·K, V, 3]`, sample-major, `K = frames`, loss
/// frames `2..K`) to the two frames its physics step starts from: `g_{k-1} -= 2 P g_k`,
/// `g_{k-2} += P g_k`, `P` the `adjoint` filter ([`TrainConfig::history_adjoint`]), every
/// `P g_k` taken from the gradient as it came in. With `P = D W` and `W ≈ (D + K)⁻¹`, the
/// result is the gradient of the least-squares residual `½ Σ_k r_kᵀ W r_k` (`r_k` the
/// physics gradient of frame k, whose derivatives with respect to frames `k - 1` and `k - 2`
/// are `-2D` and `D`): the same fixed point as the stop-gradient loss (all `r_k = 0`), but a
/// descent that is stable for every mode, where the stop-gradient one is unstable for the
/// soft modes a motion drives faster than their natural frequency (docs/TRAINING.md, round
/// 18). Samples outside `samples` are left as they are.
pub fn adjoint_history(
    adjoint: &GradientFilter,
    g: &mut [f32],
    frames: usize,
    samples: std::ops::Range<usize>,
) -> Result<(), TrainError> {
    let row = adjoint.vertex_count() * 3;
    for_each_sample(g, row, frames, samples, "gradient to hand back", |sample| {
        let mut handed = Vec::with_capacity(frames.saturating_sub(2));
        for k in 2..frames {
            let mut c = sample[k * row..(k + 1) * row].to_vec();
            adjoint.apply(&mut c)?;
            handed.push(c);
        }
        for (k, c) in (2..frames).zip(&handed) {
            for (out, c) in sample[(k - 1) * row..k * row].iter_mut().zip(c) {
                *out -= 2.0 * c;
            }
            for (out, c) in sample[(k - 2) * row..(k - 1) * row].iter_mut().zip(c) {
                *out += c;
            }
        }
        Ok(())
    })
}

/// Runs `f` on the block of `frames · row` values of each sample in `samples` of `g` (in
/// parallel); `what` names `g` when it is not whole samples of that size.
fn for_each_sample(
    g: &mut [f32],
    row: usize,
    frames: usize,
    samples: std::ops::Range<usize>,
    what: &str,
    f: impl Fn(&mut [f32]) -> Result<(), PhysicsError> + Sync + Send,
) -> Result<(), TrainError> {
    use rayon::prelude::*;
    let block = frames * row;
    if row == 0 || frames == 0 || !g.len().is_multiple_of(block) {
        return Err(PhysicsError::ShapeMismatch {
            what: what.into(),
            expected: format!("whole samples of {frames} frames of {row} values"),
            found: format!("{} values", g.len()),
        }
        .into());
    }
    let end = samples.end.min(g.len() / block);
    let start = samples.start.min(end);
    g[start * block..end * block]
        .par_chunks_mut(block)
        .try_for_each(f)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use neural_cloth_core::geometry::{Topology, Vec3};
    use neural_cloth_physics::{FabricParams, GarmentRest, shapes::sheet};

    /// The propagation's filter at β' = 1 on a 12 x 12 sheet, and the sheet's `m / Δt²`.
    fn propagation() -> (GradientFilter, Vec<f32>) {
        let mesh = sheet(12, 12, Vec3::zeros(), Vec3::x() * 0.4, Vec3::z() * 0.4);
        let fabric = FabricParams::default();
        let rest = GarmentRest::new(
            &mesh,
            &Topology::new(&mesh),
            &[],
            &[],
            fabric.density_kg_per_m2,
        )
        .unwrap();
        let dt = 1.0 / 30.0;
        let inertial = rest
            .mass_kg
            .iter()
            .map(|m| (m / f64::from(dt * dt)) as f32)
            .collect();
        (
            GradientFilter::new(&rest, &fabric, dt, 1.0).unwrap(),
            inertial,
        )
    }

    #[test]
    fn a_translation_propagates_ballistically_and_a_stiff_mode_is_damped() {
        let (p, inertial) = propagation();
        let (frames, row) = (6, p.vertex_count() * 3);
        // Sample 0 is left out; sample 1's frame 2 holds a gradient along a translation
        // (proportional to the masses: a mode the membrane does not resist).
        let mut g: Vec<f32> = (0..2 * frames * row)
            .map(|i| ((i * 31) % 17) as f32 - 8.0)
            .collect();
        let sample0 = g[..frames * row].to_vec();
        let translation: Vec<f32> = inertial.iter().flat_map(|d| [0.0, -d, 0.5 * d]).collect();
        let second = &mut g[frames * row..];
        second.fill(0.0);
        second[2 * row..3 * row].copy_from_slice(&translation);
        propagate_history(&p, &mut g, frames, 1..2).unwrap();
        assert_eq!(g[..frames * row], sample0[..]);
        // Moving frame 2 by a translation moves frame k's step start by (k - 2) + 1 times it.
        let second = &g[frames * row..];
        for k in 0..frames {
            let factor = k.saturating_sub(1) as f32;
            for (a, b) in second[k * row..(k + 1) * row].iter().zip(&translation) {
                assert!(
                    (a - factor * b).abs() <= 1e-3 * b.abs() + 1e-9,
                    "frame {k}: {a} vs {}",
                    factor * b
                );
            }
        }
        // The roughest mode barely carries: frame 3 holds far less than twice frame 2.
        let rough: Vec<f32> = (0..row / 3)
            .flat_map(|i| [if i % 2 == 0 { 1.0 } else { -1.0 }, 0.0, 0.0])
            .collect();
        let mut g = vec![0.0f32; frames * row];
        g[2 * row..3 * row].copy_from_slice(&rough);
        propagate_history(&p, &mut g, frames, 0..1).unwrap();
        let norm = |v: &[f32]| v.iter().map(|x| x * x).sum::<f32>().sqrt();
        assert!(norm(&g[3 * row..4 * row]) < 0.4 * norm(&rough));
        // A zero gradient stays zero; a gradient of broken samples is refused.
        let mut zero = vec![0.0f32; frames * row];
        propagate_history(&p, &mut zero, frames, 0..1).unwrap();
        assert!(zero.iter().all(|x| *x == 0.0));
        assert!(propagate_history(&p, &mut [0.0; 7], frames, 0..1).is_err());
    }

    #[test]
    fn the_adjoint_hands_each_loss_frames_gradient_to_the_frames_its_step_starts_from() {
        let (p, inertial) = propagation();
        let (frames, row) = (4, p.vertex_count() * 3);
        // Mass-weighted translations, which the filter passes unchanged (K t = 0).
        let translation = |a: f32, b: f32| -> Vec<f32> {
            inertial.iter().flat_map(|d| [a * d, 0.0, b * d]).collect()
        };
        let (a, b) = (translation(1.0, 0.0), translation(0.0, -2.0));
        // Sample 0 is left out; sample 1 has loss frames 2 (a) and 3 (b).
        let mut g: Vec<f32> = (0..2 * frames * row)
            .map(|i| ((i * 13) % 7) as f32 - 3.0)
            .collect();
        let sample0 = g[..frames * row].to_vec();
        let second = &mut g[frames * row..];
        second.fill(0.0);
        second[2 * row..3 * row].copy_from_slice(&a);
        second[3 * row..].copy_from_slice(&b);
        adjoint_history(&p, &mut g, frames, 1..2).unwrap();
        assert_eq!(g[..frames * row], sample0[..]);
        // g_0 = a, g_1 = -2a + b, g_2 = a - 2b, g_3 = b: each residual's derivative with
        // respect to its own frame and the two before (1, -2, 1 times D).
        let expected = [
            a.clone(),
            a.iter()
                .zip(&b)
                .map(|(a, b)| -2.0 * a + b)
                .collect::<Vec<_>>(),
            a.iter().zip(&b).map(|(a, b)| a - 2.0 * b).collect(),
            b.clone(),
        ];
        let second = &g[frames * row..];
        for (k, want) in expected.iter().enumerate() {
            for (got, want) in second[k * row..(k + 1) * row].iter().zip(want) {
                assert!(
                    (got - want).abs() <= 1e-3 * want.abs().max(1.0),
                    "frame {k}: {got} vs {want}"
                );
            }
        }
        // The roughest mode is handed back damped; zero stays zero; broken shapes refused.
        let rough: Vec<f32> = (0..row / 3)
            .flat_map(|i| [if i % 2 == 0 { 1.0 } else { -1.0 }, 0.0, 0.0])
            .collect();
        let mut g = vec![0.0f32; 3 * row];
        g[2 * row..].copy_from_slice(&rough);
        adjoint_history(&p, &mut g, 3, 0..1).unwrap();
        let norm = |v: &[f32]| v.iter().map(|x| x * x).sum::<f32>().sqrt();
        assert!(norm(&g[row..2 * row]) < 2.0 * 0.4 * norm(&rough));
        assert_eq!(g[2 * row..], rough[..]);
        let mut zero = vec![0.0f32; 3 * row];
        adjoint_history(&p, &mut zero, 3, 0..1).unwrap();
        assert!(zero.iter().all(|x| *x == 0.0));
        assert!(adjoint_history(&p, &mut [0.0; 7], 3, 0..1).is_err());
    }

    #[test]
    fn the_schedule_is_constant_without_an_end_and_geometric_with_one() {
        let mut config = TrainConfig {
            precondition_stiffness: 0.1,
            max_steps: Some(100),
            ..TrainConfig::default()
        };
        assert_eq!(precondition_schedule(&config, 50), 0.1);
        config.precondition_final_stiffness = Some(0.001);
        assert!((precondition_schedule(&config, 0) - 0.1).abs() < 1e-12);
        assert!((precondition_schedule(&config, 50) - 0.01).abs() < 1e-12);
        assert!((precondition_schedule(&config, 100) - 0.001).abs() < 1e-12);
        assert!((precondition_schedule(&config, 500) - 0.001).abs() < 1e-12);
        config.max_steps = None;
        assert_eq!(precondition_schedule(&config, 50), 0.1);
        config.precondition_stiffness = 0.0;
        assert_eq!(precondition_schedule(&config, 50), 0.0);
    }
}
