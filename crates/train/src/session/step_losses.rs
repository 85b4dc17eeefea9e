//! The losses of a training step: the static terms of every loss frame and the dynamic terms
//! from the network's own history, on the posed frames (or on detached copies of them when
//! the gradient filter acts on them).

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
    pub(super) fn step_losses(
        &self,
        x_net: &Tensor<4>,
        x: &Tensor<4>,
        filtered: bool,
        batch: &Batch,
        blended: &Tensor<4>,
        kept: usize,
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
        let static_total = losses
            .total()
            .unwrap_or_else(|| Tensor::zeros([1], &self.device));
        let (dynamic, friction) = self.dynamic_losses(x, &x_t, batch, contacts.as_ref(), kept)?;
        let (mut total, plain) = match x_static {
            Some(x_static) => (
                Tensor::zeros([1], &self.device),
                Some((x_static, static_total)),
            ),
            None => (static_total, None),
        };
        for term in dynamic {
            total = total + term;
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

impl NeuralSession {
    /// The gradients of a step: the physics loss (through the gradient `filter` when one acts;
    /// rows of `x` are sample-major, still windows first), or when fitting to reference
    /// frames ([`NeuralSession::fitting`]) the fit of the moving windows plus the physics
    /// loss: at [`crate::TrainConfig::fit_physics_weight`] for the diagnostic fit, in which
    /// case `loss` becomes the fit's, at 1 for the warm start.
    pub(super) fn step_gradients(
        &mut self,
        filter: Option<&GradientFilter>,
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
        let physics = match filter {
            _ if weight == 0.0 => None,
            None => Some(losses.total),
            Some(filter) => {
                let plain_rows = if self.config.precondition_moving_only {
                    losses.still * batch.predicted
                } else {
                    0
                };
                // The history terms act on the moving windows with dynamics: after the
                // still ones, before the augmented (quasi-static) ones.
                let dt = self.dt_secs();
                let propagation = self.filter.propagation(&self.config, &self.terms, dt)?;
                let adjoint = self.filter.adjoint(&self.config, &self.terms, dt)?;
                let dynamics = self.terms.effects().dynamics;
                let history = HistoryTerms {
                    propagation: propagation.as_deref().filter(|_| dynamics),
                    adjoint: adjoint.as_deref().filter(|_| dynamics),
                    samples: losses.still..losses.moving_end,
                };
                Some(filtered_surrogate(
                    filter,
                    x_net,
                    x,
                    losses.total,
                    plain_rows,
                    losses.plain,
                    history,
                )?)
            }
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
