//! Avatars: facts from LICENSES.md and the files, rest-pose skinning against the independent
//! glTF skinning, rig edge cases, and typed errors for bad glTF input.

use std::path::Path;

use nalgebra::Vector3;
use neural_cloth::io::{self, IoError, Units};
use serde_json::Value;

use super::raw_gltf::{load_raw, raw_gltf, simple_skin};
use super::{assert_names_file, asset, files_in, opts};

/// (file, joints, vertices, [(animation name or None, duration s)], units) from LICENSES.md.
pub type AvatarFacts = (
    &'static str,
    usize,
    usize,
    &'static [(Option<&'static str>, f32)],
    Units,
);
pub const AVATARS: [AvatarFacts; 4] = [
    ("CesiumMan.glb", 19, 3273, &[(None, 2.0)], Units::Metres),
    (
        "Fox.glb",
        24,
        1728,
        &[
            (Some("Survey"), 3.42),
            (Some("Walk"), 0.71),
            (Some("Run"), 1.16),
        ],
        Units::Centimetres,
    ),
    (
        "RiggedSimple_blender_reexport.glb",
        4,
        960,
        &[(Some("Anim_0_Armature"), 6.67)],
        Units::Metres,
    ),
    ("SimpleSkin.gltf", 2, 10, &[(None, 5.5)], Units::Metres),
];

#[test]
fn every_avatar_file_is_covered() {
    let files: Vec<String> = files_in("avatars", "glb")
        .into_iter()
        .chain(files_in("avatars", "gltf"))
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(files.len(), AVATARS.len());
    for f in files {
        assert!(
            AVATARS.iter().any(|a| a.0 == f),
            "{f} has no facts in this test"
        );
    }
}

#[test]
fn avatars_match_licence_facts_and_file_contents() {
    for (file, joints, vertices, anims, units) in AVATARS {
        let path = asset(&format!("avatars/{file}"));
        let loaded = io::load_avatar(&path, &opts()).unwrap_or_else(|e| panic!("{e}"));
        let a = &loaded.avatar;
        assert_eq!(a.skeleton.len(), joints, "{file} joints");
        assert_eq!(a.bind_mesh.vertex_count(), vertices, "{file} vertices");
        assert_eq!(loaded.units, units, "{file} units");
        assert_eq!(a.motions.len(), anims.len(), "{file} animations");
        let raw = raw_gltf(&std::fs::read(&path).unwrap());
        let ends = raw.animation_ends();
        for ((motion, (name, secs)), end) in a.motions.iter().zip(anims).zip(ends) {
            if let Some(name) = name {
                assert_eq!(&motion.name, name, "{file}");
            }
            assert_eq!(motion.fps, 30.0);
            assert!(
                (motion.duration_secs() - secs).abs() <= 1.0 / 30.0 + 0.006,
                "{file} '{}' lasts {} s, LICENSES says {secs}",
                motion.name,
                motion.duration_secs()
            );
            // Whole frames at 30 fps from t = 0 up to the last keyframe.
            let d = motion.duration_secs() as f64;
            assert!(
                d <= end + 1e-4 && d > end - 1.0 / 30.0,
                "{file}: keyframes end at {end}, motion lasts {d}"
            );
            assert!(
                motion
                    .frames
                    .iter()
                    .all(neural_cloth::scene::motion::pose_is_finite)
            );
        }
        // Parents precede children, and each skeleton joint is a distinct named node.
        for (j, p) in a.skeleton.parents.iter().enumerate() {
            assert!(p.is_none_or(|p| p < j));
        }
        // Heights in metres are plausible for each model.
        let h = a.height_m();
        assert!((0.3..10.0).contains(&h), "{file} is {h} m tall");
    }
}

