//! Independent glTF reading (serde_json plus hand-decoded accessors) and glTF-spec skinning,
//! used to check the importer against the files themselves.

use base64::Engine as _;
use nalgebra::{Matrix4, Point3, Quaternion, UnitQuaternion, Vector3};
use neural_cloth::io::{self, IoError};
use serde_json::Value;

use super::{asset, opts};

pub struct RawGltf {
    pub json: Value,
    pub buffers: Vec<Vec<u8>>,
}

pub fn raw_gltf(bytes: &[u8]) -> RawGltf {
    if bytes.starts_with(b"glTF") {
        let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
        let json_len = u32_at(12);
        let json: Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
        let bin_at = 20 + json_len;
        let bin = if bin_at + 8 <= bytes.len() {
            bytes[bin_at + 8..bin_at + 8 + u32_at(bin_at)].to_vec()
        } else {
            Vec::new()
        };
        RawGltf {
            json,
            buffers: vec![bin],
        }
    } else {
        let json: Value = serde_json::from_slice(bytes).unwrap();
        let buffers = json["buffers"]
            .as_array()
            .unwrap()
            .iter()
            .map(|b| {
                let uri = b["uri"].as_str().unwrap();
                base64::engine::general_purpose::STANDARD
                    .decode(uri.split_once(";base64,").unwrap().1)
                    .unwrap()
            })
            .collect();
        RawGltf { json, buffers }
    }
}

impl RawGltf {
    /// Accessor `i` as rows of f64 (float, u8 or u16 components, honouring byteStride).
    pub fn accessor(&self, i: usize) -> Vec<Vec<f64>> {
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
        let stride = view["byteStride"]
            .as_u64()
            .map(|s| s as usize)
            .unwrap_or(n * size);
        let base = view["byteOffset"].as_u64().unwrap_or(0) as usize
            + a["byteOffset"].as_u64().unwrap_or(0) as usize;
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

    pub fn local(&self, n: usize) -> Matrix4<f64> {
        let node = &self.json["nodes"][n];
        let nums = |key: &str, default: &[f64]| -> Vec<f64> {
            node[key]
                .as_array()
                .map(|a| a.iter().map(|v| v.as_f64().unwrap()).collect())
                .unwrap_or_else(|| default.to_vec())
        };
        if node.get("matrix").is_some() {
            return Matrix4::from_column_slice(&nums("matrix", &[]));
        }
        let t = nums("translation", &[0.0; 3]);
        let r = nums("rotation", &[0.0, 0.0, 0.0, 1.0]);
        let s = nums("scale", &[1.0; 3]);
        let q = UnitQuaternion::from_quaternion(Quaternion::new(r[3], r[0], r[1], r[2]));
        Matrix4::new_translation(&Vector3::new(t[0], t[1], t[2]))
            * q.to_homogeneous()
            * Matrix4::new_nonuniform_scaling(&Vector3::new(s[0], s[1], s[2]))
    }

    pub fn parent(&self, n: usize) -> Option<usize> {
        self.json["nodes"].as_array().unwrap().iter().position(|p| {
            p["children"]
                .as_array()
                .is_some_and(|c| c.iter().any(|c| c.as_u64() == Some(n as u64)))
        })
    }

    pub fn world(&self, n: usize) -> Matrix4<f64> {
        match self.parent(n) {
            Some(p) => self.world(p) * self.local(n),
            None => self.local(n),
        }
    }

    /// The glTF-spec skinning of every skinned mesh node at the nodes' rest transforms, times `scale`.
    pub fn rest_mesh(&self, scale: f64) -> Vec<Vector3<f64>> {
        self.skinned_mesh(scale, &|j| self.world(j))
    }

    /// The glTF-spec skinning with joint node `j` at world matrix `world(j)`, times `scale`.
    pub fn skinned_mesh(
        &self,
        scale: f64,
        world: &dyn Fn(usize) -> Matrix4<f64>,
    ) -> Vec<Vector3<f64>> {
        let mut out = Vec::new();
        for node in self.json["nodes"].as_array().unwrap() {
            let (Some(mesh), Some(skin)) = (node["mesh"].as_u64(), node["skin"].as_u64()) else {
                continue;
            };
            let skin = &self.json["skins"][skin as usize];
            let joints: Vec<usize> = skin["joints"]
                .as_array()
                .unwrap()
                .iter()
                .map(|j| j.as_u64().unwrap() as usize)
                .collect();
            let ibm = self.accessor(skin["inverseBindMatrices"].as_u64().unwrap() as usize);
            let mats: Vec<Matrix4<f64>> = joints
                .iter()
                .zip(&ibm)
                .map(|(&j, m)| {
                    Matrix4::new_scaling(scale) * world(j) * Matrix4::from_column_slice(m)
                })
                .collect();
            for prim in self.json["meshes"][mesh as usize]["primitives"]
                .as_array()
                .unwrap()
            {
                let attr =
                    |k: &str| self.accessor(prim["attributes"][k].as_u64().unwrap() as usize);
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
    pub fn world_at_first_keys(&self, anim: usize, n: usize) -> Matrix4<f64> {
        let mut node = self.json["nodes"][n].clone();
        let a = &self.json["animations"][anim];
        for c in a["channels"].as_array().unwrap() {
            if c["target"]["node"].as_u64() == Some(n as u64) {
                let sampler = &a["samplers"][c["sampler"].as_u64().unwrap() as usize];
                let first = self.accessor(sampler["output"].as_u64().unwrap() as usize)[0].clone();
                node[c["target"]["path"].as_str().unwrap()] = serde_json::json!(first);
            }
        }
        let mut raw = RawGltf {
            json: self.json.clone(),
            buffers: Vec::new(),
        };
        raw.json["nodes"][n] = node;
        let local = raw.local(n);
        match self.parent(n) {
            Some(p) => self.world_at_first_keys(anim, p) * local,
            None => local,
        }
    }

    /// Largest keyframe time of each animation, from the input accessors' `max`.
    pub fn animation_ends(&self) -> Vec<f64> {
        self.json["animations"]
            .as_array()
            .map(|anims| {
                anims
                    .iter()
                    .map(|a| {
                        a["samplers"]
                            .as_array()
                            .unwrap()
                            .iter()
                            .map(|s| {
                                self.accessor(s["input"].as_u64().unwrap() as usize)
                                    .iter()
                                    .map(|r| r[0])
                                    .fold(0.0, f64::max)
                            })
                            .fold(0.0, f64::max)
                    })
                    .collect()
            })
            .unwrap_or_default()
    }

    pub fn to_gltf_bytes(&self) -> Vec<u8> {
        let mut json = self.json.clone();
        let uris: Vec<Value> = self
            .buffers
            .iter()
            .map(|b| {
                Value::String(format!(
                    "data:application/octet-stream;base64,{}",
                    base64::engine::general_purpose::STANDARD.encode(b)
                ))
            })
            .collect();
        for (buffer, uri) in json["buffers"].as_array_mut().unwrap().iter_mut().zip(uris) {
            buffer["uri"] = uri;
        }
        serde_json::to_vec(&json).unwrap()
    }
}

pub fn simple_skin() -> RawGltf {
    raw_gltf(&std::fs::read(asset("avatars/SimpleSkin.gltf")).unwrap())
}

pub fn load_raw(raw: &RawGltf) -> Result<io::LoadedAvatar, IoError> {
    io::load_avatar_from_bytes(
        &raw.to_gltf_bytes(),
        &asset("avatars/SimpleSkin.gltf"),
        &opts(),
    )
}
