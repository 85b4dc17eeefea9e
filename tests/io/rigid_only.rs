//! An avatar built only of rigid parts (issue 13): no skinned mesh at all, the pieces
//! parented to bones, with or without a skin (used by no mesh) listing the bones. It must load
//! as an avatar, each piece with weight 1 to its bone and moving as the glTF scene graph moves
//! it, and `inspect` must say so and why; pieces under one empty node stay a plain mesh (a
//! garment), and `inspect` says why. Built with `rigid_parts`' packer.

use nalgebra::UnitQuaternion;
use neural_cloth::io;
use serde_json::{Value, json};

use super::opts;
use super::raw_gltf::RawGltf;
use super::rigid_parts::{Packer, cube, glb, placed, quat_json};

/// The joints of a body built only of rigid parts: name, parent, offset from the parent.
const BODY: [(&str, Option<usize>, [f32; 3]); 16] = [
    ("Hips", None, [0.0, 1.0, 0.0]),
    ("Spine", Some(0), [0.0, 0.25, 0.0]),
    ("Neck", Some(1), [0.0, 0.3, 0.0]),
    ("Head", Some(2), [0.0, 0.1, 0.0]),
    ("LeftArm", Some(1), [0.2, 0.25, 0.0]),
    ("LeftForeArm", Some(4), [0.28, 0.0, 0.0]),
    ("LeftHand", Some(5), [0.25, 0.0, 0.0]),
    ("RightArm", Some(1), [-0.2, 0.25, 0.0]),
    ("RightForeArm", Some(7), [-0.28, 0.0, 0.0]),
    ("RightHand", Some(8), [-0.25, 0.0, 0.0]),
    ("LeftUpLeg", Some(0), [0.1, -0.05, 0.0]),
    ("LeftLeg", Some(10), [0.0, -0.45, 0.0]),
    ("LeftFoot", Some(11), [0.0, -0.45, 0.0]),
    ("RightUpLeg", Some(0), [-0.1, -0.05, 0.0]),
    ("RightLeg", Some(13), [0.0, -0.45, 0.0]),
    ("RightFoot", Some(14), [0.0, -0.45, 0.0]),
];