#[test]
fn rest_mesh_matches_independent_gltf_skinning() {
    for (file, ..) in AVATARS {
        let path = asset(&format!("avatars/{file}"));
        let loaded = io::load_avatar(&path, &opts()).unwrap();
        let scale = loaded.units.metres_per_unit().unwrap() as f64;
        let expected = raw_gltf(&std::fs::read(&path).unwrap()).rest_mesh(scale);
        let got = &loaded.avatar.rest_mesh.positions;
        assert_eq!(got.len(), expected.len(), "{file}");
        let height = loaded.avatar.height_m() as f64;
        let worst = got
            .iter()
            .zip(&expected)
            .map(|(g, e)| (g.cast::<f64>() - e).norm())
            .fold(0.0, f64::max);
        assert!(
            worst <= 1e-5 * height.max(1.0),
            "{file}: rest mesh off by {worst} m (height {height} m)"
        );
        // The avatar's own skinning of its rest pose is its rest mesh.
        let posed = loaded
            .avatar
            .pose_vertices(&loaded.avatar.skeleton.rest_pose());
        let again = posed
            .iter()
            .zip(got)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0f32, f32::max);
        assert!(again < 1e-6, "{file}");
    }
}

#[test]
fn simple_skin_warns_about_its_zero_length_bone() {
    let loaded = io::load_avatar(&asset("avatars/SimpleSkin.gltf"), &opts()).unwrap();
    assert!(
        loaded
            .warnings
            .iter()
            .any(|w| w.contains("zero-length") && w.contains("node2")),
        "{:?}",
        loaded.warnings
    );
}

#[test]
fn fox_hip_translation_moves_the_whole_body() {
    let loaded = io::load_avatar(&asset("avatars/Fox.glb"), &opts()).unwrap();
    assert!(
        loaded
            .warnings
            .iter()
            .any(|w| w.contains("b_Hip_01") && w.contains("root translation")),
        "{:?}",
        loaded.warnings
    );
    let a = &loaded.avatar;
    let raw = raw_gltf(&std::fs::read(asset("avatars/Fox.glb")).unwrap());
    let height = a.height_m() as f64;
    for (k, motion) in a.motions.iter().enumerate() {
        // The body at t = 0, skinned independently with every channel at its first keyframe.
        let expected = raw.skinned_mesh(0.01, &|j| raw.world_at_first_keys(k, j));
        let got = a.pose_vertices(&motion.frames[0]);
        let worst = got
            .iter()
            .zip(&expected)
            .map(|(g, e)| (g.cast::<f64>() - e).norm())
            .fold(0.0, f64::max);
        assert!(
            worst < 1e-5 * height.max(1.0),
            "{}: body off by {worst} m",
            motion.name
        );
        // The hip moved: its first-key translation differs from rest by centimetres.
        let hip = a.skeleton.index_of("b_Hip_01").unwrap();
        let rest_hip = a.skeleton.joint_positions(&a.skeleton.rest_pose())[hip];
        assert!(
            (a.skeleton.joint_positions(&motion.frames[0])[hip] - rest_hip).norm() > 0.005,
            "{}",
            motion.name
        );
    }
}

#[test]
fn skinned_mesh_node_transform_is_ignored_and_ancestors_fold_in() {
    let base = load_raw(&simple_skin()).unwrap();
    // Move the skinned mesh node under a joint and give it a transform: nothing may change.
    let mut raw = simple_skin();
    raw.json["nodes"][0]["translation"] = serde_json::json!([5.0, 0.0, 0.0]);
    raw.json["nodes"][2]["children"] = serde_json::json!([0]);
    raw.json["scenes"][0]["nodes"] = serde_json::json!([1]);
    let moved = load_raw(&raw).unwrap();
    for (a, b) in base
        .avatar
        .rest_mesh
        .positions
        .iter()
        .zip(&moved.avatar.rest_mesh.positions)
    {
        assert!((a - b).norm() < 1e-6);
    }
    // Put the root joint under a translated, scaled non-joint node: the body follows it.
    let mut raw = simple_skin();
    raw.json["nodes"].as_array_mut().unwrap().push(serde_json::json!({"children": [1], "translation": [0.0, 0.0, 2.0], "scale": [0.5, 0.5, 0.5]}));
    raw.json["scenes"][0]["nodes"] = serde_json::json!([0, 3]);
    let wrapped = load_raw(&raw).unwrap();
    assert_eq!(wrapped.avatar.skeleton.len(), 2);
    let expected = raw.rest_mesh(1.0);
    for (g, e) in wrapped.avatar.rest_mesh.positions.iter().zip(&expected) {
        assert!((g.cast::<f64>() - e).norm() < 1e-6);
    }
    assert!((wrapped.avatar.rest_mesh.positions[0].z - 2.0).abs() < 1e-6);
}

