//! Resuming a run: the scene it recorded (`RUN/scene.toml`), and how a scene given again on
//! the command line differs from it, in words, so a resume can refuse a different scene.

use std::path::PathBuf;

use neural_cloth_core::io::scene_loader::load_scene;
use neural_cloth_core::scene::Scene;
use neural_cloth_core::scene::config::SceneConfig;

use super::TrainError;
use super::run_dir::RunDir;

/// How many differences [`scene_difference`] names at most.
pub const MAX_NAMED_DIFFERENCES: usize = 4;

/// The scene a run recorded, loaded.
pub struct RecordedScene {
    /// The scene, rebuilt from `scene.toml`.
    pub scene: Scene,
    /// Its description.
    pub config: SceneConfig,
    /// Non-fatal problems met while loading it.
    pub warnings: Vec<String>,
}

/// Path of the scene description a run recorded.
pub fn scene_path(run: &RunDir) -> PathBuf {
    run.root.join("scene.toml")
}

/// The description of the scene `run` was trained on, with its fabric and effects: those of
/// `scene.toml`, their one home, or in a run folder of format version 1 or 2 the copies its
/// `run.json` kept ([`RunDir::legacy_settings`]: what the run trained with).
pub fn recorded_config(run: &RunDir) -> Result<SceneConfig, TrainError> {
    let path = scene_path(run);
    let mut config =
        SceneConfig::from_toml_str(&run.scene_toml()?).map_err(|e| TrainError::Corrupt {
            reason: format!("unreadable recorded scene ({e})"),
            path,
        })?;
    if let Some(legacy) = run.legacy_settings()? {
        config.fabric = legacy.fabric;
        config.effects = legacy.effects;
    }
    Ok(config)
}

/// Loads the scene `run` was trained on (its file paths are absolute; relative ones resolve
/// against the run folder).
pub fn recorded_scene(run: &RunDir) -> Result<RecordedScene, TrainError> {
    let config = recorded_config(run)?;
    let loaded = load_scene(&config, &run.root, &scene_path(run))?;
    Ok(RecordedScene {
        scene: loaded.scene,
        config,
        warnings: loaded.warnings,
    })
}

/// How `given` differs from the `recorded` scene of a run, in words (the first
/// [`MAX_NAMED_DIFFERENCES`] differing settings by their TOML path), or `None` when they
/// describe the same scene.
pub fn scene_difference(
    recorded: &SceneConfig,
    given: &SceneConfig,
) -> Result<Option<String>, TrainError> {
    let value = |c: &SceneConfig| -> Result<toml::Value, TrainError> {
        let text = c
            .to_toml_string()
            .map_err(|e| TrainError::Data(e.to_string()))?;
        toml::from_str(&text).map_err(|e| TrainError::Data(e.to_string()))
    };
    let mut found = Vec::new();
    differences("", &value(recorded)?, &value(given)?, &mut found);
    if found.is_empty() {
        return Ok(None);
    }
    let more = found.len().saturating_sub(MAX_NAMED_DIFFERENCES);
    found.truncate(MAX_NAMED_DIFFERENCES);
    let mut text = found.join("; ");
    if more > 0 {
        text.push_str(&format!("; and {more} more"));
    }
    Ok(Some(text))
}

fn show(v: Option<&toml::Value>) -> String {
    match v {
        None => "absent".into(),
        Some(toml::Value::Table(_)) => "a table".into(),
        Some(toml::Value::Array(a)) => format!("a list of {}", a.len()),
        Some(v) => v.to_string(),
    }
}

fn join(path: &str, key: &str) -> String {
    if path.is_empty() {
        key.to_string()
    } else {
        format!("{path}.{key}")
    }
}

/// Appends one line per differing leaf of `run` and `given` under `path`.
fn differences(path: &str, run: &toml::Value, given: &toml::Value, out: &mut Vec<String>) {
    use toml::Value::{Array, Table};
    match (run, given) {
        (Table(a), Table(b)) => {
            let mut keys: Vec<&String> = a.keys().chain(b.keys()).collect();
            keys.sort();
            keys.dedup();
            for key in keys {
                let sub = join(path, key);
                match (a.get(key), b.get(key)) {
                    (Some(x), Some(y)) => differences(&sub, x, y, out),
                    (x, y) => out.push(line(&sub, x, y)),
                }
            }
        }
        (Array(a), Array(b)) if a.len() == b.len() => {
            for (k, (x, y)) in a.iter().zip(b).enumerate() {
                differences(&format!("{path}[{k}]"), x, y, out);
            }
        }
        (a, b) if a != b => out.push(line(path, Some(a), Some(b))),
        _ => {}
    }
}

fn line(path: &str, run: Option<&toml::Value>, given: Option<&toml::Value>) -> String {
    format!(
        "{path} is {} in the run, {} in the given scene",
        show(run),
        show(given)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const SCENE: &str = r#"
name = "tiny"
training_fps = 30.0
[avatar]
builtin = "mannequin"
[garment]
builtin = "tshirt"
resolution = 400
[[motions]]
builtin = "walk"
duration_secs = 1.0
[fabric]
preset = "default"
"#;

    #[test]
    fn the_difference_names_each_changed_setting() {
        let run = SceneConfig::from_toml_str(SCENE).unwrap();
        assert_eq!(scene_difference(&run, &run.clone()).unwrap(), None);
        let other = SceneConfig::from_toml_str(
            &SCENE
                .replace("resolution = 400", "resolution = 500")
                .replace("duration_secs = 1.0", "duration_secs = 2.0"),
        )
        .unwrap();
        let text = scene_difference(&run, &other).unwrap().unwrap();
        assert!(
            text.contains("garment.resolution is 400 in the run, 500 in the given scene"),
            "{text}"
        );
        assert!(text.contains("motions[0].duration_secs is 1.0"), "{text}");
        let fewer = SceneConfig::from_toml_str(&format!(
            "{SCENE}[[motions]]\nbuiltin = \"spin\"\nduration_secs = 1.0\n"
        ))
        .unwrap();
        let text = scene_difference(&run, &fewer).unwrap().unwrap();
        assert!(
            text.contains("motions is a list of 1 in the run, a list of 2"),
            "{text}"
        );
    }
}
