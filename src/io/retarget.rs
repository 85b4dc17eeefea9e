//! Retargeting BVH motions onto an avatar skeleton.
//!
//! Joints are matched by name: first exactly (ignoring case, punctuation and namespace
//! prefixes such as `mixamorig:`), then through canonical Mixamo names with aliases for common
//! CMU, Daz, Blender, Unreal, 3ds Max Biped and SMPL spellings ([`canonical_joint_name`]).
//! Rotations are transferred in world space: a mapped avatar joint turns away from its rest
//! orientation by the same world rotation as its BVH joint turns away from the BVH rest (all
//! rotations zero); unmapped joints keep their rest local rotation. The root translation is
//! scaled by the ratio of hip heights (so BVH units do not matter), grounded on the lowest
//! joint and optionally re-centred horizontally. Assumes both rest poses are alike (e.g. both
//! T-poses) and both are Y up.

use super::bvh::Bvh;
use super::gltf_avatar::short_list;
use super::{IoError, check_fps};
use crate::geometry::{Quat, Vec3};
use crate::scene::skeleton::rotation_of;
use crate::scene::{Motion, Pose, Skeleton};

/// Options for [`retarget_bvh`].
#[derive(Clone, Debug, PartialEq)]
pub struct RetargetOptions {
    /// Frame rate of the resulting motion in frames per second; (0, 1000], default 30.
    pub fps: f32,
    /// Shift the motion horizontally so its first frame's hips sit above the avatar's rest
    /// hips (BVH root positions are absolute world positions); default true.
    pub recentre: bool,
}

impl Default for RetargetOptions {
    fn default() -> Self {
        Self {
            fps: 30.0,
            recentre: true,
        }
    }
}

/// Canonical names every avatar must map when it has them: hips, spine, upper legs, legs,
/// arms and forearms.
pub const CORE_JOINTS: [&str; 10] = [
    "Hips",
    "Spine",
    "LeftUpLeg",
    "RightUpLeg",
    "LeftLeg",
    "RightLeg",
    "LeftArm",
    "RightArm",
    "LeftForeArm",
    "RightForeArm",
];

/// Lower-case alphanumerics of a name after its last `:` (namespace) and known rig prefixes.
fn normalise(name: &str) -> String {
    let tail = name.rsplit(':').next().unwrap_or(name);
    let mut s: String = tail
        .chars()
        .filter(|c| c.is_ascii_alphanumeric())
        .collect::<String>()
        .to_ascii_lowercase();
    for prefix in ["mixamorig", "bip001", "bip01"] {
        if let Some(rest) = s.strip_prefix(prefix) {
            s = rest.to_string();
        }
    }
    s
}

