//! Bake layer: runs a trained model (or the reference simulator) over a motion and writes the
//! garment (and optionally the body and the rest-space shapes) as PC2, MDD, an OBJ sequence,
//! a USD point cache or a glTF with morph targets, optionally in a destination tool's
//! convention (a [`Preset`]). Frames stream straight into the writers where the format allows
//! (everything but glTF, whose morph basis needs the whole sequence), every writer is atomic,
//! and a failed bake leaves no file behind.
//!
//! The neural model runs at its training frame rate (its recurrent state is tied to that time
//! step); output frames at another rate are interpolated linearly between model frames.

mod frames;
mod sink;

pub use frames::{FrameSource, ModelSource, SimulatorSource};
pub use neural_cloth_core::io::export::Preset;

use std::path::{Path, PathBuf};

use serde::Serialize;

use neural_cloth_core::geometry::Vec3;
use neural_cloth_core::io::export::{
    BakedSequence, Convention, ExportError, GltfExportOptions, write_glb,
};
use neural_cloth_core::scene::{Avatar, Garment, Motion, Pose};

/// Output formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BakeFormat {
    /// PC2 point cache (Blender Mesh Cache, 3ds Max).
    Pc2,
    /// MDD point cache.
    Mdd,
    /// One OBJ file per frame in a folder.
    Obj,
    /// GLB with skeleton, animation, skinned garment and morph targets.
    Gltf,
    /// USD text stage (`.usda`): the garment (and body) as meshes with time-sampled points.
    Usd,
}

impl BakeFormat {
    /// The usual file extension (the OBJ sequence is a folder).
    pub fn extension(self) -> &'static str {
        match self {
            BakeFormat::Pc2 => "pc2",
            BakeFormat::Mdd => "mdd",
            BakeFormat::Obj => "",
            BakeFormat::Gltf => "glb",
            BakeFormat::Usd => "usda",
        }
    }

    /// Parses a format name (`pc2`, `mdd`, `obj`, `gltf`/`glb`, `usd`/`usda`).
    pub fn parse(name: &str) -> Option<Self> {
        match name.to_ascii_lowercase().as_str() {
            "pc2" => Some(Self::Pc2),
            "mdd" => Some(Self::Mdd),
            "obj" => Some(Self::Obj),
            "gltf" | "glb" => Some(Self::Gltf),
            "usd" | "usda" => Some(Self::Usd),
            _ => None,
        }
    }

    /// Whether a [`Preset`] applies: glTF is defined as Y up, metres, right-handed, and every
    /// glTF importer converts to its own convention.
    pub fn takes_preset(self) -> bool {
        self != BakeFormat::Gltf
    }

    /// Rough size in bytes of the garment output (`faces` triangles, `points` vertices per
    /// frame), for showing before a bake; USD text is estimated at 36 bytes a point.
    pub fn estimate_bytes(self, frames: usize, points: usize, faces: usize) -> u64 {
        let (frames, points, faces) = (frames as u64, points as u64, faces as u64);
        match self {
            BakeFormat::Pc2 => 32 + frames * points * 12,
            BakeFormat::Mdd => 8 + frames * (4 + points * 12),
            BakeFormat::Obj => frames * (points * 36 + faces * 24),
            BakeFormat::Usd => 1024 + faces * 24 + points * 16 + frames * (points * 36 + 80),
            BakeFormat::Gltf => points * 60 + faces * 12 + frames * 64,
        }
    }
}

/// What to bake.
#[derive(Clone, Debug)]
pub struct BakeOptions {
    /// Output format.
    pub format: BakeFormat,
    /// Output path (a file; a folder for the OBJ sequence). Extra outputs (body, rest shapes)
    /// go next to it with `.body` / `.rest` before the extension.
    pub out: PathBuf,
    /// Output frame rate, (0, 1000], default 30.
    pub fps: f32,
    /// First output frame (inclusive), default 0.
    pub start_frame: usize,
    /// Last output frame (exclusive); default: the end of the motion.
    pub end_frame: Option<usize>,
    /// Dynamic weight `w` in [0, 2] (1 = trained behaviour); neural model only.
    pub w: f32,
    /// Also write the body (PC2/MDD/OBJ: a second file; glTF: the body mesh; USD: a second
    /// mesh in the stage). Default false.
    pub include_body: bool,
    /// Also write the unskinned rest-space garment (template + offsets) as a sibling file;
    /// PC2/MDD/OBJ/USD only.
    pub rest_shapes: bool,
    /// Morph targets of the glTF export, 0..=64, default 16.
    pub morph_targets: usize,
    /// Destination tool whose axis, units, handedness and frame numbering to write in; None
    /// (the default) keeps the program's own (Y up, metres, right-handed, frames from 0).
    /// Not for glTF.
    pub preset: Option<Preset>,
}

impl BakeOptions {
    /// The convention the outputs are written in: the preset's, kept right-handed for OBJ and
    /// USD (whose importers mirror into a left-handed space themselves).
    pub fn convention(&self) -> Convention {
        let c = self.preset.map_or(Convention::NATIVE, Preset::convention);
        match self.format {
            BakeFormat::Obj | BakeFormat::Usd => c.right_handed(),
            _ => c,
        }
    }
}

impl Default for BakeOptions {
    fn default() -> Self {
        Self {
            format: BakeFormat::Pc2,
            out: PathBuf::from("bake.pc2"),
            fps: 30.0,
            start_frame: 0,
            end_frame: None,
            w: 1.0,
            include_body: false,
            rest_shapes: false,
            morph_targets: 16,
            preset: None,
        }
    }
}

