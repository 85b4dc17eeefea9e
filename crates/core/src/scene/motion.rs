//! Motions: per-frame local joint rotations plus root translation, sampled at a fixed rate;
//! slerp resampling to any frame rate and left/right mirroring by joint names.

use crate::geometry::rotation::slerp_unit;
use crate::geometry::{Quat, Vec3};

use super::SceneError;
use super::skeleton::{Pose, Skeleton, rotation_of};

/// A sampled body motion for one skeleton.
#[derive(Clone, Debug, PartialEq)]
pub struct Motion {
    /// Human-readable name (animation name, file stem, or procedural name).
    pub name: String,
    /// Sampling rate in frames per second, > 0.
    pub fps: f32,
    /// One pose per frame; every pose has one rotation per skeleton joint.
    pub frames: Vec<Pose>,
}

/// Tolerance on `| |q| - 1 |` below which a rotation is silently renormalised.
pub const UNIT_TOLERANCE: f32 = 1e-3;

impl Motion {
    /// Builds a motion, checking the rate, joint counts and finiteness, and renormalising
    /// rotations whose norm is within [`UNIT_TOLERANCE`] of 1.
    pub fn new(
        name: impl Into<String>,
        fps: f32,
        mut frames: Vec<Pose>,
        joints: usize,
    ) -> Result<Self, SceneError> {
        let name = name.into();
        if !(fps.is_finite() && fps > 0.0) {
            return Err(SceneError::InvalidMotion {
                name,
                reason: format!("frame rate {fps} is not positive"),
            });
        }
        if frames.is_empty() {
            return Err(SceneError::InvalidMotion {
                name,
                reason: "no frames".into(),
            });
        }
        for (f, pose) in frames.iter_mut().enumerate() {
            if pose.rotations.len() != joints {
                return Err(SceneError::JointCountMismatch {
                    what: format!("motion '{name}' frame {f}"),
                    expected: joints,
                    found: pose.rotations.len(),
                });
            }
            if !pose.root_translation.iter().all(|v| v.is_finite()) {
                return Err(SceneError::InvalidMotion {
                    name,
                    reason: format!("frame {f}: non-finite root translation"),
                });
            }
            for (j, q) in pose.rotations.iter_mut().enumerate() {
                let raw = q.into_inner();
                let n = raw.norm();
                if !(n.is_finite() && (n - 1.0).abs() <= UNIT_TOLERANCE) {
                    return Err(SceneError::InvalidMotion {
                        name,
                        reason: format!(
                            "frame {f}, joint {j}: rotation is not a unit quaternion (norm {n})"
                        ),
                    });
                }
                *q = Quat::new_unchecked(raw / n);
            }
        }
        Ok(Self { name, fps, frames })
    }

