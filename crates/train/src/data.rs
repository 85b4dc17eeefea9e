//! Training data: the scene's motions resampled to the training rate, turned into descriptors
//! and garment skinning matrices once, then sampled as batches of temporal windows.

use std::sync::{Arc, OnceLock};

use rand::RngExt;
use rand::rngs::StdRng;

use neural_cloth_core::geometry::SkinWeights;
use neural_cloth_core::scene::config::Split;
use neural_cloth_core::scene::{Avatar, Motion, Pose};
use neural_cloth_model::{DescriptorConfig, DescriptorExtractor, Descriptors, SkinMatrixBuilder};
use neural_cloth_physics::PosedBody;

use super::TrainError;

/// Floats per garment skinning matrix (3x4).
const MAT: usize = 12;

/// One motion prepared for training.
pub struct MotionData {
    /// Name (mirrored copies end in "(mirrored)").
    pub name: String,
    /// True for the left/right mirrored copy of a motion.
    pub mirrored: bool,
    /// Poses at the training rate.
    pub poses: Vec<Pose>,
    /// Descriptors of every frame.
    pub descriptors: Descriptors,
    /// Garment skinning matrices `[T, J_all, 12]`.
    pub matrices: Vec<f32>,
    /// Posed bodies, built on first use (collision queries) and kept until
    /// [`Dataset::forget_bodies`].
    bodies: Vec<OnceLock<Arc<PosedBody>>>,
}

impl MotionData {
    /// Number of frames.
    pub fn frames(&self) -> usize {
        self.poses.len()
    }
}

/// The motions of one split.
pub struct Dataset {
    /// Prepared motions.
    pub motions: Vec<MotionData>,
    /// Input joints `J` of the descriptors.
    pub input_joints: usize,
    /// Skeleton joints `J_all` of the matrices.
    pub skeleton_joints: usize,
}

/// A batch of windows, flat and ready to become tensors.
#[derive(Clone, Debug, Default)]
pub struct Batch {
    /// Windows in the batch.
    pub size: usize,
    /// Frames per window `T`.
    pub frames: usize,
    /// Static descriptors `[B, T, J, 9]`.
    pub static_desc: Vec<f32>,
    /// Dynamic descriptors `[B, T, J, 12]`.
    pub dynamic_desc: Vec<f32>,
    /// Predicted (decoded) frames at the end of each window `K`: the loss frames plus the two
    /// frames before the first of them.
    pub predicted: usize,
    /// Per-vertex blended garment skinning matrices of the last `K` frames `[B, K, V, 12]`
    /// (3x4 row-major, `Σ_k w_k M_{j_k}`), computed on the CPU: skinning is then a cheap
    /// element-wise product on the device, with no gather in the forward or backward pass.
    pub blended: Vec<f32>,
    /// `(motion, last frame)` of each window.
    pub windows: Vec<(usize, usize)>,
    /// The first `still` windows are still (their last pose held for the whole window).
    pub still: usize,
}

impl Batch {
    /// `(motion, frame)` of the predicted frames `first..K` of every window, frame by frame
    /// (all windows' frame `first`, then all windows' frame `first + 1`, ...): a still window's
    /// frames are all its last frame. Frames are not clamped to the motion (see
    /// [`Dataset::body`]).
    pub fn stacked_frames(&self, first: usize) -> Vec<(usize, usize)> {
        (first..self.predicted)
            .flat_map(|k| {
                let back = self.predicted - 1 - k;
                self.windows.iter().enumerate().map(move |(s, &(m, last))| {
                    let back = if s < self.still { 0 } else { back };
                    (m, last.saturating_sub(back))
                })
            })
            .collect()
    }
}

/// Per-channel RMS of the dynamic descriptors of the train-split `motions` at `fps` (the
/// [`neural_cloth_model::ClothNetConfig::dynamic_input_scale`] of a new run).
pub fn dynamic_scale_of(
    avatar: &Avatar,
    motions: &[(Motion, Split)],
    fps: f32,
    descriptor_config: &DescriptorConfig,
) -> Result<Vec<f32>, TrainError> {
    let mut extractor = DescriptorExtractor::new(&avatar.skeleton, descriptor_config, fps)?;
    let sets = motions
        .iter()
        .filter(|(_, split)| *split == Split::Train)
        .map(|(motion, _)| extractor.motion(motion))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(neural_cloth_model::dynamic_channel_rms(
        &sets.iter().collect::<Vec<_>>(),
    ))
}

