//! Body motion descriptors (paper §3.2), per input joint:
//!
//! * static, 9 values: the 6D local rotation (first two columns of the local rotation matrix,
//!   [`rotation_to_6d`]) and the *unposed* unit gravity `R_globalᵀ ĝ`;
//! * dynamic, 12 values: the time derivative of the 9 static values `(s_t - s_{t-1}) / dt`
//!   and the joint acceleration `(p_t - 2 p_{t-1} + p_{t-2}) / dt²` unposed by `R_globalᵀ`
//!   (not normalised).
//!
//! [`RotationFrame`] picks how rotations enter. The paper's ([`RotationFrame::Paper`]) gives
//! the root its global rotation, heading included, and differentiates the 6D values in the
//! parent's frame: a turn about the vertical then reaches the dynamic encoder as
//! `ω (-sin φ, 0, -cos φ)` with `φ` the heading it never sees, so the sign of the turn is
//! not in any one frame's input. [`RotationFrame::HeadingFree`] (the default since round
//! 24, docs/TRAINING.md) removes the root's heading about gravity (swing-twist) from its
//! static 6D and differentiates every rotation in the joint's own frame,
//! `6D(R_{t-1}ᵀ R_t - I) / dt` (about `[0, ω_z, -ω_y, -ω_z, 0, ω_x]`): every
//! descriptor is then invariant to the heading and the turning rate appears with its sign.
//!
//! Values that need history a sequence does not have (the first frame's derivative, the first
//! two frames' acceleration) are zero, as if the sequence were padded with still frames; a
//! still body therefore always gives exactly zero dynamic descriptors. Hands, feet, toes and
//! face joints are dropped by case-insensitive name patterns.
//!
//! [`DescriptorStream`] works frame by frame with preallocated buffers (used by inference);
//! [`DescriptorExtractor`] runs the same code over whole sequences and motions (used by
//! training) and returns flat `[T, J, 9]` / `[T, J, 12]` arrays.

use serde::{Deserialize, Serialize};

use neural_cloth_core::geometry::{Mat3, Mat4, Vec3, rotation_to_6d, safe_normalize};
use neural_cloth_core::scene::{Motion, Pose, Skeleton};

use super::ModelError;
pub use super::heading::RotationFrame;
use super::heading::without_heading;

/// Static descriptor values per joint.
pub const STATIC_DIM: usize = 9;
/// Dynamic descriptor values per joint.
pub const DYNAMIC_DIM: usize = 12;

/// Which joints feed the network and how gravity points.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct DescriptorConfig {
    /// Case-insensitive name substrings; a joint whose name contains any of them is dropped
    /// from the network input (it still moves the body and garment). Default: hands, feet,
    /// toes, fingers, face and end-site joints (`hand`, `foot`, `toe`, `_end`, `headtop`,
    /// `finger`, `thumb`, `index`, `middle`, `ring`, `pinky`, `eye`, `jaw`, `tongue`, `nose`,
    /// `site`). Head and neck are kept.
    pub exclude_patterns: Vec<String>,
    /// Gravity direction in world space, normalised on use (any non-zero length); default
    /// `[0, -1, 0]` (Y up).
    pub gravity_dir: [f32; 3],
    /// How rotations enter (default [`RotationFrame::HeadingFree`]; a saved configuration
    /// without the field is [`RotationFrame::Paper`], as it was trained).
    #[serde(default = "RotationFrame::saved_before_round_24")]
    pub rotation_frame: RotationFrame,
}

/// Root mean square of each dynamic channel over every frame and joint of `sets`, floored at
/// `1e-3` so that a channel that never moves divides by little (the dynamic encoder's input
/// scale, [`crate::ClothNetConfig::dynamic_input_scale`]).
pub fn dynamic_channel_rms(sets: &[&Descriptors]) -> Vec<f32> {
    let mut sum = [0.0f64; DYNAMIC_DIM];
    let mut count = 0usize;
    for d in sets {
        for row in d.dynamic_desc.chunks_exact(DYNAMIC_DIM) {
            for (s, v) in sum.iter_mut().zip(row) {
                *s += f64::from(*v) * f64::from(*v);
            }
            count += 1;
        }
    }
    sum.iter()
        .map(|s| ((s / count.max(1) as f64).sqrt() as f32).max(1e-3))
        .collect()
}

