//! Low-level glTF access shared by the avatar and mesh importers: the GLB container, buffer
//! resolution (GLB binary chunk, `data:` URIs, external files), bounds-checked accessor
//! reading and the node hierarchy.
//!
//! The `gltf` crate is used without its `import` feature, so nothing here trusts an offset,
//! length or count from the file: every range is checked before use and no allocation is
//! sized from an unchecked count.

use std::path::{Path, PathBuf};

use base64::Engine as _;

use super::IoError;
use crate::geometry::{Mat4, Quat, Vec3};
use crate::scene::JointTransform;

/// GLB chunk type of the JSON chunk ("JSON").
const CHUNK_JSON: u32 = 0x4E4F_534A;
/// GLB chunk type of the binary chunk ("BIN\0").
const CHUNK_BIN: u32 = 0x004E_4942;
/// Tolerance on `| |q| - 1 |` for rotations stored in files.
pub(crate) const FILE_ROTATION_TOLERANCE: f32 = 1e-2;

/// A parsed glTF document with its buffers resolved and its node hierarchy indexed.
pub(crate) struct GltfDoc {
    /// The validated document.
    pub doc: gltf::Document,
    /// Bytes of each buffer, by buffer index.
    pub buffers: Vec<Vec<u8>>,
    /// Parent node of each node.
    pub parents: Vec<Option<usize>>,
    /// The file (for messages).
    pub path: PathBuf,
}

fn le_u32(bytes: &[u8], at: usize) -> Option<u32> {
    let b = bytes.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// Splits a GLB container into its JSON chunk and optional binary chunk.
fn split_glb<'a>(bytes: &'a [u8], path: &Path) -> Result<(&'a [u8], Option<&'a [u8]>), IoError> {
    let trunc = |what: String| IoError::Truncated {
        what,
        path: path.to_path_buf(),
    };
    let (Some(version), Some(length)) = (le_u32(bytes, 4), le_u32(bytes, 8)) else {
        return Err(trunc(format!(
            "GLB header needs 12 bytes, file has {}",
            bytes.len()
        )));
    };
    if version != 2 {
        return Err(IoError::NotGltf {
            reason: format!("GLB version {version} (only 2 is supported)"),
            path: path.to_path_buf(),
        });
    }
    let length = length as usize;
    if length > bytes.len() {
        return Err(trunc(format!(
            "GLB header declares {length} bytes, file has {}",
            bytes.len()
        )));
    }
    let body = &bytes[..length];
    let mut at = 12usize;
    let (mut json, mut bin) = (None, None);
    while at < body.len() {
        let (Some(chunk_len), Some(kind)) = (le_u32(body, at), le_u32(body, at + 4)) else {
            return Err(trunc(format!("GLB chunk header at byte {at}")));
        };
        let start = at + 8;
        let Some(data) = start
            .checked_add(chunk_len as usize)
            .and_then(|end| body.get(start..end))
        else {
            return Err(trunc(format!(
                "GLB chunk at byte {at} declares {chunk_len} bytes"
            )));
        };
        match kind {
            CHUNK_JSON if json.is_none() => json = Some(data),
            CHUNK_BIN if bin.is_none() && json.is_some() => bin = Some(data),
            _ => {}
        }
        at = start + data.len().div_ceil(4) * 4;
    }
    let Some(json) = json else {
        return Err(IoError::NotGltf {
            reason: "GLB has no JSON chunk".into(),
            path: path.to_path_buf(),
        });
    };
    Ok((json, bin))
}

