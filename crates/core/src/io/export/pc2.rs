//! PC2 point caches (Blender's Mesh Cache modifier, 3ds Max): little-endian; the 12-byte
//! signature `POINTCACHE2\0`, i32 version 1, i32 points, f32 start frame, f32 sampling (frames
//! between samples, 1 = every frame), i32 samples; then `samples * points * 3` f32.

use std::io::{Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use crate::geometry::Vec3;

use super::ExportError;
use super::atomic::AtomicFile;

/// The PC2 signature.
pub const PC2_SIGNATURE: &[u8; 12] = b"POINTCACHE2\0";
/// Size of the PC2 header in bytes.
pub const PC2_HEADER_BYTES: usize = 32;

/// A PC2 cache read back from disk.
#[derive(Clone, Debug, PartialEq)]
pub struct Pc2Cache {
    /// First frame number.
    pub start_frame: f32,
    /// Frames between consecutive samples (1 = every frame).
    pub sampling: f32,
    /// Positions, one `Vec` of points per sample.
    pub frames: Vec<Vec<Vec3>>,
}

/// Streams frames into a PC2 file; the sample count in the header is patched on finish.
pub struct Pc2Writer {
    file: AtomicFile,
    points: usize,
    samples: u32,
}

impl Pc2Writer {
    /// Starts a cache of `points` points per frame.
    pub fn create(
        path: &Path,
        points: usize,
        start_frame: f32,
        sampling: f32,
    ) -> Result<Self, ExportError> {
        if points == 0 || points > i32::MAX as usize {
            return Err(ExportError::Format {
                reason: format!("cannot write {points} points"),
                path: path.to_path_buf(),
            });
        }
        let mut file = AtomicFile::create(path)?;
        let mut header = Vec::with_capacity(PC2_HEADER_BYTES);
        header.extend_from_slice(PC2_SIGNATURE);
        header.extend_from_slice(&1i32.to_le_bytes());
        header.extend_from_slice(&(points as i32).to_le_bytes());
        header.extend_from_slice(&start_frame.to_le_bytes());
        header.extend_from_slice(&sampling.to_le_bytes());
        header.extend_from_slice(&0i32.to_le_bytes());
        file.write_all(&header)
            .map_err(|e| ExportError::io(e, path))?;
        Ok(Self {
            file,
            points,
            samples: 0,
        })
    }

    /// Appends one frame of exactly `points` positions.
    pub fn write_frame(&mut self, positions: &[Vec3]) -> Result<(), ExportError> {
        check_frame(positions, self.points, self.file.path())?;
        let mut buf = Vec::with_capacity(positions.len() * 12);
        for p in positions {
            for c in p.iter() {
                buf.extend_from_slice(&c.to_le_bytes());
            }
        }
        let path = self.file.path().to_path_buf();
        self.file
            .write_all(&buf)
            .map_err(|e| ExportError::io(e, &path))?;
        self.samples += 1;
        Ok(())
    }

    /// Patches the sample count and moves the file into place.
    pub fn finish(mut self) -> Result<PathBuf, ExportError> {
        let path = self.file.path().to_path_buf();
        let samples = self.samples as i32;
        let w = self.file.writer()?;
        w.seek(SeekFrom::Start(28))
            .map_err(|e| ExportError::io(e, &path))?;
        w.write_all(&samples.to_le_bytes())
            .map_err(|e| ExportError::io(e, &path))?;
        self.file.commit()
    }
}

/// Checks a frame's length and finiteness before it is written.
pub(super) fn check_frame(
    positions: &[Vec3],
    points: usize,
    path: &Path,
) -> Result<(), ExportError> {
    if positions.len() != points {
        return Err(ExportError::Format {
            reason: format!("frame has {} points, cache has {points}", positions.len()),
            path: path.to_path_buf(),
        });
    }
    if !positions.iter().all(|p| p.iter().all(|c| c.is_finite())) {
        return Err(ExportError::Format {
            reason: "frame has non-finite positions".into(),
            path: path.to_path_buf(),
        });
    }
    Ok(())
}

/// Reads a whole PC2 file, checking the signature, version and size.
pub fn read_pc2(path: &Path) -> Result<Pc2Cache, ExportError> {
    let bytes = std::fs::read(path).map_err(|e| ExportError::io(e, path))?;
    parse_pc2(&bytes).map_err(|reason| ExportError::Format {
        reason,
        path: path.to_path_buf(),
    })
}

/// Parses PC2 bytes.
pub fn parse_pc2(bytes: &[u8]) -> Result<Pc2Cache, String> {
    let header = bytes
        .get(..PC2_HEADER_BYTES)
        .ok_or("file shorter than the PC2 header")?;
    if &header[..12] != PC2_SIGNATURE {
        return Err("not a PC2 file (bad signature)".into());
    }
    let i32_at =
        |o: usize| i32::from_le_bytes([header[o], header[o + 1], header[o + 2], header[o + 3]]);
    let f32_at =
        |o: usize| f32::from_le_bytes([header[o], header[o + 1], header[o + 2], header[o + 3]]);
    if i32_at(12) != 1 {
        return Err(format!("unsupported PC2 version {}", i32_at(12)));
    }
    let (points, samples) = (i32_at(16), i32_at(28));
    if points < 0 || samples < 0 {
        return Err(format!(
            "negative counts ({points} points, {samples} samples)"
        ));
    }
    let floats = super::read_f32s(
        &bytes[PC2_HEADER_BYTES..],
        points as usize,
        samples as usize,
        false,
    )?;
    Ok(Pc2Cache {
        start_frame: f32_at(20),
        sampling: f32_at(24),
        frames: floats,
    })
}