impl Default for DescriptorConfig {
    fn default() -> Self {
        let patterns = [
            "hand", "foot", "toe", "_end", "headtop", "finger", "thumb", "index", "middle", "ring",
            "pinky", "eye", "jaw", "tongue", "nose", "site",
        ];
        Self {
            exclude_patterns: patterns.iter().map(|s| s.to_string()).collect(),
            gravity_dir: [0.0, -1.0, 0.0],
            rotation_frame: RotationFrame::default(),
        }
    }
}

/// Indices of the joints whose names contain none of `patterns` (case-insensitive).
pub fn select_input_joints(names: &[String], patterns: &[String]) -> Vec<usize> {
    let lowered: Vec<String> = patterns
        .iter()
        .map(|p| p.to_lowercase())
        .filter(|p| !p.is_empty())
        .collect();
    names
        .iter()
        .enumerate()
        .filter(|(_, n)| {
            let n = n.to_lowercase();
            !lowered.iter().any(|p| n.contains(p.as_str()))
        })
        .map(|(j, _)| j)
        .collect()
}

/// Forward kinematics into `out` without allocating (see [`Skeleton::world_from_joint_into`]).
pub fn world_from_joint_into(skeleton: &Skeleton, pose: &Pose, out: &mut [Mat4]) {
    skeleton.world_from_joint_into(pose, out);
}

/// Rotation part of an affine matrix with scale (and shear) removed by Gram-Schmidt, as
/// [`neural_cloth_core::scene::skeleton::rotation_of`] but as a matrix and without allocating; identity
/// when degenerate.
pub fn rotation_part(m: &Mat4) -> Mat3 {
    let a: Vec3 = m.fixed_view::<3, 1>(0, 0).into_owned();
    let b: Vec3 = m.fixed_view::<3, 1>(0, 1).into_owned();
    let Some(c0) = safe_normalize(a) else {
        return Mat3::identity();
    };
    let Some(c1) = safe_normalize(b - c0 * c0.dot(&b)) else {
        return Mat3::identity();
    };
    Mat3::from_columns(&[c0, c1, c0.cross(&c1)])
}

/// Frame-by-frame descriptor computation with preallocated buffers: [`DescriptorStream::push`]
/// allocates nothing.
#[derive(Clone, Debug)]
pub struct DescriptorStream {
    skeleton: Skeleton,
    input_joints: Vec<usize>,
    gravity_unit: Vec3,
    rotation_frame: RotationFrame,
    dt_secs: f32,
    world: Vec<Mat4>,
    /// Local rotation of each input joint, this frame and the last.
    rot_cur: Vec<Mat3>,
    rot_prev: Vec<Mat3>,
    static_cur: Vec<f32>,
    static_prev: Vec<f32>,
    dynamic: Vec<f32>,
    pos: [Vec<Vec3>; 3],
    frames_seen: usize,
}

impl DescriptorStream {
    /// A stream for `skeleton` sampled every `dt_secs` seconds (> 0, e.g. 1/30).
    pub fn new(
        skeleton: &Skeleton,
        config: &DescriptorConfig,
        dt_secs: f32,
    ) -> Result<Self, ModelError> {
        if !(dt_secs.is_finite() && dt_secs > 0.0) {
            return Err(ModelError::InvalidInput(format!(
                "descriptor time step {dt_secs} s is not positive"
            )));
        }
        let g = Vec3::from(config.gravity_dir);
        let Some(gravity_unit) = safe_normalize(g).filter(|v| v.iter().all(|c| c.is_finite()))
        else {
            return Err(ModelError::InvalidInput(format!(
                "gravity direction {:?} has no direction",
                config.gravity_dir
            )));
        };
        let input_joints = select_input_joints(&skeleton.names, &config.exclude_patterns);
        if input_joints.is_empty() {
            return Err(ModelError::NoInputJoints {
                patterns: config.exclude_patterns.clone(),
                joints: skeleton.len(),
            });
        }
        let j = input_joints.len();
        Ok(Self {
            skeleton: skeleton.clone(),
            gravity_unit,
            rotation_frame: config.rotation_frame,
            dt_secs,
            world: vec![Mat4::identity(); skeleton.len()],
            rot_cur: vec![Mat3::identity(); j],
            rot_prev: vec![Mat3::identity(); j],
            static_cur: vec![0.0; j * STATIC_DIM],
            static_prev: vec![0.0; j * STATIC_DIM],
            dynamic: vec![0.0; j * DYNAMIC_DIM],
            pos: [
                vec![Vec3::zeros(); j],
                vec![Vec3::zeros(); j],
                vec![Vec3::zeros(); j],
            ],
            frames_seen: 0,
            input_joints,
        })
    }

