//! Finding a rig's canonical joints from its skeleton's structure, where the names say nothing
//! (`bone_07`, `j12`, a foreign language): the legs are the two chains that reach the ground
//! from one branching joint, the hips the joint where they meet the chain that rises to the
//! head, the arms the two chains branching off that spine that reach farthest sideways. Left
//! and right come from the way the toes point in the rest pose (else from the way the knees
//! bend in the motion, else the rig is taken to face +Z); the joints along each chain from
//! their heights (legs) and bone lengths (arms: upper arm and forearm of about equal length,
//! the hand and fingers shorter). The rig must stand Y up in a T- or A-like rest pose.

use crate::geometry::{Quat, Vec3};

/// A rig's hierarchy and rest pose: what [`label_by_structure`] reads.
#[derive(Clone, Copy, Debug)]
pub struct RigShape<'a> {
    /// Parent of each joint (parents precede children).
    pub parents: &'a [Option<usize>],
    /// World position of each joint in the rest pose, any unit, Y up.
    pub rest: &'a [Vec3],
    /// World rotation and position of each joint per frame, when the rig comes with a motion
    /// (the knees' bend then tells forward when no toes do); may be empty.
    pub frames: &'a [Vec<(Quat, Vec3)>],
}

/// Canonical (Mixamo) names of the arm joints, left then right: clavicle, upper arm,
/// forearm, hand.
const ARMS: [[&str; 4]; 2] = [
    ["LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand"],
    ["RightShoulder", "RightArm", "RightForeArm", "RightHand"],
];
/// Canonical names of the leg joints, left then right: thigh, shin, foot, toes.
const LEGS: [[&str; 4]; 2] = [
    ["LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase"],
    ["RightUpLeg", "RightLeg", "RightFoot", "RightToeBase"],
];
/// Upper arm over forearm length expected of an arm (humans: about 1.1).
const ARM_RATIO: f32 = 1.1;

/// The joints found along one leg: thigh, knee, ankle and toes.
#[derive(Clone, Copy, Debug)]
struct Leg {
    up: usize,
    knee: usize,
    foot: usize,
    toe: Option<usize>,
}

/// The joints found along one arm: clavicle, upper arm, forearm and hand.
#[derive(Clone, Copy, Debug)]
struct Arm {
    clavicle: Option<usize>,
    upper: usize,
    fore: usize,
    hand: usize,
}

