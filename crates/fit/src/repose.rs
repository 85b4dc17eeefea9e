//! Garments modelled on another limb pose. A shirt made on a T-pose body has its sleeves
//! straight out, where an A-pose avatar's arms hang 40 degrees lower; trousers made on a body
//! standing with its feet apart have their legs spread where the avatar's legs hang straight.
//! Once the garment is placed around the trunk, the avatar's upper arms are raised (or
//! lowered) in the vertical plane of each arm, and its thighs spread (or drawn together) in
//! the body's frontal plane, until most of the garment lies around those limbs at the ease
//! from them ([`limb_angle`]: a garment without sleeves, such as a skirt the hands hang
//! beside, has the most there at the rest pose; the legs are only searched for a garment
//! with an opening for each leg, [`super::openings::has_leg_openings`], since a flared skirt
//! comes closer to spread thighs without being made for them). When that is clearly more
//! than at the rest pose, the garment is carried back to the rest pose by inverse skinning
//! ([`unpose`]): each vertex takes the skin weights of the nearest posed body vertex
//! (smoothed over the garment's edges) and the inverse of its blended joint motion.

use neural_cloth_core::geometry::{KdTree, Mat4, Quat, Topology, TriMesh, Vec3, safe_normalize};
use neural_cloth_core::io::joint_names::classify;
use neural_cloth_core::io::joint_structure::{RigShape, label_by_structure};
use neural_cloth_core::scene::garment::transfer_skin_weights;
use neural_cloth_core::scene::skeleton::rotation_of;
use neural_cloth_core::scene::{Avatar, GarmentOptions, Pose};

use neural_cloth_physics::PosedBody;

use super::FitError;
use super::align::Placement;
use super::openings::has_leg_openings;

/// Arm angles tried, degrees above the avatar's rest (negative: lower).
const ARM_ANGLES_DEG: [f32; 11] = [
    -40.0, -30.0, -20.0, -10.0, 0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0,
];
/// Leg angles tried, degrees of spread beyond the avatar's rest (negative: drawn together).
const LEG_ANGLES_DEG: [f32; 9] = [-15.0, -10.0, -5.0, 0.0, 5.0, 10.0, 15.0, 20.0, 30.0];
/// Share of the garment's area that must come around the limbs with the limbs moved, over
/// the share at the rest pose, for the garment to be re-posed.
const MIN_GAIN: f32 = 0.03;
/// A garment vertex is around a limb when its clearance from the nearest limb vertex is
/// within this of the ease, metres; it counts the more the closer (see [`Limbs::around`]).
const NEAR_M: f32 = 0.03;
/// A body vertex belongs to an upper arm (a thigh) when this much of its skin weight is on
/// it.
const LIMB_WEIGHT: f32 = 0.5;
/// Smoothing passes of the skin weights carried from the posed body to the garment.
const SMOOTHING_PASSES: usize = 10;
/// A joint whose skinning matrix from the rest pose to the pose differs from the identity by
/// more than this in an entry is moved by the pose.
const MOVED_EPS: f32 = 1e-6;

/// Which pair of limbs a [`Limbs`] turns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Limb {
    /// The upper arms, raised (positive degrees) or lowered in each arm's vertical plane.
    Arms,
    /// The thighs, spread apart (positive degrees) or drawn together in the plane of each
    /// thigh and the body's left-right axis.
    Legs,
}

impl Limb {
    /// Canonical names of the limb's first joint and the joint at the end of its bone, per
    /// side.
    fn joint_names(self) -> [(&'static str, &'static str); 2] {
        match self {
            Limb::Arms => [("LeftArm", "LeftForeArm"), ("RightArm", "RightForeArm")],
            Limb::Legs => [("LeftUpLeg", "LeftLeg"), ("RightUpLeg", "RightLeg")],
        }
    }