    /// Skeleton indices of the input joints, in descriptor order.
    pub fn input_joints(&self) -> &[usize] {
        &self.input_joints
    }

    /// Number of input joints `J`.
    pub fn joint_count(&self) -> usize {
        self.input_joints.len()
    }

    /// The skeleton the stream was built for.
    pub fn skeleton(&self) -> &Skeleton {
        &self.skeleton
    }

    /// Time step between pushed poses in seconds.
    pub fn dt_secs(&self) -> f32 {
        self.dt_secs
    }

    /// Forgets the history: the next pose is treated as the first of a sequence.
    pub fn reset(&mut self) {
        self.frames_seen = 0;
    }

    /// Frames pushed since the last reset.
    pub fn frames_seen(&self) -> usize {
        self.frames_seen
    }

    /// Checks that `pose` fits the skeleton and is finite.
    pub fn check_pose(&self, pose: &Pose) -> Result<(), ModelError> {
        if pose.rotations.len() != self.skeleton.len() {
            return Err(ModelError::ShapeMismatch {
                what: "pose rotations (one per skeleton joint)".into(),
                expected: self.skeleton.len(),
                found: pose.rotations.len(),
            });
        }
        let finite = pose.root_translation.iter().all(|v| v.is_finite())
            && pose
                .rotations
                .iter()
                .all(|q| q.coords.iter().all(|v| v.is_finite()));
        if !finite {
            return Err(ModelError::InvalidInput(
                "pose has a non-finite rotation or root translation".into(),
            ));
        }
        Ok(())
    }

    /// Consumes the next pose and updates the descriptors; allocates nothing.
    pub fn push(&mut self, pose: &Pose) -> Result<(), ModelError> {
        self.check_pose(pose)?;
        world_from_joint_into(&self.skeleton, pose, &mut self.world);
        std::mem::swap(&mut self.static_cur, &mut self.static_prev);
        std::mem::swap(&mut self.rot_cur, &mut self.rot_prev);
        self.pos.rotate_right(1); // pos[0] becomes free, pos[1] = t-1, pos[2] = t-2
        let inv_dt = 1.0 / self.dt_secs;
        let inv_dt2 = inv_dt * inv_dt;
        let has_prev = self.frames_seen >= 1;
        let has_prev2 = self.frames_seen >= 2;
        for (k, &j) in self.input_joints.iter().enumerate() {
            let world = self.world[j];
            let global_from_joint = rotation_part(&world);
            let local = pose.rotations[j].to_rotation_matrix().into_inner();
            self.rot_cur[k] = local;
            let heading_free = self.rotation_frame == RotationFrame::HeadingFree;
            let six = if heading_free && self.skeleton.parents[j].is_none() {
                rotation_to_6d(&without_heading(&global_from_joint, &-self.gravity_unit))
            } else {
                rotation_to_6d(&local)
            };
            let gravity = global_from_joint.transpose() * self.gravity_unit;
            let s = &mut self.static_cur[k * STATIC_DIM..(k + 1) * STATIC_DIM];
            s[..6].copy_from_slice(&six);
            s[6..].copy_from_slice(gravity.as_slice());
            let p = world.fixed_view::<3, 1>(0, 3).into_owned();
            self.pos[0][k] = p;
            let d = &mut self.dynamic[k * DYNAMIC_DIM..(k + 1) * DYNAMIC_DIM];
            if has_prev {
                let prev = &self.static_prev[k * STATIC_DIM..(k + 1) * STATIC_DIM];
                let cur = &self.static_cur[k * STATIC_DIM..(k + 1) * STATIC_DIM];
                for ((dv, c), pv) in d[..STATIC_DIM].iter_mut().zip(cur).zip(prev) {
                    *dv = (c - pv) * inv_dt;
                }
                if heading_free {
                    // R_{t-1}ᵀ R_t - I as R_{t-1}ᵀ (R_t - R_{t-1}): exactly zero when still.
                    let prev_rot = self.rot_prev[k];
                    let step = rotation_to_6d(&(prev_rot.transpose() * (local - prev_rot)));
                    for (dv, v) in d[..6].iter_mut().zip(step) {
                        *dv = v * inv_dt;
                    }
                }
            } else {
                d[..STATIC_DIM].fill(0.0);
            }
            if has_prev2 {
                let (p1, p2) = (self.pos[1][k], self.pos[2][k]);
                let accel = ((p - p1) - (p1 - p2)) * inv_dt2;
                let local_accel = global_from_joint.transpose() * accel;
                d[STATIC_DIM..].copy_from_slice(local_accel.as_slice());
            } else {
                d[STATIC_DIM..].fill(0.0);
            }
        }
        self.frames_seen += 1;
        Ok(())
    }

