//! The source types of a scene configuration (built-in or file avatar, garment and motions)
//! and their TOML shape, with field checks that give clear messages.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use super::super::UpAxis;
use super::super::procedural::{GarmentKind, MotionKind};
use super::{Split, default_duration, default_resolution};

/// Length unit of a file whose own units are not trusted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum LengthUnit {
    /// Metres.
    #[serde(rename = "m")]
    Metres,
    /// Centimetres.
    #[serde(rename = "cm")]
    Centimetres,
    /// Millimetres.
    #[serde(rename = "mm")]
    Millimetres,
    /// Inches.
    #[serde(rename = "in")]
    Inches,
}

impl LengthUnit {
    /// Metres per unit.
    pub fn metres_per_unit(self) -> f32 {
        match self {
            LengthUnit::Metres => 1.0,
            LengthUnit::Centimetres => 0.01,
            LengthUnit::Millimetres => 0.001,
            LengthUnit::Inches => 0.0254,
        }
    }
}

/// Built-in avatars.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BuiltinAvatar {
    /// The procedural mannequin (`procedural::mannequin`).
    Mannequin,
}

/// Where the avatar comes from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawSource", into = "RawSource")]
pub enum AvatarSource {
    /// A built-in avatar: `builtin = "mannequin"`.
    Builtin {
        /// Which one.
        builtin: BuiltinAvatar,
    },
    /// A skinned glTF/GLB file: `path = "avatars/body.glb"`, optional `units` and `up`.
    File {
        /// Path, relative to the config file's folder.
        path: PathBuf,
        /// Unit of the file's lengths; default: the file's own (glTF: metres).
        units: Option<LengthUnit>,
        /// Up axis of the file (`up = "z"` turns a Z-up file Y up); default auto: detected
        /// from the skeleton.
        up: UpAxis,
    },
}

/// Where the garment comes from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawSource", into = "RawSource")]
pub enum GarmentSource {
    /// A built-in garment: `builtin = "tshirt" | "skirt" | "dress"`, optional `resolution`
    /// and `smoothing_passes` (needs the mannequin).
    Builtin {
        /// Which one.
        builtin: GarmentKind,
        /// Target vertex count (degrees of freedom / 3); 200..=500000, default 3400 (about
        /// 10K DoF); the result is within a few percent.
        resolution: usize,
        /// Skin-weight smoothing passes, 0..=200; default: the kind's recommendation
        /// (5 for the t-shirt, 30 for skirt and dress).
        smoothing_passes: Option<usize>,
    },
    /// A garment file (OBJ or glTF) in the avatar's rest pose: `path`, optional `units`, `up`
    /// and `smoothing_passes`.
    File {
        /// Path, relative to the config file's folder.
        path: PathBuf,
        /// Unit of the file's lengths; default: metres for glTF, guessed for OBJ.
        units: Option<LengthUnit>,
        /// Up axis of the file; default auto: an OBJ's detected from its shape, a glTF mesh Y
        /// up as the format says.
        up: UpAxis,
        /// Skin-weight smoothing passes, 0..=200; default by the garment's name
        /// (`GarmentOptions::for_name`: 30 when it says skirt, dress, gown or robe, else 3).
        smoothing_passes: Option<usize>,
    },
}

/// Where a motion comes from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RawSource", into = "RawSource")]
pub enum MotionSource {
    /// A procedural motion: `builtin = "idle" | "walk" | "run" | "jump" | "turn" | "spin" |
    /// "twirl" | "rom"`,
    /// optional `duration_secs`, `speed`, `fps`, `split`, `name` (needs the mannequin).
    Builtin {
        /// Which one.
        builtin: MotionKind,
        /// Length in seconds, (0, 3600], default 6.
        duration_secs: f32,
        /// Playback speed factor, (0, 10], default 1 (0.5: the spin turns once a second).
        speed: f32,
        /// Sampling rate in frames per second, [1, 1000]; default: the scene's `training_fps`.
        fps: Option<f32>,
        /// Data split, default "train".
        split: Split,
        /// Display name; default: the kind's name (with ", mirrored" when `mirrored`).
        name: Option<String>,
        /// Play the motion's left/right mirror image (a spin turns the other way), default
        /// false.
        mirrored: bool,
    },
    /// A motion file (BVH, or the animations of a glTF/GLB file): `path`, optional `units`,
    /// `up`, `split`, `name`, `joint_map`.
    File {
        /// Path, relative to the config file's folder.
        path: PathBuf,
        /// Unit of the file's lengths; default: the file's own (BVH: guessed from the height).
        units: Option<LengthUnit>,
        /// Up axis of the file; default auto: detected from the rig.
        up: UpAxis,
        /// Data split, default "train".
        split: Split,
        /// Animation to take from a file holding several; default: all of them (each keeps
        /// its own name; a BVH motion is named after the file stem).
        name: Option<String>,
        /// Joint map file (TOML, `[joints] AvatarJoint = "MotionJoint"`) overriding the
        /// automatic joint mapping, relative to the config file's folder; default none.
        joint_map: Option<PathBuf>,
        /// Play each animation's left/right mirror image (named with ", mirrored"), default
        /// false.
        mirrored: bool,
    },
}