    /// Angles the search tries, degrees.
    fn angles_deg(self) -> &'static [f32] {
        match self {
            Limb::Arms => &ARM_ANGLES_DEG,
            Limb::Legs => &LEG_ANGLES_DEG,
        }
    }

    /// The axis about which a positive angle turns a bone of rest direction `dir` whose
    /// joint lies `side_x` metres from the body's middle (its sign: the side): up towards
    /// +Y for an arm, outwards along X for a leg. `None` when the bone lies along that
    /// direction.
    fn axis(self, dir: Vec3, side_x: f32) -> Option<Vec3> {
        let towards = match self {
            Limb::Arms => Vec3::y(),
            Limb::Legs if side_x != 0.0 => Vec3::x() * side_x.signum(),
            Limb::Legs => return None,
        };
        safe_normalize(dir.cross(&towards))
    }

    /// The word for the limbs in messages ("arms", "legs").
    pub fn label(self) -> &'static str {
        match self {
            Limb::Arms => "arms",
            Limb::Legs => "legs",
        }
    }
}

/// A pair of the avatar's limbs (upper arms or thighs): per side, the joint and the axis a
/// positive angle turns it about, and which body vertices the two limbs carry.
#[derive(Clone, Debug)]
pub struct Limbs {
    limb: Limb,
    sides: [(usize, Vec3); 2],
    on_limb: Vec<bool>,
}

impl Limbs {
    /// The upper arms (LeftArm/RightArm by name, else by the skeleton's structure); `None`
    /// when the avatar has no two arms.
    pub fn arms(avatar: &Avatar) -> Option<Self> {
        Self::of(avatar, Limb::Arms)
    }

    /// The thighs (LeftUpLeg/RightUpLeg by name, else by the skeleton's structure); `None`
    /// when the avatar has no two legs.
    pub fn legs(avatar: &Avatar) -> Option<Self> {
        Self::of(avatar, Limb::Legs)
    }