    /// Static descriptors of the last pushed pose, `[J, 9]` row-major.
    pub fn static_desc(&self) -> &[f32] {
        &self.static_cur
    }

    /// Dynamic descriptors of the last pushed pose, `[J, 12]` row-major.
    pub fn dynamic_desc(&self) -> &[f32] {
        &self.dynamic
    }

    /// True when every dynamic descriptor of the last pose is exactly zero.
    pub fn dynamic_is_zero(&self) -> bool {
        self.dynamic.iter().all(|v| *v == 0.0)
    }

    /// `world_from_joint` of every skeleton joint for the last pushed pose.
    pub fn world_from_joint(&self) -> &[Mat4] {
        &self.world
    }
}

/// Descriptors of a whole sequence: `frames` × `joints` × 9 and × 12, flat and row-major.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Descriptors {
    /// Number of frames `T`.
    pub frames: usize,
    /// Number of input joints `J`.
    pub joints: usize,
    /// Static descriptors `[T, J, 9]`.
    pub static_desc: Vec<f32>,
    /// Dynamic descriptors `[T, J, 12]`.
    pub dynamic_desc: Vec<f32>,
}

impl Descriptors {
    /// Static descriptors of frame `t`, `[J, 9]`.
    pub fn static_frame(&self, t: usize) -> Option<&[f32]> {
        let n = self.joints * STATIC_DIM;
        self.static_desc.get(t * n..(t + 1) * n)
    }

    /// Dynamic descriptors of frame `t`, `[J, 12]`.
    pub fn dynamic_frame(&self, t: usize) -> Option<&[f32]> {
        let n = self.joints * DYNAMIC_DIM;
        self.dynamic_desc.get(t * n..(t + 1) * n)
    }

    /// Appends the window of `len` frames ending at frame `last` (inclusive) to the two
    /// outputs (`len * J * 9` and `len * J * 12` values). Frames before 0 are still copies of
    /// frame 0 (its static descriptors, zero dynamics); `last` past the end is clamped.
    pub fn append_window(
        &self,
        last: usize,
        len: usize,
        static_out: &mut Vec<f32>,
        dynamic_out: &mut Vec<f32>,
    ) {
        if self.frames == 0 {
            return;
        }
        let last = last.min(self.frames - 1) as isize;
        for k in 0..len as isize {
            let t = last - (len as isize - 1) + k;
            let frame = t.max(0) as usize;
            if let Some(s) = self.static_frame(frame) {
                static_out.extend_from_slice(s);
            }
            match self.dynamic_frame(frame) {
                Some(d) if t >= 0 => dynamic_out.extend_from_slice(d),
                _ => dynamic_out.extend(std::iter::repeat_n(0.0, self.joints * DYNAMIC_DIM)),
            }
        }
    }
}

impl Descriptors {
    /// Appends a still window: frame `frame` held for `len` frames (its static descriptors,
    /// zero dynamics), as if the body had stood in that pose for the whole window.
    pub fn append_still(
        &self,
        frame: usize,
        len: usize,
        static_out: &mut Vec<f32>,
        dynamic_out: &mut Vec<f32>,
    ) {
        if self.frames == 0 {
            return;
        }
        let frame = frame.min(self.frames - 1);
        for _ in 0..len {
            if let Some(s) = self.static_frame(frame) {
                static_out.extend_from_slice(s);
            }
            dynamic_out.extend(std::iter::repeat_n(0.0, self.joints * DYNAMIC_DIM));
        }
    }
}

/// Descriptors of whole sequences at a fixed frame rate (the training rate).
#[derive(Clone, Debug)]
pub struct DescriptorExtractor {
    stream: DescriptorStream,
    fps: f32,
}

