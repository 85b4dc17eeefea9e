//! Retargeting motions (BVH, or the animations of a glTF rig) onto an avatar skeleton.
//!
//! Joints are matched by [`joint_mapping`]: a user joint map first, then the canonical joints
//! of both rigs' naming conventions (Mixamo, CMU, Rigify, Unreal, SMPL, Daz, ...), then equal
//! names, then, when essential joints are left over, the skeletons' structure. Rotations are transferred in world space, as deltas from each rig's rest pose: a
//! mapped avatar joint turns away from its rest orientation by the same world rotation as its
//! motion joint turns away from the motion's rest. With `align_rest`, a limb joint's rest is
//! first turned so that its bone points where the motion's bone points in the motion's rest
//! (a T-pose clip on an A-pose avatar raises the arms). Unmapped joints keep their rest local
//! rotation. The root translation is scaled by the ratio of hip heights above the lowest end
//! joint (leg lengths, so the motion's units do not matter), grounded so that the avatar's
//! lowest end joint over the whole motion is at its rest height, and optionally re-centred
//! horizontally. Both rigs are Y up (a Z-up BVH is turned Y up when it
//! is read, see [`Bvh::up_axis`]); a motion whose rig faces another way than the avatar (by
//! their toes) is first turned about the vertical to face the same way ([`super::facing`]).

use std::path::{Path, PathBuf};

use super::bvh::Bvh;
use super::gltf_avatar::short_list;
use super::joint_map::{JointMap, JointMapping, MatchKind, map_joints};
use super::joint_structure::RigShape;
use super::root_placement::{RootPlacement, end_joints, lowest_end};
use super::{IoError, check_fps};
use crate::geometry::{Mat4, Quat, Vec3};
use crate::scene::skeleton::rotation_of;
use crate::scene::{Motion, Pose, Skeleton};

pub use super::joint_names::CORE_JOINTS;

/// Options for [`retarget`] and [`retarget_bvh`].
#[derive(Clone, Debug, PartialEq)]
pub struct RetargetOptions {
    /// Frame rate of the resulting motion in frames per second; (0, 1000], default 30.
    pub fps: f32,
    /// Shift the motion horizontally so its first frame's hips sit above the avatar's rest
    /// hips (BVH root positions are absolute world positions); default true.
    pub recentre: bool,
    /// Turn limb joints' rest so their bones point as in the motion's rest pose (T-pose vs
    /// A-pose); default true.
    pub align_rest: bool,
    /// The user's joint map, overriding the automatic mapping; default none.
    pub joint_map: Option<JointMap>,
}

impl Default for RetargetOptions {
    fn default() -> Self {
        Self {
            fps: 30.0,
            recentre: true,
            align_rest: true,
            joint_map: None,
        }
    }
}

/// A motion on its own rig, as world transforms: what retargeting reads.
#[derive(Clone, Debug)]
pub struct SourceMotion {
    /// Motion name.
    pub name: String,
    /// The file it came from (for messages).
    pub path: PathBuf,
    /// Joint names.
    pub names: Vec<String>,
    /// Parent of each joint (parents precede children).
    pub parents: Vec<Option<usize>>,
    /// Frames per second.
    pub fps: f32,
    /// World rotation and position of each joint in the rig's rest pose, file units.
    pub rest: Vec<(Quat, Vec3)>,
    /// World rotation and position of each joint in each frame, file units.
    pub frames: Vec<Vec<(Quat, Vec3)>>,
    /// Metres per file unit used when hip heights are unusable, and the unit's name.
    pub fallback_scale: (f32, &'static str),
    /// What reading the motion noticed (a Z-up file turned Y up); [`retarget`] passes these
    /// on with its own warnings.
    pub warnings: Vec<String>,
}

impl SourceMotion {
    /// A BVH's motion (rest: every rotation zero), turned Y up when the file is Z up (see
    /// [`Bvh::up_axis`]).
    pub fn from_bvh(bvh: &Bvh) -> Self {
        let (units, scale) = bvh.resolve_units(super::Units::Auto);
        let (up, detected) = bvh.up_axis();
        let turn = up.to_y_up();
        Self {
            name: bvh.name.clone(),
            path: bvh.path.clone(),
            names: bvh.joints.iter().map(|j| j.name.clone()).collect(),
            parents: bvh.joints.iter().map(|j| j.parent).collect(),
            fps: bvh.fps(),
            rest: bvh
                .rest_positions()
                .into_iter()
                .map(|p| (turn, turn * p))
                .collect(),
            frames: (0..bvh.frame_count())
                .map(|f| {
                    bvh.world(f)
                        .into_iter()
                        .map(|(q, p)| (turn * q, turn * p))
                        .collect()
                })
                .collect(),
            fallback_scale: (scale, units.label()),
            warnings: up.turned_warning(detected).into_iter().collect(),
        }
    }

