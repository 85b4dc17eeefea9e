//! MDD point caches (LightWave, Blender's Mesh Cache modifier): big-endian; i32 frames, i32
//! points, f32 time of each frame in seconds, then `frames * points * 3` f32.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::geometry::Vec3;

use super::ExportError;
use super::atomic::AtomicFile;
use super::pc2::check_frame;

/// An MDD cache read back from disk.
#[derive(Clone, Debug, PartialEq)]
pub struct MddCache {
    /// Time of each frame in seconds.
    pub times_secs: Vec<f32>,
    /// Positions, one `Vec` of points per frame.
    pub frames: Vec<Vec<Vec3>>,
}

/// Streams frames into an MDD file. The frame count is part of the header, so it is fixed
/// up front and checked on finish.
pub struct MddWriter {
    file: AtomicFile,
    points: usize,
    frames: usize,
    written: usize,
}

impl MddWriter {
    /// Starts a cache of `frames` frames of `points` points sampled at `fps`.
    pub fn create(
        path: &Path,
        frames: usize,
        points: usize,
        fps: f32,
    ) -> Result<Self, ExportError> {
        if points == 0 || frames == 0 || points > i32::MAX as usize || frames > i32::MAX as usize {
            return Err(ExportError::Format {
                reason: format!("cannot write {frames} frames of {points} points"),
                path: path.to_path_buf(),
            });
        }
        if !(fps.is_finite() && fps > 0.0) {
            return Err(ExportError::Format {
                reason: format!("frame rate {fps} is not positive"),
                path: path.to_path_buf(),
            });
        }
        let mut file = AtomicFile::create(path)?;
        let mut header = Vec::with_capacity(8 + 4 * frames);
        header.extend_from_slice(&(frames as i32).to_be_bytes());
        header.extend_from_slice(&(points as i32).to_be_bytes());
        for k in 0..frames {
            header.extend_from_slice(&(k as f32 / fps).to_be_bytes());
        }
        file.write_all(&header)
            .map_err(|e| ExportError::io(e, path))?;
        Ok(Self {
            file,
            points,
            frames,
            written: 0,
        })
    }

    /// Appends one frame of exactly `points` positions.
    pub fn write_frame(&mut self, positions: &[Vec3]) -> Result<(), ExportError> {
        let path = self.file.path().to_path_buf();
        check_frame(positions, self.points, &path)?;
        if self.written == self.frames {
            return Err(ExportError::Format {
                reason: format!("more than the {} frames announced", self.frames),
                path,
            });
        }
        let mut buf = Vec::with_capacity(positions.len() * 12);
        for p in positions {
            for c in p.iter() {
                buf.extend_from_slice(&c.to_be_bytes());
            }
        }
        self.file
            .write_all(&buf)
            .map_err(|e| ExportError::io(e, &path))?;
        self.written += 1;
        Ok(())
    }

    /// Checks that every announced frame was written and moves the file into place.
    pub fn finish(self) -> Result<PathBuf, ExportError> {
        if self.written != self.frames {
            return Err(ExportError::Format {
                reason: format!("{} of {} frames written", self.written, self.frames),
                path: self.file.path().to_path_buf(),
            });
        }
        self.file.commit()
    }
}

/// Reads a whole MDD file.
pub fn read_mdd(path: &Path) -> Result<MddCache, ExportError> {
    let bytes = std::fs::read(path).map_err(|e| ExportError::io(e, path))?;
    parse_mdd(&bytes).map_err(|reason| ExportError::Format {
        reason,
        path: path.to_path_buf(),
    })
}

/// Parses MDD bytes.
pub fn parse_mdd(bytes: &[u8]) -> Result<MddCache, String> {
    let head = bytes.get(..8).ok_or("file shorter than the MDD header")?;
    let frames = i32::from_be_bytes([head[0], head[1], head[2], head[3]]);
    let points = i32::from_be_bytes([head[4], head[5], head[6], head[7]]);
    if frames < 0 || points < 0 {
        return Err(format!(
            "negative counts ({frames} frames, {points} points)"
        ));
    }
    let frames = frames as usize;
    let times_end = frames
        .checked_mul(4)
        .and_then(|n| n.checked_add(8))
        .ok_or("frame count overflows")?;
    let times = bytes
        .get(8..times_end)
        .ok_or("file ends inside the frame times")?;
    let times_secs = times
        .chunks_exact(4)
        .map(|c| f32::from_be_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    let frames = super::read_f32s(&bytes[times_end..], points as usize, frames, true)?;
    Ok(MddCache { times_secs, frames })
}