/// The TOML shape shared by all sources; converted with field checks and clear messages.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSource {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    builtin: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    path: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    units: Option<LengthUnit>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    up: Option<UpAxis>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    resolution: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    smoothing_passes: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    duration_secs: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    speed: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    fps: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    split: Option<Split>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    name: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    joint_map: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    mirrored: Option<bool>,
}

impl RawSource {
    /// Checks that exactly one of `builtin`/`path` is set and no field outside `allowed`.
    fn check(&self, what: &str, expected: &str, allowed: &[&str]) -> Result<(), String> {
        match (&self.builtin, &self.path) {
            (Some(_), Some(_)) => {
                return Err(format!("{what}: set either `builtin` or `path`, not both"));
            }
            (None, None) => {
                return Err(format!(
                    "{what}: set `builtin` (one of {expected}) or `path`"
                ));
            }
            _ => {}
        }
        let set = [
            ("units", self.units.is_some()),
            ("up", self.up.is_some()),
            ("resolution", self.resolution.is_some()),
            ("smoothing_passes", self.smoothing_passes.is_some()),
            ("duration_secs", self.duration_secs.is_some()),
            ("speed", self.speed.is_some()),
            ("fps", self.fps.is_some()),
            ("split", self.split.is_some()),
            ("name", self.name.is_some()),
            ("joint_map", self.joint_map.is_some()),
            ("mirrored", self.mirrored.is_some()),
        ];
        let kind = if self.builtin.is_some() {
            "built-in"
        } else {
            "file"
        };
        match set
            .iter()
            .find(|(field, on)| *on && !allowed.contains(field))
        {
            Some((field, _)) => Err(format!(
                "{what}: `{field}` does not apply to a {kind} {what}"
            )),
            None => Ok(()),
        }
    }
}

/// The `up` a file source writes: none for auto (the default, so files written before the
/// setting existed and files written now read the same).
fn written(up: UpAxis) -> Option<UpAxis> {
    (up != UpAxis::Auto).then_some(up)
}

fn unknown(what: &str, name: &str, expected: &str) -> String {
    format!("unknown built-in {what} \"{name}\" (expected one of {expected})")
}

impl TryFrom<RawSource> for AvatarSource {
    type Error = String;
    fn try_from(raw: RawSource) -> Result<Self, String> {
        let expected = "\"mannequin\"";
        match (raw.builtin.clone(), raw.path.clone()) {
            (Some(b), None) => {
                raw.check("avatar", expected, &[])?;
                match b.as_str() {
                    "mannequin" => Ok(Self::Builtin {
                        builtin: BuiltinAvatar::Mannequin,
                    }),
                    other => Err(unknown("avatar", other, expected)),
                }
            }
            (_, path) => {
                raw.check("avatar", expected, &["units", "up"])?;
                Ok(Self::File {
                    path: path.unwrap_or_default(),
                    units: raw.units,
                    up: raw.up.unwrap_or_default(),
                })
            }
        }
    }
}

impl From<AvatarSource> for RawSource {
    fn from(s: AvatarSource) -> Self {
        match s {
            AvatarSource::Builtin { .. } => Self {
                builtin: Some("mannequin".into()),
                ..Self::default()
            },
            AvatarSource::File { path, units, up } => Self {
                path: Some(path),
                units,
                up: written(up),
                ..Self::default()
            },
        }
    }
}

impl TryFrom<RawSource> for GarmentSource {
    type Error = String;
    fn try_from(raw: RawSource) -> Result<Self, String> {
        let expected = "\"tshirt\", \"skirt\", \"dress\"";
        match (raw.builtin.clone(), raw.path.clone()) {
            (Some(b), None) => {
                raw.check("garment", expected, &["resolution", "smoothing_passes"])?;
                let builtin =
                    GarmentKind::from_name(&b).ok_or_else(|| unknown("garment", &b, expected))?;
                let resolution = raw.resolution.unwrap_or_else(default_resolution);
                Ok(Self::Builtin {
                    builtin,
                    resolution,
                    smoothing_passes: raw.smoothing_passes,
                })
            }
            (_, path) => {
                raw.check("garment", expected, &["units", "up", "smoothing_passes"])?;
                Ok(Self::File {
                    path: path.unwrap_or_default(),
                    units: raw.units,
                    up: raw.up.unwrap_or_default(),
                    smoothing_passes: raw.smoothing_passes,
                })
            }
        }
    }
}

