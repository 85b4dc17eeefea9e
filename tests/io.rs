//! Integration tests of the importers on the shared real assets (`../shared/assets`):
//! facts from LICENSES.md and from the files themselves (read here independently), rest-pose
//! skinning against an independent glTF skinning, retargeting of every CMU clip, typed errors
//! for bad input, and a mutation test (random byte flips, truncations and splices) asserting
//! that no importer panics.

use std::path::{Path, PathBuf};

use base64::Engine as _;
use nalgebra::{Matrix4, Point3, Quaternion, UnitQuaternion, Vector3};
use neural_cloth::geometry::{Mat4, Quat, Vec3};
use neural_cloth::io::{self, Bvh, ImportOptions, IoError, RetargetOptions, Units};
use neural_cloth::scene::skeleton::rotation_of;
use neural_cloth::scene::{JointTransform, Skeleton};
use serde_json::Value;

fn asset(sub: &str) -> PathBuf {
    Path::new("../shared/assets").join(sub)
}

fn files_in(dir: &str, ext: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(asset(dir))
        .expect("assets folder")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case(ext)))
        .collect();
    v.sort();
    v
}

fn opts() -> ImportOptions {
    ImportOptions::default()
}

// ---------------------------------------------------------------------------------------------
// Independent glTF reading (serde_json + hand-decoded accessors), used to check the importer.

struct RawGltf {
    json: Value,
    buffers: Vec<Vec<u8>>,
}

fn raw_gltf(bytes: &[u8]) -> RawGltf {
    if bytes.starts_with(b"glTF") {
        let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
        let json_len = u32_at(12);
        let json: Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
        let bin_at = 20 + json_len;
        let bin = if bin_at + 8 <= bytes.len() { bytes[bin_at + 8..bin_at + 8 + u32_at(bin_at)].to_vec() } else { Vec::new() };
        RawGltf { json, buffers: vec![bin] }
    } else {
        let json: Value = serde_json::from_slice(bytes).unwrap();
        let buffers = json["buffers"]
            .as_array()
            .unwrap()
            .iter()
            .map(|b| {
                let uri = b["uri"].as_str().unwrap();
                base64::engine::general_purpose::STANDARD.decode(uri.split_once(";base64,").unwrap().1).unwrap()
            })
            .collect();
        RawGltf { json, buffers }
    }
}

impl RawGltf {
    /// Accessor `i` as rows of f64 (float, u8 or u16 components, honouring byteStride).
    fn accessor(&self, i: usize) -> Vec<Vec<f64>> {
        let a = &self.json["accessors"][i];
        let view = &self.json["bufferViews"][a["bufferView"].as_u64().unwrap() as usize];
        let buf = &self.buffers[view["buffer"].as_u64().unwrap() as usize];
        let n = match a["type"].as_str().unwrap() {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            "VEC4" => 4,
            "MAT4" => 16,
            t => panic!("type {t}"),
        };
        let ct = a["componentType"].as_u64().unwrap();
        let size = match ct {
            5126 => 4,
            5123 => 2,
            5121 => 1,
            c => panic!("component {c}"),
        };
        let stride = view["byteStride"].as_u64().map(|s| s as usize).unwrap_or(n * size);
        let base = view["byteOffset"].as_u64().unwrap_or(0) as usize + a["byteOffset"].as_u64().unwrap_or(0) as usize;
        (0..a["count"].as_u64().unwrap() as usize)
            .map(|e| {
                (0..n)
                    .map(|k| {
                        let at = base + e * stride + k * size;
                        match ct {
                            5126 => f32::from_le_bytes(buf[at..at + 4].try_into().unwrap()) as f64,
                            5123 => u16::from_le_bytes(buf[at..at + 2].try_into().unwrap()) as f64,
                            _ => buf[at] as f64,
                        }
                    })
                    .collect()
            })
            .collect()
    }

    fn local(&self, n: usize) -> Matrix4<f64> {
        let node = &self.json["nodes"][n];
        let nums = |key: &str, default: &[f64]| -> Vec<f64> {
            node[key].as_array().map(|a| a.iter().map(|v| v.as_f64().unwrap()).collect()).unwrap_or_else(|| default.to_vec())
        };
        if node.get("matrix").is_some() {
            return Matrix4::from_column_slice(&nums("matrix", &[]));
        }
        let t = nums("translation", &[0.0; 3]);
        let r = nums("rotation", &[0.0, 0.0, 0.0, 1.0]);
        let s = nums("scale", &[1.0; 3]);
        let q = UnitQuaternion::from_quaternion(Quaternion::new(r[3], r[0], r[1], r[2]));
        Matrix4::new_translation(&Vector3::new(t[0], t[1], t[2])) * q.to_homogeneous() * Matrix4::new_nonuniform_scaling(&Vector3::new(s[0], s[1], s[2]))
    }

    fn parent(&self, n: usize) -> Option<usize> {
        self.json["nodes"].as_array().unwrap().iter().position(|p| p["children"].as_array().is_some_and(|c| c.iter().any(|c| c.as_u64() == Some(n as u64))))
    }

