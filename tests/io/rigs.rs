//! Retargeting across rigs, with fixtures made by our own code: the built-in motions written
//! as BVH (and as a glTF rig) under the joint names of each common convention, and with a
//! T-pose rest; the retargeted motion must put the mannequin's joints where the source motion
//! put them. Joint maps override the automatic mapping; bad maps and BVH files without usable
//! hips are clear errors naming the file.

use std::path::{Path, PathBuf};
use std::process::Command;

use neural_cloth::geometry::{Quat, Vec3};
use neural_cloth::io::bvh_write::bvh_text;
use neural_cloth::io::export::gltf::{BakedSequence, GltfExportOptions, write_glb};
use neural_cloth::io::scene_loader::{MotionImport, load_motions};
use neural_cloth::io::{IoError, JointMap, Units};
use neural_cloth::scene::procedural::{GarmentKind, MotionKind, builtin_garment, mannequin};
use neural_cloth::scene::skeleton::rotation_of;
use neural_cloth::scene::{Avatar, Motion, Pose, Skeleton};

use super::assert_names_file;

/// A rig convention: its name, the mannequin's centre joints renamed, the two side words, and
/// per-side patterns (`#` = side) of shoulder, arm, forearm, hand, up-leg, leg, foot, toe.
type Rig = (
    &'static str,
    [&'static str; 6],
    [&'static str; 2],
    [&'static str; 8],
);

/// The mannequin's joints in each convention (see [`Rig`]).
const RIGS: [Rig; 7] = [
    (
        "mixamo",
        [
            "mixamorig:Hips",
            "mixamorig:Spine",
            "mixamorig:Spine1",
            "mixamorig:Spine2",
            "mixamorig:Neck",
            "mixamorig:Head",
        ],
        ["Left", "Right"],
        [
            "mixamorig:#Shoulder",
            "mixamorig:#Arm",
            "mixamorig:#ForeArm",
            "mixamorig:#Hand",
            "mixamorig:#UpLeg",
            "mixamorig:#Leg",
            "mixamorig:#Foot",
            "mixamorig:#ToeBase",
        ],
    ),
    (
        "cmu_3dsmax",
        ["Hips", "lowerback", "upperback", "thorax", "Neck", "Head"],
        ["Left", "Right"],
        [
            "#Collar",
            "#Shoulder",
            "#Elbow",
            "#Wrist",
            "#Hip",
            "#Knee",
            "#Ankle",
            "#Toe",
        ],
    ),
    (
        "makehuman",
        ["hips", "lowerback", "upperback", "thorax", "neck", "head"],
        ["l", "r"],
        [
            "#clavicle",
            "#shoulder",
            "#elbow",
            "#wrist",
            "#hip",
            "#knee",
            "#ankle",
            "#toe",
        ],
    ),
    (
        "rigify",
        [
            "DEF-spine",
            "DEF-spine.001",
            "DEF-spine.002",
            "DEF-spine.003",
            "DEF-spine.004",
            "DEF-spine.006",
        ],
        ["L", "R"],
        [
            "DEF-shoulder.#",
            "DEF-upper_arm.#",
            "DEF-forearm.#",
            "DEF-hand.#",
            "DEF-thigh.#",
            "DEF-shin.#",
            "DEF-foot.#",
            "DEF-toe.#",
        ],
    ),
    (
        "unreal",
        [
            "pelvis", "spine_01", "spine_02", "spine_03", "neck_01", "head",
        ],
        ["l", "r"],
        [
            "clavicle_#",
            "upperarm_#",
            "lowerarm_#",
            "hand_#",
            "thigh_#",
            "calf_#",
            "foot_#",
            "ball_#",
        ],
    ),
    (
        "smpl",
        ["Pelvis", "Spine1", "Spine2", "Spine3", "Neck", "Head"],
        ["L", "R"],
        [
            "#_Collar",
            "#_Shoulder",
            "#_Elbow",
            "#_Wrist",
            "#_Hip",
            "#_Knee",
            "#_Ankle",
            "#_Foot",
        ],
    ),
    (
        "daz",
        ["hip", "abdomen", "abdomen2", "chest", "neck", "head"],
        ["l", "r"],
        [
            "#Collar", "#Shldr", "#ForeArm", "#Hand", "#Thigh", "#Shin", "#Foot", "#Toe",
        ],
    ),
];

/// The mannequin's joint names in `rig`'s convention (mannequin joint order).
fn renamed(rig: &Rig) -> Vec<String> {
    let (_, centre, sides, parts) = rig;
    let mut names: Vec<String> = centre.iter().map(|s| s.to_string()).collect();
    for side in sides {
        names.extend(parts[..4].iter().map(|p| p.replace('#', side)));
    }
    for side in sides {
        names.extend(parts[4..].iter().map(|p| p.replace('#', side)));
    }
    names
}

pub(super) fn import(fps: f32, joint_map: Option<&JointMap>) -> MotionImport<'_> {
    MotionImport {
        units: Units::Auto,
        up: neural_cloth::io::UpAxis::Auto,
        fps,
        only: None,
        joint_map,
    }
}

/// Largest distance between the joints of `got` and `want` (on the same skeleton), both
/// taken relative to their first frame's hips.
pub(super) fn max_joint_error(sk: &Skeleton, got: &Motion, want: &Motion) -> f32 {
    assert_eq!(got.frame_count(), want.frame_count());
    let origin = |m: &Motion| sk.joint_positions(&m.frames[0])[0];
    let (og, ow) = (origin(got), origin(want));
    let mut worst = 0.0f32;
    for (g, w) in got.frames.iter().zip(&want.frames) {
        for (pg, pw) in sk.joint_positions(g).iter().zip(sk.joint_positions(w)) {
            worst = worst.max(((pg - og) - (pw - ow)).norm());
        }
    }
    worst
}

pub(super) fn write_bvh(
    dir: &Path,
    file: &str,
    sk: &Skeleton,
    m: &Motion,
    names: &[String],
) -> PathBuf {
    let path = dir.join(file);
    std::fs::write(&path, bvh_text(sk, m, names, 100.0, &path).unwrap()).unwrap();
    path
}

#[test]
fn builtin_motions_in_every_rig_naming_retarget_onto_the_mannequin() {
    let avatar = mannequin().unwrap();
    let sk = &avatar.skeleton;
    let dir = tempfile::tempdir().unwrap();
    for kind in [MotionKind::Walk, MotionKind::Spin] {
        let source = neural_cloth::scene::procedural::motion(kind, 30.0, 2.0).unwrap();
        for rig in &RIGS {
            let names = renamed(rig);
            let file = format!("{}_{}.bvh", rig.0, kind.name());
            let path = write_bvh(dir.path(), &file, sk, &source, &names);
            let mut warnings = Vec::new();
            let motions = load_motions(&path, &avatar, &import(30.0, None), &mut warnings)
                .unwrap_or_else(|e| panic!("{}: {e}", rig.0));
            assert!(warnings.is_empty(), "{}: {warnings:?}", rig.0);
            let err = max_joint_error(sk, &motions[0], &source);
            assert!(
                err < 2e-3,
                "{} {}: joints off by {err} m",
                rig.0,
                kind.name()
            );
        }
    }
}

/// The mannequin with its arms straight out (a T-pose rest; identity rest rotations), and
/// the rotation that turns each A-pose arm bone into its T-pose direction.
pub(super) fn t_pose(sk: &Skeleton) -> (Skeleton, Vec<Quat>) {
    let mut t = sk.clone();
    let mut turn = vec![Quat::identity(); sk.len()];
    for (side, x) in [("Left", 1.0f32), ("Right", -1.0)] {
        for (joint, child) in [("Arm", "ForeArm"), ("ForeArm", "Hand")] {
            let j = sk.index_of(&format!("{side}{joint}")).unwrap();
            let c = sk.index_of(&format!("{side}{child}")).unwrap();
            let offset = sk.rest_local[c].translation;
            let straight = Vec3::new(x * offset.norm(), 0.0, 0.0);
            turn[j] = Quat::rotation_between(&offset, &straight).unwrap();
            t.rest_local[c].translation = straight;
        }
    }
    (t, turn)
}

/// `motion` of `sk` re-expressed on the T-pose rig so every joint lands where it did.
pub(super) fn on_t_pose(sk: &Skeleton, t: &Skeleton, turn: &[Quat], motion: &Motion) -> Motion {
    let frames = motion
        .frames
        .iter()
        .map(|pose| {
            let world: Vec<Quat> = sk
                .world_from_joint(pose)
                .iter()
                .zip(turn)
                .map(|(m, r)| rotation_of(m) * r.inverse())
                .collect();
            let rotations = (0..t.len())
                .map(|j| match t.parents[j] {
                    Some(p) => world[p].inverse() * world[j],
                    None => world[j],
                })
                .collect();
            Pose {
                rotations,
                root_translation: pose.root_translation,
            }
        })
        .collect();
    Motion::new(motion.name.clone(), motion.fps, frames, t.len()).unwrap()
}

#[test]
fn a_t_pose_clip_drives_the_a_pose_mannequin() {
    let avatar = mannequin().unwrap();
    let sk = &avatar.skeleton;
    let source = neural_cloth::scene::procedural::motion(MotionKind::Run, 30.0, 1.5).unwrap();
    let (t, turn) = t_pose(sk);
    let on_t = on_t_pose(sk, &t, &turn, &source);
    // The fixture itself: same joint positions on the T-pose rig.
    for (a, b) in source.frames.iter().zip(&on_t.frames) {
        for (p, q) in sk.joint_positions(a).iter().zip(t.joint_positions(b)) {
            assert!((p - q).norm() < 1e-4);
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let names = renamed(&RIGS[1]);
    let path = write_bvh(dir.path(), "tpose_run.bvh", &t, &on_t, &names);
    let mut warnings = Vec::new();
    let motions = load_motions(&path, &avatar, &import(30.0, None), &mut warnings).unwrap();
    let err = max_joint_error(sk, &motions[0], &source);
    assert!(err < 2e-3, "joints off by {err} m");
    // Without rest alignment the arms would hang 45 degrees off: the check can fail.
    let bvh = neural_cloth::io::load_bvh(&path).unwrap();
    let options = neural_cloth::io::RetargetOptions {
        align_rest: false,
        ..Default::default()
    };
    let (plain, _) = neural_cloth::io::retarget_bvh(&bvh, sk, &options).unwrap();
    assert!(max_joint_error(sk, &plain, &source) > 0.1);
}

/// The mannequin whose joints carry other names.
pub(super) fn renamed_avatar(names: Vec<String>) -> Avatar {
    let mut avatar = mannequin().unwrap();
    avatar.skeleton.names = names;
    avatar
}

#[test]
fn gltf_clips_of_another_rig_retarget_like_bvh() {
    let avatar = mannequin().unwrap();
    let rig = renamed_avatar(renamed(&RIGS[0]));
    let garment = builtin_garment(&rig, GarmentKind::TShirt, 600, None).unwrap();
    let source = neural_cloth::scene::procedural::motion(MotionKind::Jump, 30.0, 1.5).unwrap();
    let offsets = vec![vec![Vec3::zeros(); garment.vertex_count()]; source.frame_count()];
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mixamo_jump.glb");
    let sequence = BakedSequence {
        name: "jump",
        fps: 30.0,
        poses: &source.frames,
        rest_offsets: &offsets,
    };
    write_glb(
        &path,
        &rig,
        &garment,
        &sequence,
        &GltfExportOptions::default(),
    )
    .unwrap();
    let mut warnings = Vec::new();
    let motions = load_motions(&path, &avatar, &import(30.0, None), &mut warnings)
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(motions.len(), 1);
    assert_eq!(motions[0].name, "jump");
    let err = max_joint_error(&avatar.skeleton, &motions[0], &source);
    assert!(err < 2e-3, "joints off by {err} m");
}

#[test]
fn joint_maps_override_and_bad_maps_name_the_joint_and_file() {
    let avatar = mannequin().unwrap();
    let sk = &avatar.skeleton;
    let source = neural_cloth::scene::procedural::motion(MotionKind::Walk, 30.0, 1.0).unwrap();
    let dir = tempfile::tempdir().unwrap();
    // Arms named so no naming convention can guess them: the skeleton's structure maps
    // them, with a warning that says so.
    let mut names = sk.names.clone();
    for (joint, name) in [("LeftArm", "bone_07"), ("RightArm", "bone_11")] {
        names[sk.index_of(joint).unwrap()] = name.into();
    }
    let path = write_bvh(dir.path(), "odd.bvh", sk, &source, &names);
    let mut warnings = Vec::new();
    let motions = load_motions(&path, &avatar, &import(30.0, None), &mut warnings).unwrap();
    assert!(max_joint_error(sk, &motions[0], &source) < 2e-3);
    assert!(
        warnings.iter().any(|w| w.contains(
            "2 joints mapped by the skeletons' structure, their names not being recognised \
             (LeftArm <- bone_07, RightArm <- bone_11)"
        ) && w.contains("--joint-map")),
        "{warnings:?}"
    );

    let map_path = dir.path().join("map.toml");
    std::fs::write(
        &map_path,
        "[joints]\nLeftArm = \"bone_07\"\nRightArm = \"bone_11\"\n",
    )
    .unwrap();
    let map = JointMap::load(&map_path).unwrap();
    let mut warnings = Vec::new();
    let motions = load_motions(&path, &avatar, &import(30.0, Some(&map)), &mut warnings)
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(max_joint_error(sk, &motions[0], &source) < 2e-3);
    assert!(warnings.is_empty(), "{warnings:?}");

    // A map naming a joint the motion does not have: the joint, the motion and the map file.
    std::fs::write(&map_path, "[joints]\nLeftArm = \"bone_7\"\n").unwrap();
    let map = JointMap::load(&map_path).unwrap();
    let err = load_motions(&path, &avatar, &import(30.0, Some(&map)), &mut Vec::new()).unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains("'bone_7'") && text.contains("odd") && text.contains("bone_07"),
        "{text}"
    );
    assert_names_file(&err, "map.toml");
    // And one naming an avatar joint that does not exist.
    std::fs::write(&map_path, "[joints]\nLeftArmm = \"bone_07\"\n").unwrap();
    let map = JointMap::load(&map_path).unwrap();
    let err = load_motions(&path, &avatar, &import(30.0, Some(&map)), &mut Vec::new()).unwrap_err();
    assert!(err.to_string().contains("no joint 'LeftArmm'"), "{err}");
    assert_names_file(&err, "map.toml");
}

#[test]
fn a_bvh_without_usable_hips_is_a_clear_error() {
    let avatar = mannequin().unwrap();
    let sk = &avatar.skeleton;
    let source = neural_cloth::scene::procedural::motion(MotionKind::Idle, 30.0, 0.5).unwrap();
    // A root named 'Bone' whose legs are folded up: neither names nor structure find hips.
    let mut names = sk.names.clone();
    names[0] = "Bone".into();
    let mut folded = sk.clone();
    for (j, name) in sk.names.iter().enumerate() {
        if ["Leg", "Foot", "Toe"].iter().any(|s| name.contains(s)) {
            let t = &mut folded.rest_local[j].translation;
            *t = Vec3::new(t.x, -0.02, 0.0);
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let path = write_bvh(dir.path(), "nohips.bvh", &folded, &source, &names);
    let err = load_motions(&path, &avatar, &import(30.0, None), &mut Vec::new()).unwrap_err();
    match &err {
        IoError::UnmappedJoints {
            joints,
            closest,
            note,
            ..
        } => {
            assert_eq!(joints, &vec!["Hips".to_string()]);
            assert!(closest.starts_with("Hips ~ "), "{closest}");
            assert!(note.contains("no two legs reach the ground"), "{note}");
        }
        other => panic!("{other}"),
    }
    assert!(err.to_string().contains("--joint-map"), "{err}");
    assert_names_file(&err, "nohips.bvh");
}

#[test]
fn inspect_with_an_avatar_prints_the_mapping() {
    let avatar = mannequin().unwrap();
    let source = neural_cloth::scene::procedural::motion(MotionKind::Walk, 30.0, 0.5).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = write_bvh(
        dir.path(),
        "cmu.bvh",
        &avatar.skeleton,
        &source,
        &renamed(&RIGS[1]),
    );
    let out = Command::new(env!("CARGO_BIN_EXE_neural-cloth"))
        .arg("inspect")
        .arg(&path)
        .args(["--avatar", "mannequin"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for line in [
        "naming: avatar Mixamo, motion CMU 3ds Max friendly / MakeHuman / ASF",
        "LeftShoulder <- LeftCollar (rig names)",
        "LeftArm <- LeftShoulder (rig names)",
        "unmapped avatar joints (keep their rest rotation): none",
        "essential joints: all mapped",
    ] {
        assert!(text.contains(line), "missing '{line}' in:\n{text}");
    }
}