    /// The limbs of kind `limb` and their bones' rest directions (towards the next joint of
    /// the chain); `None` when the avatar has no two of them.
    pub fn of(avatar: &Avatar, limb: Limb) -> Option<Self> {
        let sk = &avatar.skeleton;
        let rest = sk.joint_positions(&sk.rest_pose());
        let by_name = classify(&sk.names).canonical;
        let find =
            |labels: &[Option<&str>], name: &str| labels.iter().position(|c| *c == Some(name));
        let [(left, left_end), (right, right_end)] = limb.joint_names();
        let named = |labels: &[Option<&str>]| -> Option<[(usize, usize); 2]> {
            Some([
                (find(labels, left)?, find(labels, left_end)?),
                (find(labels, right)?, find(labels, right_end)?),
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
        // The body's middle: halfway between the two sides' joints.
        let middle_x = 0.5 * (rest[joints[0].0].x + rest[joints[1].0].x);
        let side = |(joint, end): (usize, usize)| {
            let dir = safe_normalize(rest[end] - rest[joint])?;
            Some((joint, limb.axis(dir, rest[joint].x - middle_x)?))
        };
        // The upper arms carry a sleeve, the thighs a trouser leg; forearms, hands and shins
        // are left out (a skirt's side is not a sleeve of the hand hanging beside it).
        let limb_joint: Vec<bool> = (0..sk.len())
            .map(|j| j == joints[0].0 || j == joints[1].0)
            .collect();
        let skin = &avatar.skin;
        let on_limb = (0..skin.weights.len())
            .map(|v| {
                let on: f32 = skin.joints[v]
                    .iter()
                    .zip(skin.weights[v])
                    .filter(|(j, _)| limb_joint.get(usize::from(**j)).copied().unwrap_or(false))
                    .map(|(_, w)| w)
                    .sum();
                on >= LIMB_WEIGHT
            })
            .collect();
        Some(Self {
            limb,
            sides: [side(joints[0])?, side(joints[1])?],
            on_limb,
        })
    }

    /// Which limbs these are.
    pub fn limb(&self) -> Limb {
        self.limb
    }

    /// The left and right limbs' first joints (upper arms or thighs).
    pub fn joints(&self) -> [usize; 2] {
        [self.sides[0].0, self.sides[1].0]
    }

    /// The joints [`Limbs::pose`] moves: both limbs' first joints and every joint below them.
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

    /// Share of `weights` of the garment vertices `placed` that lie around these limbs of
    /// the avatar posed with them at `degrees`: nearest to a limb vertex, at the ease from
    /// it (within [`NEAR_M`]), each counted by `1 - (d / NEAR_M)^2` for a clearance `d` off
    /// the ease. The weighting makes the share peak where the garment lies at the ease, not
    /// on a plateau of angles all within the tolerance (a thigh turns a trouser leg's
    /// vertices only a few centimetres either way).
    fn around(
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
            if !self.on_limb.get(i).copied().unwrap_or(false) {
                continue;
            }
            let clearance = (p - body.positions()[i]).dot(&body.normals()[i]);
            let off = (clearance - ease_m) / NEAR_M;
            if off.abs() < 1.0 {
                near += f64::from(w * (1.0 - off * off));
            }
        }
        Ok(if total > 0.0 {
            (near / total) as f32
        } else {
            0.0
        })
    }

    /// The avatar's rest pose with both limbs turned `degrees` (see [`Limb`]).
    pub fn pose(&self, avatar: &Avatar, degrees: f32) -> Pose {
        let mut pose = avatar.skeleton.rest_pose();
        self.turn(avatar, degrees, &mut pose);
        pose
    }

    /// Turns both limbs of `pose` by `degrees` more (see [`Limb`]), about the axes they have
    /// at the rest pose, in the frames their parents have in `pose`.
    pub fn turn(&self, avatar: &Avatar, degrees: f32, pose: &mut Pose) {
        let sk = &avatar.skeleton;
        let world = sk.world_from_joint(pose);
        for (joint, axis) in self.sides {
            let turn = Quat::from_scaled_axis(axis * degrees.to_radians());
            let parent = sk.parents[joint]
                .map(|p| rotation_of(&world[p]))
                .unwrap_or_else(|| rotation_of(&sk.world_from_root_parent[joint]));
            let local = pose.rotations[joint];
            pose.rotations[joint] = parent.inverse() * turn * parent * local;
        }
    }
}

/// The angle of `limbs` (degrees from the avatar's rest, see [`Limb`]) at which most of the
/// placed garment lies around them, with that share there and at the rest pose;
/// `(0, share, share)` when moving the limbs does not gain [`MIN_GAIN`].
pub fn limb_angle(
    avatar: &Avatar,
    limbs: &Limbs,
    placed: &[Vec3],
    weights: &[f32],
    ease_m: f32,
) -> Result<(f32, f32, f32), FitError> {
    let share_at = |degrees: f32| limbs.around(avatar, degrees, placed, weights, ease_m);
    let at_rest = share_at(0.0)?;
    let mut best = (0.0f32, at_rest);
    for &degrees in limbs.limb.angles_deg() {
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

/// How far a garment's limbs are from the avatar's, degrees (0 where they match or where
/// the avatar or the garment has no such limbs): sleeves above the upper arms, trouser legs
/// spread beyond the thighs (searched only for a garment with an opening for each leg).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LimbAngles {
    /// Degrees above the avatar's upper arms the sleeves were made (negative: below).
    pub sleeves_deg: f32,
    /// Degrees beyond the avatar's thighs the legs were spread (negative: drawn together);
    /// `None` when the garment has no opening for each leg or the avatar no two legs.
    pub legs_deg: Option<f32>,
}

impl LimbAngles {
    /// The angles of the garment `mesh` (metres, Y up) at `placed` (the same vertices
    /// placed on the avatar), area `weights` per vertex.
    pub fn measure(
        avatar: &Avatar,
        mesh: &TriMesh,
        placed: &[Vec3],
        weights: &[f32],
        ease_m: f32,
    ) -> Result<Self, FitError> {
        let angle = |limbs: Option<Limbs>| -> Result<Option<f32>, FitError> {
            limbs
                .map(|limbs| Ok(limb_angle(avatar, &limbs, placed, weights, ease_m)?.0))
                .transpose()
        };
        let legs = if has_leg_openings(mesh) {
            Limbs::legs(avatar)
        } else {
            None
        };
        Ok(Self {
            sleeves_deg: angle(Limbs::arms(avatar))?.unwrap_or(0.0),
            legs_deg: angle(legs)?,
        })
    }

    /// The avatar's rest pose with its limbs at these angles.
    pub fn pose(&self, avatar: &Avatar) -> Pose {
        let mut pose = avatar.skeleton.rest_pose();
        for (limbs, degrees) in [
            (Limbs::arms(avatar), self.sleeves_deg),
            (Limbs::legs(avatar), self.legs_deg.unwrap_or(0.0)),
        ] {
            if let Some(limbs) = limbs
                && degrees != 0.0
            {
                limbs.turn(avatar, degrees, &mut pose);
            }
        }
        pose
    }

    /// Whether any limb is off the avatar's.
    pub fn any(&self) -> bool {
        self.sleeves_deg != 0.0 || self.legs_deg.is_some_and(|d| d != 0.0)
    }
}

/// The limb step of the fit: the limb angles of the garment `given` (metres, in its file's
/// frame) placed by `placement` ([`LimbAngles::measure`]), and, when one is not 0 and
/// `repose` allows, the garment carried back to the avatar's rest pose ([`unpose`]) and
/// returned in the file's frame, to be placed again.
pub(super) fn repose_given(
    avatar: &Avatar,
    given: &TriMesh,
    placement: &Placement,
    weights: &[f32],
    ease_m: f32,
    repose: bool,
) -> Result<(LimbAngles, Option<TriMesh>), FitError> {
    let mut placed = given.clone();
    placed.positions = placement.apply_all(&given.positions);
    let angles = LimbAngles::measure(avatar, given, &placed.positions, weights, ease_m)?;
    if !angles.any() || !repose {
        return Ok((angles, None));
    }
    let rest = unpose(avatar, &angles.pose(avatar), &placed)?;
    let mut back = given.clone();
    back.positions = rest.iter().map(|q| placement.invert(q)).collect();
    Ok((angles, Some(back)))
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
        let arms = Limbs::arms(&avatar).unwrap();
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
            limb_angle(&avatar, &arms, &t_shirt, &weights, 0.015).unwrap();
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
            limb_angle(&avatar, &arms, &shirt.mesh.positions, &weights, 0.015).unwrap();
        assert_eq!(angle, 0.0);
    }

    #[test]
    fn spreading_the_legs_turns_each_knee_outwards_about_its_hip() {
        let avatar = mannequin().unwrap();
        let sk = &avatar.skeleton;
        let legs = Limbs::legs(&avatar).unwrap();
        assert_eq!(legs.limb(), Limb::Legs);
        let rest = sk.joint_positions(&sk.rest_pose());
        let spread = sk.joint_positions(&legs.pose(&avatar, 15.0));
        let together = sk.joint_positions(&legs.pose(&avatar, -10.0));
        let middle = 0.5 * (rest[legs.joints()[0]].x + rest[legs.joints()[1]].x);
        for hip in legs.joints() {
            let knee = (0..sk.len()).find(|&j| sk.parents[j] == Some(hip)).unwrap();
            let side = (rest[hip].x - middle).signum();
            let (a, b, c) = (
                rest[knee] - rest[hip],
                spread[knee] - spread[hip],
                together[knee] - together[hip],
            );
            assert!(
                (spread[hip] - rest[hip]).norm() < 1e-6,
                "the hip joint stays"
            );
            assert!((a.angle(&b).to_degrees() - 15.0).abs() < 0.1);
            assert!((a.angle(&c).to_degrees() - 10.0).abs() < 0.1);
            assert!(b.x * side > a.x * side + 0.05, "spread: {a:?} -> {b:?}");
            assert!(c.x * side < a.x * side, "together: {a:?} -> {c:?}");
            // The turn stays in the plane of the thigh and the left-right axis.
            assert!((b.z - a.z).abs() < 0.01, "{a:?} -> {b:?}");
        }
        // The arms do not move.
        let arms = Limbs::arms(&avatar).unwrap();
        for j in arms.joints() {
            assert!((spread[j] - rest[j]).norm() < 1e-6);
        }
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
        let arms = Limbs::arms(&avatar).unwrap();
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
