//! Measures of a comparison between garment sequences: pooled vertex distances, the still
//! frames of a motion, the dynamic amplitude, the hem of a long garment and its radius about
//! the body's vertical axis ([`measure_motion`] gathers them). Pure functions of positions and
//! poses, shared by [`super::compare`] and the report's fidelity experiments.

use serde::{Deserialize, Serialize};

use neural_cloth_core::geometry::Vec3;
use neural_cloth_core::scene::{Avatar, Garment, Pose};

use super::super::TrainError;

/// Share of the template's height, from its lowest point, that counts as the hem.
pub const HEM_BAND: f32 = 0.15;

/// Pooled vertex distances between two sequences of the same garment.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DistanceStats {
    /// Frames pooled.
    pub frames: usize,
    /// Mean distance over every vertex of every pooled frame, mm.
    pub mean_mm: f64,
    /// 95th percentile of the same distances, mm.
    pub p95_mm: f64,
}

/// Distances of every vertex of every frame of `candidate` to `reference`: mean and 95th
/// percentile (mm) over all frames. Both sequences must have the same frame and vertex counts.
pub fn compare_frames(
    reference: &[Vec<Vec3>],
    candidate: &[Vec<Vec3>],
) -> Result<DistanceStats, TrainError> {
    Ok(distance_stats(reference, candidate, &|_| true)?.unwrap_or_default())
}

/// Like [`compare_frames`] over the frames `k` where `select(k)`; `None` when none is selected.
pub fn distance_stats(
    reference: &[Vec<Vec3>],
    candidate: &[Vec<Vec3>],
    select: &dyn Fn(usize) -> bool,
) -> Result<Option<DistanceStats>, TrainError> {
    if reference.len() != candidate.len() {
        return Err(TrainError::Data(format!(
            "cannot compare sequences of {} and {} frames",
            reference.len(),
            candidate.len()
        )));
    }
    let mut d_mm: Vec<f64> = Vec::new();
    let mut frames = 0;
    for (k, (r, c)) in reference.iter().zip(candidate).enumerate() {
        if !select(k) {
            continue;
        }
        if r.len() != c.len() {
            return Err(TrainError::Data(format!(
                "frame {k}: cannot compare {} vertices with {}",
                r.len(),
                c.len()
            )));
        }
        frames += 1;
        d_mm.extend(
            r.iter()
                .zip(c)
                .map(|(p, q)| 1e3 * f64::from((p - q).norm())),
        );
    }
    if frames == 0 {
        return Ok(None);
    }
    if d_mm.is_empty() {
        return Ok(Some(DistanceStats {
            frames,
            ..Default::default()
        }));
    }
    let mean_mm = d_mm.iter().sum::<f64>() / d_mm.len() as f64;
    d_mm.sort_by(f64::total_cmp);
    let idx = ((0.95 * (d_mm.len() - 1) as f64).round() as usize).min(d_mm.len() - 1);
    Ok(Some(DistanceStats {
        frames,
        mean_mm,
        p95_mm: d_mm[idx],
    }))
}

/// World positions of every joint of `pose`, metres.
fn joint_positions(avatar: &Avatar, pose: &Pose) -> Vec<Vec3> {
    avatar
        .skeleton
        .world_from_joint(pose)
        .iter()
        .map(|m| Vec3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]))
        .collect()
}

/// Largest joint speed of each frame of `poses` (consecutive at `fps`), m/s: the fastest
/// world-space joint position change from the previous frame (root translation, turning
/// and limbs alike). Frame 0 has speed 0.
pub fn joint_speeds_m_per_s(avatar: &Avatar, poses: &[Pose], fps: f32) -> Vec<f32> {
    let positions: Vec<Vec<Vec3>> = poses.iter().map(|p| joint_positions(avatar, p)).collect();
    let mut speeds = vec![0.0f32; positions.len()];
    for k in 1..positions.len() {
        speeds[k] = positions[k]
            .iter()
            .zip(&positions[k - 1])
            .map(|(a, b)| (a - b).norm() * fps)
            .fold(0.0, f32::max);
    }
    speeds
}

