//! Mutation test of the files a user edits by hand: scene files, project files and joint
//! maps, damaged byte by byte (flips, truncations, splices) and value by value (a number
//! replaced by NaN, infinity, a huge or negative number, a string, a table). None may panic,
//! and whatever a loader accepts must hold only finite numbers in range: a NaN that gets past
//! the loader would reach the simulation or the playback clock.

use std::path::Path;

use neural_cloth::app::project::ProjectFile;
use neural_cloth::io::JointMap;
use neural_cloth::scene::SceneConfig;
use proptest::prelude::*;

/// Replacements for one value of the file.
const VALUES: [&str; 12] = [
    "nan", "inf", "-inf", "-nan", "1e309", "-1", "0", "1e30", "\"text\"", "true", "[]", "{}",
];

/// The default scene with a fabric that is no preset, so that every fabric value is written
/// (and damaged).
fn custom_fabric_scene() -> SceneConfig {
    let mut config = SceneConfig::default_scene();
    config.fabric.density_kg_per_m2 = 0.2;
    config
}

fn scene_text() -> String {
    custom_fabric_scene().to_toml_string().unwrap()
}

fn project_text() -> String {
    let project = ProjectFile {
        scene: custom_fabric_scene(),
        ..ProjectFile::default()
    };
    toml::to_string(&project).unwrap()
}

const JOINT_MAP: &str = "[joints]\nHips = \"pelvis\"\nLeftArm = \"upperarm_l\"\n";

#[derive(Debug, Clone)]
enum Edit {
    /// Replace the value of the `line`-th `key = value` line with `VALUES[value]`.
    Value { line: usize, value: usize },
    /// Flip bits at (position seed, xor mask).
    Flips(Vec<(usize, u8)>),
    /// Keep only the first `fraction` (per mille) of the file.
    Truncate(u16),
    /// Duplicate a line (a repeated key or table).
    Repeat(usize),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        3 => (any::<usize>(), 0..VALUES.len()).prop_map(|(line, value)| Edit::Value { line, value }),
        1 => prop::collection::vec((any::<usize>(), 1u8..=255), 1..4).prop_map(Edit::Flips),
        1 => (0u16..1000).prop_map(Edit::Truncate),
        1 => any::<usize>().prop_map(Edit::Repeat),
    ]
}

fn apply(text: &str, edit: &Edit) -> Vec<u8> {
    let lines: Vec<&str> = text.lines().collect();
    match edit {
        Edit::Value { line, value } => {
            let assignments: Vec<usize> = (0..lines.len())
                .filter(|&k| lines[k].contains(" = "))
                .collect();
            let mut out: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
            if let Some(&k) = assignments.get(line % assignments.len().max(1)) {
                let key = lines[k].split(" = ").next().unwrap_or_default();
                out[k] = format!("{key} = {}", VALUES[*value]);
            }
            out.join("\n").into_bytes()
        }
        Edit::Flips(flips) => {
            let mut out = text.as_bytes().to_vec();
            let n = out.len().max(1);
            for &(pos, mask) in flips {
                if let Some(b) = out.get_mut(pos % n) {
                    *b ^= mask;
                }
            }
            out
        }
        Edit::Truncate(per_mille) => {
            let mut out = text.as_bytes().to_vec();
            out.truncate(out.len() * *per_mille as usize / 1000);
            out
        }
        Edit::Repeat(line) => {
            let mut out: Vec<&str> = lines.clone();
            let k = line % lines.len().max(1);
            if let Some(l) = lines.get(k) {
                out.insert(k, l);
            }
            out.join("\n").into_bytes()
        }
    }
}

/// Every float of a TOML document, found by walking its values.
fn floats(value: &toml::Value, out: &mut Vec<f64>) {
    match value {
        toml::Value::Float(f) => out.push(*f),
        toml::Value::Array(a) => a.iter().for_each(|v| floats(v, out)),
        toml::Value::Table(t) => t.values().for_each(|v| floats(v, out)),
        _ => {}
    }
}

fn assert_finite<T: serde::Serialize>(what: &str, accepted: &T) {
    let value = toml::Value::try_from(accepted).unwrap();
    let mut all = Vec::new();
    floats(&value, &mut all);
    assert!(
        all.iter().all(|f| f.is_finite()),
        "{what} accepted a non-finite number: {all:?}"
    );
}

fn config(cases: u32) -> ProptestConfig {
    ProptestConfig {
        cases,
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

proptest! {
    #![proptest_config(config(600))]
    #[test]
    fn damaged_scene_files_are_refused_or_finite(e in edit()) {
        let bytes = apply(&scene_text(), &e);
        let text = String::from_utf8_lossy(&bytes);
        // A scene is accepted when it parses and validates (its [fabric] table included).
        if let Ok(config) = SceneConfig::from_toml_str(&text)
            && config.validate().is_ok()
        {
            assert_finite("a scene file", &config);
        }
    }
}

proptest! {
    #![proptest_config(config(600))]
    #[test]
    fn damaged_project_files_are_refused_or_finite(e in edit()) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("project.toml");
        std::fs::write(&path, apply(&project_text(), &e)).unwrap();
        match ProjectFile::open(&path) {
            Ok(project) => assert_finite("a project file", &project),
            Err(err) => {
                let message = err.to_string();
                assert!(message.ends_with(&path.display().to_string()), "{message}");
            }
        }
    }
}

proptest! {
    #![proptest_config(config(300))]
    #[test]
    fn damaged_joint_maps_never_panic(e in edit()) {
        let bytes = apply(JOINT_MAP, &e);
        let path = Path::new("map.toml");
        if let Err(err) = JointMap::from_toml_str(&String::from_utf8_lossy(&bytes), path) {
            assert!(err.to_string().ends_with("map.toml"), "{err}");
        }
    }
}

/// The regression the mutation test found first: a NaN playback speed passed `open` (the
/// app clamps it, and `clamp` keeps NaN), stopping the playback clock for good.
#[test]
fn a_project_with_a_nan_playback_speed_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.toml");
    let text = project_text().replace("playback_speed = 1.0", "playback_speed = nan");
    assert!(text.contains("playback_speed = nan"), "{text}");
    std::fs::write(&path, text).unwrap();
    let err = ProjectFile::open(&path).unwrap_err().to_string();
    assert!(err.contains("playback_speed"), "{err}");
}
