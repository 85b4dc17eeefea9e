//! USD point caches in the text format (`.usda`), written by hand and streamed: one root
//! `Xform` holding one `UsdGeomMesh` per cached surface (the garment, optionally the body)
//! with its topology (`faceVertexCounts`, `faceVertexIndices`, `primvars:st` where there are
//! per-vertex UVs, `subdivisionScheme = "none"`, double-sided) and, per frame, a time sample of
//! `points` and of `extent`. Stage metadata: `metersPerUnit`, `upAxis`, `timeCodesPerSecond`,
//! `framesPerSecond`, `startTimeCode`, `endTimeCode`, `defaultPrim`.
//!
//! Frames go to disk as they come: the first mesh's samples straight into the output, every
//! other mesh's into a hidden spill file beside it that is appended at the end (a usda
//! attribute's samples must be contiguous). Only the per-frame extents (24 bytes a frame) stay
//! in memory. The output is atomic like every exporter here: a failed or dropped writer leaves
//! no file, spill files included.

use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use crate::geometry::{TriMesh, Vec3};

use super::ExportError;
use super::atomic::{AtomicFile, temp_path_for};
use super::pc2::check_frame;
use super::preset::UpAxis;
use super::usda_text::{
    is_identifier, push_int_array, push_vec2_array, push_vec3, push_vec3_array, quote,
};

/// Stage-wide settings of a USD cache.
#[derive(Clone, Debug)]
pub struct UsdStage<'a> {
    /// Name of the root `Xform` (and `defaultPrim`); a valid identifier.
    pub root: &'a str,
    /// Frames (time codes) per second, > 0.
    pub fps: f32,
    /// Time code of the first frame; frame `k` is sampled at `first_time_code + k`.
    pub first_time_code: usize,
    /// Frames that will be written, > 0.
    pub frames: usize,
    /// The stage's up axis.
    pub up_axis: UpAxis,
    /// Metres per length unit of the points (1 for metres, 0.01 for centimetres).
    pub meters_per_unit: f64,
    /// A line of documentation (the stage's `doc`).
    pub doc: &'a str,
}

/// One cached mesh: its prim name and the topology (faces, UVs) shared by every frame.
#[derive(Clone, Copy, Debug)]
pub struct UsdMesh<'a> {
    /// Prim name under the root; a valid identifier, unique in the stage.
    pub name: &'a str,
    /// Faces and optional per-vertex UVs; the vertex count fixes the points per frame.
    pub topology: &'a TriMesh,
}

/// Where a mesh's text goes until the end: the output itself, or a spill file.
enum Target {
    Output,
    Spill(SpillFile),
}

struct MeshBlock {
    points: usize,
    target: Target,
    /// Per-frame `(min, max)` corners of the points.
    extents: Vec<[Vec3; 2]>,
}

/// Streams frames of one or more meshes into a `.usda` stage.
pub struct UsdWriter {
    file: AtomicFile,
    meshes: Vec<MeshBlock>,
    frames: usize,
    written: usize,
    first_time_code: usize,
    line: String,
}

impl UsdWriter {
    /// Starts the stage at `path` (the folder must exist and be writable) and writes the
    /// metadata and every mesh's topology.
    pub fn create(path: &Path, stage: &UsdStage, meshes: &[UsdMesh]) -> Result<Self, ExportError> {
        check_stage(path, stage, meshes)?;
        let mut file = AtomicFile::create(path)?;
        let mut head = header_text(stage);
        let mut blocks = Vec::with_capacity(meshes.len());
        for (k, mesh) in meshes.iter().enumerate() {
            let text = mesh_open_text(mesh);
            let target = if k == 0 {
                head.push_str(&text);
                Target::Output
            } else {
                let mut spill = SpillFile::create(path, k)?;
                spill.write(text.as_bytes())?;
                Target::Spill(spill)
            };
            blocks.push(MeshBlock {
                points: mesh.topology.positions.len(),
                target,
                extents: Vec::with_capacity(stage.frames),
            });
        }
        file.write_all(head.as_bytes())
            .map_err(|e| ExportError::io(e, path))?;
        Ok(Self {
            file,
            meshes: blocks,
            frames: stage.frames,
            written: 0,
            first_time_code: stage.first_time_code,
            line: String::new(),
        })
    }