    /// A motion of `skeleton` (e.g. a glTF animation of another rig), in metres.
    pub fn from_rig(skeleton: &Skeleton, motion: &Motion, path: &std::path::Path) -> Self {
        let world = |pose: &Pose| -> Vec<(Quat, Vec3)> {
            skeleton
                .world_from_joint(pose)
                .iter()
                .map(|m| (rotation_of(m), translation_of(m)))
                .collect()
        };
        Self {
            name: motion.name.clone(),
            path: path.to_path_buf(),
            names: skeleton.names.clone(),
            parents: skeleton.parents.clone(),
            fps: motion.fps,
            rest: world(&skeleton.rest_pose()),
            frames: motion.frames.iter().map(world).collect(),
            fallback_scale: (1.0, "metres"),
            warnings: Vec::new(),
        }
    }

    fn duration_secs(&self) -> f32 {
        self.frames.len().saturating_sub(1) as f32 / self.fps
    }
}

pub(super) fn translation_of(m: &Mat4) -> Vec3 {
    m.fixed_view::<3, 1>(0, 3).into_owned()
}

/// True when `ancestor` is `j` or above it.
fn is_under(parents: &[Option<usize>], j: usize, ancestor: usize) -> bool {
    let mut cur = Some(j);
    while let Some(c) = cur {
        if c == ancestor {
            return true;
        }
        cur = parents.get(c).copied().flatten();
    }
    false
}

/// Retargets `bvh` onto `skeleton`, resampled to `options.fps` (see [`retarget`]).
pub fn retarget_bvh(
    bvh: &Bvh,
    skeleton: &Skeleton,
    options: &RetargetOptions,
) -> Result<(Motion, Vec<String>), IoError> {
    retarget(&SourceMotion::from_bvh(bvh), skeleton, options)
}

/// Retargets `source` onto `skeleton`, resampled to `options.fps`. Returns the motion and
/// warnings. Errors (naming the motion file) when an essential avatar joint (see
/// [`CORE_JOINTS`]) has no motion joint, listing those joints and the closest names; errors
/// (naming the map file) when the joint map names a joint that does not exist.
pub fn retarget(
    source: &SourceMotion,
    skeleton: &Skeleton,
    options: &RetargetOptions,
) -> Result<(Motion, Vec<String>), IoError> {
    let fps = check_fps(options.fps, &source.path)?;
    check_length(source, fps)?;
    let mapping = joint_mapping(source, skeleton, options.joint_map.as_ref())?;
    mapping.check_essential(&skeleton.names, &source.names, &source.path)?;
    let map = &mapping.source;
    let mut warnings = source.warnings.clone();
    let turned = turn_to_face(source, skeleton, &mapping, &mut warnings);
    let source = turned.as_ref().unwrap_or(source);
    warnings.extend(mapping_warnings(&mapping, skeleton, source));

    // Avatar rest.
    let rest_world = skeleton.world_from_joint(&skeleton.rest_pose());
    let mut rest_rot: Vec<Quat> = rest_world.iter().map(rotation_of).collect();
    let rest_pos: Vec<Vec3> = rest_world.iter().map(translation_of).collect();
    if options.align_rest {
        align_rest(source, skeleton, map, &rest_pos, &mut rest_rot);
    }
    let (hips_a, hips_b) = hips_pair(&mapping, &source.path)?;
    let scale = leg_scale(source, skeleton, (hips_a, hips_b), &rest_pos, &mut warnings);
    let root = RootPlacement::new(source, skeleton, hips_a, hips_b, scale, &rest_pos, options);
    if root.under_root0.is_none() {
        warnings.push(format!(
            "joint '{}' is not under joint 0; root translation not retargeted",
            skeleton.names[hips_a]
        ));
    }
    if let Some(clearance) = root.clearance_b {
        warnings.push(format!(
            "the motion's feet never come down to its floor (y = 0; lowest {clearance:.3} file \
             units above it): kept at their height above the avatar's floor, not grounded"
        ));
    }
    let mut frames = retarget_frames(source, skeleton, map, &rest_rot, &root);
    root.ground(skeleton, &mut frames);
    let scene_err = |e| IoError::Scene {
        source: e,
        path: source.path.clone(),
    };
    let native =
        Motion::new(source.name.clone(), source.fps, frames, skeleton.len()).map_err(scene_err)?;
    let motion = native.resample(fps).map_err(scene_err)?;
    Ok((motion, warnings))
}

/// Refuses a motion too long to resample at `fps`.
fn check_length(source: &SourceMotion, fps: f32) -> Result<(), IoError> {
    if source.duration_secs() * fps > 2.0e5 {
        return Err(IoError::Unsupported {
            what: format!(
                "a {} s motion (too long to resample at {fps} fps)",
                source.duration_secs()
            ),
            path: source.path.clone(),
        });
    }
    Ok(())
}

/// `source` turned about the vertical to face as the avatar does, when its rig faces more
/// than 45 degrees away (see `io::facing`), with a warning; None when it faces the same way.
fn turn_to_face(
    source: &SourceMotion,
    skeleton: &Skeleton,
    mapping: &JointMapping,
    warnings: &mut Vec<String>,
) -> Option<SourceMotion> {
    let rest = skeleton.joint_positions(&skeleton.rest_pose());
    let (turned, degrees) = super::facing::turn_to_avatar(source, &rest, mapping)?;
    warnings.push(format!(
        "the motion's rig faces {:.0} degrees away from the avatar's (its toes point \
         elsewhere); turned to face the same way",
        degrees.abs()
    ));
    Some(turned)
}

/// The avatar's hips joint and the motion joint mapped to it.
fn hips_pair(mapping: &JointMapping, path: &Path) -> Result<(usize, usize), IoError> {
    let hips_a = hips_joint(mapping);
    let Some(hips_b) = hips_a.and_then(|a| mapping.source[a]) else {
        // check_essential refuses a mapping without any joint.
        return Err(IoError::Unsupported {
            what: "no avatar joint is mapped".into(),
            path: path.to_path_buf(),
        });
    };
    Ok((hips_a.unwrap_or(0), hips_b))
}

/// The scale of the motion's root translation: the ratio of hip heights above the lowest end
/// joint (leg lengths), both in rest; the source's fallback, with a warning, when they are
/// unusable.
fn leg_scale(
    source: &SourceMotion,
    skeleton: &Skeleton,
    (hips_a, hips_b): (usize, usize),
    rest_pos: &[Vec3],
    warnings: &mut Vec<String>,
) -> f32 {
    let src_rest_pos: Vec<Vec3> = source.rest.iter().map(|r| r.1).collect();
    let (ends_a, ends_b) = (end_joints(&skeleton.parents), end_joints(&source.parents));
    let height_b =
        src_rest_pos.get(hips_b).map(|p| p.y).unwrap_or(0.0) - lowest_end(&src_rest_pos, &ends_b);
    let height_a = rest_pos[hips_a].y - lowest_end(rest_pos, &ends_a);
    if height_a > 1e-6 && height_b > 1e-6 && (height_a / height_b).is_finite() {
        height_a / height_b
    } else {
        let (s, label) = source.fallback_scale;
        warnings.push(format!("hip heights unusable (avatar {height_a}, motion {height_b}); root translation scaled as {label}"));
        s
    }
}

/// The avatar's pose in every frame of `source`: each mapped joint takes its motion joint's
/// world rotation relative to that joint's rest (carried onto the avatar's rest rotation
/// `rest_rot`), an unmapped joint keeps its rest rotation under its parent; the root placed by
/// `root`.
fn retarget_frames(
    source: &SourceMotion,
    skeleton: &Skeleton,
    map: &[Option<usize>],
    rest_rot: &[Quat],
    root: &RootPlacement,
) -> Vec<Pose> {
    let n = skeleton.len();
    let rest_pose = skeleton.rest_pose();
    let root_parent_rot: Vec<Quat> = skeleton
        .world_from_root_parent
        .iter()
        .map(rotation_of)
        .collect();
    let src_rest_inv: Vec<Quat> = source.rest.iter().map(|r| r.0.inverse()).collect();
    let mut frames = Vec::with_capacity(source.frames.len());
    for w in &source.frames {
        let mut world_rot = vec![Quat::identity(); n];
        let mut rotations = vec![Quat::identity(); n];
        for a in 0..n {
            let parent_rot = match skeleton.parents[a] {
                Some(p) => world_rot[p],
                None => root_parent_rot[a],
            };
            let world = match map[a].and_then(|b| Some((w.get(b)?, src_rest_inv.get(b)?))) {
                Some(((q_b, _), inv)) => q_b * inv * rest_rot[a],
                None => parent_rot * skeleton.rest_local[a].rotation,
            };
            world_rot[a] = world;
            let local = parent_rot.inverse() * world;
            rotations[a] = Quat::new_normalize(local.into_inner());
        }
        let mut pose = Pose {
            rotations,
            root_translation: rest_pose.root_translation,
        };
        root.place(skeleton, w, &mut pose);
        frames.push(pose);
    }
    frames
}

/// What retargeting tells about the mapping: the joints mapped by the skeletons' structure
/// (to be checked), and the avatar joints left at their rest rotation.
fn mapping_warnings(
    mapping: &JointMapping,
    skeleton: &Skeleton,
    source: &SourceMotion,
) -> Vec<String> {
    let map = &mapping.source;
    let mut warnings = Vec::new();
    let by_structure: Vec<String> = (0..skeleton.len())
        .filter(|&a| mapping.how[a] == Some(MatchKind::Structure))
        .filter_map(|a| {
            Some(format!(
                "{} <- {}",
                skeleton.names[a],
                source.names.get(map[a]?)?
            ))
        })
        .collect();
    if !by_structure.is_empty() {
        warnings.push(format!(
            "{} joints mapped by the skeletons' structure, their names not being recognised \
             ({}); check them with inspect --avatar, or give a --joint-map",
            by_structure.len(),
            short_list(
                &by_structure.iter().map(String::as_str).collect::<Vec<_>>(),
                6
            )
        ));
    }
    let unmapped = mapping.unmapped(&skeleton.names);
    if !unmapped.is_empty() {
        warnings.push(format!(
            "{} avatar joints keep their rest rotation: {}",
            unmapped.len(),
            short_list(&unmapped, 8)
        ));
    }

    warnings
}

/// The joint mapping [`retarget`] uses from `source` onto `skeleton`: [`map_joints`] on the
/// names with the user's `joint_map`, then, when essential joints are left unmapped,
/// [`JointMapping::fill_by_structure`] on both rigs' rest poses (and the motion's frames).
/// Errors (naming the map file) when the joint map names a joint that does not exist.
pub fn joint_mapping(
    source: &SourceMotion,
    skeleton: &Skeleton,
    joint_map: Option<&JointMap>,
) -> Result<JointMapping, IoError> {
    let mut mapping = map_joints(&skeleton.names, &source.names, joint_map, &source.path)?;
    if mapping.needs_structure() {
        let avatar_rest: Vec<Vec3> = skeleton
            .world_from_joint(&skeleton.rest_pose())
            .iter()
            .map(translation_of)
            .collect();
        let motion_rest: Vec<Vec3> = source.rest.iter().map(|r| r.1).collect();
        mapping.fill_by_structure(
            &RigShape {
                parents: &skeleton.parents,
                rest: &avatar_rest,
                frames: &[],
            },
            &RigShape {
                parents: &source.parents,
                rest: &motion_rest,
                frames: &source.frames,
            },
        );
    }
    Ok(mapping)
}

/// The avatar joint whose motion joint carries the root translation: the mapped canonical
/// hips, else the joint driven by the motion's first joint, else the first mapped joint.
fn hips_joint(mapping: &JointMapping) -> Option<usize> {
    let map = &mapping.source;
    (0..map.len())
        .find(|&a| map[a].is_some() && mapping.canonical[a] == Some("Hips"))
        .or_else(|| map.iter().position(|m| *m == Some(0)))
        .or_else(|| map.iter().position(Option::is_some))
}

/// Turns the rest world rotation of every avatar joint with exactly one mapped joint below
/// it (the first mapped joint down each branch) so that its bone points as the matching
/// bone of the motion's rest pose.
fn align_rest(
    source: &SourceMotion,
    skeleton: &Skeleton,
    map: &[Option<usize>],
    rest_pos: &[Vec3],
    rest_rot: &mut [Quat],
) {
    let children = skeleton.children();
    for a in 0..skeleton.len() {
        let Some(b) = map[a] else { continue };
        let mut below = Vec::new();
        let mut stack: Vec<usize> = children[a].clone();
        while let Some(c) = stack.pop() {
            if map[c].is_some() {
                below.push(c);
            } else {
                stack.extend(&children[c]);
            }
        }
        let [c] = below.as_slice() else { continue };
        let Some(bc) = map[*c] else { continue };
        if !is_under(&source.parents, bc, b) || bc == b {
            continue;
        }
        let (Some(pb), Some(pbc)) = (source.rest.get(b), source.rest.get(bc)) else {
            continue;
        };
        let dir_a = rest_pos[*c] - rest_pos[a];
        let dir_b = pbc.1 - pb.1;
        if dir_a.norm() < 1e-6 || dir_b.norm() < 1e-9 {
            continue;
        }
        if let Some(turn) = Quat::rotation_between(&dir_a, &dir_b) {
            rest_rot[a] = turn * rest_rot[a];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::Units;
    use std::path::Path;

    const BVH: &str = "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation\n JOINT Spine\n {\n  OFFSET 0 2 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n  End Site\n  {\n   OFFSET 0 2 0\n  }\n }\n JOINT LeftUpLeg\n {\n  OFFSET 1 0 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n  JOINT LeftLeg\n  {\n   OFFSET 0 -4 0\n   CHANNELS 3 Zrotation Xrotation Yrotation\n   End Site\n   {\n    OFFSET 0 -4 0\n   }\n  }\n }\n}\nMOTION\nFrames: 3\nFrame Time: 0.5\n0 4 0 0 0 0 0 0 0 0 0 0 0 0 0\n1 3 2 10 20 30 -5 15 0 40 0 -10 0 60 5\n2 4 4 0 90 0 0 0 0 0 0 0 0 0 0\n";

    #[test]
    fn retargeting_onto_own_skeleton_reproduces_the_motion() {
        let bvh = Bvh::parse(BVH.as_bytes(), Path::new("m.bvh")).unwrap();
        let (sk, units) = bvh.to_skeleton(Units::Centimetres).unwrap();
        assert_eq!(units, Units::Centimetres);
        let opts = RetargetOptions {
            fps: 2.0,
            recentre: false,
            ..Default::default()
        };
        let (motion, warnings) = retarget_bvh(&bvh, &sk, &opts).unwrap();
        assert!(warnings.is_empty(), "{warnings:?}");
        assert_eq!(motion.frame_count(), 3);
        let first = bvh.world(0)[0].1;
        let first_a = sk.joint_positions(&motion.frames[0])[0];
        for f in 0..3 {
            let p = sk.joint_positions(&motion.frames[f]);
            let w = bvh.world(f);
            for j in 0..4 {
                // Same shape (relative to the hips) and same hip trajectory, in metres.
                let rel_a = p[j] - p[0];
                let rel_b = (w[j].1 - w[0].1) * 0.01;
                assert!(
                    (rel_a - rel_b).norm() < 1e-5,
                    "frame {f} joint {j}: {rel_a:?} vs {rel_b:?}"
                );
                assert!(motion.frames[f].rotations[j].angle_to(&bvh.local(f, j).1) < 1e-4);
            }
            assert!(((p[0] - first_a) - (w[0].1 - first) * 0.01).norm() < 1e-5);
        }
    }

    /// The lowest end joint's height of every frame of `motion` on `sk`, metres.
    fn lowest_ends(sk: &Skeleton, motion: &Motion) -> Vec<f32> {
        let ends = end_joints(&sk.parents);
        motion
            .frames
            .iter()
            .map(|pose| lowest_end(&sk.joint_positions(pose), &ends))
            .collect()
    }

    #[test]
    fn a_motion_that_never_reaches_its_floor_is_not_grounded() {
        // The same clip with the hips 26 cm higher: its lowest end joint never comes within
        // a quarter of the leg (4 cm) of its floor.
        let lifted = BVH
            .replace("0 4 0 0 0 0", "0 30 0 0 0 0")
            .replace("1 3 2 10", "1 29 2 10")
            .replace("2 4 4 0 90", "2 30 4 0 90");
        let opts = RetargetOptions {
            fps: 2.0,
            recentre: false,
            ..Default::default()
        };
        let bvh = Bvh::parse(BVH.as_bytes(), Path::new("m.bvh")).unwrap();
        let (sk, _) = bvh.to_skeleton(Units::Centimetres).unwrap();
        let ground_a = lowest_end(
            &sk.joint_positions(&sk.rest_pose()),
            &end_joints(&sk.parents),
        );
        let (standing, warnings) = retarget_bvh(&bvh, &sk, &opts).unwrap();
        assert!(warnings.is_empty(), "{warnings:?}");
        let lowest = lowest_ends(&sk, &standing);
        let min = lowest.iter().copied().fold(f32::INFINITY, f32::min);
        assert!((min - ground_a).abs() < 1e-5, "{min} vs {ground_a}");
        let bvh = Bvh::parse(lifted.as_bytes(), Path::new("lifted.bvh")).unwrap();
        let (airborne, warnings) = retarget_bvh(&bvh, &sk, &opts).unwrap();
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(warnings[0].contains("never come down to its floor"));
        let ends = end_joints(&bvh.joints.iter().map(|j| j.parent).collect::<Vec<_>>());
        for (f, lowest) in lowest_ends(&sk, &airborne).iter().enumerate() {
            let points: Vec<Vec3> = bvh.world(f).iter().map(|w| w.1).collect();
            let source = 0.01 * lowest_end(&points, &ends);
            assert!(source > 0.2);
            assert!(
                (lowest - ground_a - source).abs() < 1e-5,
                "frame {f}: {lowest} above {ground_a}, source {source}"
            );
        }
    }

    #[test]
    fn missing_core_joints_are_listed() {
        let bvh = Bvh::parse(BVH.as_bytes(), Path::new("m.bvh")).unwrap();
        let mut names = vec![
            "Hips".to_string(),
            "Spine".into(),
            "RightUpLeg".into(),
            "RightLeg".into(),
        ];
        let (mut sk, _) = bvh.to_skeleton(Units::Metres).unwrap();
        std::mem::swap(&mut sk.names, &mut names);
        let err = retarget_bvh(&bvh, &sk, &RetargetOptions::default()).unwrap_err();
        match &err {
            IoError::UnmappedJoints { joints, .. } => assert_eq!(
                joints,
                &vec!["RightUpLeg".to_string(), "RightLeg".to_string()]
            ),
            other => panic!("unexpected {other}"),
        }
        assert!(err.to_string().ends_with("m.bvh"));
    }
}