impl Dataset {
    /// Prepares `motions` of `split` (plus left/right mirrors when `mirror`) at `fps`.
    pub fn new(
        avatar: &Avatar,
        motions: &[(Motion, Split)],
        split: Split,
        fps: f32,
        descriptor_config: &DescriptorConfig,
        mirror: bool,
    ) -> Result<Self, TrainError> {
        let mut extractor = DescriptorExtractor::new(&avatar.skeleton, descriptor_config, fps)?;
        let mut builder = SkinMatrixBuilder::new(&avatar.skeleton);
        let mut out = Vec::new();
        for (motion, s) in motions {
            if *s != split {
                continue;
            }
            let resampled = motion
                .resample(fps)
                .map_err(neural_cloth_model::ModelError::from)?;
            let mut variants = vec![(resampled.clone(), false)];
            if mirror {
                variants.push((resampled.mirrored(&avatar.skeleton), true));
            }
            for (m, mirrored) in variants {
                let descriptors = extractor.motion(&m)?;
                let mut matrices = Vec::with_capacity(m.frames.len() * builder.joint_count() * MAT);
                for pose in &m.frames {
                    builder.append(pose, &mut matrices)?;
                }
                let bodies = (0..m.frames.len()).map(|_| OnceLock::new()).collect();
                out.push(MotionData {
                    name: m.name.clone(),
                    mirrored,
                    poses: m.frames,
                    descriptors,
                    matrices,
                    bodies,
                });
            }
        }
        Ok(Self {
            motions: out,
            input_joints: extractor.joint_count(),
            skeleton_joints: builder.joint_count(),
        })
    }

    /// True when the split has no frames.
    pub fn is_empty(&self) -> bool {
        self.motions.iter().all(|m| m.frames() == 0)
    }

    /// True when the split holds mirrored copies of its motions.
    pub fn has_mirrored(&self) -> bool {
        self.motions.iter().any(|m| m.mirrored)
    }

    /// Total frames over all motions.
    pub fn total_frames(&self) -> usize {
        self.motions.iter().map(|m| m.frames()).sum()
    }

    /// Draws `size` windows uniformly over all frames of all motions, or of the motions that
    /// are not mirrored copies when `with_mirrored` is false.
    pub fn sample_windows(
        &self,
        size: usize,
        with_mirrored: bool,
        rng: &mut StdRng,
    ) -> Vec<(usize, usize)> {
        let drawn = |m: &MotionData| with_mirrored || !m.mirrored;
        let total = self
            .motions
            .iter()
            .filter(|m| drawn(m))
            .map(|m| m.frames())
            .sum::<usize>()
            .max(1);
        (0..size)
            .map(|_| {
                let mut k = rng.random_range(0..total);
                for (i, m) in self.motions.iter().enumerate().filter(|(_, m)| drawn(m)) {
                    if k < m.frames() {
                        return (i, k);
                    }
                    k -= m.frames();
                }
                (0, 0)
            })
            .collect()
    }

    /// `count` windows spread evenly over every motion (deterministic; used for validation).
    pub fn even_windows(&self, count: usize) -> Vec<(usize, usize)> {
        let total = self.total_frames();
        if total == 0 {
            return Vec::new();
        }
        let step = (total as f64 / count.max(1) as f64).max(1.0);
        let mut out = Vec::new();
        let mut k = 0.0f64;
        while (k as usize) < total && out.len() < count {
            let mut f = k as usize;
            for (i, m) in self.motions.iter().enumerate() {
                if f < m.frames() {
                    out.push((i, f));
                    break;
                }
                f -= m.frames();
            }
            k += step;
        }
        out
    }

    /// Assembles the windows of `frames` frames ending at each `(motion, last)`, blending the
    /// garment's skinning matrices of the last `predicted` frames per vertex with `skin` (in
    /// parallel).
    pub fn batch(
        &self,
        windows: &[(usize, usize)],
        frames: usize,
        predicted: usize,
        skin: &SkinWeights,
    ) -> Batch {
        self.batch_with_still(windows, 0, frames, predicted, skin)
    }

    /// Appends the static and dynamic descriptors of `windows` (each `frames` long) to the two
    /// outputs, without the skinning matrices (for probing the network's units).
    pub fn append_descriptors(
        &self,
        windows: &[(usize, usize)],
        frames: usize,
        static_out: &mut Vec<f32>,
        dynamic_out: &mut Vec<f32>,
    ) {
        for &(mi, last) in windows {
            if let Some(m) = self.motions.get(mi) {
                m.descriptors
                    .append_window(last, frames, static_out, dynamic_out);
            }
        }
    }

