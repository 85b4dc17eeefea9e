//! Scene configuration: which avatar, garment and motions make a scene, which physical
//! effects it needs, the fabric and the training frame rate. This one description is what a
//! scene file holds, what the app's project file embeds (`[scene]`) and what a run folder
//! records (`RUN/scene.toml`); `io::scene_loader` builds a [`Scene`] from it.
//!
//! Human-edited files are TOML. Every source is either built in (`builtin = "mannequin"`,
//! `builtin = "tshirt"`, `builtin = "walk"`) or a file (`path = "..."`, relative to the config
//! file's folder). See `assets/default-scene.toml` for a complete, commented example.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::fabric::FabricParams;
use super::procedural::{GarmentKind, MotionKind};
use super::{Avatar, Garment, Motion, Scene, SceneError};

mod effects;
mod sources;

pub use effects::Effects;
pub use sources::{AvatarSource, BuiltinAvatar, GarmentSource, LengthUnit, MotionSource};

/// The training frame rate of a scene that names none ([`SceneConfig::training_fps`]), frames
/// per second: 30.
pub const DEFAULT_TRAINING_FPS: f32 = 30.0;

/// Errors of scene configuration files.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read or written.
    #[error("cannot access scene config ({source}): {}", path.display())]
    Io {
        /// The I/O error.
        #[source]
        source: std::io::Error,
        /// The file.
        path: PathBuf,
    },
    /// The text is not valid TOML or does not match the schema.
    #[error("malformed scene config: {0}")]
    Parse(String),
    /// A value is out of range or inconsistent.
    #[error("invalid scene config: {field}: {reason}")]
    Invalid {
        /// Dotted path of the offending field, e.g. `motions[2].duration_secs`.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// A source must be built in for this operation but names a file.
    #[error("{field} names a file; only built-in sources can be built without the importers")]
    NotBuiltin {
        /// Which source.
        field: String,
    },
    /// Building the scene failed.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// Any of the above, for the file at `path`.
    #[error("{source}: {}", path.display())]
    InFile {
        /// The underlying error.
        #[source]
        source: Box<ConfigError>,
        /// The config file.
        path: PathBuf,
    },
}

/// Which part of the data a motion belongs to.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Split {
    /// Used for training.
    #[default]
    Train,
    /// Used for validation metrics during training.
    Validation,
    /// Held out for final evaluation.
    Test,
}

/// A scene description as written in TOML.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneConfig {
    /// Display name, non-empty.
    pub name: String,
    /// The avatar.
    pub avatar: AvatarSource,
    /// The garment.
    pub garment: GarmentSource,
    /// Motions with their splits; at least one must be in the "train" split.
    #[serde(default)]
    pub motions: Vec<MotionSource>,
    /// Physical effects; default: all but pinning.
    #[serde(default)]
    pub effects: Effects,
    /// Fabric parameters; in TOML a preset plus overrides of its fields
    /// (`[fabric] preset = "denim"`, `bending_stiffness = 1e-4`); default: the "default" preset.
    #[serde(default, with = "super::fabric::table")]
    pub fabric: FabricParams,
    /// Frame rate motions are resampled to for training, frames per second, [1, 1000] (the
    /// trainer takes 5..=240), default [`DEFAULT_TRAINING_FPS`] (30). The one home of the
    /// training rate: a run records it (`RUN/scene.toml`, `RunMeta::training_fps`) and its
    /// model steps, evaluates and bakes at it.
    #[serde(default = "default_training_fps")]
    pub training_fps: f32,
}

pub(crate) fn default_resolution() -> usize {
    super::procedural::garments::DEFAULT_VERTICES
}
pub(crate) fn default_duration() -> f32 {
    6.0
}
fn default_training_fps() -> f32 {
    DEFAULT_TRAINING_FPS
}

fn invalid(field: impl Into<String>, reason: impl Into<String>) -> ConfigError {
    ConfigError::Invalid {
        field: field.into(),
        reason: reason.into(),
    }
}

fn check_rate(field: String, fps: f32) -> Result<(), ConfigError> {
    if fps.is_finite() && (1.0..=1000.0).contains(&fps) {
        Ok(())
    } else {
        Err(invalid(
            field,
            format!("{fps} frames per second is outside [1, 1000]"),
        ))
    }
}

fn check_passes(field: String, passes: Option<usize>) -> Result<(), ConfigError> {
    match passes {
        Some(p) if p > 200 => Err(invalid(
            field,
            format!("{p} smoothing passes is more than 200"),
        )),
        _ => Ok(()),
    }
}

