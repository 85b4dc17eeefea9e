//! BVH motion capture: the hierarchy (any channel order per joint, `End Site`s) and the
//! per-frame channel values, plus conversion to a skeleton and motion of its own.
//!
//! Conventions: rotation channels are in degrees and compose in the order listed
//! (`Zrotation Yrotation Xrotation` gives `Rz * Ry * Rx`); position channels replace the
//! matching component of the joint's OFFSET (so a root's positions are absolute); the rest
//! pose has every rotation at zero.

use std::path::{Path, PathBuf};

use super::units::{Units, largest_extent};
use super::{IoError, UpAxis, read_bytes};
use crate::geometry::{Mat4, Quat, Vec3};
use crate::scene::{JointTransform, Motion, Pose, Skeleton};

/// One BVH channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BvhChannel {
    /// Translation along X.
    Xposition,
    /// Translation along Y.
    Yposition,
    /// Translation along Z.
    Zposition,
    /// Rotation about X, degrees.
    Xrotation,
    /// Rotation about Y, degrees.
    Yrotation,
    /// Rotation about Z, degrees.
    Zrotation,
}

impl BvhChannel {
    pub(crate) fn parse(s: &str) -> Option<Self> {
        Some(match s.to_ascii_lowercase().as_str() {
            "xposition" => Self::Xposition,
            "yposition" => Self::Yposition,
            "zposition" => Self::Zposition,
            "xrotation" => Self::Xrotation,
            "yrotation" => Self::Yrotation,
            "zrotation" => Self::Zrotation,
            _ => return None,
        })
    }
}

/// A joint of a BVH hierarchy.
#[derive(Clone, Debug, PartialEq)]
pub struct BvhJoint {
    /// Name as written in the file.
    pub name: String,
    /// Parent joint; `None` for the root.
    pub parent: Option<usize>,
    /// Offset from the parent in file units.
    pub offset: Vec3,
    /// Channels in file order.
    pub channels: Vec<BvhChannel>,
    /// Index of this joint's first channel within a frame's values.
    pub first_channel: usize,
    /// Offset of the `End Site` below this joint, if any.
    pub end_site: Option<Vec3>,
}

/// A parsed BVH file.
#[derive(Clone, Debug)]
pub struct Bvh {
    /// Display name (file stem).
    pub name: String,
    /// The file (for messages).
    pub path: PathBuf,
    /// Joints in file (depth-first) order: parents precede children.
    pub joints: Vec<BvhJoint>,
    /// Seconds between frames, in [0.0001, 10].
    pub frame_time_secs: f32,
    /// Channels per frame.
    pub channel_count: usize,
    /// Number of frames (as declared and read), >= 1.
    pub frames: usize,
    /// `frame_count * channel_count` values, frame after frame.
    pub values: Vec<f32>,
    /// Non-fatal problems found while parsing.
    pub warnings: Vec<String>,
    /// Which axis of the file is up ([`UpAxis::Auto`] after parsing: detected from the rest
    /// pose, see [`Bvh::up_axis`]); set it to override. A Z-up file is turned Y up by
    /// [`Bvh::to_skeleton`] and by retargeting.
    pub up: UpAxis,
}

/// Loads and parses a BVH file.
pub fn load_bvh(path: &Path) -> Result<Bvh, IoError> {
    Bvh::parse(&read_bytes(path)?, path)
}