impl DescriptorExtractor {
    /// An extractor for `skeleton` at `fps` frames per second (> 0).
    pub fn new(
        skeleton: &Skeleton,
        config: &DescriptorConfig,
        fps: f32,
    ) -> Result<Self, ModelError> {
        if !(fps.is_finite() && fps > 0.0) {
            return Err(ModelError::InvalidInput(format!(
                "frame rate {fps} is not positive"
            )));
        }
        Ok(Self {
            stream: DescriptorStream::new(skeleton, config, 1.0 / fps)?,
            fps,
        })
    }

    /// Frame rate in frames per second.
    pub fn fps(&self) -> f32 {
        self.fps
    }

    /// Skeleton indices of the input joints, in descriptor order.
    pub fn input_joints(&self) -> &[usize] {
        self.stream.input_joints()
    }

    /// Number of input joints `J`.
    pub fn joint_count(&self) -> usize {
        self.stream.joint_count()
    }

    /// A fresh frame-by-frame stream with the same skeleton, joints and time step.
    pub fn stream(&self) -> DescriptorStream {
        let mut s = self.stream.clone();
        s.reset();
        s
    }

    /// Descriptors of `poses`, taken as consecutive frames `1/fps` apart.
    pub fn poses(&mut self, poses: &[Pose]) -> Result<Descriptors, ModelError> {
        let j = self.stream.joint_count();
        let mut out = Descriptors {
            frames: poses.len(),
            joints: j,
            static_desc: Vec::with_capacity(poses.len() * j * STATIC_DIM),
            dynamic_desc: Vec::with_capacity(poses.len() * j * DYNAMIC_DIM),
        };
        self.stream.reset();
        for pose in poses {
            self.stream.push(pose)?;
            out.static_desc.extend_from_slice(self.stream.static_desc());
            out.dynamic_desc
                .extend_from_slice(self.stream.dynamic_desc());
        }
        self.stream.reset();
        Ok(out)
    }