/// A character made only of rigid parts, no skinned mesh: the joints of [`BODY`] as nodes
/// (hands and feet bare), and under every other joint a node `part_NAME` placing a box
/// halfway along its bone (the head's above it). With `skin`, a skin lists the joints (used
/// by no mesh, as exporters write one for the armature); without it the file has no skin.
/// Returns the file and the (part node, joint name) of each part, in node order.
fn rigid_only_body(skin: bool) -> (RawGltf, Vec<(usize, &'static str)>) {
    let mut p = Packer::default();
    let (box_p, box_t) = cube(0.04);
    let meshes = vec![p.mesh("Box", &box_p, &box_t)];
    let mut nodes: Vec<Value> = BODY
        .iter()
        .map(|(name, _, t)| json!({ "name": name, "translation": t }))
        .collect();
    let mut parts = Vec::new();
    for (j, (name, _, _)) in BODY.iter().enumerate() {
        let child = BODY.iter().find(|b| b.1 == Some(j));
        let at = match (child, *name) {
            (Some((_, _, t)), _) => [t[0] * 0.5, t[1] * 0.5, t[2] * 0.5],
            (None, "Head") => [0.0, 0.1, 0.0],
            (None, _) => continue,
        };
        parts.push((nodes.len(), *name));
        nodes.push(json!({ "name": format!("part_{name}"), "translation": at, "mesh": 0 }));
    }
    for (n, node) in nodes.iter_mut().enumerate().take(BODY.len()) {
        let children: Vec<usize> = (0..BODY.len())
            .filter(|&c| BODY[c].1 == Some(n))
            .chain(parts.iter().filter(|p| p.1 == BODY[n].0).map(|p| p.0))
            .collect();
        if !children.is_empty() {
            node["children"] = json!(children);
        }
    }
    let mut raw = RawGltf {
        json: json!({ "nodes": nodes.clone() }),
        buffers: Vec::new(),
    };
    let mut doc = json!({
        "asset": { "version": "2.0" },
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "nodes": nodes,
        "meshes": meshes,
    });
    if skin {
        let ibms: Vec<Vec<f32>> = (0..BODY.len())
            .map(|j| {
                let m = raw.world(j).try_inverse().unwrap();
                m.as_slice().iter().map(|&v| v as f32).collect()
            })
            .collect();
        let ibm = p.floats(&ibms, "MAT4");
        doc["skins"] =
            json!([{ "joints": (0..BODY.len()).collect::<Vec<_>>(), "inverseBindMatrices": ibm }]);
    }
    doc["accessors"] = json!(p.accessors);
    doc["bufferViews"] = json!(p.views);
    doc["buffers"] = json!([{ "byteLength": p.bin.len() }]);
    raw.json = doc;
    raw.buffers = vec![p.bin];
    (raw, parts)
}

#[test]
fn an_avatar_of_rigid_parts_only_loads_issue_13() {
    let dir = tempfile::tempdir().unwrap();
    for (skin, kind) in [
        (
            false,
            "kind: glTF avatar of rigid parts (no skin: the skeleton is the node hierarchy",
        ),
        (
            true,
            "kind: glTF avatar of rigid parts (no mesh is skinned: the skeleton is the joints of skin 0, which 12 meshes hang from)",
        ),
    ] {
        let (raw, parts) = rigid_only_body(skin);
        let path = dir.path().join(format!("rigid_only_{skin}.glb"));
        std::fs::write(&path, glb(&raw)).unwrap();
        let loaded = io::load_avatar(&path, &opts()).unwrap_or_else(|e| panic!("{e}"));
        let avatar = &loaded.avatar;
        let sk = &avatar.skeleton;
        let names: Vec<&str> = BODY.iter().map(|b| b.0).collect();
        assert_eq!(sk.names, names, "skin {skin}");
        assert_eq!(parts.len(), 12);
        assert_eq!(avatar.bind_mesh.vertex_count(), 8 * parts.len());
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);

        // Each part: weight 1 to its joint.
        for (k, (_, joint)) in parts.iter().enumerate() {
            let j = sk.index_of(joint).unwrap() as u16;
            for v in 8 * k..8 * (k + 1) {
                assert_eq!(avatar.skin.joints[v][0], j, "{joint} vertex {v}");
                assert_eq!(avatar.skin.weights[v], [1.0, 0.0, 0.0, 0.0], "{joint}");
            }
        }
        // At rest and posed, the body is where the glTF scene graph puts the parts.
        let turns = [
            ("Spine", UnitQuaternion::from_euler_angles(0.3, 0.2, 0.0)),
            ("LeftArm", UnitQuaternion::from_euler_angles(0.0, -0.5, 0.9)),
            (
                "RightUpLeg",
                UnitQuaternion::from_euler_angles(-0.8, 0.0, 0.1),
            ),
        ];
        let mut pose = sk.rest_pose();
        let mut posed_raw = RawGltf {
            json: raw.json.clone(),
            buffers: Vec::new(),
        };
        for (joint, q) in &turns {
            let j = sk.index_of(joint).unwrap();
            pose.rotations[j] = q.cast::<f32>();
            posed_raw.json["nodes"][j]["rotation"] = quat_json(q);
        }
        let posed = avatar.pose_vertices(&pose);
        for (graph, positions) in [(&raw, &avatar.rest_mesh.positions), (&posed_raw, &posed)] {
            for (k, (node, joint)) in parts.iter().enumerate() {
                for (i, want) in placed(graph, *node, &cube(0.04).0).iter().enumerate() {
                    let got = positions[8 * k + i].cast::<f64>();
                    assert!(
                        (got - want).norm() < 1e-5,
                        "{joint} vertex {i}: {got:?} vs {want:?}"
                    );
                }
            }
        }
        // The left hand's forearm part moved with the turned arm (the check is not vacuous).
        let forearm = 8 * parts.iter().position(|p| p.1 == "LeftForeArm").unwrap();
        assert!((posed[forearm] - avatar.rest_mesh.positions[forearm]).norm() > 0.1);

        let report = io::inspect(&path).unwrap();
        for line in [
            kind,
            "joints: 16",
            "body: 96 vertices, 144 triangles",
            "meshes: 12 (0 skinned, 12 rigid parts, 0 ignored)",
            "  'Box' (node 'part_LeftForeArm'): 8 vertices, rigid part of joint 'LeftForeArm' (weight 1)",
            "warnings: none",
        ] {
            assert!(report.contains(line), "missing '{line}' in:\n{report}");
        }
        if !skin {
            assert!(
                report.contains(
                    "12 meshes hang from 12 nodes nested 4 deep, 16 node names read as body joints"
                ),
                "{report}"
            );
        }
    }
}

#[test]
fn pieces_under_one_node_stay_a_garment_and_inspect_says_why() {
    let mut p = Packer::default();
    let (box_p, box_t) = cube(0.2);
    let meshes = vec![
        p.mesh("Shirt", &box_p, &box_t),
        p.mesh("Collar", &box_p, &box_t),
    ];
    let raw = RawGltf {
        json: json!({
            "asset": { "version": "2.0" },
            "scene": 0,
            "scenes": [{ "nodes": [0] }],
            "nodes": [
                { "name": "Outfit", "translation": [0.0, 1.3, 0.0], "children": [1, 2] },
                { "name": "Shirt", "mesh": 0 },
                { "name": "Collar", "translation": [0.0, 0.2, 0.0], "mesh": 1 },
            ],
            "meshes": meshes,
            "accessors": p.accessors,
            "bufferViews": p.views,
            "buffers": [{ "byteLength": p.bin.len() }],
        }),
        buffers: vec![p.bin],
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("outfit.glb");
    std::fs::write(&path, glb(&raw)).unwrap();
    let err = io::load_avatar(&path, &opts()).unwrap_err();
    assert!(matches!(err, io::IoError::NoSkin { .. }), "{err}");
    let why = "2 meshes hang from 1 node nested 1 deep, 0 node names read as body joints";
    let text = err.to_string();
    assert!(text.contains(why) && text.ends_with("outfit.glb"), "{text}");
    let garment = io::load_gltf_mesh(&path, &opts()).unwrap();
    assert_eq!(garment.mesh.vertex_count(), 16);
    let report = io::inspect(&path).unwrap();
    assert!(
        report.contains(&format!(
            "kind: glTF mesh without a skin (usable as a garment; not an avatar of rigid parts: {why}; an avatar of rigid parts needs"
        )),
        "{report}"
    );
}