    /// Appends the next frame: one point list per mesh, in the order given to
    /// [`UsdWriter::create`].
    pub fn write_frame(&mut self, frame: &[&[Vec3]]) -> Result<(), ExportError> {
        let path = self.file.path().to_path_buf();
        if frame.len() != self.meshes.len() {
            return Err(ExportError::Format {
                reason: format!(
                    "frame has {} meshes, stage has {}",
                    frame.len(),
                    self.meshes.len()
                ),
                path,
            });
        }
        if self.written == self.frames {
            return Err(ExportError::Format {
                reason: format!("more than the {} frames announced", self.frames),
                path,
            });
        }
        for (block, points) in self.meshes.iter().zip(frame) {
            check_frame(points, block.points, &path)?;
        }
        let code = self.first_time_code + self.written;
        for (block, points) in self.meshes.iter_mut().zip(frame) {
            self.line.clear();
            self.line.push_str(&format!("            {code}: "));
            push_vec3_array(&mut self.line, points);
            self.line.push_str(",\n");
            match &mut block.target {
                Target::Output => self
                    .file
                    .write_all(self.line.as_bytes())
                    .map_err(|e| ExportError::io(e, &path))?,
                Target::Spill(spill) => spill.write(self.line.as_bytes())?,
            }
            block.extents.push(extent(points));
        }
        self.written += 1;
        Ok(())
    }

    /// Frames written so far.
    pub fn frames_written(&self) -> usize {
        self.written
    }

    /// Checks that every announced frame was written, closes the meshes (appending the spilled
    /// ones) and moves the file into place.
    pub fn finish(mut self) -> Result<PathBuf, ExportError> {
        let path = self.file.path().to_path_buf();
        if self.written != self.frames {
            return Err(ExportError::Format {
                reason: format!("{} of {} frames written", self.written, self.frames),
                path,
            });
        }
        for block in std::mem::take(&mut self.meshes) {
            if let Target::Spill(spill) = block.target {
                spill.append_to(&mut self.file, &path)?;
            }
            let close = mesh_close_text(&block.extents, self.first_time_code);
            self.file
                .write_all(close.as_bytes())
                .map_err(|e| ExportError::io(e, &path))?;
        }
        self.file
            .write_all(b"}\n")
            .map_err(|e| ExportError::io(e, &path))?;
        self.file.commit()
    }
}

/// Refuses settings that would write an invalid stage.
fn check_stage(path: &Path, stage: &UsdStage, meshes: &[UsdMesh]) -> Result<(), ExportError> {
    let fail = |reason: String| {
        Err(ExportError::Format {
            reason,
            path: path.to_path_buf(),
        })
    };
    if !is_identifier(stage.root) {
        return fail(format!("'{}' is not a valid prim name", stage.root));
    }
    if !(stage.fps.is_finite() && stage.fps > 0.0) {
        return fail(format!("frame rate {} is not positive", stage.fps));
    }
    if !(stage.meters_per_unit.is_finite() && stage.meters_per_unit > 0.0) {
        return fail(format!(
            "metersPerUnit {} is not positive",
            stage.meters_per_unit
        ));
    }
    if stage.frames == 0 {
        return fail("a USD cache needs at least one frame".into());
    }
    if meshes.is_empty() {
        return fail("a USD cache needs at least one mesh".into());
    }
    for (k, mesh) in meshes.iter().enumerate() {
        if !is_identifier(mesh.name) || meshes[..k].iter().any(|m| m.name == mesh.name) {
            return fail(format!("'{}' is not a valid, unique prim name", mesh.name));
        }
        let n = mesh.topology.positions.len();
        if n == 0 || n > i32::MAX as usize {
            return fail(format!("mesh '{}' has {n} points", mesh.name));
        }
        if mesh
            .topology
            .faces
            .iter()
            .flatten()
            .any(|&i| i as usize >= n)
        {
            return fail(format!(
                "mesh '{}' has a face index out of range",
                mesh.name
            ));
        }
    }
    Ok(())
}

