//! Where a retargeted avatar's hips go in each frame: the motion's hips scaled by the ratio
//! of hip heights, grounded, optionally re-centred; then the whole clip grounded on the
//! avatar's own feet (see [`RootPlacement::ground`]).

use super::retarget::{RetargetOptions, SourceMotion, translation_of};
use crate::geometry::{Quat, Vec3};
use crate::scene::{Pose, Skeleton};

/// Per joint, whether it has no children (feet, hands, head, ... ends).
pub(super) fn end_joints(parents: &[Option<usize>]) -> Vec<bool> {
    let mut end = vec![true; parents.len()];
    for p in parents.iter().flatten() {
        if let Some(e) = end.get_mut(*p) {
            *e = false;
        }
    }
    end
}

/// The lowest height of the end joints among `points` (of every point when no end joint
/// is marked).
pub(super) fn lowest_end(points: &[Vec3], ends: &[bool]) -> f32 {
    let lowest = |all: bool| {
        points
            .iter()
            .zip(ends.iter().chain(std::iter::repeat(&false)))
            .filter(|(_, e)| all || **e)
            .map(|(p, _)| p.y)
            .fold(f32::INFINITY, f32::min)
    };
    let y = lowest(false);
    if y.is_finite() { y } else { lowest(true) }
}

/// A motion whose end joints (feet, toes) stay higher than this share of its rig's leg
/// (hip height above the lowest end joint in rest) above its file's floor never stands on it:
/// a jump, a climb, a character seated on a high stool. Standing rigs' lowest end joints
/// (toes, ankles) sit within about a tenth of the leg of the floor.
pub(super) const AIRBORNE_SHARE_OF_LEG: f32 = 0.25;

/// Where the avatar's hips go in each frame.
pub(super) struct RootPlacement {
    hips_a: usize,
    hips_b: usize,
    scale: f32,
    ground_a: f32,
    ground_b: f32,
    /// The lowest height of the motion's end joints above its file's floor (y = 0), file
    /// units, when the motion never comes down to it (more than [`AIRBORNE_SHARE_OF_LEG`] of
    /// the rig's leg): the motion then keeps its height above the floor, and
    /// [`Self::ground`] leaves it there.
    pub(super) clearance_b: Option<f32>,
    offset: Vec3,
    pub(super) under_root0: Option<usize>,
    root_linear_inv: Option<crate::geometry::Mat3>,
}

impl RootPlacement {
    pub(super) fn new(
        source: &SourceMotion,
        skeleton: &Skeleton,
        hips_a: usize,
        hips_b: usize,
        scale: f32,
        rest_pos: &[Vec3],
        options: &RetargetOptions,
    ) -> Self {
        // Ground = lowest end joint over the whole motion (a root joint at the floor under
        // the hips is no foot); a motion whose feet stay well above its file's floor (y = 0)
        // keeps that floor and its height above it.
        let ends_b = end_joints(&source.parents);
        let lowest_b = source
            .frames
            .iter()
            .map(|w| lowest_end(&w.iter().map(|x| x.1).collect::<Vec<_>>(), &ends_b))
            .fold(f32::INFINITY, f32::min);
        let rest_b: Vec<Vec3> = source.rest.iter().map(|r| r.1).collect();
        let leg_b = rest_b.get(hips_b).map_or(0.0, |p| p.y) - lowest_end(&rest_b, &ends_b);
        let clearance_b = (leg_b > 0.0 && lowest_b.is_finite())
            .then_some(lowest_b)
            .filter(|y| *y > AIRBORNE_SHARE_OF_LEG * leg_b);
        let ground_b = if clearance_b.is_some() { 0.0 } else { lowest_b };
        let ground_a = lowest_end(rest_pos, &end_joints(&skeleton.parents));
        let start_b = source
            .frames
            .first()
            .and_then(|w| w.get(hips_b))
            .map(|(_, p)| *p)
            .unwrap_or_else(Vec3::zeros);
        let offset = if options.recentre {
            Vec3::new(
                rest_pos[hips_a].x - scale * start_b.x,
                0.0,
                rest_pos[hips_a].z - scale * start_b.z,
            )
        } else {
            Vec3::zeros()
        };
        let mut under_root0 = Some(hips_a);
        while let Some(j) = under_root0 {
            if j == 0 {
                break;
            }
            under_root0 = skeleton.parents[j];
        }
        Self {
            hips_a,
            hips_b,
            scale,
            ground_a,
            ground_b,
            clearance_b,
            offset,
            under_root0,
            root_linear_inv: skeleton.world_from_root_parent[0]
                .fixed_view::<3, 3>(0, 0)
                .into_owned()
                .try_inverse(),
        }
    }

    /// Sets `pose`'s root translation so the avatar's hips follow the motion's in frame `w`.
    pub(super) fn place(&self, skeleton: &Skeleton, w: &[(Quat, Vec3)], pose: &mut Pose) {
        let (Some(_), Some(inv), Some((_, p_b))) =
            (self.under_root0, self.root_linear_inv, w.get(self.hips_b))
        else {
            return;
        };
        let s = self.scale;
        let target = Vec3::new(
            s * p_b.x,
            self.ground_a + s * (p_b.y - self.ground_b),
            s * p_b.z,
        ) + self.offset;
        let current = translation_of(&skeleton.world_from_joint(pose)[self.hips_a]);
        let shift = inv * (target - current);
        if shift.iter().all(|v| v.is_finite()) {
            pose.root_translation += shift;
        }
    }

    /// Moves every frame up or down together so that the lowest end joint of the avatar over
    /// the whole motion is at its rest ground: the motion's own ground, scaled by hip
    /// heights, leaves the feet above or below the floor when the rigs' legs differ (a CMU
    /// rest pose's legs are splayed, its hips joint sits high above the thighs).
    /// A motion that never comes down to its own floor ([`Self::clearance_b`]) is left as
    /// placed.
    pub(super) fn ground(&self, skeleton: &Skeleton, frames: &mut [Pose]) {
        let (Some(_), Some(inv), None) = (self.under_root0, self.root_linear_inv, self.clearance_b)
        else {
            return;
        };
        let ends = end_joints(&skeleton.parents);
        let lowest = frames
            .iter()
            .map(|pose| lowest_end(&skeleton.joint_positions(pose), &ends))
            .fold(f32::INFINITY, f32::min);
        let shift = inv * Vec3::new(0.0, self.ground_a - lowest, 0.0);
        if shift.iter().all(|v| v.is_finite()) {
            for pose in frames {
                pose.root_translation += shift;
            }
        }
    }
}