/// The canonical joint (Mixamo name, see [`super::joint_names::CANONICAL_JOINTS`]) of each
/// joint of `shape`, found from the structure alone, or why the structure is not a standing
/// human's (no two legs reaching the ground, no spine rising to a head, no two arms).
pub fn label_by_structure(shape: &RigShape<'_>) -> Result<Vec<Option<&'static str>>, String> {
    let n = shape.parents.len();
    let p = shape.rest;
    if p.len() != n || n < 8 {
        return Err(format!("{n} joints are too few for a body"));
    }
    if shape
        .parents
        .iter()
        .enumerate()
        .any(|(j, q)| q.is_some_and(|q| q >= j))
        || !p.iter().all(|v| v.iter().all(|c| c.is_finite()))
    {
        return Err("the hierarchy or rest pose is malformed".into());
    }
    let lo = p.iter().map(|v| v.y).fold(f32::INFINITY, f32::min);
    let hi = p.iter().map(|v| v.y).fold(f32::NEG_INFINITY, f32::max);
    let height = hi - lo;
    if !height.is_finite() || height <= 1e-6 {
        return Err("the rest pose has no height (is the rig Y up?)".into());
    }
    let children = children_of(shape.parents);
    let (branch, feet) = find_feet(shape.parents, &children, p, height)?;
    let head = find_head(shape.parents, p, branch, &feet, height)?;
    let hips = lca(shape.parents, branch, head).ok_or("the legs and the head are not joined")?;
    let spine = path_down(shape.parents, hips, head);
    let (chest, arm_ends) = find_arms(shape.parents, &children, p, hips, &spine, height)?;

    let legs = [
        leg_joints(p, &path_down(shape.parents, branch, feet[0]), p[branch].y)?,
        leg_joints(p, &path_down(shape.parents, branch, feet[1]), p[branch].y)?,
    ];
    let arms = [
        arm_joints(
            p,
            &children,
            &path_down(shape.parents, spine[chest], arm_ends[0]),
            height,
        )?,
        arm_joints(
            p,
            &children,
            &path_down(shape.parents, spine[chest], arm_ends[1]),
            height,
        )?,
    ];
    let first_leg_left = first_leg_is_left(shape, &legs, height)?;
    let across = p[legs[0].up] - p[legs[1].up];
    let first_arm_with_first_leg = (p[arms[0].hand] - p[arms[1].hand]).dot(&across) > 0.0;

    let mut labels: Vec<Option<&'static str>> = vec![None; n];
    labels[hips] = Some("Hips");
    for (j, name) in spine_labels(p, &spine, chest) {
        labels[j] = Some(name);
    }
    for (k, leg) in legs.iter().enumerate() {
        let side = usize::from((k == 0) != first_leg_left);
        let names = LEGS[side];
        labels[leg.up] = Some(names[0]);
        labels[leg.knee] = Some(names[1]);
        labels[leg.foot] = Some(names[2]);
        if let Some(t) = leg.toe {
            labels[t] = Some(names[3]);
        }
    }
    for (k, arm) in arms.iter().enumerate() {
        let with_first_leg = (k == 0) == first_arm_with_first_leg;
        let side = usize::from(with_first_leg != first_leg_left);
        let names = ARMS[side];
        if let Some(c) = arm.clavicle {
            labels[c] = Some(names[0]);
        }
        labels[arm.upper] = Some(names[1]);
        labels[arm.fore] = Some(names[2]);
        labels[arm.hand] = Some(names[3]);
    }
    Ok(labels)
}

fn children_of(parents: &[Option<usize>]) -> Vec<Vec<usize>> {
    let mut children = vec![Vec::new(); parents.len()];
    for (j, p) in parents.iter().enumerate() {
        if let Some(p) = *p {
            children[p].push(j);
        }
    }
    children
}

/// `j`, its parent, ..., its root.
fn path_up(parents: &[Option<usize>], j: usize) -> Vec<usize> {
    let mut out = vec![j];
    let mut cur = j;
    // Parents precede children (checked), so this ends.
    while let Some(p) = parents[cur] {
        out.push(p);
        cur = p;
    }
    out
}

/// The lowest common ancestor of `a` and `b` (either itself when one is under the other).
fn lca(parents: &[Option<usize>], a: usize, b: usize) -> Option<usize> {
    let up_a = path_up(parents, a);
    path_up(parents, b).into_iter().find(|j| up_a.contains(j))
}

/// The chain below `top` (excluded) down to `to` (included); empty when `to` is `top`.
fn path_down(parents: &[Option<usize>], top: usize, to: usize) -> Vec<usize> {
    let mut chain: Vec<usize> = path_up(parents, to)
        .into_iter()
        .take_while(|&j| j != top)
        .collect();
    chain.reverse();
    chain
}

fn horizontal(v: Vec3) -> Vec3 {
    Vec3::new(v.x, 0.0, v.z)
}

/// The two feet: the lowest end joint, and the lowest end joint of another branch that splits
/// from its chain well above the ground; returns the joint they branch from and the two ends.
/// (End joints only: a root joint at the floor under the hips is no foot.)
fn find_feet(
    parents: &[Option<usize>],
    children: &[Vec<usize>],
    p: &[Vec3],
    height: f32,
) -> Result<(usize, [usize; 2]), String> {
    let lowest = |cands: &mut dyn Iterator<Item = usize>| {
        cands
            .filter(|&j| children[j].is_empty())
            .min_by(|&a, &b| p[a].y.total_cmp(&p[b].y).then(a.cmp(&b)))
    };
    let f1 = lowest(&mut (0..p.len())).ok_or("no end joints")?;
    let f2 = lowest(&mut (0..p.len()).filter(|&j| {
        j != f1 && lca(parents, f1, j).is_some_and(|a| p[a].y - p[f1].y >= 0.3 * height)
    }))
    .ok_or("no two legs reach the ground from one joint")?;
    if p[f2].y - p[f1].y > 0.15 * height {
        return Err("only one leg reaches the ground".into());
    }
    let branch = lca(parents, f1, f2).ok_or("the two legs are not joined")?;
    Ok((branch, [f1, f2]))
}

/// The highest joint near the vertical through the legs' branch, off the legs.
fn find_head(
    parents: &[Option<usize>],
    p: &[Vec3],
    branch: usize,
    feet: &[usize; 2],
    height: f32,
) -> Result<usize, String> {
    let leg_tops: Vec<usize> = feet
        .iter()
        .filter_map(|&f| path_down(parents, branch, f).first().copied())
        .collect();
    let on_legs = |j: usize| path_up(parents, j).iter().any(|a| leg_tops.contains(a));
    let head = (0..p.len())
        .filter(|&j| !on_legs(j) && horizontal(p[j] - p[branch]).norm() < 0.15 * height)
        .max_by(|&a, &b| p[a].y.total_cmp(&p[b].y).then(b.cmp(&a)))
        .ok_or("no chain rises to a head")?;
    if p[head].y - p[branch].y < 0.2 * height {
        return Err("no chain rises to a head above the legs".into());
    }
    Ok(head)
}

/// The two chains branching off the spine that reach farthest sideways from the hips: the
/// index in `spine` of the joint they branch from (the chest) and the farthest joint of each.
fn find_arms(
    parents: &[Option<usize>],
    children: &[Vec<usize>],
    p: &[Vec3],
    hips: usize,
    spine: &[usize],
    height: f32,
) -> Result<(usize, [usize; 2]), String> {
    let reach = |j: usize| horizontal(p[j] - p[hips]).norm();
    // (reach, spine index, farthest joint) per branch.
    let mut branches: Vec<(f32, usize, usize)> = Vec::new();
    for (k, &s) in spine.iter().enumerate() {
        for &c in &children[s] {
            if spine.contains(&c) {
                continue;
            }
            let mut far = c;
            let mut stack = vec![c];
            while let Some(j) = stack.pop() {
                if reach(j) > reach(far) {
                    far = j;
                }
                stack.extend(&children[j]);
            }
            branches.push((reach(far), k, far));
        }
    }
    branches.sort_by(|a, b| b.0.total_cmp(&a.0));
    let [a, b, ..] = branches.as_slice() else {
        return Err("no two arms branch off the spine".into());
    };
    let opposite = horizontal(p[a.2] - p[hips]).dot(&horizontal(p[b.2] - p[hips])) < 0.0;
    if b.0 < 0.15 * height || !opposite {
        return Err("no two arms reach out on either side of the spine".into());
    }
    // Both arms hang from the lower of their two spine joints (the same one, normally).
    let chest = a.1.min(b.1);
    let ends = [a.2, b.2];
    if ends
        .iter()
        .any(|&e| !path_up(parents, e).contains(&spine[chest]))
    {
        return Err("the arms do not hang from the spine".into());
    }
    Ok((chest, ends))
}

/// Thigh, knee, ankle and toes along a leg chain (top to the lowest joint): the thigh is the
/// last joint still near the hips' height, the ankle the first low joint from which the
/// foot goes forward, the knee the joint halfway between them in height.
fn leg_joints(p: &[Vec3], chain: &[usize], top: f32) -> Result<Leg, String> {
    let k = chain.len();
    let drop = top - chain.last().map_or(top, |&j| p[j].y);
    if k < 3 || drop <= 0.0 {
        return Err("a leg has fewer than three joints".into());
    }
    let t: Vec<f32> = chain.iter().map(|&j| (top - p[j].y) / drop).collect();
    let flat_next = |i: usize| {
        let d = p[chain[i + 1]] - p[chain[i]];
        horizontal(d).norm() > d.y.abs()
    };
    let foot = (1..k - 1)
        .find(|&i| t[i] >= 0.7 && flat_next(i))
        .or_else(|| (1..k).find(|&i| t[i] >= 0.8))
        .unwrap_or(k - 1);
    let up = (0..foot.saturating_sub(1))
        .rev()
        .find(|&i| t[i] <= 0.15)
        .unwrap_or(0);
    let mid = 0.5 * (t[up] + t[foot]);
    let knee = (up + 1..foot)
        .min_by(|&a, &b| (t[a] - mid).abs().total_cmp(&(t[b] - mid).abs()))
        .ok_or("a leg has no knee between the hip and the ankle")?;
    Ok(Leg {
        up: chain[up],
        knee: chain[knee],
        foot: chain[foot],
        toe: chain.get(foot + 1).copied(),
    })
}

/// Clavicle, upper arm, forearm and hand along an arm chain (from the spine out to its
/// farthest joint): the upper arm and forearm are the pair of consecutive bones closest to
/// [`ARM_RATIO`] in length, with a shorter clavicle before and a shorter hand after them, and
/// no branching joint (a hand with its fingers) inside them but at the elbow.
fn arm_joints(
    p: &[Vec3],
    children: &[Vec<usize>],
    chain: &[usize],
    height: f32,
) -> Result<Arm, String> {
    let k = chain.len();
    let at = |i: usize| p[chain[i]];
    let end = k.saturating_sub(1);
    let mut best: Option<(f32, [usize; 3])> = None;
    for s in 0..k {
        for e in s + 1..k {
            for h in e + 1..k {
                let upper = (at(e) - at(s)).norm();
                let fore = (at(h) - at(e)).norm();
                if upper < 0.02 * height || fore < 0.02 * height {
                    continue;
                }
                let clavicle = (at(s) - at(0)).norm();
                let hand = (at(end) - at(h)).norm();
                let branches_inside = (s + 1..h).any(|i| i != e && children[chain[i]].len() > 1);
                if clavicle > upper || hand > fore || branches_inside {
                    continue;
                }
                let cost = ((upper / fore).ln() - ARM_RATIO.ln()).abs();
                // Ties (joints at one place) go to the later joints, the ones that carry the
                // bones.
                if best.is_none_or(|(c, _)| cost <= c + 1e-4) {
                    best = Some((cost, [s, e, h]));
                }
            }
        }
    }
    let (_, [s, e, h]) = best.ok_or("an arm has no upper arm and forearm")?;
    Ok(Arm {
        clavicle: s.checked_sub(1).map(|c| chain[c]),
        upper: chain[s],
        fore: chain[e],
        hand: chain[h],
    })
}

/// Spine, Spine1, Spine2 (the chest), Neck and Head along the chain from the hips to the
/// head; `chest` indexes the joint the arms hang from. Of three or more joints above the
/// chest, the last is a top-of-head end when its bone is much longer than the one before.
fn spine_labels(p: &[Vec3], spine: &[usize], chest: usize) -> Vec<(usize, &'static str)> {
    let mut out = vec![(spine[0], "Spine")];
    if chest >= 1 {
        out.push((spine[chest], "Spine2"));
    }
    if chest >= 2 {
        out.push((spine[chest.div_ceil(2)], "Spine1"));
    }
    let above = &spine[chest + 1..];
    match above {
        [] => {}
        [head] => out.push((*head, "Head")),
        [neck, head] => out.extend([(*neck, "Neck"), (*head, "Head")]),
        [neck, .., before, last] => {
            let earlier = above[above.len() - 3];
            let top = (p[*last] - p[*before]).norm();
            let below = (p[*before] - p[earlier]).norm();
            let head = if top > 1.3 * below { before } else { last };
            out.extend([(*neck, "Neck"), (*head, "Head")]);
        }
    }
    out
}

/// Whether the first leg is the character's left: the toes (or the knees' bend in the
/// motion) point forward, left is up x forward; a rig with neither is taken to face +Z.
fn first_leg_is_left(shape: &RigShape<'_>, legs: &[Leg; 2], height: f32) -> Result<bool, String> {
    let p = shape.rest;
    let across = horizontal(p[legs[0].up] - p[legs[1].up]);
    if across.norm() < 0.01 * height {
        return Err("the two legs are not side by side".into());
    }
    // left = up x forward = (f.z, 0, -f.x) for up = +Y.
    let leftness = |forward: Vec3| across.dot(&Vec3::new(forward.z, 0.0, -forward.x));
    let toes: Vec3 = legs
        .iter()
        .filter_map(|l| l.toe.map(|t| horizontal(p[t] - p[l.foot])))
        .sum();
    if toes.norm() > 0.02 * height {
        return Ok(leftness(toes) > 0.0);
    }
    // Knees bend forward: each frame's knee ahead of its hip-ankle line, seen from the
    // frame's own left-right axis (so a turning motion does not cancel out).
    let mut score = 0.0f32;
    let mut bend = 0.0f32;
    for w in shape.frames {
        let at = |j: usize| w.get(j).map(|x| x.1);
        let (Some(a0), Some(a1)) = (at(legs[0].up), at(legs[1].up)) else {
            continue;
        };
        let across_now = horizontal(a0 - a1);
        let Some(across_now) = across_now.try_normalize(1e-6 * height) else {
            continue;
        };
        for l in legs {
            let (Some(u), Some(k), Some(f)) = (at(l.up), at(l.knee), at(l.foot)) else {
                continue;
            };
            let ahead = horizontal(k - (u + f) * 0.5);
            bend += ahead.norm();
            score += across_now.dot(&Vec3::new(ahead.z, 0.0, -ahead.x));
        }
    }
    // Enough bend, and mostly one way.
    if bend > 0.01 * height * shape.frames.len() as f32 && score.abs() > 0.3 * bend {
        return Ok(score > 0.0);
    }
    Ok(leftness(Vec3::z()) > 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::procedural::body::{JOINT_NAMES, JOINT_PARENTS, rest_joint_positions};

    fn mannequin_labels(rest: &[Vec3], frames: &[Vec<(Quat, Vec3)>]) -> Vec<Option<&'static str>> {
        label_by_structure(&RigShape {
            parents: &JOINT_PARENTS,
            rest,
            frames,
        })
        .unwrap()
    }

    #[test]
    fn the_mannequin_is_recognised_from_its_structure() {
        let rest = rest_joint_positions();
        let labels = mannequin_labels(&rest, &[]);
        let want: Vec<Option<&str>> = JOINT_NAMES.iter().map(|n| Some(*n)).collect();
        assert_eq!(labels, want);
    }

    #[test]
    fn a_rig_facing_back_without_toes_takes_its_sides_from_the_knees() {
        // The mannequin turned to face -Z, toes at the ankles.
        let turn = |v: Vec3| Vec3::new(-v.x, v.y, -v.z);
        let mut rest: Vec<Vec3> = rest_joint_positions().iter().map(|v| turn(*v)).collect();
        for (toe, foot) in [(17, 16), (21, 20)] {
            rest[toe] = rest[foot] - Vec3::new(0.0, 0.02, 0.0);
        }
        // Facing +Z assumed: sides swapped.
        let plain = mannequin_labels(&rest, &[]);
        assert_eq!(plain[14], Some("RightUpLeg"));
        // Knees bent towards -Z in the motion: the left leg is the +X... of the turned rig.
        let mut frame: Vec<(Quat, Vec3)> = rest.iter().map(|p| (Quat::identity(), *p)).collect();
        for knee in [15, 19] {
            frame[knee].1.z -= 0.1;
        }
        let labels = mannequin_labels(&rest, &[frame.clone(), frame]);
        assert_eq!(labels[14], Some("LeftUpLeg"));
        assert_eq!(labels[7], Some("LeftArm"));
        assert_eq!(labels[19], Some("RightLeg"));
    }

    #[test]
    fn shapes_that_are_not_a_standing_body_say_why() {
        let rest = rest_joint_positions();
        let flat: Vec<Vec3> = rest.iter().map(|v| Vec3::new(v.x, 0.0, v.y)).collect();
        let err = label_by_structure(&RigShape {
            parents: &JOINT_PARENTS,
            rest: &flat,
            frames: &[],
        })
        .unwrap_err();
        assert!(err.contains("Y up"), "{err}");
        // No arms: cut the arms off at the chest (parents moved to the hips' side).
        let mut parents = JOINT_PARENTS;
        let mut short = rest;
        for j in 6..14 {
            short[j] = Vec3::new(0.0, 1.3, 0.0);
            parents[j] = Some(3);
        }
        let err = label_by_structure(&RigShape {
            parents: &parents,
            rest: &short,
            frames: &[],
        })
        .unwrap_err();
        assert!(err.contains("arms"), "{err}");
    }
}
