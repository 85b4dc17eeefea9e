//! The export dialog's settings, its size estimate and the hook that bakes and writes a
//! sequence (the same baking the CLI's `bake` runs; the app only collects the request, runs it
//! on a background thread and shows progress and the result).

use std::path::PathBuf;
use std::sync::Arc;

use crate::bake::{BakeFormat, BakeOptions, Preset, frame_range};
use crate::model::InferenceWeights;
use crate::scene::{Avatar, Garment, Motion};

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

    /// File extension (for the OBJ sequence, of each frame file).
    pub fn extension(self) -> &'static str {
        match self {
            Self::Glb => "glb",
            Self::Pc2 => "pc2",
            Self::Mdd => "mdd",
            Self::ObjSequence => "obj",
            Self::Usd => "usda",
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
    /// Outcome of the last export: a summary or an error.
    pub last_result: Option<Result<String, String>>,
}

impl Default for ExportSettings {
    fn default() -> Self {
        Self {
            open: false,
            format: ExportFormat::Glb,
            path: "export/garment.glb".into(),
            motion: 0,
            preset: None,
            last_result: None,
        }
    }
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
    /// Weights to bake with (None: the untrained or template preview is not exportable).
    pub weights: Option<Arc<InferenceWeights>>,
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
    ) -> Result<String, String>;
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
    /// Frames and size of baking `motion` at `fps` with the app's settings (the body is
    /// always included); an error when the frame rate or the motion gives no frame.
    pub fn of(
        format: ExportFormat,
        motion: &Motion,
        fps: f32,
        garment: &Garment,
        avatar: &Avatar,
    ) -> Result<Self, String> {
        let options = BakeOptions {
            fps,
            ..Default::default()
        };
        let (start, end) = frame_range(motion, &options).map_err(|e| e.to_string())?;
        let frames = end - start;
        let f = format.bake_format();
        let garment_bytes =
            f.estimate_bytes(frames, garment.vertex_count(), garment.mesh.faces.len());
        let body = &avatar.bind_mesh;
        let body_bytes = match f {
            // The glTF body is one static skinned mesh, not a per-frame cache.
            BakeFormat::Gltf => body.positions.len() as u64 * 60 + body.faces.len() as u64 * 12,
            _ => f.estimate_bytes(frames, body.positions.len(), body.faces.len()),
        };
        Ok(Self {
            frames,
            bytes: garment_bytes + body_bytes,
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
    fn the_estimate_counts_the_frames_of_the_bake() {
        let scene = crate::scene::procedural::default_scene().unwrap();
        let motion = &scene.motions[0].0;
        let e = ExportEstimate::of(
            ExportFormat::Pc2,
            motion,
            30.0,
            &scene.garment,
            &scene.avatar,
        )
        .unwrap();
        let frames = (motion.duration_secs() * 30.0 + 1e-3).floor() as usize + 1;
        assert_eq!(e.frames, frames);
        // PC2: a 32-byte header and 12 bytes a point a frame, garment and body.
        let points = scene.garment.vertex_count() + scene.avatar.bind_mesh.positions.len();
        assert_eq!(e.bytes, 64 + (frames * points * 12) as u64);
        assert!(e.summary().starts_with(&format!("{frames} frames, about ")));
        let usd = ExportEstimate::of(
            ExportFormat::Usd,
            motion,
            30.0,
            &scene.garment,
            &scene.avatar,
        )
        .unwrap();
        assert!(usd.bytes > e.bytes * 2, "text is larger than binary");
        assert!(
            ExportEstimate::of(
                ExportFormat::Usd,
                motion,
                0.0,
                &scene.garment,
                &scene.avatar
            )
            .is_err()
        );
    }
}
