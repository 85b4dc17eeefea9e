//! The up axis as a scene setting (issue 13): a scene of Z-up files made by our own code (the
//! mannequin as a Z-up GLB, a skirt as a Z-up OBJ, a walk as a Z-up BVH) loads the same as its
//! Y-up twin, with `up = "z"` on the sources where detection cannot tell (a skirt is about as
//! deep as it is tall); the `train` command takes the same setting as `--up z`, records it in
//! the run's scene, and without it refuses the lying skirt.

use std::path::{Path, PathBuf};
use std::process::Command;

use neural_cloth::geometry::{Quat, Vec3};
use neural_cloth::io::export::gltf::{BakedSequence, GltfExportOptions, write_glb};
use neural_cloth::io::export::obj_seq::obj_text;
use neural_cloth::io::scene_loader::{SceneLoader, load_scene_file};
use neural_cloth::io::{ImportOptions, UpAxis, load_obj};
use neural_cloth::scene::procedural::{GarmentKind, MotionKind, builtin_garment, mannequin};
use neural_cloth::scene::{Avatar, Scene, SceneConfig};

use super::rigs::write_bvh;
use super::up_axis::{to_z_up, turned_bvh_rig, z_up_avatar};

/// `avatar` (with a small t-shirt, as the writer needs a garment) as a GLB file.
fn write_avatar(dir: &Path, file: &str, avatar: &Avatar) -> PathBuf {
    let mut shirt = builtin_garment(&mannequin().unwrap(), GarmentKind::TShirt, 300, None).unwrap();
    if avatar.name == "zup" {
        shirt.mesh.map_positions(|p| to_z_up() * p);
    }
    let rest = vec![avatar.skeleton.rest_pose(); 2];
    let offsets = vec![vec![Vec3::zeros(); shirt.vertex_count()]; 2];
    let sequence = BakedSequence {
        name: "rest",
        fps: 30.0,
        poses: &rest,
        rest_offsets: &offsets,
    };
    let path = dir.join(file);
    write_glb(
        &path,
        avatar,
        &shirt,
        &sequence,
        &GltfExportOptions::default(),
    )
    .unwrap();
    path
}

/// The built-in skirt turned by `r`, as an OBJ file.
fn write_skirt(dir: &Path, file: &str, r: Quat) -> PathBuf {
    let skirt = builtin_garment(&mannequin().unwrap(), GarmentKind::Skirt, 800, None)
        .unwrap()
        .mesh;
    let positions: Vec<Vec3> = skirt.positions.iter().map(|p| r * p).collect();
    let path = dir.join(file);
    std::fs::write(&path, obj_text(&positions, &skirt.faces, None, "skirt")).unwrap();
    path
}

/// The Y-up and Z-up twins of every file of the scene, in `dir`.
fn write_twins(dir: &Path) {
    let avatar = mannequin().unwrap();
    write_avatar(dir, "body_y.glb", &avatar);
    write_avatar(dir, "body_z.glb", &z_up_avatar(&avatar));
    write_skirt(dir, "skirt_y.obj", Quat::identity());
    write_skirt(dir, "skirt_z.obj", to_z_up());
    let sk = &avatar.skeleton;
    let walk = neural_cloth::scene::procedural::motion(MotionKind::Walk, 30.0, 1.0).unwrap();
    for (file, r) in [("walk_y.bvh", Quat::identity()), ("walk_z.bvh", to_z_up())] {
        let (rig, m) = turned_bvh_rig(sk, &walk, r);
        write_bvh(dir, file, &rig, &m, &sk.names);
    }
}

