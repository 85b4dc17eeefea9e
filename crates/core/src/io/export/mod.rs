//! Exporters of baked sequences: PC2 and MDD point caches, OBJ sequences, USD (`.usda`) point
//! caches and glTF with morph targets, and the presets that put coordinates into a target
//! tool's convention. Every writer is atomic (temporary file + rename) and streams frames where
//! the format allows, so a long bake never needs all frames in memory.

pub mod atomic;
pub mod gltf;
pub mod mdd;
pub mod obj_seq;
pub mod pc2;
pub mod pca;
pub mod preset;
pub mod usd;
pub mod usda_text;

pub use gltf::{BakedSequence, GltfExportOptions, GltfExportReport, write_glb};
pub use mdd::{MddCache, MddWriter, read_mdd};
pub use obj_seq::ObjSequenceWriter;
pub use pc2::{Pc2Cache, Pc2Writer, read_pc2};
pub use preset::{Convention, Preset, UnknownPreset, UpAxis};
pub use usd::{UsdMesh, UsdStage, UsdWriter};

use std::path::{Path, PathBuf};

use crate::geometry::Vec3;

/// Errors of the exporters and cache readers. The path comes last in every message.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The file system refused.
    #[error("{source}: {}", path.display())]
    Io {
        /// The OS error.
        #[source]
        source: std::io::Error,
        /// The file concerned.
        path: PathBuf,
    },
    /// The data or file does not fit the format.
    #[error("{reason}: {}", path.display())]
    Format {
        /// What is wrong.
        reason: String,
        /// The file concerned.
        path: PathBuf,
    },
}

impl ExportError {
    /// Wraps an I/O error with its path.
    pub fn io(source: std::io::Error, path: &Path) -> Self {
        Self::Io {
            source,
            path: path.to_path_buf(),
        }
    }
}