    /// Like [`Self::batch`], but the first `still` windows are still windows: the pose of their
    /// last frame held for the whole window (zero dynamic descriptors, the same skinning for
    /// every predicted frame). They teach the static branch the quasi-static drape of
    /// every training pose, which moving windows alone never show (a spin holds one pose
    /// while turning: its static code would otherwise learn the mean flared shape).
    pub fn batch_with_still(
        &self,
        windows: &[(usize, usize)],
        still: usize,
        frames: usize,
        predicted: usize,
        skin: &SkinWeights,
    ) -> Batch {
        use rayon::prelude::*;
        let j_all = self.skeleton_joints;
        let v = skin.len();
        let mut b = Batch {
            size: windows.len(),
            frames,
            predicted,
            windows: windows.to_vec(),
            still,
            ..Default::default()
        };
        let mut blocks: Vec<&[f32]> = Vec::with_capacity(windows.len() * predicted);
        for (k, &(mi, last)) in windows.iter().enumerate() {
            let Some(m) = self.motions.get(mi) else {
                continue;
            };
            let is_still = k < still;
            if is_still {
                m.descriptors
                    .append_still(last, frames, &mut b.static_desc, &mut b.dynamic_desc);
            } else {
                m.descriptors
                    .append_window(last, frames, &mut b.static_desc, &mut b.dynamic_desc);
            }
            for back in (0..predicted).rev() {
                let back = if is_still { 0 } else { back };
                let f = last.saturating_sub(back).min(m.frames().saturating_sub(1));
                let start = f * j_all * MAT;
                if let Some(block) = m.matrices.get(start..start + j_all * MAT) {
                    blocks.push(block);
                }
            }
        }
        b.blended = vec![0.0; blocks.len() * v * MAT];
        b.blended
            .par_chunks_mut(v * MAT)
            .zip(blocks.par_iter())
            .for_each(|(out, joints)| blend_matrices(joints, skin, out));
        b
    }

    /// The posed bodies of `frames` (`(motion, frame)` pairs, in order), the ones not kept yet
    /// built in parallel and kept until [`Self::forget_bodies`].
    pub fn bodies(
        &self,
        avatar: &Avatar,
        frames: &[(usize, usize)],
    ) -> Result<Vec<Arc<PosedBody>>, TrainError> {
        use rayon::prelude::*;
        frames
            .par_iter()
            .map(|&(m, f)| self.body(avatar, m, f))
            .collect()
    }

    /// Drops the posed bodies kept so far. Each costs about 0.3 MB (a 6000-vertex body's
    /// positions, normals and query tree), so keeping every frame's body of the default
    /// scene (1270 frames, twice with mirrors) grows towards 0.8 GB (615 MB more peak memory
    /// after 300 steps, measured); the trainer forgets them after each step unless
    /// [`crate::TrainConfig::keep_posed_bodies`].
    pub fn forget_bodies(&mut self) {
        for m in &mut self.motions {
            for cell in &mut m.bodies {
                cell.take();
            }
        }
    }

    /// Posed bodies kept now.
    #[cfg(test)]
    fn kept_bodies(&self) -> usize {
        self.motions
            .iter()
            .map(|m| m.bodies.iter().filter(|c| c.get().is_some()).count())
            .sum()
    }

    /// The posed body of `(motion, frame)`, built once and kept until
    /// [`Self::forget_bodies`].
    pub fn body(
        &self,
        avatar: &Avatar,
        motion: usize,
        frame: usize,
    ) -> Result<Arc<PosedBody>, TrainError> {
        let m = self
            .motions
            .get(motion)
            .ok_or_else(|| TrainError::Data(format!("no motion {motion}")))?;
        let f = frame.min(m.frames().saturating_sub(1));
        let Some(cell) = m.bodies.get(f) else {
            return Err(TrainError::Data(format!(
                "motion '{}' has no frame {f}",
                m.name
            )));
        };
        if let Some(b) = cell.get() {
            return Ok(b.clone());
        }
        let body = Arc::new(PosedBody::from_avatar(avatar, &m.poses[f])?);
        Ok(cell.get_or_init(|| body).clone())
    }
}

