//! The distance to the simulator split into the quasi-static answer and the motion.
//!
//! The network's frame at `w` is its `w = 0` answer plus what its dynamic branch adds; the
//! simulator's frame is its quasi-static solve (dynamics off) plus what momentum adds. Their
//! difference is the sum of two differences: the network's `w = 0` answer against the
//! quasi-static solve (how far the network's drape without motion is from the drape without
//! momentum) and the network's motion (`w` minus `w = 0`) against the simulator's (dynamic
//! minus quasi-static). Each is at most the distance it would leave alone, and together they
//! bound the distance (triangle inequality). A network whose branches are cleanly split has a
//! small quasi-static distance on every motion; one whose dynamic branch also corrects the
//! static drape shows a quasi-static distance larger than its distance, with a motion
//! distance that cancels it.

use serde::{Deserialize, Serialize};

use neural_cloth_core::geometry::Vec3;

use super::super::TrainError;
use super::measure::{AmplitudeStats, Sequences, frame_means};

/// The distance split into the quasi-static answer and the motion, each over all, still
/// and moving frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StaticMotionSplit {
    /// The network at `w = 0` against the simulator's quasi-static solve: mean vertex
    /// distance, mm.
    pub quasi_static: AmplitudeStats,
    /// The network's motion (each vertex at `w` minus at `w = 0`) against the simulator's
    /// (dynamic minus quasi-static): mean vertex distance between the two displacements, mm.
    pub motion: AmplitudeStats,
}

/// An error unless `a` and `b` have the same frame count and, frame by frame, vertex count.
fn same_shape(a: &[Vec<Vec3>], b: &[Vec<Vec3>]) -> Result<(), TrainError> {
    let differs = a.len() != b.len() || a.iter().zip(b).any(|(x, y)| x.len() != y.len());
    match differs {
        true => Err(TrainError::Data(format!(
            "cannot split a motion: sequences of {} and {} frames, or frames of other vertex counts",
            a.len(),
            b.len()
        ))),
        false => Ok(()),
    }
}

/// Per frame and vertex, `moving - resting` (the two of the same shape: [`same_shape`]).
fn displacement(moving: &[Vec<Vec3>], resting: &[Vec<Vec3>]) -> Vec<Vec<Vec3>> {
    moving
        .iter()
        .zip(resting)
        .map(|(m, r)| m.iter().zip(r).map(|(a, b)| a - b).collect())
        .collect()
}

/// Splits the distance between `seq.network` and `seq.simulator` ([`StaticMotionSplit`]);
/// `still[k]` marks the still frames.
pub fn static_motion_split(
    seq: &Sequences<'_>,
    still: &[bool],
) -> Result<StaticMotionSplit, TrainError> {
    let quasi_static = frame_means(seq.simulator_static, seq.network_static, still)?;
    same_shape(seq.network_static, seq.network)?;
    same_shape(seq.simulator_static, seq.simulator)?;
    let network_motion = displacement(seq.network, seq.network_static);
    let simulator_motion = displacement(seq.simulator, seq.simulator_static);
    Ok(StaticMotionSplit {
        quasi_static,
        motion: frame_means(&simulator_motion, &network_motion, still)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames(xs: &[f32]) -> Vec<Vec<Vec3>> {
        xs.iter().map(|&x| vec![Vec3::new(x, 0.0, 0.0)]).collect()
    }

    #[test]
    fn a_network_off_in_its_drape_only_has_no_motion_distance() {
        // Simulator: drape at 0, swings to 0.010 m on the second frame. The network: its
        // drape 0.002 m off, the same swing on top of it.
        let (sim0, sim) = (frames(&[0.0, 0.0]), frames(&[0.0, 0.010]));
        let (net0, net) = (frames(&[0.002, 0.002]), frames(&[0.002, 0.012]));
        let seq = Sequences {
            network: &net,
            network_static: &net0,
            simulator: &sim,
            simulator_static: &sim0,
        };
        let split = static_motion_split(&seq, &[true, false]).unwrap();
        assert!((split.quasi_static.all_mm - 2.0).abs() < 1e-4);
        assert!(split.motion.all_mm.abs() < 1e-4);
        assert_eq!(split.motion.still_mm, Some(0.0));
    }

    #[test]
    fn a_dynamic_branch_that_corrects_the_drape_shows_in_both_parts() {
        // The network's w = 1 frames equal the simulator's, but its w = 0 answer is 0.004 m
        // off: its motion carries the correction, so both parts read 4 mm on every frame.
        let (sim0, sim) = (frames(&[0.0, 0.0]), frames(&[0.0, 0.010]));
        let net0 = frames(&[0.004, 0.004]);
        let seq = Sequences {
            network: &sim,
            network_static: &net0,
            simulator: &sim,
            simulator_static: &sim0,
        };
        let split = static_motion_split(&seq, &[true, false]).unwrap();
        assert!((split.quasi_static.all_mm - 4.0).abs() < 1e-4);
        assert!((split.motion.all_mm - 4.0).abs() < 1e-4);
        assert_eq!(split.quasi_static.moving_mm.map(|v| v.round()), Some(4.0));
    }

    #[test]
    fn motions_of_other_vertex_counts_are_an_error() {
        let (a, b) = (frames(&[0.0, 0.0]), vec![vec![Vec3::zeros(); 2]; 2]);
        let seq = Sequences {
            network: &b,
            network_static: &a,
            simulator: &a,
            simulator_static: &a,
        };
        assert!(static_motion_split(&seq, &[false, false]).is_err());
    }

    #[test]
    fn sequences_of_other_lengths_are_an_error() {
        let (a, b) = (frames(&[0.0, 0.0]), frames(&[0.0]));
        let seq = Sequences {
            network: &a,
            network_static: &b,
            simulator: &a,
            simulator_static: &a,
        };
        assert!(static_motion_split(&seq, &[false, false]).is_err());
    }
}
