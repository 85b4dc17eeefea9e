//! The losses of a training step: the static terms of every loss frame and the dynamic terms
//! from the network's own history, on the posed frames (or on detached copies of them when
//! the gradient filter acts on them).

use std::sync::Arc;

use burn::tensor::Gradients;
use burn::tensor::Tensor;
use neural_cloth_physics::{Contacts, FrictionContacts, GradientFilter};

use super::{NeuralSession, stack_frames};
use crate::TrainError;
use crate::data::Batch;
use crate::filter::{HistoryTerms, filtered_surrogate};

/// What a step descends: its physics losses and which samples are which.
pub(super) struct Descent {
    /// The summed losses ([`StepLosses::total`]).
    pub total: Tensor<1>,
    /// The unfiltered static losses ([`StepLosses::plain`]).
    pub plain: Option<(Tensor<4>, Tensor<1>)>,
    /// Still windows, the batch's first samples.
    pub still: usize,
    /// End of the moving windows (the augmented ones follow).
    pub moving_end: usize,
}

impl NeuralSession {
    /// The step's losses on the posed frames `x` (`[B, K, V, 3]`; a detached copy of `x_net`
    /// when `filtered`): every loss frame k in 2..K, stacked frame by frame, with its static
    /// losses and its inertia from the network's own two previous frames (of the first `kept`
    /// samples). With `precondition_dynamic_only` (and dynamic terms to filter), the static
    /// losses are taken on a copy of their own, returned as `plain`, whose gradient is not
    /// filtered; `total` is then the dynamic terms only.
    /// `weights` scale the terms of a part of a batch so that the parts' sums are the whole
    /// batch's means ([`PartWeights::WHOLE`] for a whole batch).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn step_losses(
        &self,
        x_net: &Tensor<4>,
        x: &Tensor<4>,
        filtered: bool,
        batch: &Batch,
        blended: &Tensor<4>,
        kept: usize,
        weights: PartWeights,
    ) -> Result<StepLosses, TrainError> {
        let (b, predicted) = (batch.size, batch.predicted);
        let x_static =
            (filtered && self.config.precondition_dynamic_only && self.terms.effects().dynamics)
                .then(|| x_net.clone().detach().require_grad());
        let x_t = stack_frames(x, 2, predicted, b);
        let x_static_t = x_static.as_ref().map(|x| stack_frames(x, 2, predicted, b));
        let (contacts, losses) = self.static_losses(
            &self.train,
            batch,
            blended,
            2,
            x_static_t.as_ref().unwrap_or(&x_t),
        )?;
        let static_total = weights.scale(
            losses
                .total()
                .unwrap_or_else(|| Tensor::zeros([1], &self.device)),
            weights.samples,
        );
        let dynamic = self.dynamic_losses(x, &x_t, batch, contacts.as_ref(), kept)?;
        let friction = dynamic.friction;
        let (mut total, plain) = match x_static {
            Some(x_static) => (
                Tensor::zeros([1], &self.device),
                Some((x_static, static_total)),
            ),
            None => (static_total, None),
        };
        if let Some(inertia) = dynamic.inertia {
            total = total + weights.scale(inertia, weights.kept);
        }
        if let Some(dissipation) = dynamic.dissipation {
            total = total + weights.scale(dissipation, weights.samples);
        }
        let loss = total.clone().into_scalar::<f64>()
            + plain
                .as_ref()
                .map_or(0.0, |(_, t)| t.clone().into_scalar::<f64>());
        Ok(StepLosses {
            total,
            plain,
            contacts,
            friction,
            loss,
        })
    }
}

/// The gradient filters of one step ([`crate::filter::FilterCache`]), taken before the step's
/// parts run so that they can share them.
#[derive(Clone, Default)]
pub(super) struct StepFilters {
    /// The filter of the static (and dynamic) terms' gradient, when one acts this step.
    pub filter: Option<Arc<GradientFilter>>,
    /// The history propagation filter ([`crate::TrainConfig::history_propagation`]).
    pub propagation: Option<Arc<GradientFilter>>,
    /// The history adjoint filter ([`crate::TrainConfig::history_adjoint`]).
    pub adjoint: Option<Arc<GradientFilter>>,
}

impl NeuralSession {
    /// The step's filters: `None` filters where the configuration has none.
    pub(super) fn step_filters(&mut self) -> Result<StepFilters, TrainError> {
        let dt = self.dt_secs();
        let filter = self.filter.next(&self.config, &self.terms, dt)?;
        if filter.is_none() {
            return Ok(StepFilters::default());
        }
        Ok(StepFilters {
            filter,
            propagation: self.filter.propagation(&self.config, &self.terms, dt)?,
            adjoint: self.filter.adjoint(&self.config, &self.terms, dt)?,
        })
    }