impl Bvh {
    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.frames
    }

    /// Frames per second.
    pub fn fps(&self) -> f32 {
        1.0 / self.frame_time_secs
    }

    /// Seconds from the first to the last frame.
    pub fn duration_secs(&self) -> f32 {
        self.frame_count().saturating_sub(1) as f32 * self.frame_time_secs
    }

    /// Local translation and rotation of joint `j` in frame `f` (rest values when out of range).
    pub fn local(&self, f: usize, j: usize) -> (Vec3, Quat) {
        let Some(joint) = self.joints.get(j) else {
            return (Vec3::zeros(), Quat::identity());
        };
        let frame = self
            .values
            .get(f * self.channel_count..(f + 1) * self.channel_count)
            .unwrap_or(&[]);
        let mut t = joint.offset;
        let mut q = Quat::identity();
        for (k, ch) in joint.channels.iter().enumerate() {
            let Some(&v) = frame.get(joint.first_channel + k) else {
                break;
            };
            match ch {
                BvhChannel::Xposition => t.x = v,
                BvhChannel::Yposition => t.y = v,
                BvhChannel::Zposition => t.z = v,
                BvhChannel::Xrotation => {
                    q *= Quat::from_axis_angle(&Vec3::x_axis(), v.to_radians())
                }
                BvhChannel::Yrotation => {
                    q *= Quat::from_axis_angle(&Vec3::y_axis(), v.to_radians())
                }
                BvhChannel::Zrotation => {
                    q *= Quat::from_axis_angle(&Vec3::z_axis(), v.to_radians())
                }
            }
        }
        (t, q)
    }

    /// World rotation and position of every joint in frame `f`.
    pub fn world(&self, f: usize) -> Vec<(Quat, Vec3)> {
        let mut out: Vec<(Quat, Vec3)> = Vec::with_capacity(self.joints.len());
        for (j, joint) in self.joints.iter().enumerate() {
            let (t, q) = self.local(f, j);
            let w = match joint.parent.and_then(|p| out.get(p)) {
                Some(&(pq, pp)) => (pq * q, pp + pq * t),
                None => (q, t),
            };
            out.push(w);
        }
        out
    }

    /// Rest-pose (all rotations zero, offsets only) positions of the joints, root at its offset.
    pub fn rest_positions(&self) -> Vec<Vec3> {
        let mut out: Vec<Vec3> = Vec::with_capacity(self.joints.len());
        for joint in &self.joints {
            let p = joint
                .parent
                .and_then(|p| out.get(p))
                .copied()
                .unwrap_or_else(Vec3::zeros)
                + joint.offset;
            out.push(p);
        }
        out
    }

    /// Rest positions of the joints followed by those of the end sites.
    pub fn rest_points(&self) -> Vec<Vec3> {
        let joints = self.rest_positions();
        let ends: Vec<Vec3> = self
            .joints
            .iter()
            .zip(&joints)
            .filter_map(|(j, p)| j.end_site.map(|e| p + e))
            .collect();
        joints.into_iter().chain(ends).collect()
    }

    /// The up axis this file is read with: [`Bvh::up`], or detected from the rest skeleton's
    /// structure (see [`UpAxis::detect_body`]); and whether it was detected.
    pub fn up_axis(&self) -> (UpAxis, bool) {
        let parents: Vec<Option<usize>> = self.joints.iter().map(|j| j.parent).collect();
        self.up.resolve_body(&parents, &self.rest_positions())
    }

    /// The unit this file is in: `units`, or detected from the rest skeleton's extent.
    pub fn resolve_units(&self, units: Units) -> (Units, f32) {
        units.resolve(largest_extent(&self.rest_points()), Units::detect_mocap)
    }

    /// The BVH's own skeleton in metres, Y up (rest = zero rotations; unit scale and the turn
    /// from Z up in `world_from_root_parent`), with the unit used.
    pub fn to_skeleton(&self, units: Units) -> Result<(Skeleton, Units), IoError> {
        let (units, scale) = self.resolve_units(units);
        let root_space = Mat4::new_scaling(scale) * self.up_axis().0.to_y_up().to_homogeneous();
        let mut names: Vec<String> = Vec::with_capacity(self.joints.len());
        for (j, joint) in self.joints.iter().enumerate() {
            names.push(if names.contains(&joint.name) {
                format!("{}_{j}", joint.name)
            } else {
                joint.name.clone()
            });
        }
        let parents = self.joints.iter().map(|j| j.parent).collect();
        let rest_local = self
            .joints
            .iter()
            .map(|j| JointTransform {
                translation: j.offset,
                ..Default::default()
            })
            .collect();
        let n = self.joints.len();
        let roots = self
            .joints
            .iter()
            .map(|j| {
                if j.parent.is_none() {
                    root_space
                } else {
                    Mat4::identity()
                }
            })
            .collect();
        let err = |source| IoError::Scene {
            source,
            path: self.path.clone(),
        };
        let mut sk = Skeleton::new(names, parents, rest_local, vec![Mat4::identity(); n], roots)
            .map_err(err)?;
        let rest = sk.world_from_joint(&sk.rest_pose());
        sk.joint_from_bind = rest
            .iter()
            .map(|m| m.try_inverse().unwrap_or_else(Mat4::identity))
            .collect();
        Ok((sk, units))
    }

    /// The motion on the BVH's own skeleton (see [`Bvh::to_skeleton`]) at the file's frame
    /// rate, for inspecting and playing a BVH by itself. Position channels of non-root joints
    /// cannot be represented and are dropped with a warning in the returned list.
    pub fn to_motion_for_own_skeleton(
        &self,
        units: Units,
    ) -> Result<(Skeleton, Motion, Vec<String>), IoError> {
        let (skeleton, _) = self.to_skeleton(units)?;
        let mut warnings = Vec::new();
        let moving: Vec<&str> = self
            .joints
            .iter()
            .enumerate()
            .filter(|(j, joint)| {
                joint.parent.is_some()
                    && (0..self.frame_count())
                        .any(|f| (self.local(f, *j).0 - joint.offset).norm() > 1e-6)
            })
            .map(|(_, joint)| joint.name.as_str())
            .collect();
        if !moving.is_empty() {
            warnings.push(format!(
                "position channels of non-root joints ignored: {}",
                super::gltf_avatar::short_list(&moving, 8)
            ));
        }
        let frames = (0..self.frame_count())
            .map(|f| Pose {
                rotations: (0..self.joints.len()).map(|j| self.local(f, j).1).collect(),
                root_translation: self.local(f, 0).0,
            })
            .collect();
        let motion = Motion::new(self.name.clone(), self.fps(), frames, skeleton.len()).map_err(
            |source| IoError::Scene {
                source,
                path: self.path.clone(),
            },
        )?;
        Ok((skeleton, motion, warnings))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SMALL: &str = "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation\n JOINT Spine\n {\n  OFFSET 0 2 0\n  CHANNELS 3 Xrotation Yrotation Zrotation\n  End Site\n  {\n   OFFSET 0 1 0\n  }\n }\n}\nMOTION\nFrames: 2\nFrame Time: .5\n1 17 3 0 0 0 0 0 0\n1 17 3 90 0 0 0 0 90\n";

    fn parse(s: &str) -> Result<Bvh, IoError> {
        Bvh::parse(s.as_bytes(), Path::new("t.bvh"))
    }

    #[test]
    fn parses_hierarchy_channels_and_frames() {
        let b = parse(SMALL).unwrap();
        assert_eq!(b.joints.len(), 2);
        assert_eq!(b.frame_count(), 2);
        assert_eq!(b.channel_count, 9);
        assert_eq!(b.fps(), 2.0);
        assert_eq!(b.joints[1].first_channel, 6);
        assert_eq!(b.joints[1].end_site, Some(Vec3::new(0.0, 1.0, 0.0)));
        // Frame 1: root Z rotation of 90 degrees, spine Z rotation of 90 degrees.
        let w = b.world(1);
        assert!((w[0].1 - Vec3::new(1.0, 17.0, 3.0)).norm() < 1e-6);
        assert!(
            (w[1].1 - Vec3::new(-1.0, 17.0, 3.0)).norm() < 1e-5,
            "{:?}",
            w[1].1
        );
        let (_, q) = b.local(1, 1);
        assert!((q.angle() - std::f32::consts::FRAC_PI_2).abs() < 1e-5);
    }

    #[test]
    fn channel_order_is_respected() {
        let b = parse(&SMALL.replace("1 17 3 90 0 0 0 0 90", "0 0 0 90 90 0 0 0 0")).unwrap();
        let (_, q) = b.local(1, 0);
        let zy = Quat::from_axis_angle(&Vec3::z_axis(), 1.5707964)
            * Quat::from_axis_angle(&Vec3::y_axis(), 1.5707964);
        assert!(q.angle_to(&zy) < 1e-5);
    }

    #[test]
    fn errors_are_typed() {
        assert!(matches!(
            parse(&SMALL.replace("1 17 3 90 0 0 0 0 90\n", "")),
            Err(IoError::Truncated { .. })
        ));
        assert!(matches!(
            parse(&SMALL.replace("0 0 90\n", "0 nan 90\n")),
            Err(IoError::NonFinite { .. })
        ));
        assert!(matches!(
            parse(&SMALL.replace("Xrotation\n JOINT", "Wrotation\n JOINT")),
            Err(IoError::Syntax { line: 5, .. })
        ));
        assert!(matches!(
            parse(&SMALL.replace("Frame Time: .5", "Frame Time: 0")),
            Err(IoError::Syntax { line: 18, .. })
        ));
        assert!(matches!(
            parse("hello"),
            Err(IoError::Syntax { line: 1, .. })
        ));
        assert!(matches!(
            parse(&SMALL[..SMALL.find("JOINT").unwrap()]),
            Err(IoError::Truncated { .. })
        ));
        let e = parse(&SMALL.replace("0 0 90\n", "0 zero 90\n")).unwrap_err();
        assert!(e.to_string().ends_with("t.bvh"), "{e}");
    }

    #[test]
    fn glued_headers_and_own_skeleton() {
        let b = parse(
            &SMALL
                .replace("Frames: 2", "Frames:2")
                .replace("Frame Time: .5", "Frame Time:\t.5"),
        )
        .unwrap();
        let (sk, motion, warnings) = b.to_motion_for_own_skeleton(Units::Metres).unwrap();
        assert!(warnings.is_empty());
        assert_eq!(motion.frame_count(), 2);
        let p = sk.joint_positions(&motion.frames[1]);
        assert!((p[1] - b.world(1)[1].1).norm() < 1e-5);
        for m in sk.skin_from_bind(&sk.rest_pose()) {
            assert!((m - Mat4::identity()).norm() < 1e-5);
        }
    }
}
