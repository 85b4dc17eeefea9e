//! OBJ sequences: one OBJ file per frame (`<stem>_0001.obj`, ...) with the garment's faces and
//! UVs and a stable vertex order, written into a folder that appears atomically.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::geometry::{TriMesh, Vec3};

use super::ExportError;
use super::atomic::{AtomicDir, AtomicFile};
use super::pc2::check_frame;

/// Streams frames into a folder of OBJ files.
pub struct ObjSequenceWriter {
    dir: AtomicDir,
    stem: String,
    faces: Vec<[u32; 3]>,
    uvs: Option<Vec<[f32; 2]>>,
    points: usize,
    written: usize,
    first_number: usize,
}

impl ObjSequenceWriter {
    /// Starts a sequence in the folder `dir` (created; it must not exist or be empty), naming
    /// files `<stem>_NNNN.obj` from 1 and reusing `topology`'s faces and UVs for every frame.
    pub fn create(dir: &Path, stem: &str, topology: &TriMesh) -> Result<Self, ExportError> {
        Self::create_numbered(dir, stem, topology, 1)
    }

    /// Like [`ObjSequenceWriter::create`], numbering the first file `first_number`.
    pub fn create_numbered(
        dir: &Path,
        stem: &str,
        topology: &TriMesh,
        first_number: usize,
    ) -> Result<Self, ExportError> {
        if dir.exists()
            && std::fs::read_dir(dir)
                .map(|mut d| d.next().is_some())
                .unwrap_or(true)
        {
            return Err(ExportError::Format {
                reason: "output folder exists and is not empty".into(),
                path: dir.to_path_buf(),
            });
        }
        let uvs = topology
            .uvs
            .clone()
            .filter(|uv| uv.len() == topology.positions.len());
        Ok(Self {
            dir: AtomicDir::create(dir)?,
            stem: stem.to_string(),
            faces: topology.faces.clone(),
            uvs,
            points: topology.positions.len(),
            written: 0,
            first_number,
        })
    }

    /// File name of frame `index` (0-based index, 1-based numbering in the name).
    pub fn file_name(stem: &str, index: usize) -> String {
        Self::numbered_name(stem, index + 1)
    }

    /// File name of the frame numbered `number`.
    pub fn numbered_name(stem: &str, number: usize) -> String {
        format!("{stem}_{number:04}.obj")
    }

    /// Writes the next frame.
    pub fn write_frame(&mut self, positions: &[Vec3]) -> Result<(), ExportError> {
        let path = self.dir.temp_path().join(Self::numbered_name(
            &self.stem,
            self.first_number + self.written,
        ));
        check_frame(positions, self.points, &path)?;
        let mut f = AtomicFile::create(&path)?;
        let text = obj_text(
            positions,
            &self.faces,
            self.uvs.as_deref(),
            &format!("{} frame {}", self.stem, self.first_number + self.written),
        );
        f.write_all(text.as_bytes())
            .map_err(|e| ExportError::io(e, &path))?;
        f.commit()?;
        self.written += 1;
        Ok(())
    }

    /// Moves the folder into place and returns its path.
    pub fn finish(self) -> Result<PathBuf, ExportError> {
        self.dir.commit()
    }
}

/// One OBJ file's text. Coordinates use Rust's shortest round-trip float formatting, so
/// reading them back gives the same `f32` bits.
pub fn obj_text(
    positions: &[Vec3],
    faces: &[[u32; 3]],
    uvs: Option<&[[f32; 2]]>,
    comment: &str,
) -> String {
    use std::fmt::Write as _;
    let mut s = String::with_capacity(positions.len() * 40 + faces.len() * 24);
    let _ = writeln!(s, "# neural-cloth: {comment}");
    for p in positions {
        let _ = writeln!(s, "v {:?} {:?} {:?}", p.x, p.y, p.z);
    }
    if let Some(uvs) = uvs {
        for uv in uvs {
            let _ = writeln!(s, "vt {:?} {:?}", uv[0], uv[1]);
        }
    }
    for f in faces {
        let [a, b, c] = [f[0] + 1, f[1] + 1, f[2] + 1];
        if uvs.is_some() {
            let _ = writeln!(s, "f {a}/{a} {b}/{b} {c}/{c}");
        } else {
            let _ = writeln!(s, "f {a} {b} {c}");
        }
    }
    s
}