    /// A motion that holds `pose` still for `frames` frames.
    pub fn still(name: impl Into<String>, pose: Pose, fps: f32, frames: usize) -> Self {
        Self {
            name: name.into(),
            fps,
            frames: vec![pose; frames.max(1)],
        }
    }

    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.frames.len()
    }

    /// Duration in seconds from the first to the last frame.
    pub fn duration_secs(&self) -> f32 {
        (self.frames.len().saturating_sub(1)) as f32 / self.fps
    }

    /// Pose at `time_secs`, clamped to the motion's range; rotations by slerp, translation by
    /// linear interpolation.
    pub fn sample(&self, time_secs: f32) -> Pose {
        let last = self.frames.len() - 1;
        let x = if time_secs.is_finite() {
            (time_secs * self.fps).clamp(0.0, last as f32)
        } else {
            0.0
        };
        let i = (x.floor() as usize).min(last);
        let t = x - i as f32;
        let j = (i + 1).min(last);
        if t <= 0.0 || i == j {
            return self.frames[i].clone();
        }
        let (a, b) = (&self.frames[i], &self.frames[j]);
        Pose {
            rotations: a
                .rotations
                .iter()
                .zip(&b.rotations)
                .map(|(qa, qb)| slerp_unit(qa, qb, t))
                .collect(),
            root_translation: a.root_translation.lerp(&b.root_translation, t),
        }
    }

    /// The same motion sampled at `fps` over the same duration (at least one frame).
    pub fn resample(&self, fps: f32) -> Result<Self, SceneError> {
        if !(fps.is_finite() && fps > 0.0) {
            return Err(SceneError::InvalidMotion {
                name: self.name.clone(),
                reason: format!("target frame rate {fps} is not positive"),
            });
        }
        let count = (self.duration_secs() * fps + 1e-3).floor() as usize + 1;
        let frames = (0..count).map(|k| self.sample(k as f32 / fps)).collect();
        Ok(Self {
            name: self.name.clone(),
            fps,
            frames,
        })
    }

    /// Frames `[start, end)` as a new motion.
    pub fn slice(&self, start: usize, end: usize) -> Self {
        let end = end
            .min(self.frames.len())
            .max(start.min(self.frames.len() - 1) + 1);
        let start = start.min(end - 1);
        Self {
            name: self.name.clone(),
            fps: self.fps,
            frames: self.frames[start..end].to_vec(),
        }
    }

    /// The left/right mirror of this motion about the skeleton's sagittal (world YZ) plane.
    ///
    /// Works in world space so that joints with different local axes on each side mirror
    /// correctly: the world-space rotation of each joint away from rest is reflected and moved
    /// to its counterpart (found by name), then converted back to local rotations. Assumes the
    /// rest pose itself is left/right symmetric.
    pub fn mirrored(&self, skeleton: &Skeleton) -> Self {
        let pairs = mirror_map(&skeleton.names);
        let rest = skeleton.rest_pose();
        let rest_world: Vec<Quat> = skeleton
            .world_from_joint(&rest)
            .iter()
            .map(rotation_of)
            .collect();
        let root_parent: Vec<Quat> = skeleton
            .world_from_root_parent
            .iter()
            .map(rotation_of)
            .collect();
        let reflect = |q: &Quat| {
            let c = q.coords; // (x, y, z, w)
            Quat::new_unchecked(nalgebra::Quaternion::new(c.w, c.x, -c.y, -c.z))
        };
        let frames = self
            .frames
            .iter()
            .map(|pose| {
                let world: Vec<Quat> = skeleton
                    .world_from_joint(pose)
                    .iter()
                    .map(rotation_of)
                    .collect();
                let mut mirrored_world = vec![Quat::identity(); skeleton.len()];
                for j in 0..skeleton.len() {
                    let delta = world[j] * rest_world[j].inverse();
                    let m = pairs[j];
                    mirrored_world[m] = reflect(&delta) * rest_world[m];
                }
                let rotations = (0..skeleton.len())
                    .map(|j| {
                        let parent = match skeleton.parents[j] {
                            Some(p) => mirrored_world[p],
                            None => root_parent[j],
                        };
                        parent.inverse() * mirrored_world[j]
                    })
                    .collect();
                // The root translation is expressed in the root's parent space: mirror it in world.
                let world_from_parent = skeleton.world_from_root_parent[0];
                let t_world = world_from_parent.transform_point(&pose.root_translation.into());
                let t_mirror = nalgebra::Point3::new(-t_world.x, t_world.y, t_world.z);
                let root_translation = world_from_parent
                    .try_inverse()
                    .map(|inv| inv.transform_point(&t_mirror).coords)
                    .unwrap_or(pose.root_translation);
                Pose {
                    rotations,
                    root_translation,
                }
            })
            .collect();
        Self {
            name: format!("{}{MIRRORED_NAME_SUFFIX}", self.name),
            fps: self.fps,
            frames,
        }
    }

    /// The mirror image a scene's `mirrored = true` asks for: [`Motion::mirrored`], keeping
    /// this motion's name when `keep_name` (the scene named it) and otherwise naming it with
    /// [`SCENE_MIRRORED_NAME_SUFFIX`].
    pub fn mirrored_for_scene(&self, skeleton: &Skeleton, keep_name: bool) -> Self {
        let mut m = self.mirrored(skeleton);
        m.name = if keep_name {
            self.name.clone()
        } else {
            format!("{}{SCENE_MIRRORED_NAME_SUFFIX}", self.name)
        };
        m
    }
}

/// What [`Motion::mirrored`] appends to the name of the motion it mirrors.
pub const MIRRORED_NAME_SUFFIX: &str = " (mirrored)";

/// What a scene's `mirrored = true` appends to the name of the motion it mirrors; not
/// [`MIRRORED_NAME_SUFFIX`], so that a scene's mirror image and the trainer's mirrored copy of
/// the original never share a name.
pub const SCENE_MIRRORED_NAME_SUFFIX: &str = ", mirrored";

/// For each joint, the index of its left/right counterpart (itself when it has none).
pub fn mirror_map(names: &[String]) -> Vec<usize> {
    names
        .iter()
        .enumerate()
        .map(|(j, n)| {
            mirror_name(n)
                .and_then(|m| names.iter().position(|other| *other == m))
                .unwrap_or(j)
        })
        .collect()
}

/// The name of the mirrored joint under common rig conventions (`LeftArm`/`RightArm`,
/// `mixamorig:LeftArm`, `L_arm`/`R_arm`, `arm.L`/`arm.R`, `arm_l`/`arm_r`, `LHipJoint`), or `None`.
pub fn mirror_name(name: &str) -> Option<String> {
    const SWAPS: [(&str, &str); 4] = [
        ("Left", "Right"),
        ("left", "right"),
        ("LEFT", "RIGHT"),
        ("Right", "Left"),
    ];
    for (a, b) in SWAPS
        .iter()
        .chain([("right", "left"), ("RIGHT", "LEFT")].iter())
    {
        if name.contains(a) {
            return Some(name.replacen(a, b, 1));
        }
    }
    let suffixes = [
        (".L", ".R"),
        (".R", ".L"),
        ("_L", "_R"),
        ("_R", "_L"),
        ("_l", "_r"),
        ("_r", "_l"),
        (".l", ".r"),
        (".r", ".l"),
    ];
    for (a, b) in suffixes {
        if let Some(stem) = name.strip_suffix(a) {
            return Some(format!("{stem}{b}"));
        }
    }
    let prefixes = [("L_", "R_"), ("R_", "L_"), ("l_", "r_"), ("r_", "l_")];
    for (a, b) in prefixes {
        if let Some(rest) = name.strip_prefix(a) {
            return Some(format!("{b}{rest}"));
        }
    }
    // CMU style: "LHipJoint", "RThumb": a single capital L/R followed by another capital.
    let mut chars = name.chars();
    if let (Some(first @ ('L' | 'R')), Some(second)) = (chars.next(), chars.next())
        && second.is_ascii_uppercase()
    {
        let other = if first == 'L' { 'R' } else { 'L' };
        return Some(format!("{other}{}", &name[1..]));
    }
    None
}

