//! The export dialog's settings, its size estimate and the hook that bakes and writes a
//! sequence (the same baking the CLI's `bake` runs; the app only collects the request, runs it
//! on a background thread and shows progress and the result).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use neural_cloth_bake::{
    BakeFormat, BakeOptions, BakeReport, ModelSource, Preset, bake, frame_range, sibling_path,
};
use neural_cloth_core::scene::{Avatar, Garment, Motion};
use neural_cloth_model::{InferenceOptions, ModelArtifact};

use super::error::AppError;

/// Output formats of a baked sequence.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ExportFormat {
    /// glTF binary: skinned garment, animation and neural offsets as morph targets.
    #[default]
    Glb,
    /// PC2 point cache (Blender Mesh Cache).
    Pc2,
    /// MDD point cache.
    Mdd,
    /// One OBJ file per frame.
    ObjSequence,
    /// USD stage (`.usda`) with time-sampled points of the garment and the body.
    Usd,
}

impl ExportFormat {
    /// All formats in menu order.
    pub const ALL: [ExportFormat; 5] = [
        ExportFormat::Glb,
        ExportFormat::Usd,
        ExportFormat::Pc2,
        ExportFormat::Mdd,
        ExportFormat::ObjSequence,
    ];

    /// Menu label.
    pub fn label(self) -> &'static str {
        match self {
            Self::Glb => "glTF (.glb, morph targets)",
            Self::Pc2 => "PC2 point cache",
            Self::Mdd => "MDD point cache",
            Self::ObjSequence => "OBJ sequence",
            Self::Usd => "USD point cache (.usda)",
        }
    }

    /// The bake layer's format.
    pub fn bake_format(self) -> BakeFormat {
        match self {
            Self::Glb => BakeFormat::Gltf,
            Self::Pc2 => BakeFormat::Pc2,
            Self::Mdd => BakeFormat::Mdd,
            Self::ObjSequence => BakeFormat::Obj,
            Self::Usd => BakeFormat::Usd,
        }
    }

    /// Whether a destination preset applies (every format but glTF).
    pub fn takes_preset(self) -> bool {
        self.bake_format().takes_preset()
    }

    /// `path` with this format's extension (the OBJ sequence, a folder, gets none).
    pub fn with_extension(self, path: &str) -> String {
        let p = std::path::Path::new(path.trim());
        let ext = match self {
            Self::ObjSequence => "",
            f => f.extension(),
        };
        p.with_extension(ext).display().to_string()
    }

    /// The format a typed path names by its extension (`.glb`, `.usda`, `.pc2`, `.mdd`); None
    /// for no or another extension (the OBJ sequence is a folder and has none).
    pub fn from_path(path: &str) -> Option<Self> {
        let ext = Path::new(path.trim())
            .extension()?
            .to_str()?
            .to_ascii_lowercase();
        Self::ALL
            .into_iter()
            .find(|f| *f != Self::ObjSequence && f.extension() == ext)
    }

    /// Whether the output is a point cache (PC2, MDD): points only, applied to a mesh of the
    /// same vertex order (which [`write_rest_obj`] can write beside it).
    pub fn is_point_cache(self) -> bool {
        matches!(self, Self::Pc2 | Self::Mdd)
    }

    /// Whether "also write the body" makes a sibling file (PC2, MDD, OBJ); glTF and USD put
    /// the body into the same file.
    pub fn body_is_a_sibling(self) -> bool {
        matches!(self, Self::Pc2 | Self::Mdd | Self::ObjSequence)
    }

    /// File extension (for the OBJ sequence, of each frame file).
    pub fn extension(self) -> &'static str {
        match self.extensions() {
            [ext] => ext,
            _ => "",
        }
    }

    /// [`Self::extension`] as a list, as file-dialog filters take it.
    pub fn extensions(self) -> &'static [&'static str] {
        match self {
            Self::Glb => &["glb"],
            Self::Pc2 => &["pc2"],
            Self::Mdd => &["mdd"],
            Self::ObjSequence => &["obj"],
            Self::Usd => &["usda"],
        }
    }
}