    fn world(&self, n: usize) -> Matrix4<f64> {
        match self.parent(n) {
            Some(p) => self.world(p) * self.local(n),
            None => self.local(n),
        }
    }

    /// The glTF-spec skinning of every skinned mesh node at the nodes' rest transforms, times `scale`.
    fn rest_mesh(&self, scale: f64) -> Vec<Vector3<f64>> {
        let mut out = Vec::new();
        for node in self.json["nodes"].as_array().unwrap() {
            let (Some(mesh), Some(skin)) = (node["mesh"].as_u64(), node["skin"].as_u64()) else { continue };
            let skin = &self.json["skins"][skin as usize];
            let joints: Vec<usize> = skin["joints"].as_array().unwrap().iter().map(|j| j.as_u64().unwrap() as usize).collect();
            let ibm = self.accessor(skin["inverseBindMatrices"].as_u64().unwrap() as usize);
            let mats: Vec<Matrix4<f64>> =
                joints.iter().zip(&ibm).map(|(&j, m)| Matrix4::new_scaling(scale) * self.world(j) * Matrix4::from_column_slice(m)).collect();
            for prim in self.json["meshes"][mesh as usize]["primitives"].as_array().unwrap() {
                let attr = |k: &str| self.accessor(prim["attributes"][k].as_u64().unwrap() as usize);
                let (pos, js, ws) = (attr("POSITION"), attr("JOINTS_0"), attr("WEIGHTS_0"));
                for ((p, j), w) in pos.iter().zip(&js).zip(&ws) {
                    let total: f64 = w.iter().sum();
                    let mut m = Matrix4::zeros();
                    for k in 0..4 {
                        if w[k] > 0.0 {
                            m += mats[j[k] as usize] * (w[k] / total);
                        }
                    }
                    out.push(m.transform_point(&Point3::new(p[0], p[1], p[2])).coords);
                }
            }
        }
        out
    }

    /// World matrix of node `n` with every channel of animation `anim` at its first keyframe.
    fn world_at_first_keys(&self, anim: usize, n: usize) -> Matrix4<f64> {
        let mut node = self.json["nodes"][n].clone();
        let a = &self.json["animations"][anim];
        for c in a["channels"].as_array().unwrap() {
            if c["target"]["node"].as_u64() == Some(n as u64) {
                let sampler = &a["samplers"][c["sampler"].as_u64().unwrap() as usize];
                let first = self.accessor(sampler["output"].as_u64().unwrap() as usize)[0].clone();
                node[c["target"]["path"].as_str().unwrap()] = serde_json::json!(first);
            }
        }
        let mut raw = RawGltf { json: self.json.clone(), buffers: Vec::new() };
        raw.json["nodes"][n] = node;
        let local = raw.local(n);
        match self.parent(n) {
            Some(p) => self.world_at_first_keys(anim, p) * local,
            None => local,
        }
    }

    /// Largest keyframe time of each animation, from the input accessors' `max`.
    fn animation_ends(&self) -> Vec<f64> {
        self.json["animations"]
            .as_array()
            .map(|anims| {
                anims
                    .iter()
                    .map(|a| {
                        a["samplers"].as_array().unwrap().iter().map(|s| self.accessor(s["input"].as_u64().unwrap() as usize).iter().map(|r| r[0]).fold(0.0, f64::max)).fold(0.0, f64::max)
                    })
                    .collect()
            })
            .unwrap_or_default()
    }

    fn to_gltf_bytes(&self) -> Vec<u8> {
        let mut json = self.json.clone();
        let uris: Vec<Value> = self.buffers.iter().map(|b| Value::String(format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(b)))).collect();
        for (buffer, uri) in json["buffers"].as_array_mut().unwrap().iter_mut().zip(uris) {
            buffer["uri"] = uri;
        }
        serde_json::to_vec(&json).unwrap()
    }
}

fn simple_skin() -> RawGltf {
    raw_gltf(&std::fs::read(asset("avatars/SimpleSkin.gltf")).unwrap())
}

fn load_raw(raw: &RawGltf) -> Result<io::LoadedAvatar, IoError> {
    io::load_avatar_from_bytes(&raw.to_gltf_bytes(), &asset("avatars/SimpleSkin.gltf"), &opts())
}

// ---------------------------------------------------------------------------------------------
// Avatars.

