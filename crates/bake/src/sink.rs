//! The streaming outputs of a bake: the garment cache and, on request, the body and the
//! rest-space shapes, in PC2, MDD, an OBJ sequence or USD, with the preset's convention applied
//! to every frame. PC2, MDD and OBJ write the body and the rest shapes as sibling files; USD puts
//! the body into the garment's stage as a second mesh and the rest shapes into a sibling stage.

use std::borrow::Cow;
use std::path::{Path, PathBuf};

use neural_cloth_core::geometry::{TriMesh, Vec3};
use neural_cloth_core::io::export::{
    Convention, ExportError, MddWriter, ObjSequenceWriter, Pc2Writer, UsdMesh, UsdStage, UsdWriter,
};
use neural_cloth_core::scene::{Avatar, Garment};

use super::{BakeFormat, BakeOptions, sibling_path};

/// One output file (or folder).
enum Sink {
    Pc2(Pc2Writer),
    Mdd(MddWriter),
    Obj(ObjSequenceWriter),
    Usd(UsdWriter),
}

/// Where frames go and how they are numbered.
struct Layout<'a> {
    format: BakeFormat,
    convention: Convention,
    /// Output frames.
    frames: usize,
    /// Number of the first output frame (PC2 start frame, USD time code, OBJ file number).
    first_number: usize,
    /// OBJ file number of the first frame.
    obj_first_number: usize,
    fps: f32,
    doc: &'a str,
}

impl Sink {
    fn create(layout: &Layout, path: &Path, meshes: &[UsdMesh]) -> Result<Self, ExportError> {
        let topology = meshes
            .first()
            .map(|m| m.topology)
            .ok_or_else(|| ExportError::Format {
                reason: "nothing to write".into(),
                path: path.to_path_buf(),
            })?;
        let points = topology.positions.len();
        Ok(match layout.format {
            BakeFormat::Pc2 => Sink::Pc2(Pc2Writer::create(
                path,
                points,
                layout.first_number as f32,
                1.0,
            )?),
            BakeFormat::Mdd => {
                Sink::Mdd(MddWriter::create(path, layout.frames, points, layout.fps)?)
            }
            BakeFormat::Usd => {
                let stage = UsdStage {
                    root: "Bake",
                    fps: layout.fps,
                    first_time_code: layout.first_number,
                    frames: layout.frames,
                    up_axis: layout.convention.up_axis,
                    meters_per_unit: layout.convention.meters_per_unit(),
                    doc: layout.doc,
                };
                Sink::Usd(UsdWriter::create(path, &stage, meshes)?)
            }
            BakeFormat::Obj | BakeFormat::Gltf => {
                let stem = path
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_else(|| "frame".into());
                Sink::Obj(ObjSequenceWriter::create_numbered(
                    path,
                    &stem,
                    topology,
                    layout.obj_first_number,
                )?)
            }
        })
    }

    /// Writes one frame: one point list per mesh (only USD holds more than one).
    fn write(&mut self, frame: &[&[Vec3]]) -> Result<(), ExportError> {
        let first = frame.first().copied().unwrap_or_default();
        match self {
            Sink::Pc2(w) => w.write_frame(first),
            Sink::Mdd(w) => w.write_frame(first),
            Sink::Obj(w) => w.write_frame(first),
            Sink::Usd(w) => w.write_frame(frame),
        }
    }

    fn finish(self) -> Result<PathBuf, ExportError> {
        match self {
            Sink::Pc2(w) => w.finish(),
            Sink::Mdd(w) => w.finish(),
            Sink::Obj(w) => w.finish(),
            Sink::Usd(w) => w.finish(),
        }
    }
}

/// Every output of a streaming bake.
pub(super) struct Sinks {
    garment: Sink,
    /// The body as its own file (PC2, MDD, OBJ).
    body: Option<Sink>,
    /// The body as the second mesh of the garment's USD stage.
    body_in_garment: bool,
    rest: Option<Sink>,
    convention: Convention,
}

impl Sinks {
    /// Opens the outputs of `options` for `frames` frames starting at output frame `start`.
    pub(super) fn create(
        options: &BakeOptions,
        avatar: &Avatar,
        garment: &Garment,
        frames: usize,
        start: usize,
    ) -> Result<Self, ExportError> {
        let convention = options.convention();
        let doc = format!(
            "neural-cloth bake of '{}', {} fps, preset {}",
            garment.name,
            options.fps,
            options.preset.map_or("none", |p| p.name()),
        );
        let layout = Layout {
            format: options.format,
            convention,
            frames,
            first_number: convention.frame_base + start,
            obj_first_number: match options.preset {
                Some(_) => convention.frame_base + start,
                None => 1,
            },
            fps: options.fps,
            doc: &doc,
        };
        let usd = options.format == BakeFormat::Usd;
        let body_in_garment = usd && options.include_body;
        let garment_meshes = match body_in_garment {
            true => vec![
                mesh("Garment", &garment.mesh),
                mesh("Body", &avatar.bind_mesh),
            ],
            false => vec![mesh("Garment", &garment.mesh)],
        };
        let garment_sink = Sink::create(&layout, &options.out, &garment_meshes)?;
        let body = match options.include_body && !usd {
            true => Some(Sink::create(
                &layout,
                &sibling_path(&options.out, "body"),
                &[mesh("Body", &avatar.bind_mesh)],
            )?),
            false => None,
        };
        let rest = match options.rest_shapes {
            true => Some(Sink::create(
                &layout,
                &sibling_path(&options.out, "rest"),
                &[mesh("Garment", &garment.mesh)],
            )?),
            false => None,
        };
        Ok(Self {
            garment: garment_sink,
            body,
            body_in_garment,
            rest,
            convention,
        })
    }

    /// True when [`Sinks::write`] needs the posed body.
    pub(super) fn wants_body(&self) -> bool {
        self.body.is_some() || self.body_in_garment
    }

    /// Writes one frame of the posed garment, the posed body (when wanted) and the rest shape.
    pub(super) fn write(
        &mut self,
        garment: &[Vec3],
        body: Option<&[Vec3]>,
        rest: &[Vec3],
    ) -> Result<(), ExportError> {
        let c = self.convention;
        let garment = converted(c, garment);
        let body = body.map(|b| converted(c, b));
        match (&body, self.body_in_garment) {
            (Some(b), true) => self.garment.write(&[&garment, b])?,
            _ => self.garment.write(&[&garment])?,
        }
        if let (Some(sink), Some(b)) = (self.body.as_mut(), &body) {
            sink.write(&[b])?;
        }
        if let Some(sink) = self.rest.as_mut() {
            let rest = converted(c, rest);
            sink.write(&[&rest])?;
        }
        Ok(())
    }

    /// Finishes every output (garment first) and returns their paths.
    pub(super) fn finish(self) -> Result<Vec<PathBuf>, ExportError> {
        let mut outputs = vec![self.garment.finish()?];
        if let Some(s) = self.body {
            outputs.push(s.finish()?);
        }
        if let Some(s) = self.rest {
            outputs.push(s.finish()?);
        }
        Ok(outputs)
    }
}

/// The points unchanged when the convention is the identity, else converted.
fn converted(c: Convention, points: &[Vec3]) -> Cow<'_, [Vec3]> {
    match c.is_identity() {
        true => Cow::Borrowed(points),
        false => Cow::Owned(c.apply_all(points)),
    }
}

/// A USD mesh entry (the other formats use only its topology).
fn mesh<'a>(name: &'a str, topology: &'a TriMesh) -> UsdMesh<'a> {
    UsdMesh { name, topology }
}