/// State of the export dialog.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportSettings {
    /// Whether the dialog is open.
    pub open: bool,
    /// Chosen format.
    pub format: ExportFormat,
    /// Output file (or folder for the OBJ sequence), as typed.
    pub path: String,
    /// Motion to bake (index into the avatar's motions).
    pub motion: usize,
    /// Destination tool (None: the program's own convention); ignored for glTF.
    pub preset: Option<Preset>,
    /// Also write the posed body (PC2/MDD/OBJ: a `.body` sibling; glTF, USD: in the same
    /// file). Default false.
    pub include_body: bool,
    /// PC2/MDD: also write the garment's rest pose as an OBJ of the same vertex order (what
    /// Blender's Mesh Cache modifier is put on). Default false.
    pub rest_obj: bool,
    /// Existing outputs the user was asked about before overwriting (Some: the question is
    /// shown and the export waits for the answer).
    pub confirm_overwrite: Option<Vec<PathBuf>>,
}

impl Default for ExportSettings {
    fn default() -> Self {
        Self {
            open: false,
            format: ExportFormat::Glb,
            path: "export/garment.glb".into(),
            motion: 0,
            preset: None,
            include_body: false,
            rest_obj: false,
            confirm_overwrite: None,
        }
    }
}

impl ExportSettings {
    /// Opens the dialog on `motion`, the motion on screen.
    pub fn show_for(&mut self, motion: usize) {
        self.open = true;
        self.motion = motion;
        self.confirm_overwrite = None;
    }

    /// Takes the path chosen in the dialog's file browser, asked for as `format`: a file's
    /// extension names its format (the OBJ sequence's folder names none); a pending overwrite
    /// question is withdrawn.
    pub fn set_picked_path(&mut self, path: &Path, format: ExportFormat) {
        self.path = path.display().to_string();
        self.format = match format {
            ExportFormat::ObjSequence => format,
            _ => ExportFormat::from_path(&self.path).unwrap_or(format),
        };
        self.confirm_overwrite = None;
    }

    /// Every file (or folder) the export will write, as typed (relative to the working
    /// folder): the output, the body's sibling when asked for, the rest-pose OBJ when asked for.
    pub fn outputs(&self) -> Vec<PathBuf> {
        let out = PathBuf::from(self.path.trim());
        let mut outputs = vec![out.clone()];
        if self.include_body && self.format.body_is_a_sibling() {
            outputs.push(sibling_path(&out, "body"));
        }
        if self.rest_obj && self.format.is_point_cache() {
            outputs.push(rest_obj_path(&out));
        }
        outputs
    }
}

/// Where the rest-pose OBJ of a point cache goes: beside it, same name, `.obj`
/// (`walk.pc2` → `walk.obj`).
pub fn rest_obj_path(out: &Path) -> PathBuf {
    out.with_extension("obj")
}

/// Writes `garment`'s rest pose (template positions, faces, UVs, in its vertex order, the
/// order of every baked point cache) to `path` as one OBJ, in `preset`'s axis and units as
/// the OBJ sequence writes them. Atomic: a failure leaves no file.
pub fn write_rest_obj(
    garment: &Garment,
    preset: Option<Preset>,
    path: &Path,
) -> Result<PathBuf, AppError> {
    let convention = BakeOptions {
        format: BakeFormat::Obj,
        preset,
        ..Default::default()
    }
    .convention();
    let positions = convention.apply_all(&garment.mesh.positions);
    let text = neural_cloth_core::io::export::obj_seq::obj_text(
        &positions,
        &garment.mesh.faces,
        garment.mesh.uvs.as_deref(),
        &format!(
            "rest pose of {}, the vertex order of its point caches; preset {}",
            garment.name,
            preset.map_or("none", Preset::name)
        ),
    );
    neural_cloth_core::io::export::atomic::write_atomic(path, text.as_bytes())?;
    Ok(path.to_path_buf())
}

