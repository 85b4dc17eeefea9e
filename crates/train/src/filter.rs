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
    }
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

/// `Σ x_net · sg(F(∂total/∂x) + ∂plain/∂x_plain)`, F the gradient filter: its gradient with
/// respect to the network's output `x_net` is the filtered physics gradient (the first
/// `plain_rows` rows of `[B·K, V, 3]` keep the plain one), plus, when given, the plain
/// gradient of a second loss `plain` taken on its own detached copy `x_plain`. `x` is the
/// detached leaf copy of `x_net` that `total` was computed from.
pub fn filtered_surrogate(
    filter: &GradientFilter,
    x_net: &Tensor<4>,
    x: &Tensor<4>,
    total: Tensor<1>,
    plain_rows: usize,
    plain: Option<(Tensor<4>, Tensor<1>)>,
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
    let g = Tensor::<4>::from_data(TensorData::new(g, dims), &x_net.device());
    Ok((x_net.clone() * g).sum())
}

#[cfg(test)]
mod tests {
    use super::*;

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
