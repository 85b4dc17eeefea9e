//! Z-up files (issue 13), made by our own code: the built-in motions written as a Z-up BVH
//! (named and with nonsense joint names), the mannequin written as a Z-up GLB, and built-in
//! garments written as Z-up OBJ files (in centimetres too). Each is detected and turned Y up
//! so that it matches what it was made from; `--up y` keeps a file as it is, `--up z` turns
//! one that detection would not; `fit` and `inspect` say what they did. Motions whose rig
//! faces another way (turned 90 or 180 degrees, or Z up facing +Y) are turned to face as the
//! avatar does.

use std::path::Path;
use std::process::Command;

use neural_cloth::fit::{FitOptions, fit_file};
use neural_cloth::geometry::{Mat4, Quat, Vec3};
use neural_cloth::io::export::gltf::{BakedSequence, GltfExportOptions, write_glb};
use neural_cloth::io::export::obj_seq::obj_text;
use neural_cloth::io::scene_loader::load_motions;
use neural_cloth::io::{ImportOptions, UpAxis, load_avatar, load_obj};
use neural_cloth::scene::procedural::{GarmentKind, MotionKind, builtin_garment, mannequin};
use neural_cloth::scene::{Avatar, Motion, Pose, Skeleton};

use super::rigs::{import, max_joint_error, write_bvh};

/// The rotation that lays a Y-up model down Z up (the inverse of the importers' turn).
pub(super) fn to_z_up() -> Quat {
    UpAxis::Z.to_y_up().inverse()
}

/// `sk` with its root laid down Z up (the joints' local offsets below it unchanged).
fn z_up_skeleton(sk: &Skeleton) -> Skeleton {
    let r = to_z_up();
    let mut z = sk.clone();
    for j in 0..sk.len() {
        if sk.parents[j].is_none() {
            let t = &mut z.rest_local[j];
            t.translation = r * t.translation;
            t.rotation = r * t.rotation;
        }
    }
    z
}

/// `sk` laid down Z up with identity rest rotations (as BVH needs): every offset turned, every
/// rotation conjugated.
fn z_up_bvh_rig(sk: &Skeleton, motion: &Motion) -> (Skeleton, Motion) {
    turned_bvh_rig(sk, motion, to_z_up())
}

/// `sk` and `motion` turned by `r` with identity rest rotations (as BVH needs): every offset
/// turned, every rotation conjugated, so every joint lands at `r` times where it was.
pub(super) fn turned_bvh_rig(sk: &Skeleton, motion: &Motion, r: Quat) -> (Skeleton, Motion) {
    let mut z = sk.clone();
    for t in &mut z.rest_local {
        t.translation = r * t.translation;
    }
    let frames = motion
        .frames
        .iter()
        .map(|pose| Pose {
            rotations: pose.rotations.iter().map(|q| r * q * r.inverse()).collect(),
            root_translation: r * pose.root_translation,
        })
        .collect();
    let m = Motion::new(motion.name.clone(), motion.fps, frames, sk.len()).unwrap();
    (z, m)
}