/// Everything needed to bake one sequence.
#[derive(Clone, Debug)]
pub struct ExportRequest {
    /// Avatar with motions.
    pub avatar: Arc<Avatar>,
    /// Garment.
    pub garment: Arc<Garment>,
    /// Motion index.
    pub motion: usize,
    /// Weights to bake with, with the settings they were trained with (None: the untrained
    /// or template preview is not exportable).
    pub weights: Option<Arc<ModelArtifact>>,
    /// Dynamic weight `w` in [0, 2].
    pub w: f32,
    /// Frame rate of the bake, fps.
    pub fps: f32,
    /// Output format.
    pub format: ExportFormat,
    /// Output path.
    pub path: PathBuf,
    /// Destination tool (None: the program's own convention).
    pub preset: Option<Preset>,
    /// Also write the posed body ([`ExportSettings::include_body`]).
    pub include_body: bool,
    /// Also write the rest-pose OBJ of a point cache ([`write_rest_obj`]).
    pub rest_obj: bool,
}

/// Bakes and writes sequences; returns a one-line summary or an error for the UI.
pub trait Exporter: Send + Sync {
    /// Runs the export (blocking; the app calls it on a background thread).
    /// `progress(done, total)` is called after each frame; returning false cancels the bake,
    /// which then removes its partial output.
    fn export(
        &self,
        request: ExportRequest,
        progress: &mut dyn FnMut(usize, usize) -> bool,
    ) -> Result<String, AppError>;
}

/// The exporter of the app: bakes with the model's own settings (its training rate and
/// descriptor settings travel with the weights) through the `bake` layer, as `neural-cloth
/// bake` does.
#[derive(Clone, Copy, Debug, Default)]
pub struct ModelExporter;

impl Exporter for ModelExporter {
    fn export(
        &self,
        request: ExportRequest,
        progress: &mut dyn FnMut(usize, usize) -> bool,
    ) -> Result<String, AppError> {
        let model = request.weights.as_deref().ok_or(AppError::Missing(
            "train a model first: there are no weights to bake with",
        ))?;
        let motion = request
            .avatar
            .motions
            .get(request.motion)
            .ok_or(AppError::Missing("no such motion"))?;
        // The model runs at the rate it was trained at; the bake resamples to `request.fps`.
        let options = InferenceOptions {
            skin_body: false,
            ..Default::default()
        };
        let engine = model.engine(&request.avatar, &request.garment, options)?;
        let options = BakeOptions {
            format: request.format.bake_format(),
            out: request.path.clone(),
            fps: request.fps,
            w: request.w,
            include_body: request.include_body,
            preset: request.preset,
            ..Default::default()
        };
        let report = bake(
            &request.avatar,
            &request.garment,
            motion,
            &mut ModelSource::new(engine),
            &options,
            progress,
        )?;
        let mut outputs = report.outputs.clone();
        if request.rest_obj && request.format.is_point_cache() {
            let path = rest_obj_path(&options.out);
            outputs.push(write_rest_obj(&request.garment, request.preset, &path)?);
        }
        Ok(export_summary(&report, &outputs))
    }
}

/// "wrote N frames to PATHS" with the morph targets and their error for glTF.
fn export_summary(report: &BakeReport, outputs: &[PathBuf]) -> String {
    let mut line = format!(
        "wrote {} frames to {}",
        report.frames,
        outputs
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    if let (Some(t), Some(e)) = (report.morph_targets, report.max_error_m) {
        line.push_str(&format!(
            " ({t} morph targets, max error {:.2} mm)",
            e * 1e3
        ));
    }
    line
}

/// What an export will write, shown before it starts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExportEstimate {
    /// Output frames.
    pub frames: usize,
    /// Approximate size of all outputs in bytes.
    pub bytes: u64,
}