/// Root-translation-free check used by tests and importers: every rotation is finite.
pub fn pose_is_finite(pose: &Pose) -> bool {
    pose.root_translation.iter().all(|v| v.is_finite())
        && pose
            .rotations
            .iter()
            .all(|q| q.coords.iter().all(|v| v.is_finite()))
}

/// A helper for building poses from Euler-like per-joint rotations: `(joint, axis, radians)`.
pub fn pose_with(
    skeleton: &Skeleton,
    root_translation: Vec3,
    rotations: &[(usize, Vec3, f32)],
) -> Pose {
    let mut pose = skeleton.rest_pose();
    pose.root_translation = root_translation;
    for &(j, axis, angle) in rotations {
        if let (Some(q), Some(axis)) = (
            pose.rotations.get_mut(j),
            nalgebra::Unit::try_new(axis, 1e-9),
        ) {
            *q *= Quat::from_axis_angle(&axis, angle);
        }
    }
    pose
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::rotation::angle_between;

    #[test]
    fn mirror_names() {
        assert_eq!(mirror_name("LeftUpLeg").as_deref(), Some("RightUpLeg"));
        assert_eq!(
            mirror_name("mixamorig:RightHand").as_deref(),
            Some("mixamorig:LeftHand")
        );
        assert_eq!(mirror_name("upperarm.L").as_deref(), Some("upperarm.R"));
        assert_eq!(mirror_name("LHipJoint").as_deref(), Some("RHipJoint"));
        assert_eq!(mirror_name("Spine"), None);
        assert_eq!(mirror_name("Leg"), None);
    }

    fn spin_motion(sk: &Skeleton) -> Motion {
        let frames = (0..121)
            .map(|k| {
                let t = k as f32 / 120.0;
                pose_with(
                    sk,
                    Vec3::new(t, 0.0, 0.0),
                    &[(0, Vec3::y(), 3.0 * t), (1, Vec3::z(), (7.0 * t).sin())],
                )
            })
            .collect();
        Motion::new("spin", 120.0, frames, sk.len()).unwrap()
    }

    #[test]
    fn resample_round_trip_stays_close() {
        let sk = super::super::skeleton::tests::chain();
        let m = spin_motion(&sk);
        let back = m.resample(30.0).unwrap().resample(120.0).unwrap();
        assert_eq!(back.frame_count(), m.frame_count());
        let worst = m
            .frames
            .iter()
            .zip(&back.frames)
            .flat_map(|(a, b)| {
                a.rotations
                    .iter()
                    .zip(&b.rotations)
                    .map(|(x, y)| angle_between(x, y))
            })
            .fold(0.0f32, f32::max);
        assert!(worst < 0.01, "worst {worst} rad");
    }

    #[test]
    fn rejects_non_unit_and_nan() {
        let sk = super::super::skeleton::tests::chain();
        let mut pose = sk.rest_pose();
        pose.rotations[1] = Quat::new_unchecked(nalgebra::Quaternion::new(2.0, 0.0, 0.0, 0.0));
        assert!(Motion::new("x", 30.0, vec![pose.clone()], 3).is_err());
        pose.rotations[1] = Quat::new_unchecked(nalgebra::Quaternion::new(f32::NAN, 0.0, 0.0, 0.0));
        assert!(Motion::new("x", 30.0, vec![pose], 3).is_err());
        assert!(Motion::new("x", 0.0, vec![sk.rest_pose()], 3).is_err());
        assert!(matches!(
            Motion::new("x", 30.0, vec![sk.rest_pose()], 4),
            Err(SceneError::JointCountMismatch { .. })
        ));
    }

    #[test]
    fn mirroring_twice_is_identity() {
        let sk = super::super::skeleton::tests::chain();
        let m = spin_motion(&sk);
        let mm = m.mirrored(&sk).mirrored(&sk);
        for (a, b) in m.frames.iter().zip(&mm.frames) {
            assert!((a.root_translation - b.root_translation).norm() < 1e-5);
            for (x, y) in a.rotations.iter().zip(&b.rotations) {
                assert!(angle_between(x, y) < 1e-3);
            }
        }
    }
}