/// The still frames of `poses` (consecutive at `fps`): frame `k` is still when every joint
/// moved slower than `speed_m_per_s` in each of the frames of the last `window_secs` up to
/// and including `k` ([`joint_speeds_m_per_s`]). Frames before the first count as still (the
/// simulator holds the first pose while it settles; the network starts from rest).
pub fn still_frames(
    avatar: &Avatar,
    poses: &[Pose],
    fps: f32,
    speed_m_per_s: f32,
    window_secs: f32,
) -> Vec<bool> {
    let speeds = joint_speeds_m_per_s(avatar, poses, fps);
    let window = (window_secs.max(0.0) * fps).round() as usize;
    (0..speeds.len())
        .map(|k| {
            speeds[k.saturating_sub(window)..=k]
                .iter()
                .all(|&s| s < speed_m_per_s)
        })
        .collect()
}

/// Vertices in the lowest [`HEM_BAND`] of the garment template's height.
pub fn hem_vertices(garment: &Garment) -> Vec<usize> {
    let ys: Vec<f32> = garment.mesh.positions.iter().map(|p| p.y).collect();
    let cut = hem_cut_y(&ys);
    ys.iter()
        .enumerate()
        .filter(|(_, y)| **y <= cut)
        .map(|(i, _)| i)
        .collect()
}

/// Height of the top of the hem band of the template heights `ys`, metres.
fn hem_cut_y(ys: &[f32]) -> f32 {
    let (lo, hi) = ys
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &y| {
            (a.min(y), b.max(y))
        });
    lo + HEM_BAND * (hi - lo)
}

/// True when the garment's whole hem band (the lowest [`HEM_BAND`] of its template) lies
/// below the hips: below the rest height of the root joint and of each of its children (the
/// up-legs of a humanoid). True for skirts and dresses, false for shirts.
pub fn reaches_below_hips(avatar: &Avatar, garment: &Garment) -> bool {
    let ys: Vec<f32> = garment.mesh.positions.iter().map(|p| p.y).collect();
    if ys.is_empty() {
        return false;
    }
    let skeleton = &avatar.skeleton;
    let rest = joint_positions(avatar, &skeleton.rest_pose());
    let hips_y = rest
        .iter()
        .enumerate()
        .filter(|(j, _)| *j == 0 || skeleton.parents.get(*j).copied().flatten() == Some(0))
        .map(|(_, p)| p.y)
        .fold(f32::INFINITY, f32::min);
    hem_cut_y(&ys) < hips_y
}

/// Mean horizontal distance of the `hem` vertices of `garment` from the vertical axis through
/// the root joint of `avatar` posed at `pose`, metres.
pub fn hem_radius_m(avatar: &Avatar, pose: &Pose, garment: &[Vec3], hem: &[usize]) -> f32 {
    let world = avatar.skeleton.world_from_joint(pose);
    let Some(root) = world.first() else {
        return 0.0;
    };
    let (cx, cz) = (root[(0, 3)], root[(2, 3)]);
    let sum: f32 = hem
        .iter()
        .filter_map(|&i| garment.get(i))
        .map(|p| ((p.x - cx).powi(2) + (p.z - cz).powi(2)).sqrt())
        .sum();
    sum / hem.len().max(1) as f32
}

/// Mean of `values` over the indices `k` where `select(k)`; `None` when none is selected.
pub fn mean_where(values: &[f32], select: &dyn Fn(usize) -> bool) -> Option<f64> {
    let picked: Vec<f64> = values
        .iter()
        .enumerate()
        .filter(|(k, _)| select(*k))
        .map(|(_, v)| f64::from(*v))
        .collect();
    (!picked.is_empty()).then(|| picked.iter().sum::<f64>() / picked.len() as f64)
}

/// Mean vertex distances between two sequences over all, still and moving frames: the
/// dynamic amplitude of one side (each frame against its quasi-static counterpart), and each
/// part of [`super::StaticMotionSplit`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AmplitudeStats {
    /// Over all frames, mm.
    pub all_mm: f64,
    /// Over the still frames, mm (`None` without any).
    pub still_mm: Option<f64>,
    /// Over the moving frames, mm (`None` without any).
    pub moving_mm: Option<f64>,
}