/// (file, joints, vertices, [(animation name or None, duration s)], units) from LICENSES.md.
type AvatarFacts = (&'static str, usize, usize, &'static [(Option<&'static str>, f32)], Units);
const AVATARS: [AvatarFacts; 4] = [
    ("CesiumMan.glb", 19, 3273, &[(None, 2.0)], Units::Metres),
    ("Fox.glb", 24, 1728, &[(Some("Survey"), 3.42), (Some("Walk"), 0.71), (Some("Run"), 1.16)], Units::Centimetres),
    ("RiggedSimple_blender_reexport.glb", 4, 960, &[(Some("Anim_0_Armature"), 6.67)], Units::Metres),
    ("SimpleSkin.gltf", 2, 10, &[(None, 5.5)], Units::Metres),
];

#[test]
fn every_avatar_file_is_covered() {
    let files: Vec<String> = files_in("avatars", "glb").into_iter().chain(files_in("avatars", "gltf")).map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
    assert_eq!(files.len(), AVATARS.len());
    for f in files {
        assert!(AVATARS.iter().any(|a| a.0 == f), "{f} has no facts in this test");
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
            assert!((motion.duration_secs() - secs).abs() <= 0.5 / 30.0 + 0.006, "{file} '{}' lasts {} s, LICENSES says {secs}", motion.name, motion.duration_secs());
            assert!((motion.duration_secs() as f64 - end).abs() <= 0.5 / 30.0 + 1e-4, "{file}: keyframes end at {end}");
            assert!(motion.frames.iter().all(neural_cloth::scene::motion::pose_is_finite));
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
        let worst = got.iter().zip(&expected).map(|(g, e)| (g.cast::<f64>() - e).norm()).fold(0.0, f64::max);
        assert!(worst <= 1e-5 * height.max(1.0), "{file}: rest mesh off by {worst} m (height {height} m)");
        // The avatar's own skinning of its rest pose is its rest mesh.
        let posed = loaded.avatar.pose_vertices(&loaded.avatar.skeleton.rest_pose());
        let again = posed.iter().zip(got).map(|(a, b)| (a - b).norm()).fold(0.0f32, f32::max);
        assert!(again < 1e-6, "{file}");
    }
}

#[test]
fn simple_skin_warns_about_its_zero_length_bone() {
    let loaded = io::load_avatar(&asset("avatars/SimpleSkin.gltf"), &opts()).unwrap();
    assert!(loaded.warnings.iter().any(|w| w.contains("zero-length") && w.contains("node2")), "{:?}", loaded.warnings);
}

#[test]
fn fox_hip_translation_moves_the_whole_body() {
    let loaded = io::load_avatar(&asset("avatars/Fox.glb"), &opts()).unwrap();
    assert!(loaded.warnings.iter().any(|w| w.contains("b_Hip_01") && w.contains("root translation")), "{:?}", loaded.warnings);
    let a = &loaded.avatar;
    let raw = raw_gltf(&std::fs::read(asset("avatars/Fox.glb")).unwrap());
    for (k, motion) in a.motions.iter().enumerate() {
        // Every joint at t = 0, posed independently from the first keyframes of the file.
        let joints = a.skeleton.joint_positions(&motion.frames[0]);
        let skin = &raw.json["skins"][0]["joints"];
        for (j, name) in a.skeleton.names.iter().enumerate() {
            let node = raw.json["nodes"].as_array().unwrap().iter().position(|n| n["name"].as_str() == Some(name)).unwrap();
            assert!(skin.as_array().unwrap().iter().any(|s| s.as_u64() == Some(node as u64)));
            let expected = (Matrix4::new_scaling(0.01) * raw.world_at_first_keys(k, node)).column(3).xyz();
            let got = joints[j].cast::<f64>();
            assert!((got - expected).norm() < 1e-4, "{} '{name}': {got:?} vs {expected:?}", motion.name);
        }
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
    for (a, b) in base.avatar.rest_mesh.positions.iter().zip(&moved.avatar.rest_mesh.positions) {
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
    raw.json["nodes"].as_array_mut().unwrap().push(serde_json::json!({"mesh": 0, "skin": 1}));
    raw.json["scenes"][0]["nodes"] = serde_json::json!([0, 1, 3]);
    let two = load_raw(&raw).unwrap();
    assert_eq!(two.avatar.skeleton.len(), 2);
    assert_eq!(two.avatar.bind_mesh.vertex_count(), 20);
    assert_eq!(two.avatar.rest_mesh.positions[3], two.avatar.rest_mesh.positions[13]);

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
    assert_eq!(ext.avatar.rest_mesh.positions, emb.avatar.rest_mesh.positions);
    assert_eq!(ext.avatar.motions, emb.avatar.motions);
    std::fs::remove_file(dir.path().join("buffer 2.bin")).unwrap();
    let err = io::load_avatar(&path, &opts()).unwrap_err();
    assert!(matches!(err, IoError::Read { .. }) && err.to_string().ends_with("buffer 2.bin"), "{err}");
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

// ---------------------------------------------------------------------------------------------
// Bad glTF input.

fn assert_names_file(err: &IoError, file: &str) {
    assert!(err.to_string().ends_with(file), "message does not end with the file: {err}");
}

#[test]
fn malformed_and_truncated_gltf_are_typed_errors() {
    let path = asset("avatars/CesiumMan.glb");
    let bytes = std::fs::read(&path).unwrap();
    for cut in [0, 7, 11, 20, 200, bytes.len() / 2, bytes.len() - 1] {
        let err = io::load_avatar_from_bytes(&bytes[..cut], &path, &opts()).unwrap_err();
        assert!(matches!(err, IoError::Truncated { .. } | IoError::NotGltf { .. }), "cut {cut}: {err}");
        assert_names_file(&err, "CesiumMan.glb");
    }
    let text = std::fs::read(asset("avatars/SimpleSkin.gltf")).unwrap();
    let err = io::load_avatar_from_bytes(&text[..text.len() / 2], Path::new("half.gltf"), &opts()).unwrap_err();
    assert!(matches!(err, IoError::Truncated { .. }), "{err}");
    let err = io::load_avatar_from_bytes(b"solid cube\nfacet normal 0 0 1\n", Path::new("x.gltf"), &opts()).unwrap_err();
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
    assert!(matches!(load_raw(&raw).unwrap_err(), IoError::InvalidGltf { .. }));
}

#[test]
fn gltf_without_a_skin_is_reported() {
    let mut raw = simple_skin();
    raw.json["nodes"][0].as_object_mut().unwrap().remove("skin");
    let err = load_raw(&raw).unwrap_err();
    assert!(matches!(err, IoError::NoSkin { .. }), "{err}");
    assert!(err.to_string().contains("glTF without a skin"));
    assert_names_file(&err, "SimpleSkin.gltf");
    let mesh = io::load_gltf_mesh_from_bytes(&raw.to_gltf_bytes(), Path::new("noskin.gltf"), &opts()).unwrap();
    assert_eq!(mesh.mesh.vertex_count(), 10);
    assert!(mesh.warnings.is_empty(), "{:?}", mesh.warnings);
}

#[test]
fn nan_and_non_unit_rotations_in_gltf_are_rejected() {
    // Non-unit node rotation.
    let mut raw = simple_skin();
    raw.json["nodes"][2]["rotation"] = serde_json::json!([0.0, 0.0, 0.0, 2.0]);
    let err = load_raw(&raw).unwrap_err();
    assert!(matches!(err, IoError::NonUnitRotation { norm, .. } if (norm - 2.0).abs() < 1e-6), "{err}");
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
    assert!(matches!(err, IoError::JointCountMismatch { expected: 2, found: 1, .. }), "{err}");
    let mut raw = simple_skin();
    raw.json["skins"][0]["joints"] = serde_json::json!([1]);
    let err = load_raw(&raw).unwrap_err();
    assert!(matches!(err, IoError::JointCountMismatch { expected: 1, found: 2, .. }), "{err}");
    assert_names_file(&err, "SimpleSkin.gltf");
}

// ---------------------------------------------------------------------------------------------
// BVH.

/// (file, joints, channels, frames) from LICENSES.md.
const MOTIONS: [(&str, usize, usize, usize); 4] = [
    ("cmu_01_01_hops_turn_excerpt.bvh", 31, 96, 660),
    ("cmu_02_01_walk.bvh", 31, 96, 343),
    ("cmu_02_03_run_dazfriendly.bvh", 43, 132, 174),
    ("cmu_05_06_dance_pirouettes.bvh", 31, 96, 885),
];

/// Header facts read straight from the text: (joints, channels, frames, frame time, values).
fn bvh_header(text: &str) -> (usize, usize, usize, f64, usize) {
    let (mut joints, mut channels, mut frames, mut frame_time, mut values) = (0, 0, 0, 0.0, 0);
    let mut in_data = false;
    for line in text.lines() {
        let t: Vec<&str> = line.split_whitespace().collect();
        if in_data {
            values += t.len();
            continue;
        }
        match t.first().copied() {
            Some("ROOT" | "JOINT") => joints += 1,
            Some("CHANNELS") => channels += t[1].parse::<usize>().unwrap(),
            Some("Frames:") => frames = t[1].parse().unwrap(),
            Some("Frame") => {
                frame_time = t[2].parse().unwrap();
                in_data = true;
            }
            _ => {}
        }
    }
    (joints, channels, frames, frame_time, values)
}

#[test]
fn every_motion_file_is_covered_and_matches_its_header() {
    let files = files_in("motions", "bvh");
    assert_eq!(files.len(), MOTIONS.len());
    for path in files {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let (_, joints, channels, frames) = *MOTIONS.iter().find(|m| m.0 == name).unwrap_or_else(|| panic!("{name} has no facts"));
        let text = std::fs::read_to_string(&path).unwrap();
        let (hj, hc, hf, ht, hv) = bvh_header(&text);
        assert_eq!((hj, hc, hf), (joints, channels, frames), "{name}: header vs LICENSES");
        assert_eq!(hv, hf * hc, "{name}: data rows");
        let bvh = io::load_bvh(&path).unwrap();
        assert_eq!(bvh.joints.len(), joints, "{name}");
        assert_eq!(bvh.channel_count, channels, "{name}");
        assert_eq!(bvh.frame_count(), frames, "{name}");
        assert!((bvh.frame_time_secs as f64 - ht).abs() < 1e-9, "{name}");
        assert!((bvh.fps() - 120.0).abs() < 0.01, "{name}");
        // The last value of the file is the last channel of the last frame.
        let last: f32 = text.split_whitespace().last().unwrap().parse().unwrap();
        assert_eq!(*bvh.values.last().unwrap(), last, "{name}");
        // Own skeleton and motion.
        let (sk, motion, _) = bvh.to_motion_for_own_skeleton(Units::Auto).unwrap();
        assert_eq!(sk.len(), joints);
        assert_eq!(motion.frame_count(), frames);
        let (units, _) = bvh.resolve_units(Units::Auto);
        let expected = if name.contains("daz") { Units::Centimetres } else { Units::CmuMocap };
        assert_eq!(units, expected, "{name}");
        // Joint positions of the own-skeleton motion are the BVH's world positions, in metres.
        let scale = units.metres_per_unit().unwrap();
        for f in [0, frames / 2, frames - 1] {
            let p = sk.joint_positions(&motion.frames[f]);
            for (a, (_, b)) in p.iter().zip(bvh.world(f)) {
                assert!((a - b * scale).norm() < 1e-4, "{name} frame {f}");
            }
        }
        if !name.contains("daz") {
            assert!(bvh.warnings.iter().any(|w| w.contains("zero-length") && w.contains("LHipJoint")), "{name}: {:?}", bvh.warnings);
        }
    }
}

/// A small Mixamo-named T-pose skeleton, 1.8 m tall (hips at 1 m).
fn mixamo_skeleton() -> Skeleton {
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
        add(&n("Shoulder"), Some("Spine2"), [sign * 0.05, 0.12, 0.0], &mut names);
        add(&n("Arm"), Some(&n("Shoulder")), [sign * 0.12, 0.0, 0.0], &mut names);
        add(&n("ForeArm"), Some(&n("Arm")), [sign * 0.27, 0.0, 0.0], &mut names);
        add(&n("Hand"), Some(&n("ForeArm")), [sign * 0.25, 0.0, 0.0], &mut names);
        add(&n("UpLeg"), Some("Hips"), [sign * 0.1, -0.05, 0.0], &mut names);
        add(&n("Leg"), Some(&n("UpLeg")), [0.0, -0.45, 0.0], &mut names);
        add(&n("Foot"), Some(&n("Leg")), [0.0, -0.42, 0.0], &mut names);
        add(&n("ToeBase"), Some(&n("Foot")), [0.0, -0.05, 0.12], &mut names);
    }
    let n = names.len();
    let rest: Vec<JointTransform> = offsets.iter().map(|&translation| JointTransform { translation, ..Default::default() }).collect();
    let mut sk = Skeleton::new(names, parents, rest, vec![Mat4::identity(); n], vec![Mat4::identity(); n]).unwrap();
    let world = sk.world_from_joint(&sk.rest_pose());
    sk.joint_from_bind = world.iter().map(|m| m.try_inverse().unwrap()).collect();
    sk
}

#[test]
fn every_cmu_clip_retargets_onto_a_mixamo_skeleton() {
    let sk = mixamo_skeleton();
    let rest_world: Vec<Quat> = sk.world_from_joint(&sk.rest_pose()).iter().map(rotation_of).collect();
    for path in files_in("motions", "bvh") {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let bvh = io::load_bvh(&path).unwrap();
        let (motion, warnings) = io::retarget_bvh(&bvh, &sk, &RetargetOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(motion.fps, 30.0);
        let expected_frames = (bvh.duration_secs() * 30.0 + 1e-3).floor() as usize + 1;
        assert_eq!(motion.frame_count(), expected_frames, "{name}");
        for pose in &motion.frames {
            for q in &pose.rotations {
                assert!(q.coords.iter().all(|v| v.is_finite()) && (q.coords.norm() - 1.0).abs() < 1e-4, "{name}");
            }
            let hips = sk.joint_positions(pose)[0];
            assert!(hips.iter().all(|v| v.is_finite()) && (0.2..2.5).contains(&hips.y), "{name}: hips at {hips:?}");
        }
        // The mapping really transfers world rotations: at the native rate, the avatar's
        // LeftUpLeg turns from its rest by the BVH LeftUpLeg's (or lThigh's) world rotation.
        let (native, _) = io::retarget_bvh(&bvh, &sk, &RetargetOptions { fps: bvh.fps(), recentre: false }).unwrap();
        assert_eq!(native.frame_count(), bvh.frame_count(), "{name}");
        let thigh_a = sk.index_of("LeftUpLeg").unwrap();
        let thigh_b = bvh.joints.iter().position(|j| j.name == "LeftUpLeg" || j.name == "lThigh").unwrap();
        for f in [0, bvh.frame_count() / 3, bvh.frame_count() - 1] {
            let world_a = rotation_of(&sk.world_from_joint(&native.frames[f])[thigh_a]);
            let delta = world_a * rest_world[thigh_a].inverse();
            let angle = delta.angle_to(&bvh.world(f)[thigh_b].0);
            assert!(angle < 2e-3, "{name} frame {f}: {angle} rad");
        }
        // Unmapped joints are reported, and the BVH's helpers are not needed.
        assert!(warnings.iter().all(|w| !w.contains("LeftUpLeg")), "{warnings:?}");
    }
}

#[test]
fn bad_bvh_input_is_a_typed_error() {
    let path = asset("motions/cmu_02_01_walk.bvh");
    let text = std::fs::read_to_string(&path).unwrap();
    // Truncated data.
    let err = Bvh::parse(&text.as_bytes()[..text.len() - 500], &path).unwrap_err();
    assert!(matches!(err, IoError::Truncated { .. }), "{err}");
    assert_names_file(&err, "cmu_02_01_walk.bvh");
    // Truncated hierarchy.
    let err = Bvh::parse(&text.as_bytes()[..300], &path).unwrap_err();
    assert!(matches!(err, IoError::Truncated { .. } | IoError::Syntax { .. }), "{err}");
    // NaN rotation value in the data, with its line.
    let lines: Vec<&str> = text.lines().collect();
    let data_line = lines.iter().position(|l| l.starts_with("Frame Time")).unwrap() + 3;
    let mut bad: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    let mut values: Vec<&str> = lines[data_line].split_whitespace().collect();
    values[4] = "nan";
    bad[data_line] = values.join(" ");
    let err = Bvh::parse(bad.join("\n").as_bytes(), &path).unwrap_err();
    assert!(matches!(&err, IoError::NonFinite { what, .. } if what.contains(&format!("line {}", data_line + 1))), "{err}");
    // Malformed channel name, with its line number.
    let err = Bvh::parse(text.replacen("Xrotation", "Qrotation", 1).as_bytes(), &path).unwrap_err();
    assert!(matches!(err, IoError::Syntax { line: 5, .. }), "{err}");
    // Not a BVH at all.
    assert!(matches!(Bvh::parse(b"v 0 0 0\n", &path).unwrap_err(), IoError::Syntax { line: 1, .. }));
    // A skeleton none of whose joints can be matched is an error naming the motion file.
    let bvh = io::load_bvh(&path).unwrap();
    let mut dog = mixamo_skeleton();
    dog.names = dog.names.iter().map(|n| format!("b_{n}_01")).collect();
    let err = io::retarget_bvh(&bvh, &dog, &RetargetOptions::default()).unwrap_err();
    assert!(matches!(err, IoError::UnmappedJoints { .. }), "{err}");
    assert_names_file(&err, "cmu_02_01_walk.bvh");
}

#[test]
fn missing_core_joints_in_the_motion_are_listed() {
    // Remove the left leg chain's names from a CMU clip: the avatar's left leg cannot map.
    let path = asset("motions/cmu_02_01_walk.bvh");
    let text = std::fs::read_to_string(&path).unwrap().replace("JOINT LeftUpLeg", "JOINT LThighX").replace("JOINT LeftLeg", "JOINT LShinX");
    let bvh = Bvh::parse(text.as_bytes(), &path).unwrap();
    let err = io::retarget_bvh(&bvh, &mixamo_skeleton(), &RetargetOptions::default()).unwrap_err();
    match &err {
        IoError::UnmappedJoints { joints, .. } => assert_eq!(joints, &vec!["LeftUpLeg".to_string(), "LeftLeg".to_string()]),
        other => panic!("{other}"),
    }
    assert!(err.to_string().contains("LeftUpLeg") && err.to_string().ends_with("cmu_02_01_walk.bvh"));
}

// ---------------------------------------------------------------------------------------------
// OBJ garments.

/// (file, vertices, faces) from LICENSES.md.
const GARMENTS: [(&str, usize, usize); 7] = [
    ("makehuman_tshirt_from_male_casualsuit06.obj", 2822, 2728),
    ("makehuman_tshirt_from_female_casualsuit01.obj", 1311, 1262),
    ("makehuman_skirt_from_female_elegantsuit01.obj", 395, 364),
    ("makehuman_blouse_from_female_elegantsuit01.obj", 1810, 1732),
    ("makehuman_female_elegantsuit01_original.obj", 2205, 2096),
    ("makehuman_male_casualsuit06_original.obj", 3708, 3584),
    ("makehuman_body_proxy_female1605.obj", 1605, 1584),
];

#[test]
fn every_garment_loads_with_exact_vertex_order_in_decimetres() {
    let files = files_in("garments", "obj");
    assert_eq!(files.len(), GARMENTS.len());
    let body = io::load_obj(&asset("garments/makehuman_body_proxy_female1605.obj"), &opts()).unwrap();
    let (body_lo, body_hi) = body.mesh.bounds().unwrap();
    let body_height = body_hi.y - body_lo.y;
    assert!((1.5..1.8).contains(&body_height), "body proxy is {body_height} m tall");
    for path in files {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let (_, vertices, polygons) = *GARMENTS.iter().find(|g| g.0 == name).unwrap_or_else(|| panic!("{name} has no facts"));
        let text = std::fs::read_to_string(&path).unwrap();
        let v_lines: Vec<Vec3> = text.lines().filter(|l| l.starts_with("v ")).map(|l| {
            let c: Vec<f32> = l.split_whitespace().skip(1).take(3).map(|t| t.parse().unwrap()).collect();
            Vec3::new(c[0], c[1], c[2])
        }).collect();
        let triangles: usize = text.lines().filter(|l| l.starts_with("f ")).map(|l| l.split_whitespace().count() - 3).sum();
        let f_lines = text.lines().filter(|l| l.starts_with("f ")).count();
        assert_eq!((v_lines.len(), f_lines), (vertices, polygons), "{name}: file vs LICENSES");
        let m = io::load_obj(&path, &opts()).unwrap();
        assert_eq!(m.units, Units::Decimetres, "{name}");
        assert_eq!(m.mesh.vertex_count(), vertices, "{name}");
        assert_eq!(m.mesh.faces.len(), triangles, "{name}");
        for (p, v) in m.mesh.positions.iter().zip(&v_lines) {
            assert!((p - v * 0.1).norm() < 1e-6, "{name}: vertex order or value changed");
        }
        assert!(m.mesh.uvs.as_ref().is_some_and(|u| u.len() == vertices), "{name}: UVs");
        // Garments share the body proxy's frame: each lies within the body's bounds (+5 cm).
        let (lo, hi) = m.mesh.bounds().unwrap();
        let margin = Vec3::repeat(0.05);
        assert!(lo.iter().zip((body_lo - margin).iter()).all(|(a, b)| a >= b) && hi.iter().zip((body_hi + margin).iter()).all(|(a, b)| a <= b), "{name}");
    }
    // Explicit units override detection.
    let m = io::load_obj(&asset("garments/makehuman_skirt_from_female_elegantsuit01.obj"), &ImportOptions { units: Units::Centimetres, ..opts() }).unwrap();
    assert_eq!(m.units, Units::Centimetres);
}

#[test]
fn bad_obj_input_is_a_typed_error_with_line_numbers() {
    let path = asset("garments/makehuman_skirt_from_female_elegantsuit01.obj");
    let text = std::fs::read_to_string(&path).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let first_v = lines.iter().position(|l| l.starts_with("v ")).unwrap();
    let mut bad: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    bad[first_v] = "v 0.1 inf 0.2".into();
    let err = io::load_obj_from_bytes(bad.join("\n").as_bytes(), &path, &opts()).unwrap_err();
    assert!(matches!(&err, IoError::NonFinite { what, .. } if what.contains(&format!("line {}", first_v + 1))), "{err}");
    assert_names_file(&err, "makehuman_skirt_from_female_elegantsuit01.obj");
    // A face referring past the vertices defined so far.
    let first_f = lines.iter().position(|l| l.starts_with("f ")).unwrap();
    let mut bad: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    bad[first_f] = "f 1 2 99999".into();
    let err = io::load_obj_from_bytes(bad.join("\n").as_bytes(), &path, &opts()).unwrap_err();
    assert!(matches!(err, IoError::Syntax { line, .. } if line == first_f + 1), "{err}");
    // Truncated mid-file: the vertex list is cut, so faces refer to missing vertices.
    let cut = text.find("\nf ").unwrap() / 2;
    assert!(io::load_obj_from_bytes(&text.as_bytes()[..cut], &path, &opts()).is_err());
}

// ---------------------------------------------------------------------------------------------
// inspect.

#[test]
fn inspect_reports_every_asset() {
    for (file, joints, vertices, anims, _) in AVATARS {
        let r = io::inspect(&asset(&format!("avatars/{file}"))).unwrap();
        assert!(r.contains(&format!("joints: {joints}\n")), "{r}");
        assert!(r.contains(&format!("{vertices} vertices")), "{r}");
        assert!(r.contains(&format!("animations: {}\n", anims.len())), "{r}");
    }
    for (file, joints, _, frames) in MOTIONS {
        let r = io::inspect(&asset(&format!("motions/{file}"))).unwrap();
        assert!(r.contains(&format!("joints: {joints}\n")) && r.contains(&format!("{frames} frames")), "{r}");
        assert!(r.contains("LeftUpLeg"), "{r}");
    }
    for (file, vertices, _) in GARMENTS {
        let r = io::inspect(&asset(&format!("garments/{file}"))).unwrap();
        assert!(r.contains(&format!("{vertices} vertices")) && r.contains("decimetres"), "{r}");
    }
    assert!(matches!(io::inspect(&asset("LICENSES.md")), Err(IoError::UnsupportedFormat { .. })));
    assert!(matches!(io::inspect(Path::new("../shared/assets/missing.obj")), Err(IoError::Read { .. })));
}

// ---------------------------------------------------------------------------------------------
// Mutation test: no importer may panic on damaged files.

mod mutation {
    use super::*;
    use proptest::prelude::*;
    use std::sync::OnceLock;

    struct Corpus {
        files: Vec<(PathBuf, Vec<u8>)>,
        skeleton: Skeleton,
    }

    fn corpus() -> &'static Corpus {
        static C: OnceLock<Corpus> = OnceLock::new();
        C.get_or_init(|| {
            let mut files = Vec::new();
            for (dir, ext) in [("avatars", "glb"), ("avatars", "gltf"), ("motions", "bvh"), ("garments", "obj")] {
                for p in files_in(dir, ext) {
                    let bytes = std::fs::read(&p).unwrap();
                    files.push((p, bytes));
                }
            }
            Corpus { files, skeleton: mixamo_skeleton() }
        })
    }

    #[derive(Debug, Clone)]
    enum Mutation {
        /// Flip bits at (position seed, xor mask); `near_start` aims at headers and JSON.
        Flips(Vec<(usize, u8)>, bool),
        /// Keep only the first `fraction` (per mille) of the file.
        Truncate(u16),
        /// Copy a chunk from one place to another (overwriting), or insert it.
        Splice { from: usize, to: usize, len: u16, insert: bool },
    }

    fn mutation() -> impl Strategy<Value = Mutation> {
        prop_oneof![
            (prop::collection::vec((any::<usize>(), 1u8..=255), 1..8), any::<bool>()).prop_map(|(f, s)| Mutation::Flips(f, s)),
            (0u16..1000).prop_map(Mutation::Truncate),
            (any::<usize>(), any::<usize>(), 1u16..2048, any::<bool>()).prop_map(|(from, to, len, insert)| Mutation::Splice { from, to, len, insert }),
        ]
    }

    fn apply(bytes: &[u8], m: &Mutation) -> Vec<u8> {
        let mut out = bytes.to_vec();
        let n = out.len().max(1);
        match m {
            Mutation::Flips(flips, near_start) => {
                let span = if *near_start { n.min(8192) } else { n };
                for &(pos, mask) in flips {
                    if let Some(b) = out.get_mut(pos % span) {
                        *b ^= mask;
                    }
                }
            }
            Mutation::Truncate(per_mille) => out.truncate(out.len() * *per_mille as usize / 1000),
            Mutation::Splice { from, to, len, insert } => {
                let from = from % n;
                let end = (from + *len as usize).min(out.len());
                let chunk = out[from.min(out.len())..end].to_vec();
                let to = to % n;
                if *insert {
                    out.splice(to..to, chunk);
                } else {
                    for (k, b) in chunk.into_iter().enumerate() {
                        if let Some(slot) = out.get_mut(to + k) {
                            *slot = b;
                        }
                    }
                }
            }
        }
        out
    }

    /// Feeds `bytes` (damaged `path`) to every importer that reads its format.
    fn feed(path: &Path, bytes: &[u8], skeleton: &Skeleton) {
        let ext = path.extension().unwrap().to_string_lossy().to_ascii_lowercase();
        let o = ImportOptions::default();
        match ext.as_str() {
            "glb" | "gltf" => {
                let _ = io::load_avatar_from_bytes(bytes, path, &o);
                let _ = io::load_gltf_mesh_from_bytes(bytes, path, &o);
            }
            "obj" => {
                let _ = io::load_obj_from_bytes(bytes, path, &o);
            }
            _ => {
                if let Ok(bvh) = Bvh::parse(bytes, path) {
                    let _ = bvh.to_motion_for_own_skeleton(Units::Auto);
                    let _ = io::retarget_bvh(&bvh, skeleton, &RetargetOptions::default());
                }
            }
        }
    }

    fn config(cases: u32) -> ProptestConfig {
        ProptestConfig { cases, failure_persistence: None, ..ProptestConfig::default() }
    }

    fn run_on(filter: fn(&Path) -> bool, file: usize, m: &Mutation) {
        let c = corpus();
        let chosen: Vec<&(PathBuf, Vec<u8>)> = c.files.iter().filter(|(p, _)| filter(p)).collect();
        let (path, bytes) = chosen[file % chosen.len()];
        feed(path, &apply(bytes, m), &c.skeleton);
    }

    fn is_gltf(p: &Path) -> bool {
        p.extension().is_some_and(|e| e == "glb" || e == "gltf")
    }
    fn is_obj(p: &Path) -> bool {
        p.extension().is_some_and(|e| e == "obj")
    }
    fn is_bvh(p: &Path) -> bool {
        p.extension().is_some_and(|e| e == "bvh")
    }

    proptest! {
        #![proptest_config(config(2000))]
        #[test]
        fn damaged_gltf_never_panics(file in 0usize..16, m in mutation()) {
            run_on(is_gltf, file, &m);
        }
    }

    proptest! {
        #![proptest_config(config(600))]
        #[test]
        fn damaged_obj_never_panics(file in 0usize..16, m in mutation()) {
            run_on(is_obj, file, &m);
        }
    }

    proptest! {
        #![proptest_config(config(400))]
        #[test]
        fn damaged_bvh_never_panics(file in 0usize..16, m in mutation()) {
            run_on(is_bvh, file, &m);
        }
    }
}
