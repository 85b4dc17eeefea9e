//! Garments modelled on another arm pose: a shirt made on a T-pose body has its sleeves
//! straight out, where an A-pose avatar's arms hang 40 degrees lower. Once the garment is
//! placed around the trunk, the avatar's upper arms are raised (or lowered) in the vertical
//! plane of each arm until most of the garment lies around the arms, at the ease from them
//! ([`sleeve_angle`]: a garment without sleeves, such as a skirt the hands hang beside, has
//! the most there at the rest pose); when that is clearly more than at the rest pose, the
//! garment is carried back to the rest pose by inverse skinning ([`unpose`]): each vertex
//! takes the skin weights of the nearest posed body vertex (smoothed over the garment's
//! edges) and the inverse of its blended joint motion.

use neural_cloth_core::geometry::{KdTree, Mat4, Quat, Topology, TriMesh, Vec3, safe_normalize};
use neural_cloth_core::io::joint_names::classify;
use neural_cloth_core::io::joint_structure::{RigShape, label_by_structure};
use neural_cloth_core::scene::garment::transfer_skin_weights;
use neural_cloth_core::scene::skeleton::rotation_of;
use neural_cloth_core::scene::{Avatar, GarmentOptions, Pose};

use neural_cloth_physics::PosedBody;

use super::FitError;
use super::align::Placement;

/// Arm angles tried, degrees above the avatar's rest (negative: lower).
const ANGLES_DEG: [f32; 11] = [
    -40.0, -30.0, -20.0, -10.0, 0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0,
];
/// Share of the garment's area that must come around the arms with the arms moved, over the
/// share at the rest pose, for the garment to be re-posed.
const MIN_GAIN: f32 = 0.03;
/// A garment vertex is around an arm when its clearance from the nearest arm vertex is
/// within this of the ease, metres.
const NEAR_M: f32 = 0.03;
/// A body vertex belongs to an upper arm when this much of its skin weight is on it.
const ARM_WEIGHT: f32 = 0.5;
/// Smoothing passes of the skin weights carried from the posed body to the garment.
const SMOOTHING_PASSES: usize = 10;
/// A joint whose skinning matrix from the rest pose to the pose differs from the identity by
/// more than this in an entry is moved by the pose.
const MOVED_EPS: f32 = 1e-6;

/// The avatar's upper arms: per side, the upper-arm joint and its bone's rest direction, and
/// which body vertices the upper arms carry.
#[derive(Clone, Debug)]
pub struct Arms {
    sides: [(usize, Vec3); 2],
    on_arm: Vec<bool>,
}

impl Arms {
    /// The upper arms (LeftArm/RightArm by name, else by the skeleton's structure) and their
    /// forearms' rest positions; None when the avatar has no two arms.
    pub fn of(avatar: &Avatar) -> Option<Self> {
        let sk = &avatar.skeleton;
        let rest = sk.joint_positions(&sk.rest_pose());
        let by_name = classify(&sk.names).canonical;
        let find =
            |labels: &[Option<&str>], name: &str| labels.iter().position(|c| *c == Some(name));
        let named = |labels: &[Option<&str>]| -> Option<[(usize, usize); 2]> {
            Some([
                (find(labels, "LeftArm")?, find(labels, "LeftForeArm")?),
                (find(labels, "RightArm")?, find(labels, "RightForeArm")?),
            ])
        };
        let joints = named(&by_name).or_else(|| {
            let shape = RigShape {
                parents: &sk.parents,
                rest: &rest,
                frames: &[],
            };
            named(&label_by_structure(&shape).ok()?)
        })?;
        let dir = |(arm, fore): (usize, usize)| safe_normalize(rest[fore] - rest[arm]);
        // The upper arms carry a sleeve; forearms and hands are left out (a skirt's side is
        // not a sleeve of the hand hanging beside it).
        let arm_joint: Vec<bool> = (0..sk.len())
            .map(|j| j == joints[0].0 || j == joints[1].0)
            .collect();
        let skin = &avatar.skin;
        let on_arm = (0..skin.weights.len())
            .map(|v| {
                let on: f32 = skin.joints[v]
                    .iter()
                    .zip(skin.weights[v])
                    .filter(|(j, _)| arm_joint.get(usize::from(**j)).copied().unwrap_or(false))
                    .map(|(_, w)| w)
                    .sum();
                on >= ARM_WEIGHT
            })
            .collect();
        Some(Self {
            sides: [
                (joints[0].0, dir(joints[0])?),
                (joints[1].0, dir(joints[1])?),
            ],
            on_arm,
        })
    }