fn check_path(field: String, path: &Path) -> Result<(), ConfigError> {
    if path.as_os_str().is_empty() {
        Err(invalid(field, "empty path"))
    } else {
        Ok(())
    }
}

/// Checks the values of motion source `k` (speed, duration, rate, name, path).
fn check_motion_values(k: usize, m: &MotionSource) -> Result<(), ConfigError> {
    match m {
        MotionSource::Builtin {
            duration_secs,
            speed,
            fps,
            name,
            ..
        } => {
            let max = crate::scene::procedural::motions::MAX_SPEED;
            if !(speed.is_finite() && *speed > 0.0 && *speed <= max) {
                return Err(invalid(
                    format!("motions[{k}].speed"),
                    format!("{speed} is outside (0, {max}]"),
                ));
            }
            if !(duration_secs.is_finite() && *duration_secs > 0.0 && *duration_secs <= 3600.0) {
                return Err(invalid(
                    format!("motions[{k}].duration_secs"),
                    format!("{duration_secs} s is outside (0, 3600]"),
                ));
            }
            if let Some(fps) = fps {
                check_rate(format!("motions[{k}].fps"), *fps)?;
            }
            if name.as_deref().is_some_and(|n| n.trim().is_empty()) {
                return Err(invalid(
                    format!("motions[{k}].name"),
                    "must not be empty when given",
                ));
            }
            Ok(())
        }
        MotionSource::File { path, .. } => check_path(format!("motions[{k}].path"), path),
    }
}

impl SceneConfig {
    /// The built-in default scene: mannequin, t-shirt (about 10K DoF) and all procedural
    /// motions, split per action (idle/walk/run/jump/twirl train, turn validation, spin test); every
    /// effect but pinning, friction included.
    pub fn default_scene() -> Self {
        let motions = MotionKind::ALL
            .into_iter()
            .filter(|kind| *kind != MotionKind::Rom)
            .map(|kind| MotionSource::Builtin {
                builtin: kind,
                duration_secs: match kind {
                    MotionKind::Turn => 6.4,
                    MotionKind::Jump => 5.4,
                    MotionKind::Twirl => 7.6,
                    MotionKind::Rom => 13.8,
                    _ => 6.0,
                },
                speed: 1.0,
                fps: None,
                split: kind.default_split(),
                name: None,
                mirrored: false,
            })
            .collect();
        Self {
            name: "default".into(),
            avatar: AvatarSource::Builtin {
                builtin: BuiltinAvatar::Mannequin,
            },
            garment: GarmentSource::Builtin {
                builtin: GarmentKind::TShirt,
                resolution: default_resolution(),
                smoothing_passes: None,
            },
            motions,
            // A shirt grips the skin: without friction the simulator's shirt slides around
            // the running body as a whole (docs/TRAINING.md, rounds 5 and 6).
            effects: Effects {
                friction: true,
                ..Effects::default()
            },
            fabric: FabricParams::default(),
            training_fps: default_training_fps(),
        }
    }

    /// Parses and validates a TOML scene description.
    pub fn from_toml_str(text: &str) -> Result<Self, ConfigError> {
        let config: Self = toml::from_str(text).map_err(|e| ConfigError::Parse(e.to_string()))?;
        config.validate()?;
        Ok(config)
    }