#[test]
fn skins_sharing_joints_make_one_skeleton_and_external_buffers_load() {
    let mut raw = simple_skin();
    let skin = raw.json["skins"][0].clone();
    raw.json["skins"].as_array_mut().unwrap().push(skin);
    raw.json["nodes"]
        .as_array_mut()
        .unwrap()
        .push(serde_json::json!({"mesh": 0, "skin": 1}));
    raw.json["scenes"][0]["nodes"] = serde_json::json!([0, 1, 3]);
    let two = load_raw(&raw).unwrap();
    assert_eq!(two.avatar.skeleton.len(), 2);
    assert_eq!(two.avatar.bind_mesh.vertex_count(), 20);
    assert_eq!(
        two.avatar.rest_mesh.positions[3],
        two.avatar.rest_mesh.positions[13]
    );

    // The same file with its buffers as external .bin files (one name needs percent-decoding).
    let dir = tempfile::tempdir().unwrap();
    let mut json = simple_skin().json;
    for (k, buffer) in simple_skin().buffers.iter().enumerate() {
        let name = format!("buffer {k}.bin");
        std::fs::write(dir.path().join(&name), buffer).unwrap();
        json["buffers"][k]["uri"] = Value::String(name.replace(' ', "%20"));
    }
    let path = dir.path().join("external.gltf");
    std::fs::write(&path, serde_json::to_vec(&json).unwrap()).unwrap();
    let ext = io::load_avatar(&path, &opts()).unwrap();
    let emb = io::load_avatar(&asset("avatars/SimpleSkin.gltf"), &opts()).unwrap();
    assert_eq!(
        ext.avatar.rest_mesh.positions,
        emb.avatar.rest_mesh.positions
    );
    assert_eq!(ext.avatar.motions, emb.avatar.motions);
    std::fs::remove_file(dir.path().join("buffer 2.bin")).unwrap();
    let err = io::load_avatar(&path, &opts()).unwrap_err();
    assert!(
        matches!(err, IoError::Read { .. }) && err.to_string().ends_with("buffer 2.bin"),
        "{err}"
    );
}

#[test]
fn gltf_meshes_load_as_garment_templates() {
    for (file, _, vertices, ..) in AVATARS {
        let m = io::load_gltf_mesh(&asset(&format!("avatars/{file}")), &opts()).unwrap();
        assert_eq!(m.mesh.vertex_count(), vertices, "{file}");
        assert!(m.warnings.iter().any(|w| w.contains("skin")), "{file}");
    }
    // SimpleSkin's mesh node is a scene root with no transform: positions are the file's.
    let m = io::load_gltf_mesh(&asset("avatars/SimpleSkin.gltf"), &opts()).unwrap();
    let raw = simple_skin();
    for (p, r) in m.mesh.positions.iter().zip(raw.accessor(1)) {
        assert!((p.cast::<f64>() - Vector3::new(r[0], r[1], r[2])).norm() < 1e-7);
    }
}

