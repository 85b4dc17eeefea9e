//! The export dialog's settings and the hook that bakes and writes a sequence (the same baking
//! the CLI's `bake` runs; the app only collects the request and shows the result).

use std::path::PathBuf;
use std::sync::Arc;

use crate::model::InferenceWeights;
use crate::scene::{Avatar, Garment};

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
}

impl ExportFormat {
    /// All formats in menu order.
    pub const ALL: [ExportFormat; 4] = [
        ExportFormat::Glb,
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
        }
    }

    /// File extension (for the OBJ sequence, of each frame file).
    pub fn extension(self) -> &'static str {
        match self {
            Self::Glb => "glb",
            Self::Pc2 => "pc2",
            Self::Mdd => "mdd",
            Self::ObjSequence => "obj",
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
}

/// Bakes and writes sequences; returns a one-line summary or an error for the UI.
pub trait Exporter: Send {
    /// Runs the export (blocking; the app calls it from the export dialog).
    fn export(&mut self, request: ExportRequest) -> Result<String, String>;
}