    /// The left and right upper-arm joints.
    pub fn joints(&self) -> [usize; 2] {
        [self.sides[0].0, self.sides[1].0]
    }

    /// The joints [`Arms::pose`] moves: both upper arms and every joint below them.
    pub fn moved_joints(&self, sk: &neural_cloth_core::scene::Skeleton) -> Vec<bool> {
        let mut moved = vec![false; sk.len()];
        for (joint, _) in self.sides {
            if let Some(m) = moved.get_mut(joint) {
                *m = true;
            }
        }
        // Parents come before their children.
        for j in 0..sk.len() {
            if let Some(p) = sk.parents[j]
                && moved[p]
            {
                moved[j] = true;
            }
        }
        moved
    }

    /// Share of `weights` of the garment vertices `placed` that lie around the upper arms of
    /// the avatar posed with its arms at `degrees`: nearest to an upper-arm vertex, at the
    /// ease from it (within [`NEAR_M`]).
    fn around_arms(
        &self,
        avatar: &Avatar,
        degrees: f32,
        placed: &[Vec3],
        weights: &[f32],
        ease_m: f32,
    ) -> Result<f32, FitError> {
        let body = PosedBody::from_avatar(avatar, &self.pose(avatar, degrees)).map_err(|e| {
            FitError::Body {
                avatar: avatar.name.clone(),
                reason: e.to_string(),
            }
        })?;
        let tree = KdTree::new(body.positions());
        let (mut near, mut total) = (0.0f64, 0.0f64);
        for (p, &w) in placed.iter().zip(weights) {
            total += f64::from(w);
            let Some((i, _)) = tree.nearest(p) else {
                continue;
            };
            let i = i as usize;
            if !self.on_arm.get(i).copied().unwrap_or(false) {
                continue;
            }
            let clearance = (p - body.positions()[i]).dot(&body.normals()[i]);
            if (clearance - ease_m).abs() < NEAR_M {
                near += f64::from(w);
            }
        }
        Ok(if total > 0.0 {
            (near / total) as f32
        } else {
            0.0
        })
    }

    /// The avatar's rest pose with both upper arms turned `degrees` up (negative: down) in
    /// the vertical plane of each arm.
    pub fn pose(&self, avatar: &Avatar, degrees: f32) -> Pose {
        let sk = &avatar.skeleton;
        let mut pose = sk.rest_pose();
        let world = sk.world_from_joint(&pose);
        for (joint, dir) in self.sides {
            // Raising turns the bone towards +Y about dir x Y.
            let Some(axis) = safe_normalize(dir.cross(&Vec3::y())) else {
                continue;
            };
            let turn = Quat::from_scaled_axis(axis * degrees.to_radians());
            let parent = sk.parents[joint]
                .map(|p| rotation_of(&world[p]))
                .unwrap_or_else(|| rotation_of(&sk.world_from_root_parent[joint]));
            let local = pose.rotations[joint];
            pose.rotations[joint] = parent.inverse() * turn * parent * local;
        }
        pose
    }
}

/// The arm angle (degrees above the avatar's rest, see [`Arms::pose`]) at which most of the
/// placed garment lies around the arms, with that share there and at the rest pose;
/// `(0, share, share)` when moving the arms does not gain [`MIN_GAIN`].
pub fn sleeve_angle(
    avatar: &Avatar,
    arms: &Arms,
    placed: &[Vec3],
    weights: &[f32],
    ease_m: f32,
) -> Result<(f32, f32, f32), FitError> {
    let share_at = |degrees: f32| arms.around_arms(avatar, degrees, placed, weights, ease_m);
    let at_rest = share_at(0.0)?;
    let mut best = (0.0f32, at_rest);
    for degrees in ANGLES_DEG {
        if degrees != 0.0 {
            let share = share_at(degrees)?;
            if share > best.1 {
                best = (degrees, share);
            }
        }
    }
    // Refine to 2.5 degrees around the best.
    for step in [5.0, 2.5] {
        if best.0 != 0.0 {
            let centre = best.0;
            for degrees in [centre - step, centre + step] {
                let share = share_at(degrees)?;
                if share > best.1 {
                    best = (degrees, share);
                }
            }
        }
    }
    if best.1 < at_rest + MIN_GAIN {
        return Ok((0.0, at_rest, at_rest));
    }
    Ok((best.0, best.1, at_rest))
}