/// Dynamic amplitude of both sides.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Amplitude {
    /// The network: its output at `w` against its output at `w = 0`.
    pub network: AmplitudeStats,
    /// The simulator: the simulation against the quasi-static simulation.
    pub simulator: AmplitudeStats,
}

/// Mean hem radius of both sides over some frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct HemPair {
    /// The network, metres.
    pub network_m: f64,
    /// The simulator, metres.
    pub simulator_m: f64,
    /// The network at `w = 0` (its quasi-static answer), metres.
    #[serde(default)]
    pub network_static_m: f64,
    /// The simulator's quasi-static solve (dynamics off), metres: the drape an energy descent
    /// reaches without the momentum of a fall.
    #[serde(default)]
    pub simulator_static_m: f64,
}

/// Hem radius about the body's vertical axis (garments below the hips only).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct HemComparison {
    /// Hem vertices.
    pub vertices: usize,
    /// Over the still frames (`None` without any).
    pub still: Option<HemPair>,
    /// Over the moving frames (`None` without any).
    pub moving: Option<HemPair>,
}

/// The four sequences of one motion, one frame per pose each.
#[derive(Clone, Copy, Debug)]
pub struct Sequences<'a> {
    /// The network at `w`.
    pub network: &'a [Vec<Vec3>],
    /// The network at `w = 0`.
    pub network_static: &'a [Vec<Vec3>],
    /// The reference simulation.
    pub simulator: &'a [Vec<Vec3>],
    /// The quasi-static reference simulation.
    pub simulator_static: &'a [Vec<Vec3>],
}

/// Geometric measures of one motion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MotionMeasures {
    /// Frames compared.
    pub frames: usize,
    /// Still frames among them.
    pub still_frames: usize,
    /// Network to simulator over all frames.
    pub all: DistanceStats,
    /// Over the still frames (`None` without any).
    pub still: Option<DistanceStats>,
    /// Over the moving frames (`None` without any).
    pub moving: Option<DistanceStats>,
    /// How much each side swings.
    pub amplitude: Amplitude,
    /// Hem radius (`None` for garments that end above the hips).
    pub hem: Option<HemComparison>,
    /// The distance and both swings split into rigid slip and shape (`None` in checks
    /// recorded before it was measured, and when a frame is not finite).
    #[serde(default)]
    pub rigid: Option<super::RigidSplit>,
    /// The distance split into the network's `w = 0` answer against the quasi-static solve
    /// and its motion against the simulator's ([`super::static_motion_split`]; `None` in
    /// checks recorded before it was measured).
    #[serde(default)]
    pub split: Option<super::StaticMotionSplit>,
    /// The GRU state carried over the motion against windowed replays ([`super::state_drift`];
    /// `None` in checks recorded before it was measured, at `w = 0` and without a dynamic
    /// branch).
    #[serde(default)]
    pub drift: Option<super::StateDrift>,
    /// The network's frames against one simulator step from their own history
    /// ([`super::one_step`]; `None` unless asked for, at `w` other than 1, without dynamics,
    /// and in older checks).
    #[serde(default)]
    pub one_step: Option<super::OneStep>,
    /// The reference against itself at twice the iterations ([`super::reference_spread`];
    /// `None` unless asked for, and in older checks).
    #[serde(default)]
    pub spread: Option<super::ReferenceSpread>,
    /// The reference against itself from a start moved by a micrometre
    /// ([`super::reference_sensitivity`]; `None` unless asked for, and in older checks).
    #[serde(default)]
    pub sensitivity: Option<super::ReferenceSpread>,
}

/// Mean distances of `candidate` to `reference` over all frames, the still frames
/// (`still[k]`) and the moving ones.
pub fn frame_means(
    reference: &[Vec<Vec3>],
    candidate: &[Vec<Vec3>],
    still: &[bool],
) -> Result<AmplitudeStats, TrainError> {
    let is_still = |k: usize| still.get(k).copied().unwrap_or(false);
    let is_moving = |k: usize| !is_still(k);
    Ok(AmplitudeStats {
        all_mm: compare_frames(reference, candidate)?.mean_mm,
        still_mm: distance_stats(reference, candidate, &is_still)?.map(|s| s.mean_mm),
        moving_mm: distance_stats(reference, candidate, &is_moving)?.map(|s| s.mean_mm),
    })
}

