//! A diagnostic, not the method: frames of our own reference simulator to fit the network to
//! directly ([`TrainConfig::fit_reference`](crate::TrainConfig::fit_reference)). Trained on
//! them with a plain mass-weighted squared distance, the network shows how close its
//! architecture (a GRU over one training window, linear bases, skinning) *can* come to the
//! simulator on a motion, which separates what it cannot represent from what the
//! unsupervised physics loss does not teach it (docs/TRAINING.md, round 18).
//!
//! The frames are the PC2 caches `compare` writes in a run's `reference/` folder: one
//! `<motion>-<iterations>it-<fps>fps-<key>.pc2` per motion (the `.static.pc2` quasi-static
//! ones are not used), at the training rate. The training warm start
//! ([`TrainConfig::warm_start_steps`](crate::TrainConfig::warm_start_steps)) fits to the same
//! kind of frames for its first steps; its mirrored motions have none
//! ([`FitReference::from_frames`]).

use std::path::{Path, PathBuf};

use neural_cloth_core::geometry::Vec3;
use neural_cloth_core::io::export::read_pc2;

use super::TrainError;

/// Reference frames of the training motions, flattened `[T, V, 3]` per motion.
#[derive(Clone, Debug)]
pub struct FitReference {
    /// Per motion of the dataset (same order), its frames, or None for a motion without
    /// simulated frames (a mirrored copy in the warm start).
    motions: Vec<Option<Vec<f32>>>,
    /// Vertices per frame.
    vertices: usize,
}