/// The layer header (metadata) and the root prim's opening.
fn header_text(stage: &UsdStage) -> String {
    let end = stage.first_time_code + stage.frames - 1;
    let mut s = String::from("#usda 1.0\n(\n");
    s.push_str(&format!("    defaultPrim = {}\n", quote(stage.root)));
    s.push_str(&format!("    doc = {}\n", quote(stage.doc)));
    s.push_str(&format!("    endTimeCode = {end}\n"));
    s.push_str(&format!("    framesPerSecond = {}\n", stage.fps));
    s.push_str(&format!("    metersPerUnit = {}\n", stage.meters_per_unit));
    s.push_str(&format!("    startTimeCode = {}\n", stage.first_time_code));
    s.push_str(&format!("    timeCodesPerSecond = {}\n", stage.fps));
    s.push_str(&format!("    upAxis = {}\n", quote(stage.up_axis.token())));
    s.push_str(")\n\n");
    s.push_str(&format!("def Xform {}\n{{\n", quote(stage.root)));
    s
}

/// A mesh's opening, topology and the start of its `points` samples.
fn mesh_open_text(mesh: &UsdMesh) -> String {
    let t = mesh.topology;
    let mut s = format!("    def Mesh {}\n    {{\n", quote(mesh.name));
    s.push_str("        uniform bool doubleSided = 1\n");
    s.push_str("        int[] faceVertexCounts = ");
    push_int_array(&mut s, t.faces.iter().map(|_| 3));
    s.push_str("\n        int[] faceVertexIndices = ");
    push_int_array(&mut s, t.faces.iter().flatten().copied());
    s.push('\n');
    if let Some(uvs) = t.uvs.as_ref().filter(|uv| uv.len() == t.positions.len()) {
        s.push_str("        texCoord2f[] primvars:st = ");
        push_vec2_array(&mut s, uvs);
        s.push_str(" (\n            interpolation = \"vertex\"\n        )\n");
    }
    s.push_str("        uniform token subdivisionScheme = \"none\"\n");
    s.push_str("        point3f[] points.timeSamples = {\n");
    s
}

/// The end of a mesh's `points` samples, its `extent` samples and the mesh's closing.
fn mesh_close_text(extents: &[[Vec3; 2]], first_time_code: usize) -> String {
    let mut s = String::from("        }\n        float3[] extent.timeSamples = {\n");
    for (k, [lo, hi]) in extents.iter().enumerate() {
        s.push_str(&format!("            {}: [", first_time_code + k));
        push_vec3(&mut s, lo);
        s.push_str(", ");
        push_vec3(&mut s, hi);
        s.push_str("],\n");
    }
    s.push_str("        }\n    }\n");
    s
}

/// The axis-aligned bounds `(min, max)` of a non-empty point list.
fn extent(points: &[Vec3]) -> [Vec3; 2] {
    let first = points.first().copied().unwrap_or_else(Vec3::zeros);
    points.iter().fold([first, first], |[lo, hi], p| {
        [lo.zip_map(p, f32::min), hi.zip_map(p, f32::max)]
    })
}

/// A hidden temporary beside the output that holds one mesh's text until the end; removed
/// when dropped.
struct SpillFile {
    path: PathBuf,
    writer: Option<BufWriter<File>>,
}