/// The sleeve step of the fit: the arm angle of the garment `given` (metres, in its file's
/// frame) placed by `placement` ([`sleeve_angle`]; 0 for an avatar without two arms), and,
/// when it is not 0 and `repose` allows, the garment carried back to the avatar's rest pose
/// ([`unpose`]) and returned in the file's frame, to be placed again.
pub(super) fn repose_given(
    avatar: &Avatar,
    given: &TriMesh,
    placement: &Placement,
    weights: &[f32],
    ease_m: f32,
    repose: bool,
) -> Result<(f32, Option<TriMesh>), FitError> {
    let Some(arms) = Arms::of(avatar) else {
        return Ok((0.0, None));
    };
    let mut placed = given.clone();
    placed.positions = placement.apply_all(&given.positions);
    let (degrees, ..) = sleeve_angle(avatar, &arms, &placed.positions, weights, ease_m)?;
    if degrees == 0.0 || !repose {
        return Ok((degrees, None));
    }
    let rest = unpose(avatar, &arms.pose(avatar, degrees), &placed)?;
    let mut back = given.clone();
    back.positions = rest.iter().map(|q| placement.invert(q)).collect();
    Ok((degrees, Some(back)))
}

/// Carries `mesh`'s vertices, made around the avatar at `pose`, back to the avatar's rest
/// pose: each vertex is bound to the posed body (nearest vertex's skin weights, smoothed
/// over the mesh's edges) and moved by the inverse of its blended joint motion from the rest
/// pose to `pose`. Only the parts around the joints `pose` moves are carried (a shirt's
/// sleeves when the arms moved): a vertex whose nearest posed body vertex has no weight on a
/// moved joint stays exactly where it is, however the smoothing spread the weights, so the
/// torso of a shirt is untouched. A vertex whose blended motion cannot be inverted stays
/// where it is too.
pub fn unpose(avatar: &Avatar, pose: &Pose, mesh: &TriMesh) -> Result<Vec<Vec3>, FitError> {
    let body = avatar.pose_vertices(pose);
    let topology = Topology::new(mesh);
    let bind = |smoothing_passes: usize| {
        let options = GarmentOptions {
            smoothing_passes,
            max_distance_m: 5.0,
        };
        transfer_skin_weights(
            &body,
            &avatar.skin,
            &mesh.positions,
            &topology,
            &options,
            "garment",
        )
        .map_err(|e| FitError::Body {
            avatar: avatar.name.clone(),
            reason: e.to_string(),
        })
    };
    let skin = bind(SMOOTHING_PASSES)?;
    let nearest = bind(0)?;
    let sk = &avatar.skeleton;
    let to_rest: Vec<Mat4> = sk
        .skin_from_bind(&sk.rest_pose())
        .iter()
        .zip(sk.skin_from_bind(pose))
        .map(|(rest, posed)| posed * rest.try_inverse().unwrap_or_else(Mat4::identity))
        .collect();
    let moved: Vec<bool> = to_rest
        .iter()
        .map(|m| (m - Mat4::identity()).amax() > MOVED_EPS)
        .collect();
    let on_moved = |joints: &[u16], weights: &[f32]| {
        joints
            .iter()
            .zip(weights)
            .any(|(j, w)| *w > 0.0 && moved.get(usize::from(*j)).copied().unwrap_or(false))
    };
    Ok(mesh
        .positions
        .iter()
        .enumerate()
        .map(|(v, p)| {
            if !on_moved(&nearest.joints[v], &nearest.weights[v]) {
                return *p;
            }
            let mut blend = Mat4::zeros();
            for (j, w) in skin.joints[v].iter().zip(skin.weights[v]) {
                if let Some(m) = to_rest.get(usize::from(*j)) {
                    blend += m * w;
                }
            }
            match blend.try_inverse() {
                Some(inv) => inv.transform_point(&(*p).into()).coords,
                None => *p,
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use neural_cloth_core::scene::procedural::{GarmentKind, builtin_garment, mannequin};

    #[test]
    fn a_t_posed_shirt_is_found_and_carried_back_to_the_a_pose() {
        let avatar = mannequin().unwrap();
        let arms = Arms::of(&avatar).unwrap();
        // Raising by the A-pose's drop makes the arms horizontal.
        let t_pose = arms.pose(&avatar, 42.0);
        let joints = avatar.skeleton.joint_positions(&t_pose);
        let (arm, fore) = (7, 8);
        let bone = joints[fore] - joints[arm];
        assert!(bone.y.abs() < 1e-3 * bone.norm(), "{bone:?}");
        let shirt = builtin_garment(&avatar, GarmentKind::TShirt, 600, None).unwrap();
        let t_shirt = shirt.pose_vertices(&avatar, &t_pose);
        let weights = vec![1.0; t_shirt.len()];
        let (angle, share, at_rest) =
            sleeve_angle(&avatar, &arms, &t_shirt, &weights, 0.015).unwrap();
        assert!((angle - 42.0).abs() <= 5.0, "{angle}: {share} vs {at_rest}");
        let mut mesh = shirt.mesh.clone();
        mesh.positions = t_shirt;
        let back = unpose(&avatar, &arms.pose(&avatar, angle), &mesh).unwrap();
        let mean = back
            .iter()
            .zip(&shirt.mesh.positions)
            .map(|(p, q)| (p - q).norm())
            .sum::<f32>()
            / back.len() as f32;
        assert!(mean < 0.01, "{mean} m");
        // The A-pose shirt itself stays.
        let weights = vec![1.0; shirt.vertex_count()];
        let (angle, ..) =
            sleeve_angle(&avatar, &arms, &shirt.mesh.positions, &weights, 0.015).unwrap();
        assert_eq!(angle, 0.0);
    }

    /// Share of each vertex's weights in `skin` on the joints of `moved`.
    fn share_on(skin: &neural_cloth_core::geometry::SkinWeights, moved: &[bool]) -> Vec<f32> {
        skin.joints
            .iter()
            .zip(&skin.weights)
            .map(|(js, ws)| {
                js.iter()
                    .zip(ws)
                    .filter(|(j, _)| moved[usize::from(**j)])
                    .map(|(_, w)| w)
                    .sum()
            })
            .collect()
    }

    #[test]
    fn reposing_a_t_posed_shirt_moves_its_sleeves_only() {
        let avatar = mannequin().unwrap();
        let sk = &avatar.skeleton;
        let arms = Arms::of(&avatar).unwrap();
        let t_pose = arms.pose(&avatar, 42.0);
        let moved = arms.moved_joints(sk);
        let shirt = builtin_garment(&avatar, GarmentKind::TShirt, 1200, None).unwrap();
        let t_shirt = shirt.pose_vertices(&avatar, &t_pose);
        let mut mesh = shirt.mesh.clone();
        mesh.positions = t_shirt.clone();
        let back = unpose(&avatar, &t_pose, &mesh).unwrap();
        // The torso: the shirt's vertices with no weight on the upper arms or below. Posing
        // the arms did not move them, and re-posing must not either.
        let share = share_on(&shirt.skin, &moved);
        let mut torso = 0;
        let mut worst = 0.0f32;
        for v in 0..back.len() {
            if share[v] == 0.0 {
                torso += 1;
                worst = worst.max((back[v] - t_shirt[v]).norm());
            }
        }
        assert!(torso > back.len() / 3, "{torso} of {}", back.len());
        assert!(worst <= 1e-6, "a torso vertex moved {worst} m");
        // The sleeve tips (the vertices farthest out along each arm, all but 1 % of their
        // weight on it) turn back down by the 42 degrees the arms were raised, about the
        // shoulder: to where the A-pose shirt had them.
        let rest = sk.joint_positions(&sk.rest_pose());
        for (joint, _) in arms.sides {
            let side = rest[joint].x.signum();
            let out = |v: usize| (shirt.mesh.positions[v] - rest[joint]).norm();
            let tip = (0..back.len())
                .filter(|&v| share[v] > 0.99 && shirt.mesh.positions[v].x * side > 0.0)
                .max_by(|&a, &b| out(a).total_cmp(&out(b)))
                .unwrap();
            let (a, t, b) = (shirt.mesh.positions[tip], t_shirt[tip], back[tip]);
            let turned = (t - rest[joint]).angle(&(b - rest[joint])).to_degrees();
            assert!(
                (turned - 42.0).abs() < 1.0,
                "tip {tip} turned {turned} degrees"
            );
            assert!(
                (t - a).norm() > 0.1,
                "tip {tip} did not move for the T-pose"
            );
            assert!((b - a).norm() < 2e-3, "tip {tip}: {b:?} vs {a:?}");
        }
    }
}