impl FitReference {
    /// Loads the reference of every motion named in `motions` (the dataset's order) from
    /// `dir`: the first `.pc2` file (by name) that starts with the motion's name and a dash
    /// and is not a quasi-static cache. Refused when a motion has none, its vertex count is
    /// not `vertices` or a position is not finite.
    pub fn load<'a>(
        dir: &Path,
        motions: impl IntoIterator<Item = &'a str>,
        vertices: usize,
    ) -> Result<Self, TrainError> {
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(|source| TrainError::File {
                source,
                path: dir.to_path_buf(),
            })?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
                name.ends_with(".pc2") && !name.ends_with(".static.pc2")
            })
            .collect();
        files.sort();
        let mut loaded = Vec::new();
        for name in motions {
            let prefix = format!("{name}-");
            let path = files
                .iter()
                .find(|p| {
                    p.file_name()
                        .and_then(|n| n.to_str())
                        .is_some_and(|n| n.starts_with(&prefix))
                })
                .ok_or_else(|| {
                    TrainError::Data(format!(
                        "no reference frames for motion '{name}' (a {prefix}….pc2 as `compare` \
                         caches them) in {}",
                        dir.display()
                    ))
                })?;
            let cache = read_pc2(path)?;
            let bad = |reason: String| TrainError::Corrupt {
                reason,
                path: path.clone(),
            };
            if cache.frames.is_empty() {
                return Err(bad("no frames".into()));
            }
            let mut flat = Vec::with_capacity(cache.frames.len() * vertices * 3);
            for frame in &cache.frames {
                if frame.len() != vertices {
                    return Err(bad(format!(
                        "{} points per frame, the garment has {vertices}",
                        frame.len()
                    )));
                }
                flat.extend(frame.iter().flat_map(|p| [p.x, p.y, p.z]));
            }
            if flat.iter().any(|c| !c.is_finite()) {
                return Err(bad("non-finite positions".into()));
            }
            loaded.push(Some(flat));
        }
        Ok(Self {
            motions: loaded,
            vertices,
        })
    }

    /// The reference of simulated `frames` per motion of the dataset (same order; None for a
    /// motion without them). Refused when a motion has no frames, a frame has not `vertices`
    /// points or a position is not finite.
    pub fn from_frames(
        motions: Vec<Option<Vec<Vec<Vec3>>>>,
        vertices: usize,
    ) -> Result<Self, TrainError> {
        let mut loaded = Vec::with_capacity(motions.len());
        for (m, frames) in motions.into_iter().enumerate() {
            let Some(frames) = frames else {
                loaded.push(None);
                continue;
            };
            if frames.is_empty() || frames.iter().any(|f| f.len() != vertices) {
                return Err(TrainError::Data(format!(
                    "the simulated frames of training motion {m} do not hold {vertices} points \
                     per frame"
                )));
            }
            let flat: Vec<f32> = frames
                .iter()
                .flatten()
                .flat_map(|p| [p.x, p.y, p.z])
                .collect();
            if flat.iter().any(|c| !c.is_finite()) {
                return Err(TrainError::Data(format!(
                    "the simulated frames of training motion {m} are not finite"
                )));
            }
            loaded.push(Some(flat));
        }
        Ok(Self {
            motions: loaded,
            vertices,
        })
    }

    /// Positions of the given `(motion, frame)` rows, flattened `[rows, V, 3]`, and per row 1
    /// where the motion has reference frames or 0 where it has none (its positions are then
    /// zeros); a frame past the end of the reference takes its last frame.
    pub fn rows(&self, rows: &[(usize, usize)]) -> Result<(Vec<f32>, Vec<f32>), TrainError> {
        let n = self.vertices * 3;
        let mut out = Vec::with_capacity(rows.len() * n);
        let mut mask = Vec::with_capacity(rows.len());
        for &(m, f) in rows {
            let frames = self.motions.get(m).ok_or_else(|| {
                TrainError::Data(format!("no reference frames for motion {m} of the batch"))
            })?;
            match frames {
                Some(frames) if frames.len() >= n => {
                    let last = frames.len() / n - 1;
                    let f = f.min(last);
                    out.extend_from_slice(&frames[f * n..(f + 1) * n]);
                    mask.push(1.0);
                }
                _ => {
                    out.resize(out.len() + n, 0.0);
                    mask.push(0.0);
                }
            }
        }
        Ok((out, mask))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use neural_cloth_core::io::export::Pc2Writer;

    fn write(path: &Path, frames: &[Vec<Vec3>]) {
        let mut w = Pc2Writer::create(path, frames[0].len(), 0.0, 1.0).unwrap();
        for f in frames {
            w.write_frame(f).unwrap();
        }
        w.finish().unwrap();
    }

    #[test]
    fn reference_rows_come_from_each_motions_cache_and_clamp_at_its_end() {
        let dir = tempfile::tempdir().unwrap();
        let frame = |m: f32, f: f32| vec![Vec3::new(m, f, 0.0), Vec3::new(m, f, 1.0)];
        write(
            &dir.path().join("walk-100it-30fps-abc.pc2"),
            &[frame(1.0, 0.0), frame(1.0, 1.0)],
        );
        // A quasi-static cache of the same motion is not the reference.
        write(
            &dir.path().join("walk-100it-30fps-abc.static.pc2"),
            &[frame(9.0, 0.0)],
        );
        write(
            &dir.path().join("spin-100it-30fps-abc.pc2"),
            &[frame(2.0, 0.0), frame(2.0, 1.0), frame(2.0, 2.0)],
        );
        let r = FitReference::load(dir.path(), ["spin", "walk"], 2).unwrap();
        let (rows, mask) = r.rows(&[(1, 1), (0, 2), (1, 7)]).unwrap();
        assert_eq!(mask, vec![1.0; 3]);
        assert_eq!(
            rows,
            vec![
                1.0, 1.0, 0.0, 1.0, 1.0, 1.0, // walk, frame 1
                2.0, 2.0, 0.0, 2.0, 2.0, 1.0, // spin, frame 2
                1.0, 1.0, 0.0, 1.0, 1.0, 1.0, // walk, past its end: its last frame
            ]
        );
        assert!(r.rows(&[(2, 0)]).is_err());
        // A motion without a cache, or a cache of another garment, is refused.
        let missing = FitReference::load(dir.path(), ["twirl"], 2).unwrap_err();
        assert!(missing.to_string().contains("'twirl'"), "{missing}");
        assert!(FitReference::load(dir.path(), ["walk"], 3).is_err());
    }

    #[test]
    fn a_motion_without_simulated_frames_is_masked_out() {
        let frames = |x: f32| {
            Some(vec![
                vec![Vec3::new(x, 0.0, 0.0)],
                vec![Vec3::new(x, 1.0, 0.0)],
            ])
        };
        // Motion 1 is a mirrored copy: no frames.
        let r = FitReference::from_frames(vec![frames(1.0), None, frames(3.0)], 1).unwrap();
        let (rows, mask) = r.rows(&[(0, 1), (1, 0), (2, 0)]).unwrap();
        assert_eq!(mask, vec![1.0, 0.0, 1.0]);
        assert_eq!(rows, vec![1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 3.0, 0.0, 0.0]);
        // Wrong vertex count or non-finite frames are refused.
        assert!(FitReference::from_frames(vec![frames(1.0)], 2).is_err());
        assert!(FitReference::from_frames(vec![frames(f32::NAN)], 1).is_err());
        assert!(FitReference::from_frames(vec![Some(Vec::new())], 1).is_err());
    }
}
