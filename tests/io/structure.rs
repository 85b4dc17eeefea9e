//! Mapping joints by skeleton structure where names say nothing: the built-in motions written
//! as BVH under nonsense joint names (in the A-pose, in a T-pose, and on a larger rig with a
//! root joint at the floor, CMU-style hip helper joints, fingers and end joints), retargeted
//! onto the mannequin and onto a mannequin whose own joints have nonsense names; the
//! retargeted joints must land where the source motion put them. `inspect` shows the joints
//! mapped by structure; a skeleton that is not a body's is a clear error naming the file.

use std::path::Path;

use neural_cloth::geometry::Vec3;
use neural_cloth::io::SourceMotion;
use neural_cloth::io::inspect::inspect_mapping;
use neural_cloth::io::joint_names::classify;
use neural_cloth::io::joint_structure::{RigShape, label_by_structure};
use neural_cloth::io::scene_loader::load_motions;
use neural_cloth::io::{IoError, JointMap};
use neural_cloth::scene::procedural::{MotionKind, mannequin};
use neural_cloth::scene::{JointTransform, Motion, Pose, Skeleton};

use super::assert_names_file;
use super::rigs::{import, max_joint_error, on_t_pose, renamed_avatar, t_pose, write_bvh};

/// `count` distinct joint names that no convention knows: `prefix` and a number from a
/// permutation of the indices.
fn nonsense(count: usize, prefix: &str) -> Vec<String> {
    (0..count)
        .map(|k| format!("{prefix}{}", (k * 7919 + 13) % 10007))
        .collect()
}

fn motion(kind: MotionKind, secs: f32) -> Motion {
    neural_cloth::scene::procedural::motion(kind, 30.0, secs).unwrap()
}

#[test]
fn nonsense_joint_names_map_by_structure_in_a_and_t_poses() {
    let avatar = mannequin().unwrap();
    let sk = &avatar.skeleton;
    let names = nonsense(sk.len(), "bone_");
    let dir = tempfile::tempdir().unwrap();
    for kind in [MotionKind::Walk, MotionKind::Spin, MotionKind::Run] {
        let source = motion(kind, 1.5);
        let path = write_bvh(
            dir.path(),
            &format!("{}.bvh", kind.name()),
            sk,
            &source,
            &names,
        );
        let mut warnings = Vec::new();
        let motions = load_motions(&path, &avatar, &import(30.0, None), &mut warnings)
            .unwrap_or_else(|e| panic!("{}: {e}", kind.name()));
        let err = max_joint_error(sk, &motions[0], &source);
        assert!(err < 2e-3, "{}: joints off by {err} m", kind.name());
        assert!(
            warnings
                .iter()
                .any(|w| w.contains("22 joints mapped by the skeletons' structure")),
            "{warnings:?}"
        );
    }
    // A T-pose rig: the arms straight out.
    let source = motion(MotionKind::Walk, 1.0);
    let (t, turn) = t_pose(sk);
    let path = write_bvh(
        dir.path(),
        "tpose.bvh",
        &t,
        &on_t_pose(sk, &t, &turn, &source),
        &names,
    );
    let motions = load_motions(&path, &avatar, &import(30.0, None), &mut Vec::new()).unwrap();
    let err = max_joint_error(sk, &motions[0], &source);
    assert!(err < 2e-3, "T-pose: joints off by {err} m");
}

#[test]
fn an_avatar_with_nonsense_names_takes_a_motion_with_other_nonsense_names() {
    let avatar = renamed_avatar(nonsense(22, "Avatar_J"));
    let sk = &avatar.skeleton;
    let source = motion(MotionKind::Jump, 1.2);
    let dir = tempfile::tempdir().unwrap();
    let path = write_bvh(dir.path(), "jump.bvh", sk, &source, &nonsense(22, "m"));
    let motions = load_motions(&path, &avatar, &import(30.0, None), &mut Vec::new())
        .unwrap_or_else(|e| panic!("{e}"));
    let err = max_joint_error(sk, &motions[0], &source);
    assert!(err < 2e-3, "joints off by {err} m");
}

/// Where each mannequin joint went in the larger rig of [`larger_rig`].
struct LargerRig {
    skeleton: Skeleton,
    /// Per mannequin joint, its index in the larger rig.
    index: Vec<usize>,
}

