//! A training step's batch in two parts on two threads ([`crate::TrainConfig::split_batch`]).
//!
//! A step is about 40 % serial element-wise work between the matrix kernels (measured with
//! perf on the default scene: the trainer thread busy alone while the pool's workers wait),
//! so one batch uses about 1.4 of 2 cores. Two halves of the batch, each with its own copy of
//! the network's leaves (so their autodiff graphs and locks are separate), run their
//! forward and backward passes side by side; their gradients are summed. Each part's losses
//! are weighted by its share of the batch's samples ([`PartWeights`]), so the sum is the
//! whole batch's gradient up to rounding (tested). [`NeuralSession::descend`] runs one part,
//! the whole batch included.

use std::ops::Range;

use burn::module::{Module, ModuleMapper, ModuleVisitor, Param};
use burn::optim::GradientsParams;
use burn::tensor::Tensor;
use neural_cloth_model::ClothNet;

use neural_cloth_physics::{Contacts, FrictionContacts};

use super::NeuralSession;
use super::step_losses::{Descent, PartWeights, StepFilters, StepLosses};
use crate::TrainError;
use crate::data::Batch;

/// Windows of a batch that one part of a step computes.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Part {
    /// The part's windows, a range of the batch's (still windows first, augmented last).
    pub windows: Range<usize>,
    /// Still windows at the start of the part.
    pub still: usize,
    /// Augmented windows at the end of the part.
    pub augment: usize,
    /// The part's weights in the batch's means.
    pub weights: PartWeights,
}

impl Part {
    /// Windows in the part.
    pub fn size(&self) -> usize {
        self.windows.len()
    }

    /// Windows whose inertia counts (all but the augmented ones).
    pub fn kept(&self) -> usize {
        self.size() - self.augment
    }
}

/// The parts of a batch of `b` windows whose first `still` are still and last `augment`
/// augmented: the whole batch, or with `split` two halves, when each half keeps at least one
/// window with inertia (otherwise the whole batch).
pub(super) fn parts(b: usize, still: usize, augment: usize, split: bool) -> Vec<Part> {
    let whole = Part {
        windows: 0..b,
        still,
        augment,
        weights: PartWeights::WHOLE,
    };
    let kept = b.saturating_sub(augment);
    if !split || b < 2 || kept == 0 {
        return vec![whole];
    }
    let h = b / 2;
    let first = Part {
        windows: 0..h,
        still: still.min(h),
        augment: augment.saturating_sub(b - h),
        weights: PartWeights::WHOLE,
    };
    let second = Part {
        windows: h..b,
        still: still.saturating_sub(h),
        augment: augment.min(b - h),
        weights: PartWeights::WHOLE,
    };
    if first.kept() == 0 || second.kept() == 0 {
        return vec![whole];
    }
    [first, second]
        .into_iter()
        .map(|p| Part {
            weights: PartWeights {
                samples: p.size() as f64 / b as f64,
                kept: p.kept() as f64 / kept as f64,
            },
            ..p
        })
        .collect()
}

/// A copy of `model` whose trainable parameters are new autodiff leaves (same ids, same
/// values): a forward pass through it builds a graph of its own, which another thread's pass
/// through another copy does not share.
pub(super) fn fresh_leaves(model: &ClothNet) -> ClothNet {
    model.clone().map(&mut FreshLeaves)
}

struct FreshLeaves;

impl ModuleMapper for FreshLeaves {
    fn map_float<const D: usize>(&mut self, param: Param<Tensor<D>>) -> Param<Tensor<D>> {
        let (id, tensor, mapper) = param.consume();
        let tensor = match tensor.is_require_grad() {
            true => tensor.detach().require_grad(),
            false => tensor,
        };
        Param::from_mapped_value(id, tensor, mapper)
    }
}

/// The sum of the parts' gradients, parameter by parameter of `model`.
pub(super) fn sum_gradients(model: &ClothNet, parts: Vec<GradientsParams>) -> GradientsParams {
    let mut parts = parts.into_iter();
    let Some(first) = parts.next() else {
        return GradientsParams::new();
    };
    parts.fold(first, |sum, other| {
        let mut adder = Adder { sum, other };
        model.visit(&mut adder);
        adder.sum
    })
}

struct Adder {
    sum: GradientsParams,
    other: GradientsParams,
}

impl ModuleVisitor for Adder {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        let Some(other) = self.other.remove::<D>(param.id) else {
            return;
        };
        let sum = match self.sum.remove::<D>(param.id) {
            Some(sum) => sum + other,
            None => other,
        };
        self.sum.register::<D>(param.id, sum);
    }
}

