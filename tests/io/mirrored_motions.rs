//! A scene's `mirrored = true` (issue 11): the left/right mirror image of a motion as a source
//! of its own, built in or read from a file. It turns the other way, is named apart from the
//! trainer's mirrored copies, and is written back to the scene file.

use std::f32::consts::{PI, TAU};

use neural_cloth::geometry::{Quat, Vec3};
use neural_cloth::io::scene_loader::{SceneLoader, load_scene_file};
use neural_cloth::scene::motion::{MIRRORED_NAME_SUFFIX, SCENE_MIRRORED_NAME_SUFFIX};
use neural_cloth::scene::procedural::{self, MotionKind, mannequin};
use neural_cloth::scene::{Motion, SceneConfig};

use super::rigs::write_bvh;

/// The root's signed turn about world +Y over the motion, radians: the sum of its heading's
/// steps, each wrapped to [-π, π).
fn root_turn_about_y(m: &Motion) -> f32 {
    let heading = |q: &Quat| {
        let forward = q * Vec3::z();
        forward.x.atan2(forward.z)
    };
    m.frames
        .windows(2)
        .map(|w| {
            let step = heading(&w[1].rotations[0]) - heading(&w[0].rotations[0]);
            (step + PI).rem_euclid(TAU) - PI
        })
        .sum()
}

/// Asserts that every motion after the first turns as far as the first, the other way.
fn assert_turn_the_other_way(motions: &[&Motion]) {
    let turns: Vec<f32> = motions.iter().map(|m| root_turn_about_y(m)).collect();
    assert!(turns[0].abs() > PI, "the spin turns: {turns:?}");
    for t in &turns[1..] {
        assert!((t + turns[0]).abs() < 1e-3 * turns[0].abs(), "{turns:?}");
    }
}

const SCENE: &str = r#"name = "both ways"
[avatar]
builtin = "mannequin"
[garment]
builtin = "tshirt"
resolution = 400
[[motions]]
builtin = "spin"
duration_secs = 2.0
[[motions]]
builtin = "spin"
duration_secs = 2.0
mirrored = true
[[motions]]
builtin = "spin"
duration_secs = 2.0
mirrored = true
name = "left"
"#;

#[test]
fn a_mirrored_built_in_spin_turns_the_other_way_from_either_builder() {
    let config = SceneConfig::from_toml_str(SCENE).unwrap();
    let text = config.to_toml_string().unwrap();
    assert_eq!(text.matches("mirrored = true").count(), 2, "{text}");
    assert_eq!(SceneConfig::from_toml_str(&text).unwrap(), config);
    let built = procedural::build_builtin(&config).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.toml");
    std::fs::write(&path, SCENE).unwrap();
    let loaded = load_scene_file(&path).unwrap().scene;
    for scene in [&built, &loaded] {
        let motions: Vec<&Motion> = scene.motions.iter().map(|(m, _)| m).collect();
        let names: Vec<&str> = motions.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["spin", "spin, mirrored", "left"]);
        assert_turn_the_other_way(&motions);
        // The trainer's mirrored copies never take a name the scene already uses.
        let mut all: Vec<String> = names.iter().map(|n| n.to_string()).collect();
        all.extend(
            motions
                .iter()
                .map(|m| m.mirrored(&scene.avatar.skeleton).name),
        );
        all.sort();
        all.dedup();
        assert_eq!(all.len(), 6, "{all:?}");
        assert!(all.contains(&format!("spin{MIRRORED_NAME_SUFFIX}")));
    }
    // The setting belongs to motions only.
    let err = SceneConfig::from_toml_str(
        &SCENE.replace("resolution = 400", "resolution = 400\nmirrored = true"),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("`mirrored`"), "{err}");
}

#[test]
fn a_mirrored_motion_file_loads_as_the_mirror_image_of_each_animation() {
    let avatar = mannequin().unwrap();
    let spin = procedural::motion(MotionKind::Spin, 30.0, 2.0).unwrap();
    let dir = tempfile::tempdir().unwrap();
    write_bvh(
        dir.path(),
        "spin.bvh",
        &avatar.skeleton,
        &spin,
        &avatar.skeleton.names,
    );
    let text = "name = \"file\"\n[avatar]\nbuiltin = \"mannequin\"\n[garment]\n\
                builtin = \"tshirt\"\n[[motions]]\npath = \"spin.bvh\"\n[[motions]]\n\
                path = \"spin.bvh\"\nmirrored = true\n";
    let config = SceneConfig::from_toml_str(text).unwrap();
    let scene_path = dir.path().join("scene.toml");
    let loader = SceneLoader::new(&config, dir.path(), &scene_path);
    let mut warnings = Vec::new();
    let plain = loader.motions(0, &avatar, &mut warnings).unwrap();
    let mirrored = loader.motions(1, &avatar, &mut warnings).unwrap();
    assert_eq!((plain.len(), mirrored.len()), (1, 1));
    assert_eq!(
        mirrored[0].name,
        format!("{}{SCENE_MIRRORED_NAME_SUFFIX}", plain[0].name)
    );
    assert_turn_the_other_way(&[&plain[0], &mirrored[0]]);
    // Frame by frame it is the mirror image of the file's motion.
    let expected = plain[0].mirrored(&avatar.skeleton);
    assert_eq!(mirrored[0].frames.len(), expected.frames.len());
    for (a, b) in mirrored[0].frames.iter().zip(&expected.frames) {
        for (qa, qb) in a.rotations.iter().zip(&b.rotations) {
            assert!((qa.coords - qb.coords).norm() < 1e-6, "{qa:?} {qb:?}");
        }
        assert!((a.root_translation - b.root_translation).norm() < 1e-6);
    }
}
