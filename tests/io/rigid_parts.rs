//! Rigid parts: a character built partly of meshes parented to bones (no skin), written here
//! as a GLB with our own packer (`glb_bytes`). They must join the body with weight 1 to their
//! joint and move with it as the glTF scene graph moves them (checked against the independent
//! node-hierarchy maths of `raw_gltf`); a static prop and an unplaced mesh are left out with a
//! warning; `inspect` lists every mesh and what became of it.

use nalgebra::{Matrix4, Point3, UnitQuaternion, Vector3};
use neural_cloth::io::export::gltf::glb_bytes;
use neural_cloth::io::{self, MeshUsage};
use serde_json::{Value, json};

use super::opts;
use super::raw_gltf::RawGltf;

/// Accessors packed into one binary buffer.
#[derive(Default)]
pub(super) struct Packer {
    pub(super) bin: Vec<u8>,
    pub(super) views: Vec<Value>,
    pub(super) accessors: Vec<Value>,
}

impl Packer {
    fn push(&mut self, bytes: &[u8], mut accessor: Value) -> usize {
        self.views
            .push(json!({ "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len() }));
        self.bin.extend_from_slice(bytes);
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        accessor["bufferView"] = json!(self.views.len() - 1);
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    pub(super) fn floats(&mut self, rows: &[Vec<f32>], ty: &str) -> usize {
        let bytes: Vec<u8> = rows
            .iter()
            .flatten()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        self.push(
            &bytes,
            json!({ "componentType": 5126, "count": rows.len(), "type": ty }),
        )
    }

    fn positions(&mut self, points: &[[f32; 3]]) -> usize {
        let rows: Vec<Vec<f32>> = points.iter().map(|p| p.to_vec()).collect();
        let a = self.floats(&rows, "VEC3");
        let (lo, hi) = (0..3)
            .map(|k| {
                let it = points.iter().map(|p| p[k]);
                (
                    it.clone().fold(f32::INFINITY, f32::min),
                    it.fold(f32::NEG_INFINITY, f32::max),
                )
            })
            .unzip::<f32, f32, Vec<f32>, Vec<f32>>();
        self.accessors[a]["min"] = json!(lo);
        self.accessors[a]["max"] = json!(hi);
        a
    }

    fn indices(&mut self, tris: &[[u16; 3]]) -> usize {
        let bytes: Vec<u8> = tris
            .iter()
            .flatten()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        self.push(
            &bytes,
            json!({ "componentType": 5123, "count": tris.len() * 3, "type": "SCALAR" }),
        )
    }

    fn joints(&mut self, joints: &[[u8; 4]]) -> usize {
        let bytes: Vec<u8> = joints.iter().flatten().copied().collect();
        self.push(
            &bytes,
            json!({ "componentType": 5121, "count": joints.len(), "type": "VEC4" }),
        )
    }

    /// A mesh of one indexed triangle primitive.
    pub(super) fn mesh(&mut self, name: &str, points: &[[f32; 3]], tris: &[[u16; 3]]) -> Value {
        let position = self.positions(points);
        let indices = self.indices(tris);
        json!({ "name": name, "primitives": [{ "attributes": { "POSITION": position }, "indices": indices }] })
    }
}

/// An axis-aligned box of half-size `h` (8 vertices, 12 triangles).
pub(super) fn cube(h: f32) -> (Vec<[f32; 3]>, Vec<[u16; 3]>) {
    let points = (0..8)
        .map(|i| {
            let s = |bit: usize| if i & bit == 0 { -h } else { h };
            [s(1), s(2), s(4)]
        })
        .collect();
    let tris = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    (points, tris)
}

/// A tetrahedron of size `s` (4 vertices, 4 triangles).
fn tetra(s: f32) -> (Vec<[f32; 3]>, Vec<[u16; 3]>) {
    let points = vec![[0.0, 0.0, 0.0], [s, 0.0, 0.0], [0.0, s, 0.0], [0.0, 0.0, s]];
    (points, vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
}

pub(super) fn quat_json(q: &UnitQuaternion<f64>) -> Value {
    json!([q.i, q.j, q.k, q.w])
}

/// Node indices of the fixture.
const HIPS: usize = 1;
const SPINE: usize = 2;
const LEFT_ARM: usize = 4;
const HELMET: usize = 5;
const HAND: usize = 8;

/// A character: a skinned torso strip on Hips/Spine; rigid parts on Spine itself (a mesh on
/// the joint node), under Head (Helmet) and under LeftArm through a rotated, scaled non-joint
/// socket (Hand); a prop under the armature node but not under a bone (Shield), a prop at the
/// scene root (Crate) and a mesh no node places (Unused).
fn character() -> RawGltf {
    let mut p = Packer::default();
    let strip: Vec<[f32; 3]> = [0.8f32, 1.1, 1.4]
        .iter()
        .flat_map(|&y| [[-0.1, y + 0.1, 0.0], [0.1, y + 0.1, 0.0]])
        .collect();
    let strip_tris = [[0, 1, 2], [1, 3, 2], [2, 3, 4], [3, 5, 4]];
    let mut body = p.mesh("BodySkin", &strip, &strip_tris);
    let joints = p.joints(&[
        [0, 0, 0, 0],
        [0, 0, 0, 0],
        [0, 1, 0, 0],
        [0, 1, 0, 0],
        [1, 0, 0, 0],
        [1, 0, 0, 0],
    ]);
    let w = |a: f32, b: f32| vec![a, b, 0.0, 0.0];
    let weights = p.floats(
        &[
            w(1.0, 0.0),
            w(1.0, 0.0),
            w(0.5, 0.5),
            w(0.5, 0.5),
            w(1.0, 0.0),
            w(1.0, 0.0),
        ],
        "VEC4",
    );
    body["primitives"][0]["attributes"]["JOINTS_0"] = json!(joints);
    body["primitives"][0]["attributes"]["WEIGHTS_0"] = json!(weights);
    let (cube_p, cube_t) = cube(0.05);
    let (tet_p, tet_t) = tetra(0.08);
    let meshes = vec![
        body,
        p.mesh("Box", &cube_p, &cube_t),
        p.mesh("Tetra", &tet_p, &tet_t),
        p.mesh("Unused", &tet_p, &tet_t),
    ];
    let arm_rot = UnitQuaternion::from_euler_angles(0.0, 0.3, -0.4);
    let socket_rot = UnitQuaternion::from_euler_angles(0.5, 0.0, 0.2);
    let nodes = json!([
        { "name": "Armature", "translation": [0.1, 0.0, 0.0], "children": [1, 6] },
        { "name": "Hips", "translation": [0.0, 0.9, 0.0], "children": [2] },
        { "name": "Spine", "translation": [0.0, 0.3, 0.0], "mesh": 2, "children": [3, 4] },
        { "name": "Head", "translation": [0.0, 0.35, 0.0], "children": [5] },
        { "name": "LeftArm", "translation": [0.2, 0.1, 0.0], "rotation": quat_json(&arm_rot), "children": [7] },
        { "name": "Helmet", "translation": [0.0, 0.12, 0.02], "mesh": 1 },
        { "name": "Shield", "translation": [0.5, 1.0, 0.0], "mesh": 1 },
        { "name": "HandSocket", "translation": [0.3, 0.0, 0.0], "rotation": quat_json(&socket_rot), "scale": [0.5, 0.5, 0.5], "children": [8] },
        { "name": "Hand", "translation": [0.05, 0.0, 0.0], "mesh": 2 },
        { "name": "Crate", "translation": [2.0, 0.0, 0.0], "mesh": 1 },
        { "name": "Body", "mesh": 0, "skin": 0 },
    ]);
    let mut raw = RawGltf {
        json: json!({ "nodes": nodes }),
        buffers: Vec::new(),
    };
    // Bind pose = rest pose: inverse rest world matrices of the skin joints.
    let ibms: Vec<Vec<f32>> = [HIPS, SPINE, 3, LEFT_ARM]
        .iter()
        .map(|&j| {
            let m = raw.world(j).try_inverse().unwrap();
            m.as_slice().iter().map(|&v| v as f32).collect()
        })
        .collect();
    let ibm = p.floats(&ibms, "MAT4");
    raw.json = json!({
        "asset": { "version": "2.0" },
        "scene": 0,
        "scenes": [{ "nodes": [0, 9, 10] }],
        "nodes": nodes,
        "meshes": meshes,
        "skins": [{ "joints": [HIPS, SPINE, 3, LEFT_ARM], "inverseBindMatrices": ibm }],
        "accessors": p.accessors,
        "bufferViews": p.views,
        "buffers": [{ "byteLength": p.bin.len() }],
    });
    raw.buffers = vec![p.bin];
    raw
}

pub(super) fn glb(raw: &RawGltf) -> Vec<u8> {
    glb_bytes(&raw.json, &raw.buffers[0]).unwrap()
}

/// The positions of mesh `mesh` placed by node `node`'s world matrix.
pub(super) fn placed(raw: &RawGltf, node: usize, mesh_points: &[[f32; 3]]) -> Vec<Vector3<f64>> {
    let world: Matrix4<f64> = raw.world(node);
    mesh_points
        .iter()
        .map(|p| {
            world
                .transform_point(&Point3::new(p[0] as f64, p[1] as f64, p[2] as f64))
                .coords
        })
        .collect()
}

/// Rigid vertices in load order (after the 6 skinned ones): Spine's tetra, Helmet's box,
/// Hand's tetra; each with its node and joint.
fn rigid_layout() -> Vec<(usize, &'static str, Vec<[f32; 3]>)> {
    vec![
        (SPINE, "Spine", tetra(0.08).0),
        (HELMET, "Head", cube(0.05).0),
        (HAND, "LeftArm", tetra(0.08).0),
    ]
}

#[test]
fn rigid_parts_join_the_body_with_weight_one_and_follow_their_joint() {
    let raw = character();
    let path = std::path::Path::new("rigid_character.glb");
    let loaded = io::load_avatar_from_bytes(&glb(&raw), path, &opts()).unwrap();
    let avatar = &loaded.avatar;
    let sk = &avatar.skeleton;
    assert_eq!(sk.len(), 4, "{:?}", sk.names);
    assert_eq!(avatar.bind_mesh.vertex_count(), 6 + 4 + 8 + 4);
    assert_eq!(avatar.bind_mesh.faces.len(), 4 + 4 + 12 + 4);

    // Each rigid vertex: one influence, weight 1, on its joint.
    let mut at = 6;
    for (_, joint, points) in rigid_layout() {
        let j = sk.index_of(joint).unwrap() as u16;
        for v in at..at + points.len() {
            assert_eq!(avatar.skin.joints[v][0], j, "vertex {v}");
            assert_eq!(avatar.skin.weights[v], [1.0, 0.0, 0.0, 0.0], "vertex {v}");
        }
        at += points.len();
    }

    // Posed: the glTF scene graph with the same joint rotations moves them the same way.
    let spine_turn = UnitQuaternion::from_euler_angles(0.6, 0.2, 0.0);
    let arm_turn = UnitQuaternion::from_euler_angles(0.0, -0.5, 0.9)
        * UnitQuaternion::from_euler_angles(0.0, 0.3, -0.4);
    let mut pose = sk.rest_pose();
    for (joint, q) in [("Spine", spine_turn), ("LeftArm", arm_turn)] {
        pose.rotations[sk.index_of(joint).unwrap()] = q.cast::<f32>();
    }
    let mut posed_raw = RawGltf {
        json: raw.json.clone(),
        buffers: Vec::new(),
    };
    posed_raw.json["nodes"][SPINE]["rotation"] = quat_json(&spine_turn);
    posed_raw.json["nodes"][LEFT_ARM]["rotation"] = quat_json(&arm_turn);
    for (graph, positions) in [
        (&raw, avatar.rest_mesh.positions.clone()),
        (&posed_raw, avatar.pose_vertices(&pose)),
    ] {
        let mut at = 6;
        for (node, joint, points) in rigid_layout() {
            for (k, want) in placed(graph, node, &points).iter().enumerate() {
                let got = positions[at + k].cast::<f64>();
                assert!(
                    (got - want).norm() < 1e-5,
                    "{joint} vertex {k}: {got:?} vs {want:?}"
                );
            }
            at += points.len();
        }
    }
    // The posed Helmet moved (the spine turned), so the check above is not vacuous.
    let helmet_rest = avatar.rest_mesh.positions[10];
    assert!((avatar.pose_vertices(&pose)[10] - helmet_rest).norm() > 0.1);
}

#[test]
fn props_and_unplaced_meshes_are_left_out_with_a_warning() {
    let loaded =
        io::load_avatar_from_bytes(&glb(&character()), std::path::Path::new("c.glb"), &opts())
            .unwrap();
    let usage = |node: Option<&str>, mesh: &str| {
        loaded
            .meshes
            .iter()
            .find(|m| m.node.as_deref() == node && m.mesh == mesh)
            .unwrap_or_else(|| panic!("{node:?} {mesh} not listed: {:?}", loaded.meshes))
            .usage
            .clone()
    };
    assert_eq!(loaded.meshes.len(), 7, "{:?}", loaded.meshes);
    assert_eq!(usage(Some("Body"), "BodySkin"), MeshUsage::Skinned);
    for (node, mesh, joint) in [
        ("Spine", "Tetra", "Spine"),
        ("Helmet", "Box", "Head"),
        ("Hand", "Tetra", "LeftArm"),
    ] {
        assert_eq!(
            usage(Some(node), mesh),
            MeshUsage::Rigid {
                joint: joint.into()
            }
        );
    }
    for (node, mesh) in [
        (Some("Shield"), "Box"),
        (Some("Crate"), "Box"),
        (None, "Unused"),
    ] {
        assert!(
            matches!(usage(node, mesh), MeshUsage::Ignored { .. }),
            "{node:?}"
        );
    }
    let warned = |needle: &str| loaded.warnings.iter().any(|w| w.contains(needle));
    assert!(
        warned("2 meshes left out of the body (not parented to a joint")
            && warned("'Box' (node 'Shield'), 'Box' (node 'Crate')")
            && warned("1 mesh left out of the body (no node places it): 'Unused'"),
        "{:?}",
        loaded.warnings
    );
    // Loaded as a garment, the unplaced mesh is named too.
    let garment =
        io::load_gltf_mesh_from_bytes(&glb(&character()), std::path::Path::new("c.glb"), &opts())
            .unwrap();
    assert!(
        garment
            .warnings
            .iter()
            .any(|w| w == "1 mesh ignored (no node places it): Unused"),
        "{:?}",
        garment.warnings
    );
    let mut outside = character();
    outside.json["scenes"][0]["nodes"] = json!([9, 10]);
    let garment =
        io::load_gltf_mesh_from_bytes(&glb(&outside), std::path::Path::new("c.glb"), &opts())
            .unwrap();
    assert!(
        garment.warnings.iter().any(|w| w
            == "4 mesh nodes ignored (outside the default scene): Spine, Helmet, Shield, Hand"),
        "{:?}",
        garment.warnings
    );
}

#[test]
fn inspect_lists_every_mesh_and_how_it_was_used() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rigid_character.glb");
    std::fs::write(&path, glb(&character())).unwrap();
    let report = io::inspect(&path).unwrap();
    for line in [
        "body: 22 vertices, 24 triangles",
        "meshes: 7 (1 skinned, 3 rigid parts, 3 ignored)",
        "  'BodySkin' (node 'Body'): 6 vertices, skinned body part",
        "  'Tetra' (node 'Spine'): 4 vertices, rigid part of joint 'Spine' (weight 1)",
        "  'Box' (node 'Helmet'): 8 vertices, rigid part of joint 'Head' (weight 1)",
        "  'Tetra' (node 'Hand'): 4 vertices, rigid part of joint 'LeftArm' (weight 1)",
        "  'Box' (node 'Shield'): 8 vertices, ignored: not parented to a joint",
        "  'Box' (node 'Crate'): 8 vertices, ignored: not parented to a joint",
        "  'Unused': 4 vertices, ignored: no node places it",
        "warnings: 2",
    ] {
        assert!(report.contains(line), "missing '{line}' in:\n{report}");
    }
}