/// A part of a step's batch ([`parts`]) with its windows' data and augmentation picks.
pub(super) struct PartBatch {
    part: Part,
    batch: Batch,
    picks: Vec<i64>,
}

/// What one part of a step computed ([`NeuralSession::descend`]).
pub(super) struct PartOutcome {
    /// Gradients of the part's weighted losses.
    pub grads: GradientsParams,
    /// The part's weighted physics loss.
    pub loss: f64,
    /// The part's posed frames `[b, K, V, 3]` (detached copy when filtered).
    pub x: Tensor<4>,
    /// Contacts of its loss frames.
    pub contacts: Option<Contacts>,
    /// Friction contacts of its loss frames.
    pub friction: Option<FrictionContacts>,
    /// Windows in the part.
    pub size: usize,
}

impl NeuralSession {
    /// The data of `part` of a batch of training `windows` (`frames` per window, the last
    /// `predicted` decoded), with its augmentation `picks`.
    pub(super) fn part_batch(
        &self,
        windows: &[(usize, usize)],
        part: Part,
        frames: usize,
        predicted: usize,
        picks: Vec<i64>,
    ) -> PartBatch {
        let batch = self.train.batch_with_still(
            &windows[part.windows.clone()],
            part.still,
            frames,
            predicted,
            &self.garment.skin,
        );
        PartBatch { part, batch, picks }
    }

    /// The forward and backward passes of one part of a step through `model` (the session's
    /// network, or for a batch in parts a copy with leaves of its own).
    pub(super) fn descend(
        &self,
        model: &ClothNet,
        part: &PartBatch,
        filters: &StepFilters,
    ) -> Result<PartOutcome, TrainError> {
        let PartBatch { part, batch, picks } = part;
        let (x_net, blended) = self.predict(model, batch, part.still, picks);
        // With the gradient filter, the losses are taken on a detached copy of the posed
        // frames; their gradient is filtered and handed to the network through a surrogate.
        let filtered = filters.filter.is_some();
        let x = match filtered {
            true => x_net.clone().detach().require_grad(),
            false => x_net.clone(),
        };
        let kept = part.kept();
        let StepLosses {
            total,
            plain,
            contacts,
            friction,
            mut loss,
        } = self.step_losses(&x_net, &x, filtered, batch, &blended, kept, part.weights)?;
        let losses = Descent {
            total,
            plain,
            still: part.still,
            moving_end: kept,
        };
        let grads = self.step_gradients(filters, &x_net, &x, losses, batch, &mut loss)?;
        Ok(PartOutcome {
            grads: GradientsParams::from_grads(grads, model),
            loss,
            x,
            contacts,
            friction,
            size: part.size(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn halves_split_still_and_augmented_windows_where_they_fall() {
        let p = parts(16, 4, 4, true);
        assert_eq!(p.len(), 2);
        assert_eq!(
            (p[0].windows.clone(), p[0].still, p[0].augment),
            (0..8, 4, 0)
        );
        assert_eq!(
            (p[1].windows.clone(), p[1].still, p[1].augment),
            (8..16, 0, 4)
        );
        // 12 windows keep their inertia: 8 in the first half, 4 in the second.
        assert_eq!(
            p[0].weights,
            PartWeights {
                samples: 0.5,
                kept: 8.0 / 12.0
            }
        );
        assert_eq!(
            p[1].weights,
            PartWeights {
                samples: 0.5,
                kept: 4.0 / 12.0
            }
        );
        let sum: f64 = p.iter().map(|p| p.weights.kept).sum();
        assert!((sum - 1.0).abs() < 1e-12);
    }

    #[test]
    fn still_windows_crossing_the_middle_are_shared() {
        let p = parts(7, 5, 2, true);
        assert_eq!(
            (p[0].windows.clone(), p[0].still, p[0].augment),
            (0..3, 3, 0)
        );
        assert_eq!(
            (p[1].windows.clone(), p[1].still, p[1].augment),
            (3..7, 2, 2)
        );
    }

    #[test]
    fn a_half_without_inertia_keeps_the_batch_whole() {
        // With 3 augmented windows the second half keeps one with inertia; with 4 none.
        assert_eq!(parts(8, 0, 3, true).len(), 2);
        let p = parts(8, 0, 4, true);
        assert_eq!(p.len(), 1);
        assert_eq!(p[0].weights, PartWeights::WHOLE);
        assert_eq!(parts(16, 4, 4, false).len(), 1);
        assert_eq!(parts(1, 0, 0, true).len(), 1);
    }
}