/// The canonical (Mixamo) name of a joint, or `None` when the name is not recognised.
///
/// Examples: `mixamorig:LeftUpLeg`, `lThigh`, `thigh_l`, `thigh.L`, `Bip01 L Thigh` and `L_Hip`
/// all give `LeftUpLeg`; `hip`, `pelvis` give `Hips`; `abdomen` gives `Spine`; `chest` gives
/// `Spine2`; CMU helper joints such as `LHipJoint` or `LowerBack` give `None`.
pub fn canonical_joint_name(name: &str) -> Option<&'static str> {
    let tail = name.rsplit(':').next().unwrap_or(name);
    let tail = ["mixamorig", "Bip001", "Bip01", "bip001", "bip01"]
        .iter()
        .fold(tail, |t, p| t.strip_prefix(p).unwrap_or(t));
    let tokens: Vec<String> = tail
        .split(|c: char| !c.is_ascii_alphanumeric())
        .filter(|t| !t.is_empty())
        .map(str::to_string)
        .collect();
    let mut side: Option<bool> = None; // Some(true) = left
    let mut parts: Vec<String> = Vec::new();
    for token in &tokens {
        match token.to_ascii_lowercase().as_str() {
            "l" | "left" if side.is_none() => side = Some(true),
            "r" | "right" if side.is_none() => side = Some(false),
            _ => parts.push(token.clone()),
        }
    }
    let mut base = parts.concat();
    if side.is_none() {
        let lower = base.to_ascii_lowercase();
        let chars: Vec<char> = base.chars().collect();
        if let Some(rest) = lower.strip_prefix("left") {
            side = Some(true);
            base = rest.to_string();
        } else if let Some(rest) = lower.strip_prefix("right") {
            side = Some(false);
            base = rest.to_string();
        } else if chars.len() > 1
            && matches!(chars[0], 'L' | 'l' | 'R' | 'r')
            && chars[1].is_ascii_uppercase()
        {
            // CMU / Daz style: LHipJoint, lThigh, rShldr.
            side = Some(matches!(chars[0], 'L' | 'l'));
            base = chars[1..].iter().collect();
        } else if let Some(rest) = lower.strip_suffix("left") {
            side = Some(true);
            base = rest.to_string();
        } else if let Some(rest) = lower.strip_suffix("right") {
            side = Some(false);
            base = rest.to_string();
        }
    }
    let base = base.to_ascii_lowercase();
    match side {
        None => Some(match base.as_str() {
            "hips" | "hip" | "pelvis" => "Hips",
            "spine" | "abdomen" | "spine01" => "Spine",
            "spine1" | "spine02" | "abdomen2" => "Spine1",
            "spine2" | "chest" | "spine03" | "upperchest" => "Spine2",
            "neck" | "neck01" => "Neck",
            "head" => "Head",
            _ => return None,
        }),
        Some(left) => {
            let part = match base.as_str() {
                "shoulder" | "collar" | "clavicle" => "Shoulder",
                "arm" | "upperarm" | "uparm" | "shldr" => "Arm",
                "forearm" | "lowerarm" | "elbow" => "ForeArm",
                "hand" | "wrist" => "Hand",
                "upleg" | "thigh" | "upperleg" | "hip" => "UpLeg",
                "leg" | "shin" | "calf" | "lowerleg" | "knee" => "Leg",
                "foot" | "ankle" => "Foot",
                "toebase" | "toe" | "toes" | "ball" => "ToeBase",
                _ => return None,
            };
            const LEFT: [(&str, &str); 8] = [
                ("Shoulder", "LeftShoulder"),
                ("Arm", "LeftArm"),
                ("ForeArm", "LeftForeArm"),
                ("Hand", "LeftHand"),
                ("UpLeg", "LeftUpLeg"),
                ("Leg", "LeftLeg"),
                ("Foot", "LeftFoot"),
                ("ToeBase", "LeftToeBase"),
            ];
            const RIGHT: [&str; 8] = [
                "RightShoulder",
                "RightArm",
                "RightForeArm",
                "RightHand",
                "RightUpLeg",
                "RightLeg",
                "RightFoot",
                "RightToeBase",
            ];
            let k = LEFT.iter().position(|(p, _)| *p == part)?;
            Some(if left { LEFT[k].1 } else { RIGHT[k] })
        }
    }
}

/// For each avatar joint, the BVH joint that drives it.
pub fn map_joints(bvh: &Bvh, skeleton: &Skeleton) -> Vec<Option<usize>> {
    let bvh_norm: Vec<String> = bvh.joints.iter().map(|j| normalise(&j.name)).collect();
    let bvh_canon: Vec<Option<&str>> = bvh
        .joints
        .iter()
        .map(|j| canonical_joint_name(&j.name))
        .collect();
    skeleton
        .names
        .iter()
        .map(|name| {
            let n = normalise(name);
            bvh_norm
                .iter()
                .position(|b| !n.is_empty() && *b == n)
                .or_else(|| {
                    let c = canonical_joint_name(name)?;
                    bvh_canon.iter().position(|b| *b == Some(c))
                })
        })
        .collect()
}