    /// Reads, parses and validates a scene file. Relative paths inside stay as written;
    /// resolve them with [`SceneConfig::resolve_path`] and the file's folder.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let in_file = |source: ConfigError| ConfigError::InFile {
            source: Box::new(source),
            path: path.to_path_buf(),
        };
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
            source,
            path: path.to_path_buf(),
        })?;
        Self::from_toml_str(&text).map_err(in_file)
    }

    /// `path` as seen from a config file in folder `config_dir` (absolute paths unchanged).
    pub fn resolve_path(config_dir: &Path, path: &Path) -> PathBuf {
        if path.is_absolute() {
            path.to_path_buf()
        } else {
            config_dir.join(path)
        }
    }

    /// Serialises to TOML (validated first, so what is written can be read back).
    pub fn to_toml_string(&self) -> Result<String, ConfigError> {
        self.validate()?;
        toml::to_string_pretty(self).map_err(|e| ConfigError::Parse(e.to_string()))
    }

    /// Checks ranges and consistency; the first problem found is returned.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.validate_values()?;
        let builtin_avatar = matches!(self.avatar, AvatarSource::Builtin { .. });
        if let (GarmentSource::Builtin { builtin, .. }, false) = (&self.garment, builtin_avatar) {
            return Err(invalid(
                "garment.builtin",
                format!(
                    "built-in garment '{}' needs the built-in mannequin",
                    builtin.name()
                ),
            ));
        }
        if self.motions.is_empty() {
            return Err(invalid("motions", "at least one motion is needed"));
        }
        for (k, m) in self.motions.iter().enumerate() {
            if let (MotionSource::Builtin { builtin, .. }, false) = (m, builtin_avatar) {
                return Err(invalid(
                    format!("motions[{k}].builtin"),
                    format!(
                        "built-in motion '{}' needs the built-in mannequin",
                        builtin.name()
                    ),
                ));
            }
        }
        if !self.motions.iter().any(|m| m.split() == Split::Train) {
            return Err(invalid("motions", "no motion is in the \"train\" split"));
        }
        let e = &self.effects;
        if e.friction && !(e.collision && e.dynamics) {
            return Err(invalid(
                "effects.friction",
                "friction acts where the cloth touches the moving body: it needs collision and dynamics",
            ));
        }
        Ok(())
    }

    /// Checks every value against its range (name, rates, fabric, resolution, smoothing,
    /// durations, speeds, paths) but not whether the parts make a trainable scene (built-in
    /// garment and motions on the built-in mannequin, a motion to train on): what a scene being
    /// edited in the app may hold between two loads.
    pub fn validate_values(&self) -> Result<(), ConfigError> {
        if self.name.trim().is_empty() {
            return Err(invalid("name", "must not be empty"));
        }
        check_rate("training_fps".into(), self.training_fps)?;
        self.fabric
            .validate()
            .map_err(|e| invalid("fabric", e.to_string()))?;
        if let AvatarSource::File { path, .. } = &self.avatar {
            check_path("avatar.path".into(), path)?;
        }
        match &self.garment {
            GarmentSource::Builtin {
                resolution,
                smoothing_passes,
                ..
            } => {
                use super::procedural::garments::{MAX_VERTICES, MIN_VERTICES};
                if !(MIN_VERTICES..=MAX_VERTICES).contains(resolution) {
                    return Err(invalid(
                        "garment.resolution",
                        format!("{resolution} vertices is outside {MIN_VERTICES}..={MAX_VERTICES}"),
                    ));
                }
                check_passes("garment.smoothing_passes".into(), *smoothing_passes)?;
            }
            GarmentSource::File {
                path,
                smoothing_passes,
                ..
            } => {
                check_path("garment.path".into(), path)?;
                check_passes("garment.smoothing_passes".into(), *smoothing_passes)?;
            }
        }
        for (k, m) in self.motions.iter().enumerate() {
            check_motion_values(k, m)?;
        }
        Ok(())
    }

    /// Applies `f` to every file path of the description (avatar, garment, motions and their
    /// joint maps), e.g. to resolve them against a folder or store them relative to one.
    pub fn map_paths(&mut self, f: impl Fn(&Path) -> PathBuf) {
        if let AvatarSource::File { path, .. } = &mut self.avatar {
            *path = f(path);
        }
        if let GarmentSource::File { path, .. } = &mut self.garment {
            *path = f(path);
        }
        for m in &mut self.motions {
            if let MotionSource::File {
                path, joint_map, ..
            } = m
            {
                *path = f(path);
                if let Some(map) = joint_map {
                    *map = f(map);
                }
            }
        }
    }

    /// Assembles a scene from sources the caller has already loaded (one motion list entry
    /// per loaded motion, with its split), taking name, effects, fabric and rate from here.
    pub fn assemble(
        &self,
        avatar: Avatar,
        garment: Garment,
        motions: Vec<(Motion, Split)>,
    ) -> Result<Scene, SceneError> {
        Scene::new(
            self.name.clone(),
            avatar,
            garment,
            motions,
            self.effects,
            self.fabric.clone(),
            self.training_fps,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DEFAULT_TOML: &str = include_str!(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/default-scene.toml"
    ));

    #[test]
    fn friction_needs_collision_and_dynamics() {
        let mut c = SceneConfig::default_scene();
        assert!(c.effects.friction && c.validate().is_ok());
        c.effects.collision = false;
        let err = c.validate().unwrap_err().to_string();
        assert!(err.contains("effects.friction"), "{err}");
        c.effects.drop_unmet_needs();
        assert!(!c.effects.friction && c.validate().is_ok());
        let mut e = Effects {
            friction: true,
            dynamics: false,
            ..Effects::default()
        };
        e.drop_unmet_needs();
        assert!(!e.friction);
        let mut kept = SceneConfig::default_scene().effects;
        kept.drop_unmet_needs();
        assert!(kept.friction, "all needs met: friction stays");
    }

    #[test]
    fn default_asset_matches_code_default() {
        let parsed = SceneConfig::from_toml_str(DEFAULT_TOML).unwrap();
        assert_eq!(parsed, SceneConfig::default_scene());
        let again = SceneConfig::from_toml_str(&parsed.to_toml_string().unwrap()).unwrap();
        assert_eq!(again, parsed);
    }

    #[test]
    fn defaults_fill_in() {
        let c = SceneConfig::from_toml_str(
            "name = \"x\"\navatar = { builtin = \"mannequin\" }\ngarment = { builtin = \"skirt\" }\n[[motions]]\nbuiltin = \"walk\"\n",
        )
        .unwrap();
        assert_eq!(c.training_fps, 30.0);
        assert_eq!(c.effects, Effects::default());
        assert!(!c.effects.pinning);
        assert_eq!(c.fabric, FabricParams::default());
        assert_eq!(
            c.garment,
            GarmentSource::Builtin {
                builtin: GarmentKind::Skirt,
                resolution: 3400,
                smoothing_passes: None
            }
        );
        assert_eq!(c.motions[0].split(), Split::Train);
    }

    #[test]
    fn file_sources_parse_with_units_and_splits() {
        let c = SceneConfig::from_toml_str(
            r#"name = "files"
avatar = { path = "avatars/body.glb" }
garment = { path = "garments/shirt.obj", units = "cm", smoothing_passes = 40 }
[[motions]]
path = "motions/walk.bvh"
units = "in"
split = "validation"
[[motions]]
path = "avatars/body.glb"
name = "Run"
"#,
        )
        .unwrap();
        assert!(matches!(
            &c.garment,
            GarmentSource::File {
                units: Some(LengthUnit::Centimetres),
                smoothing_passes: Some(40),
                ..
            }
        ));
        assert_eq!(c.motions[0].split(), Split::Validation);
        let dir = Path::new("/scenes");
        assert_eq!(
            SceneConfig::resolve_path(dir, Path::new("a/b.obj")),
            PathBuf::from("/scenes/a/b.obj")
        );
    }

    #[test]
    fn bad_values_give_clear_errors() {
        let base = SceneConfig::default_scene();
        let mut c = base.clone();
        c.training_fps = 0.0;
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("training_fps")
        );
        let mut c = base.clone();
        c.garment = GarmentSource::Builtin {
            builtin: GarmentKind::Dress,
            resolution: 10,
            smoothing_passes: None,
        };
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("garment.resolution")
        );
        let mut c = base.clone();
        c.avatar = AvatarSource::File {
            path: "x.glb".into(),
            units: None,
            up: crate::scene::UpAxis::Auto,
        };
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("needs the built-in mannequin")
        );
        let mut c = base.clone();
        c.motions.retain(|m| m.split() != Split::Train);
        assert!(c.validate().unwrap_err().to_string().contains("train"));
        let err = SceneConfig::from_toml_str("name = \"x\"\navatar = { builtin = \"robot\" }")
            .unwrap_err();
        assert!(matches!(err, ConfigError::Parse(_)), "{err}");
        assert!(
            err.to_string()
                .contains("unknown built-in avatar \"robot\""),
            "{err}"
        );
        let err = SceneConfig::from_toml_str(&DEFAULT_TOML.replace(
            "builtin = \"tshirt\"",
            "builtin = \"tshirt\"\npath = \"a.obj\"",
        ))
        .unwrap_err();
        assert!(err.to_string().contains("not both"), "{err}");
        let err = SceneConfig::from_toml_str(&DEFAULT_TOML.replace(
            "builtin = \"mannequin\"",
            "builtin = \"mannequin\"\nresolution = 5",
        ))
        .unwrap_err();
        assert!(
            err.to_string().contains("`resolution` does not apply"),
            "{err}"
        );
        let err = SceneConfig::from_toml_str(&DEFAULT_TOML.replace("training_fps", "training_fsp"))
            .unwrap_err();
        assert!(err.to_string().contains("training_fsp"), "{err}");
    }

    #[test]
    fn load_names_the_file_last() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("scene.toml");
        std::fs::write(
            &path,
            "name = \"\"\navatar = { builtin = \"mannequin\" }\ngarment = { builtin = \"tshirt\" }",
        )
        .unwrap();
        let msg = SceneConfig::load(&path).unwrap_err().to_string();
        assert!(msg.ends_with(&path.display().to_string()), "{msg}");
        assert!(msg.contains("name"), "{msg}");
        let missing = SceneConfig::load(&dir.path().join("none.toml")).unwrap_err();
        assert!(matches!(missing, ConfigError::Io { .. }));
    }
}