#[test]
fn malformed_and_truncated_gltf_are_typed_errors() {
    let path = asset("avatars/CesiumMan.glb");
    let bytes = std::fs::read(&path).unwrap();
    for cut in [0, 7, 11, 20, 200, bytes.len() / 2, bytes.len() - 1] {
        let err = io::load_avatar_from_bytes(&bytes[..cut], &path, &opts()).unwrap_err();
        assert!(
            matches!(err, IoError::Truncated { .. } | IoError::NotGltf { .. }),
            "cut {cut}: {err}"
        );
        assert_names_file(&err, "CesiumMan.glb");
    }
    let text = std::fs::read(asset("avatars/SimpleSkin.gltf")).unwrap();
    let err = io::load_avatar_from_bytes(&text[..text.len() / 2], Path::new("half.gltf"), &opts())
        .unwrap_err();
    assert!(matches!(err, IoError::Truncated { .. }), "{err}");
    let err = io::load_avatar_from_bytes(
        b"solid cube\nfacet normal 0 0 1\n",
        Path::new("x.gltf"),
        &opts(),
    )
    .unwrap_err();
    assert!(matches!(err, IoError::NotGltf { .. }), "{err}");
    // An accessor that reads past its buffer view.
    let mut raw = simple_skin();
    raw.json["accessors"][1]["count"] = serde_json::json!(11);
    let err = load_raw(&raw).unwrap_err();
    assert!(matches!(err, IoError::InvalidGltf { .. }), "{err}");
    assert_names_file(&err, "SimpleSkin.gltf");
    // An index past the vertices.
    let mut raw = simple_skin();
    raw.buffers[0][0] = 200;
    assert!(matches!(
        load_raw(&raw).unwrap_err(),
        IoError::InvalidGltf { .. }
    ));
}

#[test]
fn gltf_without_a_skin_is_reported() {
    let mut raw = simple_skin();
    raw.json["nodes"][0].as_object_mut().unwrap().remove("skin");
    let err = load_raw(&raw).unwrap_err();
    assert!(matches!(err, IoError::NoSkin { .. }), "{err}");
    assert!(err.to_string().contains("glTF without a skin"));
    assert_names_file(&err, "SimpleSkin.gltf");
    let mesh =
        io::load_gltf_mesh_from_bytes(&raw.to_gltf_bytes(), Path::new("noskin.gltf"), &opts())
            .unwrap();
    assert_eq!(mesh.mesh.vertex_count(), 10);
    assert!(mesh.warnings.is_empty(), "{:?}", mesh.warnings);
}

#[test]
fn nan_and_non_unit_rotations_in_gltf_are_rejected() {
    // Non-unit node rotation.
    let mut raw = simple_skin();
    raw.json["nodes"][2]["rotation"] = serde_json::json!([0.0, 0.0, 0.0, 2.0]);
    let err = load_raw(&raw).unwrap_err();
    assert!(
        matches!(err, IoError::NonUnitRotation { norm, .. } if (norm - 2.0).abs() < 1e-6),
        "{err}"
    );
    // Non-unit animation keyframe (buffer 3 holds 12 times, then 12 quaternions).
    let mut raw = simple_skin();
    let at = 48 + 5 * 16 + 12;
    raw.buffers[3][at..at + 4].copy_from_slice(&3.0f32.to_le_bytes());
    let err = load_raw(&raw).unwrap_err();
    assert!(matches!(err, IoError::NonUnitRotation { .. }), "{err}");
    // NaN vertex position.
    let mut raw = simple_skin();
    raw.buffers[0][48 + 12..48 + 16].copy_from_slice(&f32::NAN.to_le_bytes());
    let err = load_raw(&raw).unwrap_err();
    assert!(matches!(err, IoError::NonFinite { .. }), "{err}");
    assert_names_file(&err, "SimpleSkin.gltf");
}

#[test]
fn gltf_joint_count_mismatches_are_typed_errors() {
    let mut raw = simple_skin();
    raw.json["accessors"][4]["count"] = serde_json::json!(1);
    let err = load_raw(&raw).unwrap_err();
    assert!(
        matches!(
            err,
            IoError::JointCountMismatch {
                expected: 2,
                found: 1,
                ..
            }
        ),
        "{err}"
    );
    let mut raw = simple_skin();
    raw.json["skins"][0]["joints"] = serde_json::json!([1]);
    let err = load_raw(&raw).unwrap_err();
    assert!(
        matches!(
            err,
            IoError::JointCountMismatch {
                expected: 1,
                found: 2,
                ..
            }
        ),
        "{err}"
    );
    assert_names_file(&err, "SimpleSkin.gltf");
}
