//! The network's side of a training step: descriptors in, posed garment out (with the
//! paper's motion augmentation and the still windows' detached static code), and the pinning
//! targets of the predicted frames.

use burn::tensor::{Int, Tensor, TensorData};
use neural_cloth_model::ClothNet;
use rand::Rng;
use rand::seq::SliceRandom;

use super::NeuralSession;
use crate::data::Batch;

/// The samples whose dynamic codes the last `augment` of `b` samples take (the paper's motion
/// augmentation): the first `augment` entries of a shuffle of `0..b` drawn from `rng`.
pub(super) fn augmentation_picks(rng: &mut impl Rng, b: usize, augment: usize) -> Vec<i64> {
    if augment == 0 {
        return Vec::new();
    }
    let mut perm: Vec<i64> = (0..b as i64).collect();
    perm.shuffle(rng);
    perm.truncate(augment);
    perm
}

impl NeuralSession {
    /// Pinning targets of the predicted frames `first..K` of `batch`, stacked frame by frame
    /// (`[(K - first)·B, V, 3]`, the order of [`stack_frames`]): the skinned template, where
    /// the reference simulator holds pinned vertices too. `None` when nothing is pinned or the
    /// scene's pinning effect is off.
    pub(super) fn pin_target(
        &self,
        batch: &Batch,
        blended: &Tensor<4>,
        first: usize,
    ) -> Option<Tensor<3>> {
        self.terms.tensors().pinned.as_ref()?;
        let (b, v, k) = (batch.size, self.garment.vertex_count(), batch.predicted);
        let frames = k.saturating_sub(first);
        let blended = blended
            .clone()
            .narrow(1, first, frames)
            .swap_dims(0, 1)
            .reshape([frames * b, 1, v, 12]);
        let template = self
            .lbs
            .rest(Tensor::zeros([frames * b, 1, v, 3], &self.device));
        Some(crate::losses::skin_blended(template, blended).reshape([frames * b, v, 3]))
    }

    /// `(z_s + z_d, z_d)`, except for the last `picks.len()` samples: their own static code
    /// (detached) plus the dynamic code (detached) of the sample `picks` names, the paper's
    /// motion augmentation ([`augmentation_picks`]). The second code feeds the dynamic basis,
    /// when the network has one.
    fn mix_codes(&self, z_s: Tensor<3>, z_d: Tensor<3>, picks: &[i64]) -> (Tensor<3>, Tensor<3>) {
        let augment = picks.len();
        if augment == 0 {
            return (z_s + z_d.clone(), z_d);
        }
        let b = z_s.dims()[0];
        let kept = b - augment;
        let picks =
            Tensor::<1, Int>::from_data(TensorData::new(picks.to_vec(), [augment]), &self.device);
        let shuffled_d = z_d.clone().select(0, picks).detach();
        let mixed_d = Tensor::cat(vec![z_d.narrow(0, 0, kept), shuffled_d], 0);
        let z_s = Tensor::cat(
            vec![
                z_s.clone().narrow(0, 0, kept),
                z_s.narrow(0, kept, augment).detach(),
            ],
            0,
        );
        (z_s + mixed_d.clone(), mixed_d)
    }

    /// Posed garment `[B, K, V, 3]` of the last `K = batch.predicted` frames of `batch` whose
    /// first `still` windows are still, with `augment` samples (the last ones) given another
    /// sample's dynamic code and detached encoders.
    /// Also returns the batch's blended skinning matrices as a tensor (`[B, K, V, 12]`), for
    /// the pinning targets.
    /// `model` is the session's network or a copy of it with leaves of its own
    /// ([`super::split::fresh_leaves`]); `picks` are the augmented samples' picks
    /// ([`augmentation_picks`], empty when none are augmented).
    pub(super) fn predict(
        &self,
        model: &ClothNet,
        batch: &Batch,
        still: usize,
        picks: &[i64],
    ) -> (Tensor<4>, Tensor<4>) {
        let augment = picks.len();
        let (b, t, k) = (batch.size, batch.frames, batch.predicted);
        let j = self.train.input_joints;
        let statics = self.tensor4(batch.static_desc.clone(), [b, t, j, 9]);
        let dynamics = (model.kind() != neural_cloth_model::EncoderKind::StaticOnly)
            .then(|| self.tensor4(batch.dynamic_desc.clone(), [b, t, j, 12]));
        // The frames before the window only set the GRU's starting state (no gradient).
        let burn = t.saturating_sub(self.window_frames());
        let (statics, dynamics, state) = if burn > 0 {
            let state = dynamics
                .as_ref()
                .and_then(|d| model.burn_in_state(d.clone().narrow(1, 0, burn)));
            (
                statics.narrow(1, burn, t - burn),
                dynamics.map(|d| d.narrow(1, burn, t - burn)),
                state,
            )
        } else {
            (statics, dynamics, None)
        };
        // Still windows (the first `still` rows) skip the dynamic encoder where allowed.
        let quiet = if self.config.skip_still_dynamics {
            still
        } else {
            0
        };
        let split_static = self.config.static_from_still && still > 0 && still < b;
        let offsets = if (augment == 0 && !split_static) || !model.has_dynamic_branch() {
            model.forward_last(statics, dynamics, 1.0, k, state, quiet)
        } else {
            let (z_s, z_d) = model.encode_last(statics, dynamics, k, state, quiet);
            match z_d {
                Some(z_d) => {
                    let z_s = if split_static {
                        detach_from(z_s, still)
                    } else {
                        z_s
                    };
                    let (z, z_d) = self.mix_codes(z_s, z_d, picks);
                    model.decode_with(z, Some(z_d))
                }
                None => model.decode(z_s),
            }
        };
        let v = self.garment.vertex_count();
        let blended = self.tensor4(batch.blended.clone(), [b, k, v, 12]);
        let x = crate::losses::skin_blended(self.lbs.rest(offsets), blended.clone());
        (x, blended)
    }
}

/// `z` with rows `from..` detached (their gradient stops here).
fn detach_from(z: Tensor<3>, from: usize) -> Tensor<3> {
    let b = z.dims()[0];
    if from >= b {
        return z;
    }
    let tail = z.clone().narrow(0, from, b - from).detach();
    Tensor::cat(vec![z.narrow(0, 0, from), tail], 0)
}