/// A scene file of the files ending in `suffix`, each source with `up` (None: left out).
fn write_scene(dir: &Path, suffix: &str, up: Option<&str>) -> PathBuf {
    let inline = up.map(|u| format!(", up = \"{u}\"")).unwrap_or_default();
    let line = up.map(|u| format!("up = \"{u}\"\n")).unwrap_or_default();
    let text = format!(
        "name = \"twins\"\navatar = {{ path = \"body_{suffix}.glb\"{inline} }}\n\
         garment = {{ path = \"skirt_{suffix}.obj\"{inline} }}\n\
         [[motions]]\npath = \"walk_{suffix}.bvh\"\nsplit = \"train\"\n{line}"
    );
    let path = dir.join(format!("scene_{suffix}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// Largest distance between matching points.
fn max_gap(a: &[Vec3], b: &[Vec3]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, f32::max)
}

/// Asserts that two scenes hold the same avatar, garment and motions (positions after the
/// conversion, metres).
fn assert_same_scene(got: &Scene, want: &Scene) {
    let (a, b) = (&got.avatar, &want.avatar);
    let rest = |av: &Avatar| av.skeleton.joint_positions(&av.skeleton.rest_pose());
    assert!(max_gap(&rest(a), &rest(b)) < 1e-4, "rest joints");
    assert!(
        max_gap(&a.rest_mesh.positions, &b.rest_mesh.positions) < 1e-4,
        "body"
    );
    let gap = max_gap(&got.garment.mesh.positions, &want.garment.mesh.positions);
    assert!(gap < 1e-4, "garment off by {gap} m");
    assert_eq!(got.garment.skin.joints, want.garment.skin.joints);
    assert_eq!(got.motions.len(), want.motions.len());
    for ((m, _), (n, _)) in got.motions.iter().zip(&want.motions) {
        assert_eq!(m.frames.len(), n.frames.len(), "{}", m.name);
        for (p, q) in m.frames.iter().zip(&n.frames) {
            let gap = max_gap(
                &a.skeleton.joint_positions(p),
                &b.skeleton.joint_positions(q),
            );
            assert!(gap < 2e-3, "{}: joints off by {gap} m", m.name);
        }
    }
}

#[test]
fn a_scene_of_z_up_files_loads_the_same_as_its_y_up_twin() {
    let dir = tempfile::tempdir().unwrap();
    write_twins(dir.path());
    // The lying skirt is as deep as it is tall: detection leaves it lying.
    let lying = load_obj(&dir.path().join("skirt_z.obj"), &ImportOptions::default()).unwrap();
    assert_eq!(lying.up, UpAxis::Y);
    let y = load_scene_file(&write_scene(dir.path(), "y", None)).unwrap();
    let z = load_scene_file(&write_scene(dir.path(), "z", Some("z"))).unwrap();
    assert_same_scene(&z.scene, &y.scene);
    // The given axis is no detection: no "Z up detected" warning.
    assert!(
        !z.warnings.iter().any(|w| w.contains("Z up detected")),
        "{:?}",
        z.warnings
    );
    // And the explicit setting overrides detection: `up = "y"` keeps the Z-up body lying
    // (auto detects it and stands it up).
    let path = write_scene(dir.path(), "z", Some("y"));
    let config = SceneConfig::load(&path).unwrap();
    let kept = SceneLoader::new(&config, dir.path(), &path)
        .avatar(&mut Vec::new())
        .unwrap();
    let rest = |av: &Avatar| av.skeleton.joint_positions(&av.skeleton.rest_pose());
    let (k, w) = (rest(&kept), rest(&y.scene.avatar));
    assert!(max_gap(&k, &w) > 0.5);
    let lying: Vec<Vec3> = w.iter().map(|p| to_z_up() * p).collect();
    assert!(max_gap(&k, &lying) < 1e-4);
}

/// Runs the binary in `dir`; its success and stderr.
fn cli(args: &[&str], dir: &Path) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_neural-cloth"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn train_takes_the_up_axis_and_records_it_in_the_run() {
    let dir = tempfile::tempdir().unwrap();
    write_skirt(dir.path(), "skirt_z.obj", to_z_up());
    std::fs::write(
        dir.path().join("scene.toml"),
        "name = \"lying skirt\"\navatar = { builtin = \"mannequin\" }\n\
         garment = { path = \"skirt_z.obj\" }\n[[motions]]\nbuiltin = \"walk\"\n\
         duration_secs = 1.0\n",
    )
    .unwrap();
    let train = ["train", "--scene", "scene.toml", "--steps", "1"];
    // Left lying, the skirt does not fit the body and is refused.
    let (ok, log) = cli(&[&train[..], &["--out", "lying"]].concat(), dir.path());
    assert!(!ok && log.contains("skirt_z.obj"), "{log}");
    let (ok, log) = cli(
        &[
            &train[..],
            &["--up", "z", "--predrape-secs", "0", "--out", "run"],
        ]
        .concat(),
        dir.path(),
    );
    assert!(ok, "{log}");
    let recorded = std::fs::read_to_string(dir.path().join("run/scene.toml")).unwrap();
    assert!(recorded.contains("up = \"z\""), "{recorded}");
}