/// Measures `seq` on `poses` (one frame each) with the still flags `still`.
pub fn measure_motion(
    avatar: &Avatar,
    garment: &Garment,
    poses: &[Pose],
    still: &[bool],
    seq: &Sequences<'_>,
) -> Result<MotionMeasures, TrainError> {
    let n = poses.len();
    let lengths = [
        still.len(),
        seq.network.len(),
        seq.network_static.len(),
        seq.simulator.len(),
        seq.simulator_static.len(),
    ];
    if lengths.iter().any(|&l| l != n) {
        return Err(TrainError::Data(format!(
            "{n} poses but still flags and sequences of {lengths:?} frames"
        )));
    }
    let is_still = |k: usize| still.get(k).copied().unwrap_or(false);
    let is_moving = |k: usize| !is_still(k);
    let amplitude = |dynamic: &[Vec<Vec3>], quiet: &[Vec<Vec3>]| frame_means(quiet, dynamic, still);
    let hem = match reaches_below_hips(avatar, garment) {
        true => {
            let hem = hem_vertices(garment);
            let radii = |frames: &[Vec<Vec3>]| -> Vec<f32> {
                frames
                    .iter()
                    .zip(poses)
                    .map(|(x, p)| hem_radius_m(avatar, p, x, &hem))
                    .collect()
            };
            let (net, sim) = (radii(seq.network), radii(seq.simulator));
            let (net0, sim0) = (radii(seq.network_static), radii(seq.simulator_static));
            let pair = |select: &dyn Fn(usize) -> bool| {
                Some(HemPair {
                    network_m: mean_where(&net, select)?,
                    simulator_m: mean_where(&sim, select)?,
                    network_static_m: mean_where(&net0, select)?,
                    simulator_static_m: mean_where(&sim0, select)?,
                })
            };
            Some(HemComparison {
                vertices: hem.len(),
                still: pair(&is_still),
                moving: pair(&is_moving),
            })
        }
        false => None,
    };
    Ok(MotionMeasures {
        frames: n,
        still_frames: still.iter().filter(|s| **s).count(),
        all: compare_frames(seq.simulator, seq.network)?,
        still: distance_stats(seq.simulator, seq.network, &is_still)?,
        moving: distance_stats(seq.simulator, seq.network, &is_moving)?,
        amplitude: Amplitude {
            network: amplitude(seq.network, seq.network_static)?,
            simulator: amplitude(seq.simulator, seq.simulator_static)?,
        },
        hem,
        rigid: super::rigid_split(
            seq.network,
            seq.network_static,
            seq.simulator,
            seq.simulator_static,
        )?,
        split: Some(super::static_motion_split(seq, still)?),
        drift: None,
        one_step: None,
        spread: None,
        sensitivity: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pooled_distances_and_selection() {
        let a = vec![vec![Vec3::zeros(), Vec3::zeros()]; 2];
        let b = vec![
            vec![Vec3::new(0.001, 0.0, 0.0), Vec3::new(0.003, 0.0, 0.0)],
            vec![Vec3::new(0.010, 0.0, 0.0), Vec3::new(0.010, 0.0, 0.0)],
        ];
        let first = distance_stats(&a, &b, &|k| k == 0).unwrap().unwrap();
        assert!((first.mean_mm - 2.0).abs() < 1e-4 && (first.p95_mm - 3.0).abs() < 1e-4);
        assert_eq!(first.frames, 1);
        assert!(distance_stats(&a, &b, &|_| false).unwrap().is_none());
        assert!((compare_frames(&a, &b).unwrap().mean_mm - 6.0).abs() < 1e-4);
        assert!(compare_frames(&a, &b[..1]).is_err());
    }

    #[test]
    fn mean_where_skips_unselected() {
        assert_eq!(mean_where(&[1.0, 3.0, 5.0], &|k| k != 1), Some(3.0));
        assert_eq!(mean_where(&[1.0], &|_| false), None);
    }
}