impl ExportEstimate {
    /// Frames and size of baking `motion` at `fps` with the dialog's `settings` (format, body,
    /// rest-pose OBJ); an error when the frame rate or the motion gives no frame.
    pub fn of(
        settings: &ExportSettings,
        motion: &Motion,
        fps: f32,
        garment: &Garment,
        avatar: &Avatar,
    ) -> Result<Self, AppError> {
        let format = settings.format;
        let options = BakeOptions {
            fps,
            ..Default::default()
        };
        let (start, end) = frame_range(motion, &options)?;
        let frames = end - start;
        let f = format.bake_format();
        let garment_bytes =
            f.estimate_bytes(frames, garment.vertex_count(), garment.mesh.faces.len());
        let body = &avatar.bind_mesh;
        let body_bytes = match (settings.include_body, f) {
            (false, _) => 0,
            // The glTF body is one static skinned mesh, not a per-frame cache.
            (true, BakeFormat::Gltf) => {
                body.positions.len() as u64 * 60 + body.faces.len() as u64 * 12
            }
            (true, _) => f.estimate_bytes(frames, body.positions.len(), body.faces.len()),
        };
        let rest_bytes = match settings.rest_obj && format.is_point_cache() {
            true => {
                BakeFormat::Obj.estimate_bytes(1, garment.vertex_count(), garment.mesh.faces.len())
            }
            false => 0,
        };
        Ok(Self {
            frames,
            bytes: garment_bytes + body_bytes + rest_bytes,
        })
    }