/// Writes `Σ_k w_k M_{j_k}` for every vertex of `skin` into `out` (`[V, 12]`), from joint
/// matrices `joints` (`[J_all, 12]`). Joints outside the block contribute nothing.
pub fn blend_matrices(joints: &[f32], skin: &SkinWeights, out: &mut [f32]) {
    for ((o, js), ws) in out
        .chunks_exact_mut(MAT)
        .zip(&skin.joints)
        .zip(&skin.weights)
    {
        o.fill(0.0);
        for k in 0..4 {
            let w = ws[k];
            if w == 0.0 {
                continue;
            }
            let start = js[k] as usize * MAT;
            if let Some(m) = joints.get(start..start + MAT) {
                for (a, b) in o.iter_mut().zip(m) {
                    *a += w * b;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn posed_bodies_are_built_once_per_frame_and_forgotten_on_request() {
        use neural_cloth_core::scene::config::SceneConfig;
        use neural_cloth_core::scene::procedural::build_builtin;
        let mut config = SceneConfig::default_scene();
        config.motions.truncate(2);
        let scene = build_builtin(&config).unwrap();
        let mut data = Dataset::new(
            &scene.avatar,
            &scene.motions,
            Split::Train,
            30.0,
            &DescriptorConfig::default(),
            true,
        )
        .unwrap();
        assert_eq!(data.kept_bodies(), 0);
        // A frame asked for twice is built once; frames past a motion's end are its last.
        let frames = [(0, 3), (1, 5), (0, 3), (1, 100_000)];
        let bodies = data.bodies(&scene.avatar, &frames).unwrap();
        assert_eq!(bodies.len(), 4);
        assert!(Arc::ptr_eq(&bodies[0], &bodies[2]));
        assert_eq!(data.kept_bodies(), 3);
        let again = data.body(&scene.avatar, 1, 5).unwrap();
        assert!(Arc::ptr_eq(&again, &bodies[1]), "kept until forgotten");
        data.forget_bodies();
        assert_eq!(data.kept_bodies(), 0);
        let rebuilt = data.body(&scene.avatar, 0, 3).unwrap();
        assert!(!Arc::ptr_eq(&rebuilt, &bodies[0]));
        assert_eq!(rebuilt.positions(), bodies[0].positions(), "the same pose");
        assert!(data.body(&scene.avatar, 9, 0).is_err());
    }

    #[test]
    fn mirrored_copies_are_drawn_only_when_asked() {
        use neural_cloth_core::scene::config::SceneConfig;
        use neural_cloth_core::scene::procedural::build_builtin;
        use rand::SeedableRng;
        let mut config = SceneConfig::default_scene();
        config.motions.truncate(2);
        let scene = build_builtin(&config).unwrap();
        let data = |mirror| {
            Dataset::new(
                &scene.avatar,
                &scene.motions,
                Split::Train,
                30.0,
                &DescriptorConfig::default(),
                mirror,
            )
            .unwrap()
        };
        let (both, plain) = (data(true), data(false));
        assert_eq!(both.motions.iter().filter(|m| m.mirrored).count(), 2);
        let draw = |d: &Dataset, with_mirrored| {
            let windows = d.sample_windows(400, with_mirrored, &mut StdRng::seed_from_u64(3));
            windows
                .iter()
                .map(|&(i, f)| (d.motions[i].name.clone(), f))
                .collect::<Vec<_>>()
        };
        let originals = draw(&both, false);
        assert!(originals.iter().all(|(n, _)| !n.ends_with("(mirrored)")));
        assert_eq!(
            originals,
            draw(&plain, true),
            "the same windows as without the copies"
        );
        let mixed = draw(&both, true);
        assert!(mixed.iter().any(|(n, _)| n.ends_with("(mirrored)")));
    }

    #[test]
    fn stacked_frames_go_frame_by_frame_and_still_windows_hold_their_last_pose() {
        let batch = Batch {
            size: 3,
            predicted: 4,
            windows: vec![(0, 10), (1, 20), (2, 1)],
            still: 1,
            ..Default::default()
        };
        // Loss frames 2 and 3 of K = 4: one and zero frames back from each window's end.
        assert_eq!(
            batch.stacked_frames(2),
            vec![(0, 10), (1, 19), (2, 0), (0, 10), (1, 20), (2, 1)]
        );
        // From frame 0 the oldest predicted frame is three back (clamped at the motion start).
        assert_eq!(batch.stacked_frames(0)[..3], [(0, 10), (1, 17), (2, 0)]);
        assert!(batch.stacked_frames(4).is_empty());
    }
}