impl SpillFile {
    fn create(output: &Path, index: usize) -> Result<Self, ExportError> {
        let mut name = temp_path_for(output).into_os_string();
        name.push(format!(".mesh{index}"));
        let path = PathBuf::from(name);
        let file = File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&path)
            .map_err(|e| ExportError::io(e, output))?;
        Ok(Self {
            path,
            writer: Some(BufWriter::with_capacity(1 << 20, file)),
        })
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), ExportError> {
        match self.writer.as_mut() {
            Some(w) => w
                .write_all(bytes)
                .map_err(|e| ExportError::io(e, &self.path)),
            None => Ok(()),
        }
    }

    /// Copies everything written so far onto the end of `out` (whose path is `out_path`).
    fn append_to(mut self, out: &mut AtomicFile, out_path: &Path) -> Result<(), ExportError> {
        let Some(writer) = self.writer.take() else {
            return Ok(());
        };
        let mut file = writer
            .into_inner()
            .map_err(|e| ExportError::io(e.into_error(), &self.path))?;
        file.seek(SeekFrom::Start(0))
            .map_err(|e| ExportError::io(e, &self.path))?;
        std::io::copy(&mut file, out).map_err(|e| ExportError::io(e, out_path))?;
        Ok(())
    }
}

impl Drop for SpillFile {
    fn drop(&mut self) {
        self.writer = None;
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn triangle(uvs: bool) -> TriMesh {
        let mut m =
            TriMesh::new(vec![Vec3::zeros(), Vec3::x(), Vec3::y()], vec![[0, 1, 2]]).unwrap();
        if uvs {
            m.uvs = Some(vec![[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]]);
        }
        m
    }

    fn stage(frames: usize) -> UsdStage<'static> {
        UsdStage {
            root: "Bake",
            fps: 30.0,
            first_time_code: 1,
            frames,
            up_axis: UpAxis::Z,
            meters_per_unit: 0.01,
            doc: "a \"test\"",
        }
    }

    fn frame(k: f32) -> Vec<Vec3> {
        vec![
            Vec3::new(k, 0.5, -0.25),
            Vec3::new(1.0, k, 1e-7),
            Vec3::new(-2.0, 0.1, k),
        ]
    }