/// The mannequin with more joints, as game and mocap rigs have: a root at the floor above the
/// hips, a helper joint at the hips above each thigh (CMU's `LHipJoint`), a toe end, three
/// joints down two fingers and two down a thumb on each hand, and a top-of-head end.
fn larger_rig(sk: &Skeleton) -> LargerRig {
    let mut names = Vec::new();
    let mut parents = Vec::new();
    let mut offsets: Vec<Vec3> = Vec::new();
    let mut add = |parent: Option<usize>, offset: Vec3| {
        names.push(format!("x{}", names.len()));
        parents.push(parent);
        offsets.push(offset);
        names.len() - 1
    };
    let root = add(None, Vec3::zeros());
    let mut index = vec![0; sk.len()];
    for j in 0..sk.len() {
        let offset = sk.rest_local[j].translation;
        let parent = match sk.parents[j] {
            None => root,
            Some(p) => index[p],
        };
        let name = &sk.names[j];
        let parent = if name.ends_with("UpLeg") {
            add(Some(parent), Vec3::zeros())
        } else {
            parent
        };
        index[j] = add(Some(parent), offset);
        if name.ends_with("Hand") {
            let along = offset.normalize();
            let side = Vec3::new(0.0, 0.0, 0.02);
            for (start, bones) in [
                (along * 0.09 + side, [0.04, 0.03]),
                (along * 0.09 - side, [0.035, 0.025]),
            ] {
                let mut at = add(Some(index[j]), start);
                for b in bones {
                    at = add(Some(at), along * b);
                }
            }
            let thumb = add(Some(index[j]), along * 0.03 + Vec3::new(0.0, 0.0, 0.04));
            add(Some(thumb), along * 0.03);
        }
        if name.ends_with("ToeBase") {
            add(Some(index[j]), Vec3::new(0.0, 0.0, 0.06));
        }
        if name == "Head" {
            add(Some(index[j]), Vec3::new(0.0, 0.18, 0.0));
        }
    }
    let n = names.len();
    let rest = offsets
        .into_iter()
        .map(|translation| JointTransform {
            translation,
            ..Default::default()
        })
        .collect();
    let identity = vec![neural_cloth::geometry::Mat4::identity(); n];
    let skeleton = Skeleton::new(names, parents, rest, identity.clone(), identity).unwrap();
    LargerRig { skeleton, index }
}

/// `source` (on the mannequin) on the larger rig: the same rotations, the extra joints at
/// rest, the root at the floor under the hips.
fn on_larger_rig(sk: &Skeleton, rig: &LargerRig, source: &Motion) -> Motion {
    let hips_rest = sk.rest_local[0].translation;
    let frames = source
        .frames
        .iter()
        .map(|pose| {
            let mut rotations = vec![neural_cloth::geometry::Quat::identity(); rig.skeleton.len()];
            for (j, &k) in rig.index.iter().enumerate() {
                rotations[k] = pose.rotations[j];
            }
            Pose {
                rotations,
                root_translation: pose.root_translation - hips_rest,
            }
        })
        .collect();
    Motion::new(source.name.clone(), source.fps, frames, rig.skeleton.len()).unwrap()
}