/// Retargets `bvh` onto `skeleton`, resampled to `options.fps`. Returns the motion and
/// warnings. Errors (naming the BVH file) when a core joint of the avatar (see
/// [`CORE_JOINTS`]) has no BVH counterpart, listing those joints.
pub fn retarget_bvh(
    bvh: &Bvh,
    skeleton: &Skeleton,
    options: &RetargetOptions,
) -> Result<(Motion, Vec<String>), IoError> {
    let fps = check_fps(options.fps, &bvh.path)?;
    let path = || bvh.path.clone();
    if bvh.duration_secs() * fps > 2.0e5 {
        return Err(IoError::Unsupported {
            what: format!(
                "a {} s motion (too long to resample at {fps} fps)",
                bvh.duration_secs()
            ),
            path: path(),
        });
    }
    let n = skeleton.len();
    let map = map_joints(bvh, skeleton);
    let bvh_names: Vec<&str> = bvh.joints.iter().map(|j| j.name.as_str()).collect();
    let unmapped_core: Vec<String> = (0..n)
        .filter(|&a| {
            map[a].is_none()
                && canonical_joint_name(&skeleton.names[a])
                    .is_some_and(|c| CORE_JOINTS.contains(&c))
        })
        .map(|a| skeleton.names[a].clone())
        .collect();
    if !unmapped_core.is_empty() || map.iter().all(Option::is_none) {
        let joints = if unmapped_core.is_empty() {
            skeleton.names.iter().take(12).cloned().collect()
        } else {
            unmapped_core
        };
        return Err(IoError::UnmappedJoints {
            joints,
            available: short_list(&bvh_names, 12),
            path: path(),
        });
    }
    let mut warnings = Vec::new();
    let unmapped: Vec<&str> = (0..n)
        .filter(|&a| map[a].is_none())
        .map(|a| skeleton.names[a].as_str())
        .collect();
    if !unmapped.is_empty() {
        warnings.push(format!(
            "{} avatar joints keep their rest rotation: {}",
            unmapped.len(),
            short_list(&unmapped, 8)
        ));
    }

    // Avatar rest.
    let rest_pose = skeleton.rest_pose();
    let rest_world = skeleton.world_from_joint(&rest_pose);
    let rest_rot: Vec<Quat> = rest_world.iter().map(rotation_of).collect();
    let rest_pos: Vec<Vec3> = rest_world
        .iter()
        .map(|m| m.fixed_view::<3, 1>(0, 3).into_owned())
        .collect();
    let root_parent_rot: Vec<Quat> = skeleton
        .world_from_root_parent
        .iter()
        .map(rotation_of)
        .collect();

    // Hips: the avatar joint driven by the BVH root, else the mapped "Hips", else the first mapped.
    let Some(hips_a) = map
        .iter()
        .position(|m| *m == Some(0))
        .or_else(|| {
            (0..n).find(|&a| {
                map[a].is_some() && canonical_joint_name(&skeleton.names[a]) == Some("Hips")
            })
        })
        .or_else(|| map.iter().position(Option::is_some))
    else {
        return Err(IoError::UnmappedJoints {
            joints: skeleton.names.iter().take(12).cloned().collect(),
            available: short_list(&bvh_names, 12),
            path: path(),
        });
    };
    let hips_b = map[hips_a].unwrap_or(0);

    // Scale from hip heights above the lowest joint, both in rest.
    let bvh_rest = bvh.rest_positions();
    let min_y = |pts: &[Vec3]| pts.iter().map(|p| p.y).fold(f32::INFINITY, f32::min);
    let height_b = bvh_rest.get(hips_b).map(|p| p.y).unwrap_or(0.0) - min_y(&bvh_rest);
    let height_a = rest_pos[hips_a].y - min_y(&rest_pos);
    let scale = if height_a > 1e-6 && height_b > 1e-6 && (height_a / height_b).is_finite() {
        height_a / height_b
    } else {
        let (units, s) = bvh.resolve_units(super::Units::Auto);
        warnings.push(format!("hip heights unusable (avatar {height_a}, motion {height_b}); root translation scaled as {}", units.label()));
        s
    };

    // BVH world transforms per frame; ground = lowest joint over the whole motion.
    let worlds: Vec<Vec<(Quat, Vec3)>> = (0..bvh.frame_count()).map(|f| bvh.world(f)).collect();
    let ground_b = worlds
        .iter()
        .flat_map(|w| w.iter().map(|(_, p)| p.y))
        .fold(f32::INFINITY, f32::min);
    let ground_a = min_y(&rest_pos);
    let start_b = worlds
        .first()
        .and_then(|w| w.get(hips_b))
        .map(|(_, p)| *p)
        .unwrap_or_else(Vec3::zeros);

    let mut under_root0 = Some(hips_a);
    while let Some(j) = under_root0 {
        if j == 0 {
            break;
        }
        under_root0 = skeleton.parents[j];
    }
    if under_root0.is_none() {
        warnings.push(format!(
            "joint '{}' is not under joint 0; root translation not retargeted",
            skeleton.names[hips_a]
        ));
    }
    let root_linear_inv = skeleton.world_from_root_parent[0]
        .fixed_view::<3, 3>(0, 0)
        .into_owned()
        .try_inverse();

    let mut frames = Vec::with_capacity(worlds.len());
    for w in &worlds {
        let mut world_rot = vec![Quat::identity(); n];
        let mut rotations = vec![Quat::identity(); n];
        for a in 0..n {
            let parent_rot = match skeleton.parents[a] {
                Some(p) => world_rot[p],
                None => root_parent_rot[a],
            };
            let world = match map[a].and_then(|b| w.get(b)) {
                Some((q_b, _)) => q_b * rest_rot[a],
                None => parent_rot * skeleton.rest_local[a].rotation,
            };
            world_rot[a] = world;
            let local = parent_rot.inverse() * world;
            rotations[a] = Quat::new_normalize(local.into_inner());
        }
        let mut pose = Pose {
            rotations,
            root_translation: rest_pose.root_translation,
        };
        if let (Some(_), Some(inv), Some((_, p_b))) = (under_root0, root_linear_inv, w.get(hips_b))
        {
            let offset = if options.recentre {
                Vec3::new(
                    rest_pos[hips_a].x - scale * start_b.x,
                    0.0,
                    rest_pos[hips_a].z - scale * start_b.z,
                )
            } else {
                Vec3::zeros()
            };
            let target = Vec3::new(
                scale * p_b.x,
                ground_a + scale * (p_b.y - ground_b),
                scale * p_b.z,
            ) + offset;
            let current = skeleton.world_from_joint(&pose)[hips_a]
                .fixed_view::<3, 1>(0, 3)
                .into_owned();
            let shift = inv * (target - current);
            if shift.iter().all(|v| v.is_finite()) {
                pose.root_translation += shift;
            }
        }
        frames.push(pose);
    }
    let scene_err = |source| IoError::Scene {
        source,
        path: path(),
    };
    let native = Motion::new(bvh.name.clone(), bvh.fps(), frames, n).map_err(scene_err)?;
    let motion = native.resample(fps).map_err(scene_err)?;
    Ok((motion, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::Units;
    use std::path::Path;

    #[test]
    fn canonical_names_across_conventions() {
        let cases = [
            ("mixamorig:LeftUpLeg", Some("LeftUpLeg")),
            ("lThigh", Some("LeftUpLeg")),
            ("thigh_l", Some("LeftUpLeg")),
            ("thigh.L", Some("LeftUpLeg")),
            ("Bip01 L Thigh", Some("LeftUpLeg")),
            ("L_Hip", Some("LeftUpLeg")),
            ("rShldr", Some("RightArm")),
            ("RightForeArm", Some("RightForeArm")),
            ("upperarm_r", Some("RightArm")),
            ("hip", Some("Hips")),
            ("Hips", Some("Hips")),
            ("abdomen", Some("Spine")),
            ("chest", Some("Spine2")),
            ("rCollar", Some("RightShoulder")),
            ("LeftToeBase", Some("LeftToeBase")),
            ("LHipJoint", None),
            ("LowerBack", None),
            ("LeftHandIndex1", None),
            ("Root", None),
            ("Leg", None),
        ];
        for (name, want) in cases {
            assert_eq!(canonical_joint_name(name), want, "{name}");
        }
    }

    const BVH: &str = "HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation\n JOINT Spine\n {\n  OFFSET 0 2 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n  End Site\n  {\n   OFFSET 0 2 0\n  }\n }\n JOINT LeftUpLeg\n {\n  OFFSET 1 0 0\n  CHANNELS 3 Zrotation Xrotation Yrotation\n  JOINT LeftLeg\n  {\n   OFFSET 0 -4 0\n   CHANNELS 3 Zrotation Xrotation Yrotation\n   End Site\n   {\n    OFFSET 0 -4 0\n   }\n  }\n }\n}\nMOTION\nFrames: 3\nFrame Time: 0.5\n0 8 0 0 0 0 0 0 0 0 0 0 0 0 0\n1 7 2 10 20 30 -5 15 0 40 0 -10 0 60 5\n2 8 4 0 90 0 0 0 0 0 0 0 0 0 0\n";

    #[test]
    fn retargeting_onto_own_skeleton_reproduces_the_motion() {
        let bvh = Bvh::parse(BVH.as_bytes(), Path::new("m.bvh")).unwrap();
        let (sk, units) = bvh.to_skeleton(Units::Centimetres).unwrap();
        assert_eq!(units, Units::Centimetres);
        let opts = RetargetOptions {
            fps: 2.0,
            recentre: false,
        };
        let (motion, warnings) = retarget_bvh(&bvh, &sk, &opts).unwrap();
        assert!(warnings.is_empty(), "{warnings:?}");
        assert_eq!(motion.frame_count(), 3);
        let first = bvh.world(0)[0].1;
        let first_a = sk.joint_positions(&motion.frames[0])[0];
        for f in 0..3 {
            let p = sk.joint_positions(&motion.frames[f]);
            let w = bvh.world(f);
            for j in 0..4 {
                // Same shape (relative to the hips) and same hip trajectory, in metres.
                let rel_a = p[j] - p[0];
                let rel_b = (w[j].1 - w[0].1) * 0.01;
                assert!(
                    (rel_a - rel_b).norm() < 1e-5,
                    "frame {f} joint {j}: {rel_a:?} vs {rel_b:?}"
                );
                assert!(motion.frames[f].rotations[j].angle_to(&bvh.local(f, j).1) < 1e-4);
            }
            assert!(((p[0] - first_a) - (w[0].1 - first) * 0.01).norm() < 1e-5);
        }
    }

    #[test]
    fn missing_core_joints_are_listed() {
        let bvh = Bvh::parse(BVH.as_bytes(), Path::new("m.bvh")).unwrap();
        let mut names = vec![
            "Hips".to_string(),
            "Spine".into(),
            "RightUpLeg".into(),
            "RightLeg".into(),
        ];
        let (mut sk, _) = bvh.to_skeleton(Units::Metres).unwrap();
        std::mem::swap(&mut sk.names, &mut names);
        let err = retarget_bvh(&bvh, &sk, &RetargetOptions::default()).unwrap_err();
        match &err {
            IoError::UnmappedJoints { joints, .. } => assert_eq!(
                joints,
                &vec!["RightUpLeg".to_string(), "RightLeg".to_string()]
            ),
            other => panic!("unexpected {other}"),
        }
        assert!(err.to_string().ends_with("m.bvh"));
    }
}