    /// The objective whose gradient a step descends for its physics: the summed losses, or
    /// through the gradient filter when one acts (rows of `x` are sample-major, still windows
    /// first) their filtered surrogate.
    pub(super) fn physics_objective(
        &self,
        filters: &StepFilters,
        x_net: &Tensor<4>,
        x: &Tensor<4>,
        losses: Descent,
        batch: &Batch,
    ) -> Result<Tensor<1>, TrainError> {
        let Some(filter) = filters.filter.as_deref() else {
            return Ok(losses.total);
        };
        let plain_rows = if self.config.precondition_moving_only {
            losses.still * batch.predicted
        } else {
            0
        };
        // The history terms act on the moving windows with dynamics: after the still ones,
        // before the augmented (quasi-static) ones.
        let dynamics = self.terms.effects().dynamics;
        let history = HistoryTerms {
            propagation: filters.propagation.as_deref().filter(|_| dynamics),
            adjoint: filters.adjoint.as_deref().filter(|_| dynamics),
            samples: losses.still..losses.moving_end,
        };
        filtered_surrogate(
            filter,
            x_net,
            x,
            losses.total,
            plain_rows,
            losses.plain,
            history,
        )
    }

    /// The gradients of a step: the physics objective ([`Self::physics_objective`]), or when
    /// fitting to reference frames ([`NeuralSession::fitting`]) the fit of the moving windows
    /// plus the physics loss: at [`crate::TrainConfig::fit_physics_weight`] for the
    /// diagnostic fit, in which case `loss` becomes the fit's, at 1 for the warm start.
    pub(super) fn step_gradients(
        &self,
        filters: &StepFilters,
        x_net: &Tensor<4>,
        x: &Tensor<4>,
        losses: Descent,
        batch: &Batch,
        loss: &mut f64,
    ) -> Result<Gradients, TrainError> {
        // The diagnostic fit weighs the physics as configured; the warm start keeps it whole.
        let fitting = self.fitting();
        let weight = match fitting && self.config.fit_reference.is_some() {
            true => self.config.fit_physics_weight,
            false => 1.0,
        };
        let fit_samples = losses.still..losses.moving_end;
        let physics = match weight == 0.0 {
            true => None,
            false => Some(self.physics_objective(filters, x_net, x, losses, batch)?),
        };
        if !fitting {
            return physics
                .map(|p| p.backward())
                .ok_or_else(|| TrainError::Data("no loss to descend".into()));
        }
        let fit = self.reference_loss(x_net, batch, fit_samples)?;
        // The diagnostic logs the fit's loss; the warm start keeps the paper's on the curve.
        if self.config.fit_reference.is_some() {
            *loss = fit.clone().into_scalar::<f64>();
        }
        Ok(match physics {
            Some(p) => (fit + p.mul_scalar(weight)).backward(),
            None => fit.backward(),
        })
    }
}

/// The weights of a part of a batch's windows in the batch's means: its share of the samples
/// (static terms, pinning, friction) and of the kept samples (inertia, which the augmented
/// windows do not take).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct PartWeights {
    /// Samples of the part over the batch's samples.
    pub samples: f64,
    /// Kept samples of the part over the batch's kept samples.
    pub kept: f64,
}

impl PartWeights {
    /// A whole batch.
    pub const WHOLE: Self = Self {
        samples: 1.0,
        kept: 1.0,
    };

    /// `loss · weight`, `loss` itself at weight 1 (the whole batch's path is unchanged).
    fn scale(self, loss: Tensor<1>, weight: f64) -> Tensor<1> {
        if weight == 1.0 {
            loss
        } else {
            loss.mul_scalar(weight)
        }
    }
}

/// What [`NeuralSession::step_losses`] returns.
pub(super) struct StepLosses {
    /// The losses whose gradient the filter acts on (all of them, or the dynamic terms only).
    pub total: Tensor<1>,
    /// The static losses on their own detached copy of the posed frames, whose gradient stays
    /// plain (`precondition_dynamic_only`).
    pub plain: Option<(Tensor<4>, Tensor<1>)>,
    /// Contacts of the loss frames, when the scene collides.
    pub contacts: Option<Contacts>,
    /// Friction contacts of the loss frames, when the scene has friction.
    pub friction: Option<FrictionContacts>,
    /// The step's physics loss (static and dynamic terms).
    pub loss: f64,
}