    #[test]
    fn two_meshes_two_frames_match_hand_written_usda() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.usda");
        let (g, b) = (triangle(true), triangle(false));
        let meshes = [
            UsdMesh {
                name: "Garment",
                topology: &g,
            },
            UsdMesh {
                name: "Body",
                topology: &b,
            },
        ];
        let mut w = UsdWriter::create(&path, &stage(2), &meshes).unwrap();
        for k in [0.0, 3.0] {
            let (f, body) = (frame(k), frame(k + 1.0));
            w.write_frame(&[&f, &body]).unwrap();
        }
        assert_eq!(w.frames_written(), 2);
        // While writing, the body's samples wait in a hidden spill file beside the output.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
        w.finish().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let expected = r#"#usda 1.0
(
    defaultPrim = "Bake"
    doc = "a \"test\""
    endTimeCode = 2
    framesPerSecond = 30
    metersPerUnit = 0.01
    startTimeCode = 1
    timeCodesPerSecond = 30
    upAxis = "Z"
)

def Xform "Bake"
{
    def Mesh "Garment"
    {
        uniform bool doubleSided = 1
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        texCoord2f[] primvars:st = [(0, 0), (1, 0), (0.5, 1)] (
            interpolation = "vertex"
        )
        uniform token subdivisionScheme = "none"
        point3f[] points.timeSamples = {
            1: [(0, 0.5, -0.25), (1, 0, 0.0000001), (-2, 0.1, 0)],
            2: [(3, 0.5, -0.25), (1, 3, 0.0000001), (-2, 0.1, 3)],
        }
        float3[] extent.timeSamples = {
            1: [(-2, 0, -0.25), (1, 0.5, 0.0000001)],
            2: [(-2, 0.1, -0.25), (3, 3, 3)],
        }
    }
    def Mesh "Body"
    {
        uniform bool doubleSided = 1
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        uniform token subdivisionScheme = "none"
        point3f[] points.timeSamples = {
            1: [(1, 0.5, -0.25), (1, 1, 0.0000001), (-2, 0.1, 1)],
            2: [(4, 0.5, -0.25), (1, 4, 0.0000001), (-2, 0.1, 4)],
        }
        float3[] extent.timeSamples = {
            1: [(-2, 0.1, -0.25), (1, 1, 1)],
            2: [(-2, 0.1, -0.25), (4, 4, 4)],
        }
    }
}
"#;
        assert_eq!(text, expected);
        // Only the final file is left: the spill file is gone.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn bad_frames_and_unfinished_writes_leave_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("b.usda");
        let (g, b) = (triangle(false), triangle(false));
        let meshes = [
            UsdMesh {
                name: "Garment",
                topology: &g,
            },
            UsdMesh {
                name: "Body",
                topology: &b,
            },
        ];
        let mut w = UsdWriter::create(&path, &stage(2), &meshes).unwrap();
        let f = frame(0.0);
        assert!(w.write_frame(&[&f]).is_err(), "one mesh missing");
        assert!(w.write_frame(&[&f, &f[..2]]).is_err(), "short body");
        let mut nan = f.clone();
        nan[2].z = f32::NAN;
        let err = w.write_frame(&[&f, &nan]).unwrap_err();
        assert!(err.to_string().ends_with("b.usda"), "{err}");
        w.write_frame(&[&f, &f]).unwrap();
        let err = w.finish().unwrap_err();
        assert_eq!(
            err.to_string(),
            format!("1 of 2 frames written: {}", path.display())
        );
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        // Dropped half-way: no file either.
        let mut w = UsdWriter::create(&path, &stage(1), &meshes).unwrap();
        w.write_frame(&[&f, &f]).unwrap();
        assert!(
            w.write_frame(&[&f, &f]).is_err(),
            "more frames than announced"
        );
        drop(w);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn invalid_stages_are_refused_before_any_file_exists() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.usda");
        let g = triangle(false);
        let one = |name| [UsdMesh { name, topology: &g }];
        let bad = [
            UsdStage {
                root: "1root",
                ..stage(1)
            },
            UsdStage {
                fps: 0.0,
                ..stage(1)
            },
            UsdStage {
                meters_per_unit: f64::NAN,
                ..stage(1)
            },
            stage(0),
        ];
        for s in &bad {
            assert!(UsdWriter::create(&path, s, &one("Garment")).is_err());
        }
        assert!(UsdWriter::create(&path, &stage(1), &one("t-shirt")).is_err());
        assert!(UsdWriter::create(&path, &stage(1), &[]).is_err());
        let twice = [one("A")[0], one("A")[0]];
        assert!(UsdWriter::create(&path, &stage(1), &twice).is_err());
        let mut broken = triangle(false);
        broken.faces.push([0, 1, 7]);
        let m = [UsdMesh {
            name: "M",
            topology: &broken,
        }];
        assert!(UsdWriter::create(&path, &stage(1), &m).is_err());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        // A missing folder: an I/O error that ends with the path.
        let missing = dir.path().join("missing/d.usda");
        let err = UsdWriter::create(&missing, &stage(1), &one("G"))
            .err()
            .unwrap();
        assert!(err.to_string().ends_with("missing/d.usda"), "{err}");
    }

    #[test]
    fn a_folder_without_write_permission_is_a_clear_error() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let locked = dir.path().join("locked");
        std::fs::create_dir(&locked).unwrap();
        std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o555)).unwrap();
        if File::create(locked.join("probe")).is_ok() {
            println!("skipped: this user (root?) writes into read-only folders");
            return;
        }
        let g = triangle(false);
        let mesh = [UsdMesh {
            name: "G",
            topology: &g,
        }];
        let err = UsdWriter::create(&locked.join("e.usda"), &stage(1), &mesh)
            .err()
            .unwrap();
        let text = err.to_string();
        assert!(text.contains("ermission denied"), "{text}");
        assert!(text.ends_with("locked/e.usda"), "{text}");
        assert_eq!(std::fs::read_dir(&locked).unwrap().count(), 0);
    }
}