    /// "N frames, about S" with S in kB, MB or GB.
    pub fn summary(&self) -> String {
        let b = self.bytes as f64;
        let size = if b < 1e6 {
            format!("{:.0} kB", b / 1e3)
        } else if b < 1e9 {
            format!("{:.1} MB", b / 1e6)
        } else {
            format!("{:.2} GB", b / 1e9)
        };
        format!("{} frames, about {size}", self.frames)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_format_maps_to_the_bake_layer_and_its_extension() {
        assert_eq!(ExportFormat::Usd.bake_format(), BakeFormat::Usd);
        assert!(ExportFormat::Usd.takes_preset());
        assert!(!ExportFormat::Glb.takes_preset());
        assert_eq!(
            ExportFormat::Usd.with_extension("export/garment.glb"),
            "export/garment.usda"
        );
        assert_eq!(
            ExportFormat::ObjSequence.with_extension("export/garment.usda"),
            "export/garment"
        );
        for f in ExportFormat::ALL {
            assert_eq!(
                ExportFormat::ALL
                    .iter()
                    .filter(|g| g.bake_format() == f.bake_format())
                    .count(),
                1
            );
        }
    }

    #[test]
    fn a_typed_extension_names_its_format() {
        assert_eq!(
            ExportFormat::from_path("a/walk.pc2"),
            Some(ExportFormat::Pc2)
        );
        assert_eq!(
            ExportFormat::from_path(" walk.MDD "),
            Some(ExportFormat::Mdd)
        );
        assert_eq!(
            ExportFormat::from_path("walk.usda"),
            Some(ExportFormat::Usd)
        );
        assert_eq!(ExportFormat::from_path("walk.glb"), Some(ExportFormat::Glb));
        assert_eq!(ExportFormat::from_path("walk.obj"), None);
        assert_eq!(ExportFormat::from_path("walk"), None);
        for f in ExportFormat::ALL {
            let path = f.with_extension("x/walk.glb");
            let back = ExportFormat::from_path(&path);
            assert!(back == Some(f) || f == ExportFormat::ObjSequence, "{path}");
        }
    }

    #[test]
    fn outputs_are_the_requested_files_only() {
        let mut s = ExportSettings {
            format: ExportFormat::Pc2,
            path: "out/walk.pc2".into(),
            ..Default::default()
        };
        assert_eq!(s.outputs(), vec![PathBuf::from("out/walk.pc2")]);
        s.include_body = true;
        s.rest_obj = true;
        assert_eq!(
            s.outputs(),
            ["out/walk.pc2", "out/walk.body.pc2", "out/walk.obj"].map(PathBuf::from)
        );
        // glTF keeps the body in its one file and has no rest OBJ.
        s.format = ExportFormat::Glb;
        s.path = "out/walk.glb".into();
        assert_eq!(s.outputs(), vec![PathBuf::from("out/walk.glb")]);
        s.show_for(3);
        assert!(s.open && s.motion == 3);
    }

    #[test]
    fn the_rest_obj_keeps_the_vertex_order_and_the_preset() {
        let scene = neural_cloth_core::scene::procedural::default_scene().unwrap();
        let dir = std::env::temp_dir().join(format!("nc-rest-obj-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("walk.obj");
        write_rest_obj(&scene.garment, Some(Preset::Maya), &path).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let numbers = |line: &str| -> Vec<f32> {
            line.split_whitespace()
                .skip(1)
                .map(|v| v.split('/').next().unwrap().parse().unwrap())
                .collect()
        };
        let points: Vec<Vec<f32>> = text
            .lines()
            .filter(|l| l.starts_with("v "))
            .map(numbers)
            .collect();
        let faces: Vec<Vec<f32>> = text
            .lines()
            .filter(|l| l.starts_with("f "))
            .map(numbers)
            .collect();
        let rest = &scene.garment.mesh;
        assert_eq!(points.len(), rest.positions.len());
        for (read, p) in points.iter().zip(&rest.positions) {
            let want = [p.x * 100.0, p.y * 100.0, p.z * 100.0];
            assert_eq!(
                read.as_slice(),
                want.as_slice(),
                "Maya: centimetres, same order"
            );
        }
        assert_eq!(faces.len(), rest.faces.len());
        for (read, f) in faces.iter().zip(&rest.faces) {
            assert_eq!(read.as_slice(), f.map(|i| (i + 1) as f32).as_slice());
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn the_estimate_counts_the_frames_of_the_bake() {
        let scene = neural_cloth_core::scene::procedural::default_scene().unwrap();
        let motion = &scene.motions[0].0;
        let pc2 = ExportSettings {
            format: ExportFormat::Pc2,
            include_body: true,
            ..Default::default()
        };
        let e = ExportEstimate::of(&pc2, motion, 30.0, &scene.garment, &scene.avatar).unwrap();
        let frames = (motion.duration_secs() * 30.0 + 1e-3).floor() as usize + 1;
        assert_eq!(e.frames, frames);
        // PC2: a 32-byte header and 12 bytes a point a frame, garment and body.
        let points = scene.garment.vertex_count() + scene.avatar.bind_mesh.positions.len();
        assert_eq!(e.bytes, 64 + (frames * points * 12) as u64);
        assert!(e.summary().starts_with(&format!("{frames} frames, about ")));
        let usd_settings = ExportSettings {
            format: ExportFormat::Usd,
            ..pc2.clone()
        };
        let usd =
            ExportEstimate::of(&usd_settings, motion, 30.0, &scene.garment, &scene.avatar).unwrap();
        assert!(usd.bytes > e.bytes * 2, "text is larger than binary");
        // Without the body, only the garment's points.
        let alone = ExportSettings {
            include_body: false,
            ..pc2.clone()
        };
        let alone = ExportEstimate::of(&alone, motion, 30.0, &scene.garment, &scene.avatar);
        assert_eq!(
            alone.unwrap().bytes,
            32 + (frames * scene.garment.vertex_count() * 12) as u64
        );
        assert!(
            ExportEstimate::of(&usd_settings, motion, 0.0, &scene.garment, &scene.avatar).is_err()
        );
    }
}
