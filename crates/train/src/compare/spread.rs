//! Whether the reference is converged: the same motion simulated with twice the L-BFGS
//! iterations per frame, and how far the two simulations are apart. On fast turns a small
//! difference in the early frames' solves can leave a loose garment in another state for the
//! rest of the motion (the t-shirt on the spin whirls to the other side of the body at 100
//! iterations than at 200, 36 mm apart, while 200 and 400 agree to 5 mm: docs/TRAINING.md
//! round 20), so a network's distance to an unconverged reference means little.
//!
//! And whether the motion is predictable at all: the same simulation from the settled garment
//! moved by a micrometre (the **sensitivity**). On the twirl the whole t-shirt slips about the
//! body by 10-30 degrees at one frame in one simulation and at another in the next (100 and
//! 400 iterations agree to 4 mm for 150 frames while 200 slipped at frame 70: docs/TRAINING.md
//! round 21): such a fork is a property of the physics, not of the solver, and no model can
//! be expected to match it frame by frame.

use serde::{Deserialize, Serialize};

use neural_cloth_core::geometry::Vec3;
use neural_cloth_core::scene::Motion;

use super::super::TrainError;
use super::super::trained::TrainedModel;
use super::rigid::mean_fit;
use super::{CompareOptions, ComparePhase, distance_stats, simulation_for};

/// Largest change of each coordinate of the settled garment in the sensitivity check,
/// metres: a micrometre, far below what a viewer or the solver's tolerance could tell apart.
pub const SENSITIVITY_JITTER_M: f64 = 1e-6;

/// How far the reference simulation is from another simulation of the same motion: at twice
/// the iterations (the spread) or from a start moved by [`SENSITIVITY_JITTER_M`] (the
/// sensitivity).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReferenceSpread {
    /// Iterations per frame of the other simulation (twice the reference's for the spread).
    pub iterations: usize,
    /// Largest change of each start coordinate of the other simulation, metres (0 for the
    /// spread, and in older checks).
    #[serde(default)]
    pub start_jitter_m: f64,
    /// Mean distance between the two over every vertex of every frame, mm.
    pub mean_mm: f64,
    /// 95th percentile of the same distances, mm.
    pub p95_mm: f64,
    /// Mean distance after each frame's best rigid motion of the whole garment (the
    /// difference in shape, without the difference in slip), mm; `None` when a frame is not
    /// finite.
    pub shape_mm: Option<f64>,
}

/// The spread of `reference` (the simulation of `motion` under `options`) against the
/// simulation at twice the iterations (cached beside it).
pub fn reference_spread(
    trained: &TrainedModel,
    motion: &Motion,
    options: &CompareOptions,
    reference: &[Vec<Vec3>],
    progress: &mut dyn FnMut(ComparePhase, usize, usize) -> bool,
) -> Result<ReferenceSpread, TrainError> {
    let finer = CompareOptions {
        iterations: 2 * options.iterations,
        ..options.clone()
    };
    against_simulation(trained, motion, &finer, reference, progress)
}

/// The sensitivity of `reference` (the simulation of `motion` under `options`): the same
/// simulation from the settled garment moved by at most [`SENSITIVITY_JITTER_M`] per
/// coordinate (cached beside it), and how far the two are apart.
pub fn reference_sensitivity(
    trained: &TrainedModel,
    motion: &Motion,
    options: &CompareOptions,
    reference: &[Vec<Vec3>],
    progress: &mut dyn FnMut(ComparePhase, usize, usize) -> bool,
) -> Result<ReferenceSpread, TrainError> {
    let moved = CompareOptions {
        start_jitter_m: options.start_jitter_m + SENSITIVITY_JITTER_M,
        ..options.clone()
    };
    against_simulation(trained, motion, &moved, reference, progress)
}

/// How far the simulation of `motion` under `other` (read from or written to the cache) is
/// from `reference`.
fn against_simulation(
    trained: &TrainedModel,
    motion: &Motion,
    other: &CompareOptions,
    reference: &[Vec<Vec3>],
    progress: &mut dyn FnMut(ComparePhase, usize, usize) -> bool,
) -> Result<ReferenceSpread, TrainError> {
    let (simulated, _, _) = simulation_for(trained, motion, other, progress)?;
    spread_between(
        reference,
        &simulated,
        other.iterations,
        other.start_jitter_m,
    )
}

/// How far `other` (simulated with `iterations` per frame from a start moved by up to
/// `start_jitter_m`) is from `reference`.
pub fn spread_between(
    reference: &[Vec<Vec3>],
    other: &[Vec<Vec3>],
    iterations: usize,
    start_jitter_m: f64,
) -> Result<ReferenceSpread, TrainError> {
    let all = distance_stats(other, reference, &|_| true)?
        .ok_or_else(|| TrainError::Data("no frames to measure the reference's spread".into()))?;
    Ok(ReferenceSpread {
        iterations,
        start_jitter_m,
        mean_mm: all.mean_mm,
        p95_mm: all.p95_mm,
        shape_mm: mean_fit(other, reference)?.map(|(shape, _)| shape),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_spread_of_a_simulation_against_itself_is_zero_and_a_turn_is_slip() {
        let frame: Vec<Vec3> = (0..20)
            .map(|i| Vec3::new((i % 5) as f32 * 0.1, (i / 5) as f32 * 0.1, 0.02 * i as f32))
            .collect();
        let one = std::slice::from_ref(&frame);
        let same = spread_between(one, one, 200, 0.0).unwrap();
        assert_eq!(same.mean_mm, 0.0);
        assert!(same.shape_mm.unwrap() < 1e-9, "{same:?}");
        assert_eq!(same.iterations, 200);
        // The same garment turned 10 degrees about the vertical: far apart, the same shape.
        let (s, c) = 10f32.to_radians().sin_cos();
        let turned: Vec<Vec3> = frame
            .iter()
            .map(|p| Vec3::new(c * p.x + s * p.z, p.y, -s * p.x + c * p.z))
            .collect();
        let spread = spread_between(&[frame], &[turned], 100, 1e-6).unwrap();
        assert!(spread.mean_mm > 5.0, "{spread:?}");
        assert!(spread.shape_mm.unwrap() < 1e-3, "{spread:?}");
        assert_eq!((spread.iterations, spread.start_jitter_m), (100, 1e-6));
    }
}