    /// Descriptors of `motion`, resampled (slerp) to the extractor's rate when its own differs.
    pub fn motion(&mut self, motion: &Motion) -> Result<Descriptors, ModelError> {
        if (motion.fps - self.fps).abs() <= 1e-4 * self.fps {
            self.poses(&motion.frames)
        } else {
            let resampled = motion.resample(self.fps)?;
            self.poses(&resampled.frames)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dynamic_channel_rms_is_per_channel_over_every_set_and_floored() {
        let set = |rows: &[[f32; DYNAMIC_DIM]]| Descriptors {
            frames: rows.len(),
            joints: 1,
            static_desc: vec![0.0; rows.len() * STATIC_DIM],
            dynamic_desc: rows.iter().flatten().copied().collect(),
        };
        let mut a = [0.0f32; DYNAMIC_DIM];
        a[0] = 3.0;
        a[11] = -30.0;
        let mut b = [0.0f32; DYNAMIC_DIM];
        b[0] = -4.0;
        let rms = dynamic_channel_rms(&[&set(&[a]), &set(&[b])]);
        assert_eq!(rms.len(), DYNAMIC_DIM);
        assert!((rms[0] - (12.5f32).sqrt()).abs() < 1e-5, "{}", rms[0]);
        assert!((rms[11] - (450.0f32).sqrt()).abs() < 1e-4, "{}", rms[11]);
        assert_eq!(rms[5], 1e-3, "a channel that never moves is floored");
    }
    use neural_cloth_core::geometry::Quat;
    use neural_cloth_core::scene::JointTransform;

    fn skeleton(names: &[&str]) -> Skeleton {
        let n = names.len();
        let rest: Vec<JointTransform> = (0..n)
            .map(|j| JointTransform {
                translation: if j == 0 {
                    Vec3::zeros()
                } else {
                    Vec3::y() * 0.3
                },
                ..Default::default()
            })
            .collect();
        let parents = (0..n).map(|j| j.checked_sub(1)).collect();
        Skeleton::new(
            names.iter().map(|s| s.to_string()).collect(),
            parents,
            rest,
            vec![Mat4::identity(); n],
            vec![Mat4::identity(); n],
        )
        .unwrap()
    }

    #[test]
    fn default_patterns_drop_extremities_and_keep_head() {
        let names: Vec<String> = [
            "Hips",
            "Spine",
            "Spine1",
            "Spine2",
            "Neck",
            "Head",
            "LeftShoulder",
            "LeftArm",
            "LeftForeArm",
            "LeftHand",
            "LeftUpLeg",
            "LeftLeg",
            "LeftFoot",
            "LeftToeBase",
            "RightHandIndex1",
            "HeadTop_End",
            "mixamorig:LeftEye",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        let kept = select_input_joints(&names, &DescriptorConfig::default().exclude_patterns);
        let kept_names: Vec<&str> = kept.iter().map(|&j| names[j].as_str()).collect();
        assert_eq!(
            kept_names,
            [
                "Hips",
                "Spine",
                "Spine1",
                "Spine2",
                "Neck",
                "Head",
                "LeftShoulder",
                "LeftArm",
                "LeftForeArm",
                "LeftUpLeg",
                "LeftLeg"
            ]
        );
    }

    #[test]
    fn rotation_part_strips_scale() {
        let q = Quat::from_euler_angles(0.3, -0.5, 1.1);
        let m = Mat4::new_translation(&Vec3::new(1.0, 2.0, 3.0))
            * q.to_homogeneous()
            * Mat4::new_scaling(0.01);
        assert!((rotation_part(&m) - q.to_rotation_matrix().into_inner()).norm() < 1e-5);
        assert_eq!(rotation_part(&Mat4::zeros()), Mat3::identity());
    }

    #[test]
    fn fk_matches_skeleton() {
        let sk = skeleton(&["a", "b", "c"]);
        let mut pose = sk.rest_pose();
        pose.rotations[1] = Quat::from_euler_angles(0.2, 0.7, -0.4);
        pose.root_translation = Vec3::new(0.5, 1.0, -2.0);
        let mut out = vec![Mat4::zeros(); 3];
        world_from_joint_into(&sk, &pose, &mut out);
        for (a, b) in out.iter().zip(sk.world_from_joint(&pose)) {
            assert!((a - b).norm() < 1e-6);
        }
    }

    #[test]
    fn first_frames_have_zero_dynamics_and_rejects_bad_poses() {
        let sk = skeleton(&["a", "b"]);
        let mut s = DescriptorStream::new(&sk, &DescriptorConfig::default(), 1.0 / 30.0).unwrap();
        let mut pose = sk.rest_pose();
        pose.rotations[0] = Quat::from_euler_angles(0.0, 0.0, 0.5);
        s.push(&pose).unwrap();
        assert!(s.dynamic_is_zero());
        pose.rotations[0] = Quat::from_euler_angles(0.0, 0.0, 0.6);
        s.push(&pose).unwrap();
        assert!(s.dynamic_desc()[..STATIC_DIM].iter().any(|v| *v != 0.0));
        assert!(
            s.dynamic_desc()[STATIC_DIM..DYNAMIC_DIM]
                .iter()
                .all(|v| *v == 0.0),
            "no acceleration without two past frames"
        );
        pose.root_translation.x = f32::NAN;
        assert!(s.push(&pose).is_err());
        pose.rotations.pop();
        assert!(matches!(
            s.push(&pose),
            Err(ModelError::ShapeMismatch { .. })
        ));
        assert!(DescriptorStream::new(&sk, &DescriptorConfig::default(), 0.0).is_err());
        let all = DescriptorConfig {
            exclude_patterns: vec!["".into(), "a".into(), "b".into()],
            ..Default::default()
        };
        assert!(matches!(
            DescriptorStream::new(&sk, &all, 0.1),
            Err(ModelError::NoInputJoints { .. })
        ));
    }

    #[test]
    fn windows_pad_with_still_frames() {
        let d = Descriptors {
            frames: 2,
            joints: 1,
            static_desc: (0..18).map(|v| v as f32).collect(),
            dynamic_desc: (0..24).map(|v| 1.0 + v as f32).collect(),
        };
        let (mut s, mut dy) = (Vec::new(), Vec::new());
        d.append_window(1, 3, &mut s, &mut dy);
        assert_eq!(s.len(), 27);
        assert_eq!(&s[..9], &s[9..18], "padding repeats frame 0");
        assert_eq!(&s[18..], d.static_frame(1).unwrap());
        assert!(dy[..12].iter().all(|v| *v == 0.0));
        assert_eq!(&dy[12..24], d.dynamic_frame(0).unwrap());
        assert_eq!(&dy[24..], d.dynamic_frame(1).unwrap());
    }
}
