//! BVH motions: header facts read from the text, own-skeleton playback, retargeting every CMU
//! clip onto a Mixamo-named skeleton, and typed errors for bad BVH input.

use neural_cloth::geometry::{Quat, Vec3};
use neural_cloth::io::{self, Bvh, IoError, RetargetOptions, Units};
use neural_cloth::scene::skeleton::rotation_of;

use super::{assert_names_file, asset, files_in, mixamo_skeleton};

/// (file, joints, channels, frames) from LICENSES.md.
pub const MOTIONS: [(&str, usize, usize, usize); 4] = [
    ("cmu_01_01_hops_turn_excerpt.bvh", 31, 96, 660),
    ("cmu_02_01_walk.bvh", 31, 96, 343),
    ("cmu_02_03_run_dazfriendly.bvh", 43, 132, 174),
    ("cmu_05_06_dance_pirouettes.bvh", 31, 96, 885),
];

/// Header facts read straight from the text: (joints, channels, frames, frame time, values).
fn bvh_header(text: &str) -> (usize, usize, usize, f64, usize) {
    let (mut joints, mut channels, mut frames, mut frame_time, mut values) = (0, 0, 0, 0.0, 0);
    let mut in_data = false;
    for line in text.lines() {
        let t: Vec<&str> = line.split_whitespace().collect();
        if in_data {
            values += t.len();
            continue;
        }
        match t.first().copied() {
            Some("ROOT" | "JOINT") => joints += 1,
            Some("CHANNELS") => channels += t[1].parse::<usize>().unwrap(),
            Some("Frames:") => frames = t[1].parse().unwrap(),
            Some("Frame") => {
                frame_time = t[2].parse().unwrap();
                in_data = true;
            }
            _ => {}
        }
    }
    (joints, channels, frames, frame_time, values)
}

#[test]
fn every_motion_file_is_covered_and_matches_its_header() {
    let files = files_in("motions", "bvh");
    assert_eq!(files.len(), MOTIONS.len());
    for path in files {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let (_, joints, channels, frames) = *MOTIONS
            .iter()
            .find(|m| m.0 == name)
            .unwrap_or_else(|| panic!("{name} has no facts"));
        let text = std::fs::read_to_string(&path).unwrap();
        let (hj, hc, hf, ht, hv) = bvh_header(&text);
        assert_eq!(
            (hj, hc, hf),
            (joints, channels, frames),
            "{name}: header vs LICENSES"
        );
        assert_eq!(hv, hf * hc, "{name}: data rows");
        let bvh = io::load_bvh(&path).unwrap();
        assert_eq!(bvh.joints.len(), joints, "{name}");
        assert_eq!(bvh.channel_count, channels, "{name}");
        assert_eq!(bvh.frame_count(), frames, "{name}");
        assert!((bvh.frame_time_secs as f64 - ht).abs() < 1e-9, "{name}");
        assert!((bvh.fps() - 120.0).abs() < 0.01, "{name}");
        // The last value of the file is the last channel of the last frame.
        let last: f32 = text.split_whitespace().last().unwrap().parse().unwrap();
        assert_eq!(*bvh.values.last().unwrap(), last, "{name}");
        // Own skeleton and motion.
        let (sk, motion, _) = bvh.to_motion_for_own_skeleton(Units::Auto).unwrap();
        assert_eq!(sk.len(), joints);
        assert_eq!(motion.frame_count(), frames);
        let (units, _) = bvh.resolve_units(Units::Auto);
        let expected = if name.contains("daz") {
            Units::Centimetres
        } else {
            Units::CmuMocap
        };
        assert_eq!(units, expected, "{name}");
        // Joint positions of the own-skeleton motion are the BVH's world positions, in metres.
        let scale = units.metres_per_unit().unwrap();
        for f in [0, frames / 2, frames - 1] {
            let p = sk.joint_positions(&motion.frames[f]);
            for (a, (_, b)) in p.iter().zip(bvh.world(f)) {
                assert!((a - b * scale).norm() < 1e-4, "{name} frame {f}");
            }
        }
        if !name.contains("daz") {
            assert!(
                bvh.warnings
                    .iter()
                    .any(|w| w.contains("zero-length") && w.contains("LHipJoint")),
                "{name}: {:?}",
                bvh.warnings
            );
        }
    }
}

