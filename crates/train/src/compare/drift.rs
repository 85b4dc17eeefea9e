//! The recurrent state's drift at inference: how far the network's frames, played with the
//! GRU state carried over the whole motion (as `bake`, `compare` and the app play it), are
//! from the same network started afresh a training window before each frame (all that
//! training ever shows the GRU).
//!
//! A network whose state, run for seconds of motion, goes where training never looked shows
//! it here first: docs/TRAINING.md round 10 found a 30-minute t-shirt run 7.6 mm from its own
//! windowed frames on the idle (the shirt lifted), where the simulator's distance alone could
//! not say why.

use serde::{Deserialize, Serialize};

use neural_cloth_core::geometry::Vec3;
use neural_cloth_core::scene::Pose;
use neural_cloth_physics::PhysicsError;

use super::super::TrainError;
use super::super::trained::TrainedModel;
use super::ComparePhase;

/// The carried state against windowed replays, over all frames of a motion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StateDrift {
    /// Frames of each windowed replay: the training window plus its GRU burn-in.
    pub window_frames: usize,
    /// Mean vertex distance, carried against windowed, over all frames and vertices, mm.
    pub mean_mm: f64,
    /// The largest frame's mean vertex distance, mm.
    pub max_frame_mm: f64,
    /// Mean height difference, carried minus windowed, mm (positive: the carried state lifts
    /// the garment).
    pub height_mm: f64,
}

/// Frames of one windowed replay for `trained`: what one training window and its burn-in
/// show the GRU.
pub fn drift_window_frames(trained: &TrainedModel) -> usize {
    let fps = trained.meta.training_fps;
    let train = &trained.meta.train;
    train.window_frames(fps) + train.burn_in_frames(fps)
}

/// The drift of `carried` (the network's frames on `poses` at `w`, state carried from the
/// first frame) from windowed replays of `window_frames` frames each; each frame costs one
/// replay, so the whole costs about `window_frames` plays of the motion. `say` sees the
/// frames done; returning false cancels.
pub fn state_drift(
    trained: &TrainedModel,
    poses: &[Pose],
    w: f32,
    carried: &[Vec<Vec3>],
    window_frames: usize,
    say: &mut dyn FnMut(ComparePhase, usize, usize) -> bool,
) -> Result<StateDrift, TrainError> {
    let mut engine = trained.garment_engine()?;
    let window = window_frames.max(1);
    let (mut sum_mm, mut max_frame_mm, mut height_mm) = (0.0f64, 0.0f64, 0.0f64);
    let mut counted = 0usize;
    for (t, carried_frame) in carried.iter().enumerate().take(poses.len()) {
        engine.reset();
        for pose in &poses[(t + 1).saturating_sub(window)..=t] {
            engine.step(pose, w)?;
        }
        let windowed = engine.garment_positions();
        let n = windowed.len().min(carried_frame.len());
        if n > 0 {
            let (mut d, mut dy) = (0.0f64, 0.0f64);
            for (a, b) in carried_frame.iter().zip(windowed) {
                d += f64::from((*a - *b).norm());
                dy += f64::from(a.y - b.y);
            }
            let frame_mm = 1000.0 * d / n as f64;
            sum_mm += frame_mm;
            max_frame_mm = max_frame_mm.max(frame_mm);
            height_mm += 1000.0 * dy / n as f64;
            counted += 1;
        }
        if !say(ComparePhase::Drift, t + 1, poses.len()) {
            return Err(PhysicsError::Cancelled { frames: t + 1 }.into());
        }
    }
    let frames = counted.max(1) as f64;
    Ok(StateDrift {
        window_frames: window,
        mean_mm: sum_mm / frames,
        max_frame_mm,
        height_mm: height_mm / frames,
    })
}