#[test]
fn a_larger_rig_with_helpers_fingers_and_end_joints_maps_by_structure() {
    let avatar = mannequin().unwrap();
    let sk = &avatar.skeleton;
    let rig = larger_rig(sk);
    assert!(rig.skeleton.len() > 40, "{}", rig.skeleton.len());
    let source = motion(MotionKind::Walk, 1.5);
    let on_rig = on_larger_rig(sk, &rig, &source);
    // The fixture: the mannequin's joints land where they did.
    for (a, b) in source.frames.iter().zip(&on_rig.frames) {
        let (p, q) = (sk.joint_positions(a), rig.skeleton.joint_positions(b));
        for (j, &k) in rig.index.iter().enumerate() {
            assert!((p[j] - q[k]).norm() < 1e-5);
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let names = nonsense(rig.skeleton.len(), "n");
    let path = write_bvh(dir.path(), "larger.bvh", &rig.skeleton, &on_rig, &names);
    let motions = load_motions(&path, &avatar, &import(30.0, None), &mut Vec::new())
        .unwrap_or_else(|e| panic!("{e}"));
    let err = max_joint_error(sk, &motions[0], &source);
    assert!(err < 2e-3, "joints off by {err} m");

    // inspect shows each joint and how it was found.
    let report = inspect_mapping(&path, Path::new("mannequin"), None, &super::opts()).unwrap();
    for (canonical, j) in [("LeftArm", 7usize), ("RightUpLeg", 18), ("Head", 5)] {
        let line = format!("{canonical} <- {} (structure)", names[rig.index[j]]);
        assert!(report.contains(&line), "missing '{line}' in:\n{report}");
    }
    assert!(
        report.contains("structure: 22 joints mapped by the skeletons' structure"),
        "{report}"
    );
    assert!(report.contains("essential joints: all mapped"), "{report}");
    // The hip height is the hips' (found by structure), not the root's at the floor.
    let line = format!(
        "hip height (rest, above the lowest end joint): 0.925 m ('{}', found by structure)",
        names[rig.index[0]]
    );
    assert!(report.contains(&line), "missing '{line}' in:\n{report}");
    assert!(
        report.contains("end sites: ") && report.contains("position channels: 0 (none)"),
        "{report}"
    );
}

#[test]
fn a_joint_map_and_names_come_before_structure() {
    let avatar = mannequin().unwrap();
    let sk = &avatar.skeleton;
    let source = motion(MotionKind::Walk, 0.5);
    let mut names = nonsense(sk.len(), "bone_");
    names[0] = "Hips".into();
    let dir = tempfile::tempdir().unwrap();
    let path = write_bvh(dir.path(), "partly.bvh", sk, &source, &names);
    let map_path = dir.path().join("map.toml");
    std::fs::write(&map_path, format!("[joints]\nLeftArm = \"{}\"\n", names[7])).unwrap();
    let map = JointMap::load(&map_path).unwrap();
    let report =
        inspect_mapping(&path, Path::new("mannequin"), Some(&map), &super::opts()).unwrap();
    for line in [
        "Hips <- Hips (rig names)".to_string(),
        format!("LeftArm <- {} (joint map)", names[7]),
        format!("RightArm <- {} (structure)", names[11]),
        "structure: 20 joints mapped".to_string(),
    ] {
        assert!(report.contains(&line), "missing '{line}' in:\n{report}");
    }
}

#[test]
fn a_skeleton_that_is_not_a_body_is_a_clear_error() {
    let avatar = mannequin().unwrap();
    let sk = &avatar.skeleton;
    // The arms folded into the chest: no two arms reach out.
    let mut folded = sk.clone();
    for j in 0..sk.len() {
        let name = &sk.names[j];
        if ["Arm", "ForeArm", "Hand"].iter().any(|s| name.ends_with(s)) {
            folded.rest_local[j].translation = Vec3::new(0.0, 0.01, 0.0);
        }
        if name.ends_with("Shoulder") {
            folded.rest_local[j].translation = Vec3::new(0.0, 0.05, 0.0);
        }
    }
    let source = motion(MotionKind::Idle, 0.5);
    let dir = tempfile::tempdir().unwrap();
    let path = write_bvh(
        dir.path(),
        "armless.bvh",
        &folded,
        &source,
        &nonsense(sk.len(), "q"),
    );
    let err = load_motions(&path, &avatar, &import(30.0, None), &mut Vec::new()).unwrap_err();
    let text = err.to_string();
    assert!(matches!(err, IoError::UnmappedJoints { .. }), "{text}");
    assert!(
        text.contains("by structure: the motion's skeleton is not recognised (no two arms"),
        "{text}"
    );
    assert_names_file(&err, "armless.bvh");
}

/// Canonical joints the structure must find as the names do on real rigs (the spine's
/// first joint is left out: CMU's `LowerBack` and `Spine` both claim it).
const COMPARED: [&str; 18] = [
    "Hips",
    "LeftArm",
    "RightArm",
    "LeftForeArm",
    "RightForeArm",
    "LeftHand",
    "RightHand",
    "LeftUpLeg",
    "RightUpLeg",
    "LeftLeg",
    "RightLeg",
    "LeftFoot",
    "RightFoot",
    "LeftShoulder",
    "RightShoulder",
    "Neck",
    "Head",
    "LeftToeBase",
];

#[test]
fn structure_agrees_with_the_names_of_the_shared_cmu_clips() {
    let files = super::files_in("motions", "bvh");
    assert!(files.len() >= 4);
    for path in files {
        let source = SourceMotion::from_bvh(&neural_cloth::io::load_bvh(&path).unwrap());
        let rest: Vec<Vec3> = source.rest.iter().map(|r| r.1).collect();
        let by_name = classify(&source.names).canonical;
        let by_shape = label_by_structure(&RigShape {
            parents: &source.parents,
            rest: &rest,
            frames: &source.frames,
        })
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        for canonical in COMPARED {
            let named = by_name.iter().position(|c| *c == Some(canonical));
            let found = by_shape.iter().position(|c| *c == Some(canonical));
            if named.is_some() {
                assert_eq!(
                    found.map(|j| &source.names[j]),
                    named.map(|j| &source.names[j]),
                    "{canonical} in {}",
                    path.display()
                );
            }
        }
    }
}

#[test]
fn a_quadruped_and_tiny_rigs_are_not_taken_for_bodies() {
    for (file, why) in [
        ("Fox.glb", "no chain rises to a head"),
        ("SimpleSkin.gltf", "too few"),
    ] {
        let loaded =
            neural_cloth::io::load_avatar(&super::asset("avatars").join(file), &super::opts())
                .unwrap();
        let sk = &loaded.avatar.skeleton;
        let rest = sk.joint_positions(&sk.rest_pose());
        let err = label_by_structure(&RigShape {
            parents: &sk.parents,
            rest: &rest,
            frames: &[],
        })
        .unwrap_err();
        assert!(err.contains(why), "{file}: {err}");
    }
}

#[test]
fn an_avatar_whose_names_say_nothing_takes_a_cmu_clip_by_structure() {
    // CesiumMan's joints are 'leg_joint_L_1', 'Skeleton_arm_joint_R', ...: no convention's.
    let report = inspect_mapping(
        &super::asset("motions/cmu_02_01_walk.bvh"),
        &super::asset("avatars/CesiumMan.glb"),
        None,
        &super::opts(),
    )
    .unwrap();
    for line in [
        "leg_joint_L_1 <- LeftUpLeg (structure)",
        "leg_joint_R_2 <- RightLeg (structure)",
        "Skeleton_arm_joint_L__4_ <- LeftArm (structure)",
        "Skeleton_arm_joint_R__2_ <- RightForeArm (structure)",
        "essential joints: all mapped",
    ] {
        assert!(report.contains(line), "missing '{line}' in:\n{report}");
    }
    // And the walk stays a walk on it: hips near their height, feet on the ground.
    let avatar =
        neural_cloth::io::load_avatar(&super::asset("avatars/CesiumMan.glb"), &super::opts())
            .unwrap()
            .avatar;
    let sk = &avatar.skeleton;
    let motions = load_motions(
        &super::asset("motions/cmu_02_01_walk.bvh"),
        &avatar,
        &import(30.0, None),
        &mut Vec::new(),
    )
    .unwrap();
    let rest = sk.joint_positions(&sk.rest_pose());
    let hips = sk.index_of("Skeleton_torso_joint_1").unwrap();
    let ground = rest.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    let hip_height = rest[hips].y - ground;
    let mut lowest_over_clip = f32::INFINITY;
    for pose in &motions[0].frames {
        let p = sk.joint_positions(pose);
        let lowest = p.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
        lowest_over_clip = lowest_over_clip.min(lowest);
        // A foot may lift off the ground; the body stays on its legs.
        let feet = (lowest - ground) / hip_height;
        assert!(
            (-0.01..0.2).contains(&feet),
            "feet at {feet} of the hip height"
        );
        let h = p[hips].y - ground;
        assert!(
            (0.85..1.1).contains(&(h / hip_height)),
            "hips at {h} of {hip_height}"
        );
    }
    // Grounded: the feet reach the floor, not above or below it.
    assert!(
        (lowest_over_clip - ground).abs() < 2e-3,
        "the lowest foot over the clip is {} m off the ground",
        lowest_over_clip - ground
    );
}