/// Decodes `%XX` escapes of a relative URI.
fn percent_decode(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%'
            && let Some(v) = bytes
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
        {
            out.push(v);
            i += 3;
            continue;
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

impl GltfDoc {
    /// Parses glTF JSON or GLB bytes from `path` and resolves all buffers.
    pub fn parse(bytes: &[u8], path: &Path) -> Result<Self, IoError> {
        let p = || path.to_path_buf();
        let (json, bin) = if bytes.starts_with(b"glTF") {
            split_glb(bytes, path)?
        } else {
            let body = bytes
                .strip_prefix(b"\xEF\xBB\xBF".as_slice())
                .unwrap_or(bytes);
            match body.iter().find(|b| !b.is_ascii_whitespace()) {
                Some(b'{') => (body, None),
                None => {
                    return Err(IoError::Truncated {
                        what: "empty file".into(),
                        path: p(),
                    });
                }
                Some(_) => {
                    return Err(IoError::NotGltf {
                        reason: "neither GLB magic nor a JSON object".into(),
                        path: p(),
                    });
                }
            }
        };
        // The crate's parser is third-party code fed untrusted bytes: contain any panic.
        let parsed = std::panic::catch_unwind(|| gltf::Gltf::from_slice(json)).map_err(|_| {
            IoError::InvalidGltf {
                reason: "the glTF parser failed on this document".into(),
                path: p(),
            }
        })?;
        let gltf = parsed.map_err(|e| match e {
            gltf::Error::Deserialize(ref d) if d.classify() == serde_json::error::Category::Eof => {
                IoError::Truncated {
                    what: format!("JSON ends early ({d})"),
                    path: p(),
                }
            }
            gltf::Error::Deserialize(ref d)
                if d.classify() == serde_json::error::Category::Syntax =>
            {
                IoError::NotGltf {
                    reason: format!("malformed JSON ({d})"),
                    path: p(),
                }
            }
            other => IoError::InvalidGltf {
                reason: other.to_string(),
                path: p(),
            },
        })?;
        let doc = gltf.document;
        let base_dir = path.parent().unwrap_or(Path::new("."));
        let mut buffers = Vec::new();
        for buffer in doc.buffers() {
            let data = match buffer.source() {
                gltf::buffer::Source::Bin => match bin {
                    Some(b) => b.to_vec(),
                    None => {
                        return Err(IoError::InvalidGltf {
                            reason: format!(
                                "buffer {} refers to a GLB binary chunk that does not exist",
                                buffer.index()
                            ),
                            path: p(),
                        });
                    }
                },
                gltf::buffer::Source::Uri(uri) => {
                    Self::load_uri(uri, base_dir, buffer.index(), path)?
                }
            };
            if data.len() < buffer.length() {
                return Err(IoError::Truncated {
                    what: format!(
                        "buffer {} has {} bytes, {} declared",
                        buffer.index(),
                        data.len(),
                        buffer.length()
                    ),
                    path: p(),
                });
            }
            buffers.push(data);
        }
        let node_count = doc.nodes().len();
        let mut parents = vec![None; node_count];
        for node in doc.nodes() {
            for child in node.children() {
                let c = child.index();
                match parents.get_mut(c) {
                    Some(slot @ None) if c != node.index() => *slot = Some(node.index()),
                    _ => {
                        return Err(IoError::InvalidGltf {
                            reason: format!(
                                "node {c} has more than one parent or is its own child"
                            ),
                            path: p(),
                        });
                    }
                }
            }
        }
        let me = Self {
            doc,
            buffers,
            parents,
            path: path.to_path_buf(),
        };
        for n in 0..node_count {
            me.ancestors(n)?;
        }
        Ok(me)
    }

    fn load_uri(uri: &str, base_dir: &Path, index: usize, path: &Path) -> Result<Vec<u8>, IoError> {
        if let Some(rest) = uri.strip_prefix("data:") {
            let Some((_, payload)) = rest.split_once(";base64,") else {
                return Err(IoError::Unsupported {
                    what: format!("buffer {index}: data URI that is not base64"),
                    path: path.to_path_buf(),
                });
            };
            return base64::engine::general_purpose::STANDARD
                .decode(payload.trim())
                .map_err(|e| IoError::InvalidGltf {
                    reason: format!("buffer {index}: bad base64 data URI ({e})"),
                    path: path.to_path_buf(),
                });
        }
        if uri.contains("://") {
            return Err(IoError::Unsupported {
                what: format!("buffer {index}: remote URI '{uri}'"),
                path: path.to_path_buf(),
            });
        }
        let file = base_dir.join(percent_decode(uri));
        std::fs::read(&file).map_err(|source| IoError::Read { source, path: file })
    }

    /// An `InvalidGltf` error for this file.
    pub fn invalid(&self, reason: impl Into<String>) -> IoError {
        IoError::InvalidGltf {
            reason: reason.into(),
            path: self.path.clone(),
        }
    }

    /// Ancestors of node `n`, nearest first. Errors on a cycle.
    pub fn ancestors(&self, n: usize) -> Result<Vec<usize>, IoError> {
        let mut out = Vec::new();
        let mut cur = self.parents.get(n).copied().flatten();
        while let Some(p) = cur {
            if out.len() > self.parents.len() {
                return Err(
                    self.invalid(format!("the node hierarchy has a cycle through node {n}"))
                );
            }
            out.push(p);
            cur = self.parents.get(p).copied().flatten();
        }
        Ok(out)
    }

    /// The rest (node) transform of node `n` as translation, rotation and scale.
    pub fn node_transform(&self, node: &gltf::Node) -> Result<JointTransform, IoError> {
        let what = format!("node {} transform", node.index());
        match node.transform() {
            gltf::scene::Transform::Decomposed {
                translation,
                rotation,
                scale,
            } => {
                let translation = Vec3::from(translation);
                let scale = Vec3::from(scale);
                if !(translation
                    .iter()
                    .chain(scale.iter())
                    .all(|v| v.is_finite()))
                {
                    return Err(IoError::NonFinite {
                        what,
                        path: self.path.clone(),
                    });
                }
                let rotation = self.quat(rotation, &what)?;
                Ok(JointTransform {
                    translation,
                    rotation,
                    scale,
                })
            }
            gltf::scene::Transform::Matrix { matrix } => {
                let m = Mat4::from_fn(|r, c| matrix[c][r]);
                decompose(&m).ok_or(IoError::NonFinite {
                    what,
                    path: self.path.clone(),
                })
            }
        }
    }

    /// The local matrix of node `n` at rest.
    pub fn local_matrix(&self, n: usize) -> Result<Mat4, IoError> {
        let node = self
            .doc
            .nodes()
            .nth(n)
            .ok_or_else(|| self.invalid(format!("node {n} does not exist")))?;
        match node.transform() {
            gltf::scene::Transform::Matrix { matrix } => {
                let m = Mat4::from_fn(|r, c| matrix[c][r]);
                if m.iter().all(|v| v.is_finite()) {
                    Ok(m)
                } else {
                    Err(IoError::NonFinite {
                        what: format!("node {n} matrix"),
                        path: self.path.clone(),
                    })
                }
            }
            _ => Ok(self.node_transform(&node)?.to_matrix()),
        }
    }

    /// The rest world matrix of node `n` (product of its ancestors' local matrices and its own).
    pub fn world_matrix(&self, n: usize) -> Result<Mat4, IoError> {
        let mut m = self.local_matrix(n)?;
        for a in self.ancestors(n)? {
            m = self.local_matrix(a)? * m;
        }
        Ok(m)
    }

    /// A unit quaternion from file components `[x, y, z, w]`.
    pub fn quat(&self, xyzw: [f32; 4], what: &str) -> Result<Quat, IoError> {
        if !xyzw.iter().all(|c| c.is_finite()) {
            return Err(IoError::NonFinite {
                what: what.to_string(),
                path: self.path.clone(),
            });
        }
        crate::geometry::rotation::quat_from_xyzw(xyzw, FILE_ROTATION_TOLERANCE).ok_or_else(|| {
            IoError::NonUnitRotation {
                what: what.to_string(),
                norm: xyzw.iter().map(|c| c * c).sum::<f32>().sqrt(),
                path: self.path.clone(),
            }
        })
    }
}

/// Splits an affine matrix into translation, rotation and (signed) scale; `None` when it is not
/// finite. Shear is dropped; a zero-scale axis keeps an identity rotation part.
pub(crate) fn decompose(m: &Mat4) -> Option<JointTransform> {
    if !m.iter().all(|v| v.is_finite()) {
        return None;
    }
    let translation = m.fixed_view::<3, 1>(0, 3).into_owned();
    let r = m.fixed_view::<3, 3>(0, 0).into_owned();
    let sign = if r.determinant() < 0.0 { -1.0 } else { 1.0 };
    let scale = Vec3::new(
        r.column(0).norm(),
        r.column(1).norm(),
        sign * r.column(2).norm(),
    );
    let rotation = crate::scene::skeleton::rotation_of(&Mat4::from_fn(|i, j| {
        if i < 3 && j < 3 {
            r[(i, j)] * if j == 2 { sign } else { 1.0 }
        } else if i == j {
            1.0
        } else {
            0.0
        }
    }));
    Some(JointTransform {
        translation,
        rotation,
        scale,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decompose_round_trips_trs() {
        let t = JointTransform {
            translation: Vec3::new(1.0, -2.0, 3.0),
            rotation: Quat::from_euler_angles(0.3, -0.7, 1.1),
            scale: Vec3::new(2.0, 0.5, 1.5),
        };
        let back = decompose(&t.to_matrix()).unwrap();
        assert!((back.to_matrix() - t.to_matrix()).norm() < 1e-5);
        assert!(decompose(&Mat4::from_element(f32::NAN)).is_none());
        let mirrored =
            decompose(&Mat4::new_nonuniform_scaling(&Vec3::new(1.0, 1.0, -1.0))).unwrap();
        assert!(
            (mirrored.to_matrix() - Mat4::new_nonuniform_scaling(&Vec3::new(1.0, 1.0, -1.0)))
                .norm()
                < 1e-6
        );
    }

    #[test]
    fn glb_container_errors() {
        let p = Path::new("x.glb");
        assert!(matches!(
            split_glb(b"glTF\x02\0\0\0", p),
            Err(IoError::Truncated { .. })
        ));
        assert!(matches!(
            split_glb(b"glTF\x01\0\0\0\x0c\0\0\0", p),
            Err(IoError::NotGltf { .. })
        ));
        assert!(matches!(
            split_glb(b"glTF\x02\0\0\0\xff\0\0\0", p),
            Err(IoError::Truncated { .. })
        ));
        let mut glb = b"glTF\x02\0\0\0\x18\0\0\0\x04\0\0\0JSON{}  ".to_vec();
        assert_eq!(split_glb(&glb, p).unwrap().0, b"{}  ");
        glb[12] = 0x40;
        assert!(matches!(split_glb(&glb, p), Err(IoError::Truncated { .. })));
        assert!(matches!(
            GltfDoc::parse(b"hello", p),
            Err(IoError::NotGltf { .. })
        ));
        assert!(matches!(
            GltfDoc::parse(b"{\"asset\":", p),
            Err(IoError::Truncated { .. })
        ));
    }

    #[test]
    fn percent_decoding() {
        assert_eq!(percent_decode("my%20file.bin"), "my file.bin");
        assert_eq!(percent_decode("a%2"), "a%2");
    }
}