/// Reads `frames * points * 3` floats (little- or big-endian) into per-frame point lists,
/// failing when the data is short; trailing bytes are an error too.
fn read_f32s(
    data: &[u8],
    points: usize,
    frames: usize,
    big_endian: bool,
) -> Result<Vec<Vec<Vec3>>, String> {
    let need = points
        .checked_mul(frames)
        .and_then(|n| n.checked_mul(12))
        .ok_or("point count overflows")?;
    if data.len() != need {
        return Err(format!(
            "expected {need} bytes of positions, found {}",
            data.len()
        ));
    }
    let f = |c: &[u8]| {
        let b = [c[0], c[1], c[2], c[3]];
        if big_endian {
            f32::from_be_bytes(b)
        } else {
            f32::from_le_bytes(b)
        }
    };
    Ok(data
        .chunks_exact(points.max(1) * 12)
        .take(frames)
        .map(|frame| {
            frame
                .chunks_exact(12)
                .map(|p| Vec3::new(f(&p[0..4]), f(&p[4..8]), f(&p[8..12])))
                .collect()
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames() -> Vec<Vec<Vec3>> {
        vec![
            vec![
                Vec3::new(1.0, 2.0, 3.0),
                Vec3::new(-0.5, 0.25, 1e-7),
                Vec3::new(0.1, 0.2, 0.3),
            ],
            vec![
                Vec3::new(4.0, 5.0, 6.0),
                Vec3::new(7.0, 8.0, 9.0),
                Vec3::new(f32::MIN_POSITIVE, -0.0, 1e30),
            ],
        ]
    }

    fn le(bytes: &mut Vec<u8>, v: &[f32]) {
        v.iter()
            .for_each(|x| bytes.extend_from_slice(&x.to_le_bytes()));
    }

    #[test]
    fn pc2_bytes_match_hand_computed_header_and_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.pc2");
        let mut w = Pc2Writer::create(&path, 3, 1.0, 1.0).unwrap();
        for f in frames() {
            w.write_frame(&f).unwrap();
        }
        w.finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let mut expected = b"POINTCACHE2\0".to_vec();
        expected.extend_from_slice(&[1, 0, 0, 0, 3, 0, 0, 0]);
        expected.extend_from_slice(&[0, 0, 0x80, 0x3f, 0, 0, 0x80, 0x3f]); // 1.0f32 twice
        expected.extend_from_slice(&[2, 0, 0, 0]);
        for f in frames() {
            for p in f {
                le(&mut expected, &[p.x, p.y, p.z]);
            }
        }
        assert_eq!(bytes, expected);
        let back = read_pc2(&path).unwrap();
        assert_eq!(back.frames, frames());
        assert_eq!((back.start_frame, back.sampling), (1.0, 1.0));
        // Only the final file is left in the folder.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn mdd_bytes_match_hand_computed_header_and_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.mdd");
        let mut w = MddWriter::create(&path, 2, 3, 4.0).unwrap();
        for f in frames() {
            w.write_frame(&f).unwrap();
        }
        w.finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let mut expected = vec![0, 0, 0, 2, 0, 0, 0, 3];
        expected.extend_from_slice(&[0, 0, 0, 0, 0x3e, 0x80, 0, 0]); // 0.0 and 0.25 s, big-endian
        for f in frames() {
            for p in f {
                for c in [p.x, p.y, p.z] {
                    expected.extend_from_slice(&c.to_be_bytes());
                }
            }
        }
        assert_eq!(bytes, expected);
        let back = read_mdd(&path).unwrap();
        assert_eq!(back.frames, frames());
        assert_eq!(back.times_secs, vec![0.0, 0.25]);
    }

    #[test]
    fn incomplete_or_bad_writes_leave_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("b.mdd");
        let mut w = MddWriter::create(&path, 3, 3, 30.0).unwrap();
        w.write_frame(&frames()[0]).unwrap();
        assert!(w.finish().is_err());
        let mut w = Pc2Writer::create(&dir.path().join("c.pc2"), 3, 0.0, 1.0).unwrap();
        assert!(w.write_frame(&frames()[0][..2]).is_err());
        let mut bad = frames()[0].clone();
        bad[1].y = f32::NAN;
        assert!(w.write_frame(&bad).is_err());
        drop(w);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        assert!(Pc2Writer::create(&dir.path().join("missing/x.pc2"), 3, 0.0, 1.0).is_err());
    }

    #[test]
    fn readers_reject_truncated_and_foreign_files() {
        assert!(pc2::parse_pc2(b"POINTCACHE2\0").is_err());
        assert!(pc2::parse_pc2(&[0u8; 64]).is_err());
        assert!(mdd::parse_mdd(&[0, 0, 0, 2, 0, 0, 0, 3, 0, 0]).is_err());
        assert!(mdd::parse_mdd(&[0x7f, 0xff, 0xff, 0xff, 0x7f, 0xff, 0xff, 0xff]).is_err());
    }

    #[test]
    fn obj_sequence_round_trips_through_text() {
        let dir = tempfile::tempdir().unwrap();
        let mut mesh = TriMeshLike::mesh();
        mesh.uvs = Some(vec![[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]]);
        let out = dir.path().join("seq");
        let mut w = ObjSequenceWriter::create(&out, "shirt", &mesh).unwrap();
        for f in frames() {
            w.write_frame(&f).unwrap();
        }
        w.finish().unwrap();
        let text = std::fs::read_to_string(out.join("shirt_0002.obj")).unwrap();
        let vs: Vec<Vec3> = text
            .lines()
            .filter_map(|l| l.strip_prefix("v "))
            .map(|l| {
                let c: Vec<f32> = l.split(' ').map(|x| x.parse().unwrap()).collect();
                Vec3::new(c[0], c[1], c[2])
            })
            .collect();
        assert_eq!(vs, frames()[1]);
        assert!(text.contains("f 1/1 2/2 3/3"));
        assert_eq!(std::fs::read_dir(&out).unwrap().count(), 2);
    }

    struct TriMeshLike;
    impl TriMeshLike {
        fn mesh() -> crate::geometry::TriMesh {
            crate::geometry::TriMesh::new(
                vec![Vec3::zeros(), Vec3::x(), Vec3::y()],
                vec![[0, 1, 2]],
            )
            .unwrap()
        }
    }
}
