//! Linear blend skinning with up to four joint influences per vertex.

use super::{Mat4, Vec3};

/// Influences per vertex.
pub const MAX_INFLUENCES: usize = 4;

/// Per-vertex joint indices and weights. Weights of a vertex sum to 1 and unused slots have
/// weight 0 (their joint index is then irrelevant, conventionally 0).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SkinWeights {
    /// Joint indices into the skeleton.
    pub joints: Vec<[u16; MAX_INFLUENCES]>,
    /// Matching weights, each in `[0, 1]`, summing to 1 per vertex.
    pub weights: Vec<[f32; MAX_INFLUENCES]>,
}

impl SkinWeights {
    /// Number of vertices covered.
    pub fn len(&self) -> usize {
        self.weights.len()
    }

    /// True when no vertex is covered.
    pub fn is_empty(&self) -> bool {
        self.weights.is_empty()
    }

    /// Builds weights from arbitrary `(joint, weight)` lists: keeps the four largest
    /// positive finite weights and renormalises them. A vertex with no usable weight is bound
    /// fully to `fallback_joint`. Returns the weights and how many vertices needed the fallback.
    pub fn from_influences(
        influences: impl IntoIterator<Item = Vec<(u16, f32)>>,
        fallback_joint: u16,
    ) -> (Self, usize) {
        let mut out = Self::default();
        let mut fallbacks = 0;
        for mut list in influences {
            list.retain(|&(_, w)| w.is_finite() && w > 0.0);
            list.sort_by(|a, b| b.1.total_cmp(&a.1));
            list.truncate(MAX_INFLUENCES);
            let sum: f32 = list.iter().map(|&(_, w)| w).sum();
            let mut joints = [0u16; MAX_INFLUENCES];
            let mut weights = [0f32; MAX_INFLUENCES];
            if sum > 1e-8 {
                for (k, &(j, w)) in list.iter().enumerate() {
                    joints[k] = j;
                    weights[k] = w / sum;
                }
            } else {
                joints[0] = fallback_joint;
                weights[0] = 1.0;
                fallbacks += 1;
            }
            out.joints.push(joints);
            out.weights.push(weights);
        }
        (out, fallbacks)
    }

    /// Largest joint index referenced with a non-zero weight, if any.
    pub fn max_joint(&self) -> Option<u16> {
        self.joints
            .iter()
            .zip(&self.weights)
            .flat_map(|(j, w)| j.iter().zip(w).filter(|(_, w)| **w > 0.0).map(|(j, _)| *j))
            .max()
    }
}

/// Skins `positions` with `skin_from_bind[j] = world_from_joint[j] * joint_from_bind[j]`.
pub fn linear_blend_skin(
    positions: &[Vec3],
    skin: &SkinWeights,
    skin_from_bind: &[Mat4],
) -> Vec<Vec3> {
    let mut out = vec![Vec3::zeros(); positions.len()];
    linear_blend_skin_into(positions, skin, skin_from_bind, &mut out);
    out
}

/// Like [`linear_blend_skin`] but writes into `out` (no allocation). Joint indices outside
/// `skin_from_bind` are ignored (their weight is dropped).
pub fn linear_blend_skin_into(
    positions: &[Vec3],
    skin: &SkinWeights,
    skin_from_bind: &[Mat4],
    out: &mut [Vec3],
) {
    for (((p, joints), weights), o) in positions
        .iter()
        .zip(&skin.joints)
        .zip(&skin.weights)
        .zip(out.iter_mut())
    {
        let mut m = Mat4::zeros();
        for k in 0..MAX_INFLUENCES {
            let w = weights[k];
            if w != 0.0
                && let Some(jm) = skin_from_bind.get(joints[k] as usize)
            {
                m += jm * w;
            }
        }
        *o = m.fixed_view::<3, 3>(0, 0) * p + m.fixed_view::<3, 1>(0, 3);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_are_normalised_and_truncated() {
        let (w, fallbacks) = SkinWeights::from_influences(
            vec![
                vec![(0, 1.0), (1, 1.0), (2, 2.0), (3, 0.5), (4, 0.1)],
                vec![(5, f32::NAN), (6, -1.0)],
            ],
            9,
        );
        assert_eq!(fallbacks, 1);
        let s: f32 = w.weights[0].iter().sum();
        assert!((s - 1.0).abs() < 1e-6);
        assert_eq!(w.joints[0][0], 2);
        assert!(!w.joints[0].contains(&4));
        assert_eq!((w.joints[1][0], w.weights[1][0]), (9, 1.0));
    }

    #[test]
    fn blends_two_translations() {
        let (w, _) = SkinWeights::from_influences(vec![vec![(0, 0.25), (1, 0.75)]], 0);
        let ms = [
            Mat4::new_translation(&Vec3::new(4.0, 0.0, 0.0)),
            Mat4::new_translation(&Vec3::new(0.0, 4.0, 0.0)),
        ];
        let out = linear_blend_skin(&[Vec3::new(1.0, 1.0, 1.0)], &w, &ms);
        assert!((out[0] - Vec3::new(2.0, 4.0, 1.0)).norm() < 1e-6);
    }
}
