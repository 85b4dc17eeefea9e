//! Integration tests of the importers on the shared real assets (`../shared/assets`):
//! facts from LICENSES.md and from the files themselves (read here independently), rest-pose
//! skinning against an independent glTF skinning, retargeting of every CMU clip, typed errors
//! for bad input, and a mutation test (random byte flips, truncations and splices) asserting
//! that no importer panics. The USD export is read back by Pixar's usd-core and checked with
//! its validators (`io/usd_export.rs`). Retargeting across rig naming conventions, rest poses,
//! glTF rigs and joint maps, on fixtures written by our own code (`io/rigs.rs`); by skeleton
//! structure where the joint names say nothing (`io/structure.rs`). Z-up BVH, GLB and OBJ files
//! turned Y up (`io/up_axis.rs`), and a scene of them loading as its Y-up twin (`io/scene_up.rs`). Garment
//! fitting on built-in and MakeHuman garments, and the `fit` command (`io/fit.rs`); garments
//! made for another arm pose re-posed (`io/sleeves.rs`). Characters
//! built partly of rigid meshes parented to bones (`io/rigid_parts.rs`), and only of them
//! (`io/rigid_only.rs`). A scene's mirrored motions, built in and from files
//! (`io/mirrored_motions.rs`).
//!
//! Layout: this file holds the shared helpers; the tests live in `io/*.rs` (one test binary).

#[path = "io/avatars.rs"]
mod avatars;
#[path = "io/config_mutation.rs"]
mod config_mutation;
#[path = "io/fit.rs"]
mod fit;
#[path = "io/garments.rs"]
mod garments;
#[path = "io/mirrored_motions.rs"]
mod mirrored_motions;
#[path = "io/motions.rs"]
mod motions;
#[path = "io/mutation.rs"]
mod mutation;
#[path = "io/raw_gltf.rs"]
mod raw_gltf;
#[path = "io/rigid_only.rs"]
mod rigid_only;
#[path = "io/rigid_parts.rs"]
mod rigid_parts;
#[path = "io/rigs.rs"]
mod rigs;
#[path = "io/scene_up.rs"]
mod scene_up;
#[path = "io/sleeves.rs"]
mod sleeves;
#[path = "io/structure.rs"]
mod structure;
#[path = "io/up_axis.rs"]
mod up_axis;
#[path = "io/usd_export.rs"]
mod usd_export;

use std::path::{Path, PathBuf};

use neural_cloth::geometry::{Mat4, Vec3};
use neural_cloth::io::{ImportOptions, IoError};
use neural_cloth::scene::{JointTransform, Skeleton};

/// A file under the shared assets folder.
pub fn asset(sub: &str) -> PathBuf {
    Path::new("../shared/assets").join(sub)
}

/// The files of an assets subfolder with extension `ext`, sorted.
pub fn files_in(dir: &str, ext: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(asset(dir))
        .expect("assets folder")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case(ext)))
        .collect();
    v.sort();
    v
}

/// Default import options (auto units, 30 fps).
pub fn opts() -> ImportOptions {
    ImportOptions::default()
}

/// Asserts that an error message ends with the file it is about.
pub fn assert_names_file(err: &IoError, file: &str) {
    assert!(
        err.to_string().ends_with(file),
        "message does not end with the file: {err}"
    );
}

/// A small Mixamo-named T-pose skeleton, 1.8 m tall (hips at 1 m).
pub fn mixamo_skeleton() -> Skeleton {
    let mut names = Vec::new();
    let mut parents = Vec::new();
    let mut offsets = Vec::new();
    let mut add = |name: &str, parent: Option<&str>, offset: [f32; 3], names: &mut Vec<String>| {
        parents.push(parent.map(|p| names.iter().position(|n| n == p).unwrap()));
        names.push(name.to_string());
        offsets.push(Vec3::from(offset));
    };
    add("Hips", None, [0.0, 1.0, 0.0], &mut names);
    add("Spine", Some("Hips"), [0.0, 0.1, 0.0], &mut names);
    add("Spine1", Some("Spine"), [0.0, 0.12, 0.0], &mut names);
    add("Spine2", Some("Spine1"), [0.0, 0.13, 0.0], &mut names);
    add("Neck", Some("Spine2"), [0.0, 0.15, 0.0], &mut names);
    add("Head", Some("Neck"), [0.0, 0.1, 0.0], &mut names);
    for (side, sign) in [("Left", 1.0), ("Right", -1.0)] {
        let n = |s: &str| format!("{side}{s}");
        add(
            &n("Shoulder"),
            Some("Spine2"),
            [sign * 0.05, 0.12, 0.0],
            &mut names,
        );
        add(
            &n("Arm"),
            Some(&n("Shoulder")),
            [sign * 0.12, 0.0, 0.0],
            &mut names,
        );
        add(
            &n("ForeArm"),
            Some(&n("Arm")),
            [sign * 0.27, 0.0, 0.0],
            &mut names,
        );
        add(
            &n("Hand"),
            Some(&n("ForeArm")),
            [sign * 0.25, 0.0, 0.0],
            &mut names,
        );
        add(
            &n("UpLeg"),
            Some("Hips"),
            [sign * 0.1, -0.05, 0.0],
            &mut names,
        );
        add(&n("Leg"), Some(&n("UpLeg")), [0.0, -0.45, 0.0], &mut names);
        add(&n("Foot"), Some(&n("Leg")), [0.0, -0.42, 0.0], &mut names);
        add(
            &n("ToeBase"),
            Some(&n("Foot")),
            [0.0, -0.05, 0.12],
            &mut names,
        );
    }
    let n = names.len();
    let rest: Vec<JointTransform> = offsets
        .iter()
        .map(|&translation| JointTransform {
            translation,
            ..Default::default()
        })
        .collect();
    let mut sk = Skeleton::new(
        names,
        parents,
        rest,
        vec![Mat4::identity(); n],
        vec![Mat4::identity(); n],
    )
    .unwrap();
    let world = sk.world_from_joint(&sk.rest_pose());
    sk.joint_from_bind = world.iter().map(|m| m.try_inverse().unwrap()).collect();
    sk
}