#[test]
fn every_cmu_clip_retargets_onto_a_mixamo_skeleton() {
    let sk = mixamo_skeleton();
    let rest_world: Vec<Quat> = sk
        .world_from_joint(&sk.rest_pose())
        .iter()
        .map(rotation_of)
        .collect();
    for path in files_in("motions", "bvh") {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let bvh = io::load_bvh(&path).unwrap();
        let (motion, warnings) = io::retarget_bvh(&bvh, &sk, &RetargetOptions::default())
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(motion.fps, 30.0);
        let expected_frames = (bvh.duration_secs() * 30.0 + 1e-3).floor() as usize + 1;
        assert_eq!(motion.frame_count(), expected_frames, "{name}");
        for pose in &motion.frames {
            for q in &pose.rotations {
                assert!(
                    q.coords.iter().all(|v| v.is_finite()) && (q.coords.norm() - 1.0).abs() < 1e-4,
                    "{name}"
                );
            }
            let hips = sk.joint_positions(pose)[0];
            assert!(
                hips.iter().all(|v| v.is_finite()) && (0.2..2.5).contains(&hips.y),
                "{name}: hips at {hips:?}"
            );
        }
        // The mapping really transfers world rotations: at the native rate, the avatar's
        // LeftUpLeg turns from its rest by the BVH LeftUpLeg's (or lThigh's) world rotation.
        let (native, _) = io::retarget_bvh(
            &bvh,
            &sk,
            &RetargetOptions {
                fps: bvh.fps(),
                recentre: false,
                align_rest: false,
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(native.frame_count(), bvh.frame_count(), "{name}");
        let thigh_a = sk.index_of("LeftUpLeg").unwrap();
        let thigh_b = bvh
            .joints
            .iter()
            .position(|j| j.name == "LeftUpLeg" || j.name == "lThigh")
            .unwrap();
        for f in [0, bvh.frame_count() / 3, bvh.frame_count() - 1] {
            let world_a = rotation_of(&sk.world_from_joint(&native.frames[f])[thigh_a]);
            let delta = world_a * rest_world[thigh_a].inverse();
            let angle = delta.angle_to(&bvh.world(f)[thigh_b].0);
            assert!(angle < 2e-3, "{name} frame {f}: {angle} rad");
        }
        // Unmapped joints are reported, and the BVH's helpers are not needed.
        assert!(
            warnings.iter().all(|w| !w.contains("LeftUpLeg")),
            "{warnings:?}"
        );
    }
}

#[test]
fn bad_bvh_input_is_a_typed_error() {
    let path = asset("motions/cmu_02_01_walk.bvh");
    let text = std::fs::read_to_string(&path).unwrap();
    // Truncated data.
    let err = Bvh::parse(&text.as_bytes()[..text.len() - 500], &path).unwrap_err();
    assert!(matches!(err, IoError::Truncated { .. }), "{err}");
    assert_names_file(&err, "cmu_02_01_walk.bvh");
    // Truncated hierarchy.
    let err = Bvh::parse(&text.as_bytes()[..300], &path).unwrap_err();
    assert!(
        matches!(err, IoError::Truncated { .. } | IoError::Syntax { .. }),
        "{err}"
    );
    // NaN rotation value in the data, with its line.
    let lines: Vec<&str> = text.lines().collect();
    let data_line = lines
        .iter()
        .position(|l| l.starts_with("Frame Time"))
        .unwrap()
        + 3;
    let mut bad: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    let mut values: Vec<&str> = lines[data_line].split_whitespace().collect();
    values[4] = "nan";
    bad[data_line] = values.join(" ");
    let err = Bvh::parse(bad.join("\n").as_bytes(), &path).unwrap_err();
    assert!(
        matches!(&err, IoError::NonFinite { what, .. } if what.contains(&format!("line {}", data_line + 1))),
        "{err}"
    );
    // Malformed channel name, with its line number.
    let err = Bvh::parse(text.replacen("Xrotation", "Qrotation", 1).as_bytes(), &path).unwrap_err();
    assert!(matches!(err, IoError::Syntax { line: 5, .. }), "{err}");
    // Not a BVH at all.
    assert!(matches!(
        Bvh::parse(b"v 0 0 0\n", &path).unwrap_err(),
        IoError::Syntax { line: 1, .. }
    ));
    // A skeleton none of whose joints can be matched, by name or by structure (it lies flat),
    // is an error naming the motion file.
    let bvh = io::load_bvh(&path).unwrap();
    let mut dog = mixamo_skeleton();
    dog.names = dog.names.iter().map(|n| format!("b_{n}_01")).collect();
    for t in &mut dog.rest_local {
        t.translation = Vec3::new(t.translation.x, 0.0, t.translation.y);
    }
    let err = io::retarget_bvh(&bvh, &dog, &RetargetOptions::default()).unwrap_err();
    assert!(matches!(err, IoError::UnmappedJoints { .. }), "{err}");
    assert!(
        err.to_string()
            .contains("the avatar's skeleton is not recognised (the rest pose has no height"),
        "{err}"
    );
    assert_names_file(&err, "cmu_02_01_walk.bvh");
}

#[test]
fn renamed_core_joints_of_a_cmu_clip_are_found_by_structure() {
    // The left leg chain's names of a CMU clip made unrecognisable: the skeleton's structure
    // finds the same joints, and the clip retargets exactly as with its own names.
    let path = asset("motions/cmu_02_01_walk.bvh");
    let original = std::fs::read_to_string(&path).unwrap();
    let text = original
        .replace("JOINT LeftUpLeg", "JOINT LThighX")
        .replace("JOINT LeftLeg", "JOINT LShinX");
    let options = RetargetOptions::default();
    let sk = mixamo_skeleton();
    let bvh = Bvh::parse(text.as_bytes(), &path).unwrap();
    let (renamed, warnings) = io::retarget_bvh(&bvh, &sk, &options).unwrap();
    assert!(
        warnings.iter().any(|w| w.contains(
            "2 joints mapped by the skeletons' structure, their names not being recognised \
             (LeftUpLeg <- LThighX, LeftLeg <- LShinX)"
        )),
        "{warnings:?}"
    );
    let bvh = Bvh::parse(original.as_bytes(), &path).unwrap();
    let (named, _) = io::retarget_bvh(&bvh, &sk, &options).unwrap();
    assert_eq!(renamed.frame_count(), named.frame_count());
    for (a, b) in renamed.frames.iter().zip(&named.frames) {
        for (p, q) in sk.joint_positions(a).iter().zip(sk.joint_positions(b)) {
            assert!((p - q).norm() < 1e-5, "{p:?} vs {q:?}");
        }
    }
}
