//! The losses of a training step: the static terms of every loss frame and the dynamic terms
//! from the network's own history, on the posed frames (or on detached copies of them when
//! the gradient filter acts on them), split into the part whose gradient the filter acts on
//! and the part that keeps its plain gradient.

use burn::tensor::Tensor;
use neural_cloth_physics::{Contacts, FrictionContacts, Term};

use super::{NeuralSession, stack_frames};
use crate::TrainError;
use crate::config::InertiaMode;
use crate::data::Batch;

impl NeuralSession {
    /// The step's losses on the posed frames `x` (`[B, K, V, 3]`; a detached copy of `x_net`
    /// when `filtered`): every loss frame k in 2..K, stacked frame by frame, with its static
    /// losses and its inertia from the network's own two previous frames (of the first `kept`
    /// samples). When filtered, the terms whose gradient stays plain are taken on a copy of
    /// their own, returned as `plain`: the static terms with `precondition_dynamic_only` (and
    /// dynamic terms to filter), the contact terms (collision, friction, pinning) with
    /// `precondition_plain_contacts`; `total` is then the rest.
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
        let statics_plain =
            filtered && self.config.precondition_dynamic_only && self.terms.effects().dynamics;
        let contacts_plain = filtered && self.config.precondition_plain_contacts;
        let x_plain =
            (statics_plain || contacts_plain).then(|| x_net.clone().detach().require_grad());
        let x_t = stack_frames(x, 2, predicted, b);
        let x_plain_t = x_plain.as_ref().map(|x| stack_frames(x, 2, predicted, b));
        let x_static_t = match (&x_plain_t, statics_plain) {
            (Some(xp), true) => xp,
            _ => &x_t,
        };
        let (contacts, mut losses) =
            self.static_losses(&self.train, batch, blended, 2, x_static_t)?;
        // Plain-gradient terms other than the static ones: the contacts, retaken on the copy.
        let mut plain_terms: Vec<Tensor<1>> = Vec::new();
        if let (Some(xp), true, false) = (&x_plain_t, contacts_plain, statics_plain) {
            losses
                .terms
                .retain(|(t, _)| !matches!(t, Term::Collision | Term::Pinning));
            if let Some(c) = &contacts {
                plain_terms.extend(self.terms.collision_loss(xp, c)?);
            }
            plain_terms.extend(
                self.pin_target(batch, blended, 2)
                    .and_then(|target| self.terms.pinning(xp, &target)),
            );
        }
        let static_total = losses.total();
        let x_friction_t = match (&x_plain_t, contacts_plain) {
            (Some(xp), true) => xp,
            _ => &x_t,
        };
        let dynamic = self.dynamic_losses(x, x_friction_t, batch, contacts.as_ref(), kept)?;
        // In the order of the unfiltered sum: static terms, inertia, dissipation.
        let mut filtered_terms: Vec<Tensor<1>> = Vec::new();
        match (statics_plain, static_total) {
            (true, Some(t)) => plain_terms.push(t),
            (false, Some(t)) => filtered_terms.push(t),
            (_, None) => {}
        }
        filtered_terms.extend(dynamic.inertia);
        match (contacts_plain, dynamic.dissipation) {
            (true, Some(d)) => plain_terms.push(d),
            (false, Some(d)) => filtered_terms.push(d),
            (_, None) => {}
        }
        let sum = |terms: Vec<Tensor<1>>| terms.into_iter().reduce(|a, b| a + b);
        let total = sum(filtered_terms).unwrap_or_else(|| Tensor::zeros([1], &self.device));
        let plain_total = sum(plain_terms);
        let loss = total.clone().into_scalar::<f64>()
            + plain_total
                .as_ref()
                .map_or(0.0, |t| t.clone().into_scalar::<f64>());
        let plain = match (x_plain, plain_total) {
            (Some(xp), Some(t)) => Some((xp, t)),
            _ => None,
        };
        Ok(StepLosses {
            total,
            plain,
            contacts,
            friction: dynamic.friction,
            loss,
        })
    }

    /// With the dynamics effect: the inertia of the first `kept` samples of every loss frame
    /// of `x` (`[B, K, V, 3]`) from the network's own two previous frames, and with the
    /// friction effect the friction dissipation of every loss frame `x_t` (stacked,
    /// [`stack_frames`]: `x`'s own or a copy of them whose gradient stays plain), with the
    /// friction contacts for the step's metrics.
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
            InertiaMode::Ours => self.terms.inertia(&xt, &xt1, &xt2, self.dt_secs()),
            InertiaMode::Snug => {
                crate::losses::inertia_through_past(&self.terms, &xt, &xt1, &xt2, self.dt_secs())
            }
        };
        let friction = match (contacts, self.terms.friction_on()) {
            (Some(c), true) => crate::losses::friction_contacts(
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
}

/// What [`NeuralSession::step_losses`] returns.
pub(super) struct StepLosses {
    /// The losses whose gradient the filter acts on (all of them when unfiltered).
    pub total: Tensor<1>,
    /// The losses whose gradient stays plain, on their own detached copy of the posed frames
    /// (`precondition_dynamic_only`, `precondition_plain_contacts`).
    pub plain: Option<(Tensor<4>, Tensor<1>)>,
    /// Contacts of the loss frames, when the scene collides.
    pub contacts: Option<Contacts>,
    /// Friction contacts of the loss frames, when the scene has friction.
    pub friction: Option<FrictionContacts>,
    /// The step's physics loss (static and dynamic terms).
    pub loss: f64,
}

/// What [`NeuralSession::dynamic_losses`] returns.
#[derive(Default)]
struct DynamicLosses {
    /// The inertia term, with the dynamics effect.
    inertia: Option<Tensor<1>>,
    /// The friction dissipation, with the friction effect.
    dissipation: Option<Tensor<1>>,
    /// The friction contacts of the loss frames.
    friction: Option<FrictionContacts>,
}