/// What a bake wrote.
#[derive(Clone, Debug, Serialize)]
pub struct BakeReport {
    /// Files (or folders) written.
    pub outputs: Vec<PathBuf>,
    /// Output frames.
    pub frames: usize,
    /// Garment vertices per frame.
    pub vertices: usize,
    /// glTF only: morph targets and the compression's largest vertex error in metres.
    pub morph_targets: Option<usize>,
    /// glTF only: largest rest-space vertex error of the morph-target compression, metres.
    pub max_error_m: Option<f32>,
}

/// Errors of a bake.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    /// A setting is out of range.
    #[error("{0}")]
    Invalid(String),
    /// The model or simulator failed.
    #[error("{0}")]
    Source(String),
    /// Writing failed.
    #[error(transparent)]
    Export(#[from] ExportError),
    /// The user cancelled.
    #[error("bake cancelled")]
    Cancelled,
}

/// Output frame range `[start, end)` of `motion` at `fps`.
pub fn frame_range(motion: &Motion, options: &BakeOptions) -> Result<(usize, usize), BakeError> {
    if !(options.fps.is_finite() && options.fps > 0.0 && options.fps <= 1000.0) {
        return Err(BakeError::Invalid(format!(
            "frame rate {} is not in (0, 1000]",
            options.fps
        )));
    }
    let total = (motion.duration_secs() * options.fps + 1e-3).floor() as usize + 1;
    let end = options.end_frame.unwrap_or(total).min(total);
    if options.start_frame >= end {
        return Err(BakeError::Invalid(format!(
            "frame range {}..{end} is empty (the motion has {total} frames at {} fps)",
            options.start_frame, options.fps
        )));
    }
    Ok((options.start_frame, end))
}

/// Checks `w` and the output folder before any work starts.
pub fn check_options(options: &BakeOptions) -> Result<(), BakeError> {
    if !(options.w.is_finite() && (0.0..=2.0).contains(&options.w)) {
        return Err(BakeError::Invalid(format!(
            "w = {} is outside [0, 2]",
            options.w
        )));
    }
    if let (Some(preset), false) = (options.preset, options.format.takes_preset()) {
        return Err(BakeError::Invalid(format!(
            "the {preset} preset does not apply to glTF: glTF is always Y up, metres, \
             right-handed and every importer converts it (use usd, pc2, mdd or obj)"
        )));
    }
    if options.morph_targets > 64 {
        return Err(BakeError::Invalid(format!(
            "{} morph targets (at most 64)",
            options.morph_targets
        )));
    }
    let parent = options
        .out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !parent.is_dir() {
        return Err(BakeError::Export(ExportError::Format {
            reason: "output folder does not exist".into(),
            path: parent.to_path_buf(),
        }));
    }
    Ok(())
}

/// `out` with `tag` inserted before the extension (`shirt.pc2` → `shirt.body.pc2`).
pub fn sibling_path(out: &Path, tag: &str) -> PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "bake".into());
    let name = match out.extension() {
        Some(ext) => format!("{stem}.{tag}.{}", ext.to_string_lossy()),
        None => format!("{stem}.{tag}"),
    };
    out.with_file_name(name)
}

/// Bakes `motion` with `source` into the files of `options`. `progress(done, total)` is called
/// after each output frame; returning false cancels (and removes every partial output).
pub fn bake(
    avatar: &Avatar,
    garment: &Garment,
    motion: &Motion,
    source: &mut dyn FrameSource,
    options: &BakeOptions,
    progress: &mut dyn FnMut(usize, usize) -> bool,
) -> Result<BakeReport, BakeError> {
    check_options(options)?;
    let (start, end) = frame_range(motion, options)?;
    let frames = end - start;
    let mut sampler = frames::Resampler::new(motion, source, options.w)?;
    let v = garment.vertex_count();
    if options.format == BakeFormat::Gltf {
        let mut poses: Vec<Pose> = Vec::with_capacity(frames);
        let mut offsets: Vec<Vec<Vec3>> = Vec::with_capacity(frames);
        for (k, f) in (start..end).enumerate() {
            let t = f as f32 / options.fps;
            let out = sampler.at(t)?;
            poses.push(motion.sample(t));
            offsets.push(
                out.rest
                    .iter()
                    .zip(&garment.mesh.positions)
                    .map(|(r, p)| r - p)
                    .collect(),
            );
            if !progress(k + 1, frames) {
                return Err(BakeError::Cancelled);
            }
        }
        let name = motion.name.clone();
        let seq = BakedSequence {
            name: &name,
            fps: options.fps,
            poses: &poses,
            rest_offsets: &offsets,
        };
        let gltf = GltfExportOptions {
            max_morph_targets: options.morph_targets,
            include_body: options.include_body,
        };
        let report = write_glb(&options.out, avatar, garment, &seq, &gltf)?;
        return Ok(BakeReport {
            outputs: vec![options.out.clone()],
            frames,
            vertices: v,
            morph_targets: Some(report.morph_targets),
            max_error_m: Some(report.max_error_m),
        });
    }
    let mut sinks = sink::Sinks::create(options, avatar, garment, frames, start)?;
    for (k, f) in (start..end).enumerate() {
        let t = f as f32 / options.fps;
        let out = sampler.at(t)?;
        let body = match sinks.wants_body() {
            true => Some(avatar.pose_vertices(&motion.sample(t))),
            false => None,
        };
        sinks.write(&out.garment, body.as_deref(), &out.rest)?;
        if !progress(k + 1, frames) {
            return Err(BakeError::Cancelled);
        }
    }
    let outputs = sinks.finish()?;
    Ok(BakeReport {
        outputs,
        frames,
        vertices: v,
        morph_targets: None,
        max_error_m: None,
    })
}
