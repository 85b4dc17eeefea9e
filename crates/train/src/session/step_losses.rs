//! The losses of a training step: the static terms of every loss frame and the dynamic terms
//! from the network's own history, on the posed frames (or on detached copies of them when
//! the gradient filter acts on them).

use burn::tensor::Tensor;
use neural_cloth_physics::{Contacts, FrictionContacts};

use super::{NeuralSession, stack_frames};
use crate::TrainError;
use crate::data::Batch;

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