impl From<GarmentSource> for RawSource {
    fn from(s: GarmentSource) -> Self {
        match s {
            GarmentSource::Builtin {
                builtin,
                resolution,
                smoothing_passes,
            } => Self {
                builtin: Some(builtin.name().into()),
                resolution: Some(resolution),
                smoothing_passes,
                ..Self::default()
            },
            GarmentSource::File {
                path,
                units,
                up,
                smoothing_passes,
            } => Self {
                path: Some(path),
                units,
                up: written(up),
                smoothing_passes,
                ..Self::default()
            },
        }
    }
}

impl TryFrom<RawSource> for MotionSource {
    type Error = String;
    fn try_from(raw: RawSource) -> Result<Self, String> {
        let expected = "\"idle\", \"walk\", \"run\", \"jump\", \"turn\", \"spin\"";
        let split = raw.split.unwrap_or_default();
        match (raw.builtin.clone(), raw.path.clone()) {
            (Some(b), None) => {
                raw.check(
                    "motion",
                    expected,
                    &["duration_secs", "speed", "fps", "split", "name", "mirrored"],
                )?;
                let builtin =
                    MotionKind::from_name(&b).ok_or_else(|| unknown("motion", &b, expected))?;
                let duration_secs = raw.duration_secs.unwrap_or_else(default_duration);
                Ok(Self::Builtin {
                    builtin,
                    duration_secs,
                    speed: raw.speed.unwrap_or(1.0),
                    fps: raw.fps,
                    split,
                    name: raw.name,
                    mirrored: raw.mirrored.unwrap_or(false),
                })
            }
            (_, path) => {
                raw.check(
                    "motion",
                    expected,
                    &["units", "up", "split", "name", "joint_map", "mirrored"],
                )?;
                Ok(Self::File {
                    path: path.unwrap_or_default(),
                    units: raw.units,
                    up: raw.up.unwrap_or_default(),
                    split,
                    name: raw.name,
                    joint_map: raw.joint_map,
                    mirrored: raw.mirrored.unwrap_or(false),
                })
            }
        }
    }
}

impl From<MotionSource> for RawSource {
    fn from(s: MotionSource) -> Self {
        match s {
            MotionSource::Builtin {
                builtin,
                duration_secs,
                speed,
                fps,
                split,
                name,
                mirrored,
            } => Self {
                builtin: Some(builtin.name().into()),
                duration_secs: Some(duration_secs),
                speed: (speed != 1.0).then_some(speed),
                fps,
                split: Some(split),
                name,
                mirrored: mirrored.then_some(true),
                ..Self::default()
            },
            MotionSource::File {
                path,
                units,
                up,
                split,
                name,
                joint_map,
                mirrored,
            } => Self {
                path: Some(path),
                units,
                up: written(up),
                split: Some(split),
                name,
                joint_map,
                mirrored: mirrored.then_some(true),
                ..Self::default()
            },
        }
    }
}

impl MotionSource {
    /// The motion's data split.
    pub fn split(&self) -> Split {
        match self {
            MotionSource::Builtin { split, .. } | MotionSource::File { split, .. } => *split,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::SceneConfig;
    use super::*;

    /// A scene of Z-up files, as a user writes it.
    const Z_UP: &str = r#"name = "z-up files"
avatar = { path = "body.glb", up = "z" }
garment = { path = "skirt.obj", up = "Z", units = "cm" }
[[motions]]
path = "walk.bvh"
up = "y"
[[motions]]
path = "run.bvh"
"#;

    #[test]
    fn the_up_axis_of_file_sources_round_trips_through_toml() {
        let c = SceneConfig::from_toml_str(Z_UP).unwrap();
        assert!(matches!(c.avatar, AvatarSource::File { up: UpAxis::Z, .. }));
        assert!(matches!(
            c.garment,
            GarmentSource::File {
                up: UpAxis::Z,
                units: Some(LengthUnit::Centimetres),
                ..
            }
        ));
        assert!(matches!(
            c.motions[0],
            MotionSource::File { up: UpAxis::Y, .. }
        ));
        // Left out, the axis is detected (auto), and auto is not written back.
        assert!(matches!(
            c.motions[1],
            MotionSource::File {
                up: UpAxis::Auto,
                ..
            }
        ));
        let text = c.to_toml_string().unwrap();
        assert_eq!(text.matches("up = ").count(), 3, "{text}");
        assert!(text.contains("up = \"z\""), "{text}");
        assert_eq!(SceneConfig::from_toml_str(&text).unwrap(), c);
    }

    #[test]
    fn up_on_a_built_in_source_or_an_unknown_axis_is_refused() {
        let err = SceneConfig::from_toml_str(
            "name = \"x\"\navatar = { builtin = \"mannequin\", up = \"z\" }\n\
             garment = { builtin = \"tshirt\" }\n[[motions]]\nbuiltin = \"walk\"\n",
        )
        .unwrap_err();
        assert!(err.to_string().contains("`up` does not apply"), "{err}");
        let err =
            SceneConfig::from_toml_str(&Z_UP.replace("up = \"y\"", "up = \"x\"")).unwrap_err();
        assert!(err.to_string().contains("unknown variant"), "{err}");
    }
}