#[test]
fn a_z_up_bvh_is_turned_y_up_named_or_not() {
    let avatar = mannequin().unwrap();
    let sk = &avatar.skeleton;
    let source = neural_cloth::scene::procedural::motion(MotionKind::Walk, 30.0, 1.5).unwrap();
    let (z, on_z) = z_up_bvh_rig(sk, &source);
    // The fixture: every joint where the Y-up motion put it, laid down.
    for (a, b) in source.frames.iter().zip(&on_z.frames) {
        for (p, q) in sk.joint_positions(a).iter().zip(z.joint_positions(b)) {
            assert!((to_z_up() * p - q).norm() < 1e-4);
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let nonsense: Vec<String> = (0..sk.len()).map(|k| format!("j{}", k * 13 % 97)).collect();
    for (file, names) in [("named.bvh", sk.names.clone()), ("nonsense.bvh", nonsense)] {
        let path = write_bvh(dir.path(), file, &z, &on_z, &names);
        let mut warnings = Vec::new();
        let motions = load_motions(&path, &avatar, &import(30.0, None), &mut warnings)
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        let err = max_joint_error(sk, &motions[0], &source);
        assert!(err < 2e-3, "{file}: joints off by {err} m");
        assert!(
            warnings.iter().any(|w| w.contains("Z up detected")),
            "{file}: {warnings:?}"
        );
        // The BVH's own skeleton stands up too.
        let bvh = neural_cloth::io::load_bvh(&path).unwrap();
        let (own, _) = bvh.to_skeleton(neural_cloth::io::Units::Auto).unwrap();
        let span = |sk: &Skeleton| {
            let rest = sk.joint_positions(&sk.rest_pose());
            rest.iter().map(|p| p.y).fold(f32::MIN, f32::max)
                - rest.iter().map(|p| p.y).fold(f32::MAX, f32::min)
        };
        assert!((span(&own) - span(sk)).abs() < 1e-3, "{}", span(&own));
    }
}

/// The mannequin laid down Z up: root rest, inverse bind matrices and bind mesh turned.
pub(super) fn z_up_avatar(avatar: &Avatar) -> Avatar {
    let r = to_z_up();
    let mut sk = z_up_skeleton(&avatar.skeleton);
    let back: Mat4 = r.inverse().to_homogeneous();
    sk.joint_from_bind = sk.joint_from_bind.iter().map(|m| m * back).collect();
    let mut mesh = avatar.bind_mesh.clone();
    mesh.map_positions(|p| r * p);
    Avatar::new("zup", sk, mesh, avatar.skin.clone(), Vec::new()).unwrap()
}

#[test]
fn a_z_up_glb_avatar_stands_up() {
    let avatar = mannequin().unwrap();
    let lying = z_up_avatar(&avatar);
    let mut garment = builtin_garment(&avatar, GarmentKind::TShirt, 400, None).unwrap();
    garment.mesh.map_positions(|p| to_z_up() * p);
    let rest = vec![lying.skeleton.rest_pose(); 2];
    let offsets = vec![vec![Vec3::zeros(); garment.vertex_count()]; 2];
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("zup.glb");
    let sequence = BakedSequence {
        name: "rest",
        fps: 30.0,
        poses: &rest,
        rest_offsets: &offsets,
    };
    write_glb(
        &path,
        &lying,
        &garment,
        &sequence,
        &GltfExportOptions::default(),
    )
    .unwrap();
    let want = avatar
        .skeleton
        .joint_positions(&avatar.skeleton.rest_pose());
    let joints = |up: UpAxis| {
        let loaded = load_avatar(
            &path,
            &ImportOptions {
                up,
                ..Default::default()
            },
        )
        .unwrap();
        let sk = &loaded.avatar.skeleton;
        (
            loaded.up,
            sk.joint_positions(&sk.rest_pose()),
            loaded.warnings,
        )
    };
    let (up, got, warnings) = joints(UpAxis::Auto);
    assert_eq!(up, UpAxis::Z);
    assert!(
        warnings.iter().any(|w| w.contains("Z up detected")),
        "{warnings:?}"
    );
    for (p, q) in want.iter().zip(&got) {
        assert!((p - q).norm() < 1e-4, "{p:?} vs {q:?}");
    }
    // inspect tells what else the document holds.
    let text = neural_cloth::io::inspect(&path).unwrap();
    for line in [
        "up: Z (detected; turned Y up)",
        "document: 1 scenes, ",
        "animation channels: ",
        "materials: ",
        "extensions: used ",
    ] {
        assert!(text.contains(line), "missing '{line}' in:\n{text}");
    }
    // Kept as it is when asked.
    let (up, kept, _) = joints(UpAxis::Y);
    assert_eq!(up, UpAxis::Y);
    assert!((to_z_up() * want[5] - kept[5]).norm() < 1e-4);
}

#[test]
fn z_up_garments_are_turned_and_fit_and_inspect_say_so() {
    let avatar = mannequin().unwrap();
    let original = builtin_garment(&avatar, GarmentKind::TShirt, 700, None)
        .unwrap()
        .mesh;
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, f: &dyn Fn(Vec3) -> Vec3| {
        let positions: Vec<Vec3> = original.positions.iter().map(|p| f(*p)).collect();
        let path = dir.path().join(format!("{name}.obj"));
        std::fs::write(&path, obj_text(&positions, &original.faces, None, name)).unwrap();
        path
    };
    let lying = write("zup", &|p| to_z_up() * p);
    let loaded = load_obj(&lying, &super::opts()).unwrap();
    assert_eq!(loaded.up, UpAxis::Z);
    for (p, q) in loaded.mesh.positions.iter().zip(&original.positions) {
        assert!((p - q).norm() < 1e-5);
    }
    // --up y keeps it lying; --up z turns a Y-up file.
    let kept = load_obj(
        &lying,
        &ImportOptions {
            up: UpAxis::Y,
            ..Default::default()
        },
    )
    .unwrap();
    assert!((kept.mesh.positions[0] - to_z_up() * original.positions[0]).norm() < 1e-5);
    let standing = write("yup", &|p| p);
    assert_eq!(load_obj(&standing, &super::opts()).unwrap().up, UpAxis::Y);

    // fit: a Z-up garment in centimetres, 20 cm off, comes back where it was made.
    let cm = write("zup_cm", &|p| {
        to_z_up() * (p + Vec3::new(0.0, 0.2, 0.0)) * 100.0
    });
    let options = FitOptions {
        relax: None,
        ..Default::default()
    };
    let fitted = fit_file(&avatar, &cm, &options).unwrap();
    assert_eq!(fitted.report.up, UpAxis::Z);
    let mean = fitted
        .mesh
        .positions
        .iter()
        .zip(&original.positions)
        .map(|(p, q)| (p - q).norm())
        .sum::<f32>()
        / original.vertex_count() as f32;
    assert!(mean < 0.01, "{mean} m");

    // The commands say what they did.
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_neural-cloth"))
            .args(args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let path = |p: &Path| p.display().to_string();
    let text = run(&["inspect", &path(&lying)]);
    assert!(text.contains("up: Z (detected; turned Y up)"), "{text}");
    let text = run(&["inspect", &path(&lying), "--up", "y"]);
    assert!(text.contains("up: Y (given)"), "{text}");
    for line in [
        "objects and groups: 1 ((no name): ",
        "materials: none",
        "normals: 0 (not used: recomputed from the faces)",
    ] {
        assert!(text.contains(line), "missing '{line}' in:\n{text}");
    }
    let out = dir.path().join("fitted.obj");
    let text = run(&[
        "fit",
        "--avatar",
        "mannequin",
        "--garment",
        &path(&cm),
        "--out",
        &path(&out),
        "--no-relax",
    ]);
    assert!(
        text.contains("up:      Z (detected from its shape; turned Y up)"),
        "{text}"
    );
}

#[test]
fn a_motion_whose_rig_faces_another_way_is_turned_to_face_the_avatars_way() {
    let avatar = mannequin().unwrap();
    let sk = &avatar.skeleton;
    let source = neural_cloth::scene::procedural::motion(MotionKind::Walk, 30.0, 1.5).unwrap();
    let nonsense: Vec<String> = (0..sk.len()).map(|k| format!("q{}", k * 17 % 89)).collect();
    let yaw = |deg: f32| Quat::from_scaled_axis(Vec3::y() * deg.to_radians());
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("back.bvh", yaw(180.0), sk.names.clone(), 180.0),
        ("side.bvh", yaw(90.0), nonsense.clone(), 90.0),
        ("other_side.bvh", yaw(-90.0), sk.names.clone(), 90.0),
        // Z up, made facing +Y: -Z once turned Y up.
        ("zup_plus_y.bvh", to_z_up() * yaw(180.0), nonsense, 180.0),
    ];
    for (file, r, names, degrees) in cases {
        let (t, on_t) = turned_bvh_rig(sk, &source, r);
        let path = write_bvh(dir.path(), file, &t, &on_t, &names);
        let mut warnings = Vec::new();
        let motions = load_motions(&path, &avatar, &import(30.0, None), &mut warnings)
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        let err = max_joint_error(sk, &motions[0], &source);
        assert!(err < 2e-3, "{file}: joints off by {err} m");
        let said = format!("faces {degrees:.0} degrees away from the avatar's");
        assert!(
            warnings.iter().any(|w| w.contains(&said)),
            "{file}: {warnings:?}"
        );
    }
}
