//! The up axis of a file, as the scene description records it (`up = "z"` on a file source)
//! and every importer takes it: the one home of the setting. Everything inside the tool is Y
//! up (glTF's convention); a Z-up file is turned Y up by Blender's own glTF convention,
//! `(x, y, z) -> (x, z, -y)` (the -Y forward of a Z-up scene becomes +Z). Detection from a
//! file's skeleton or shape lives with the importers (`io::axes`).

use crate::geometry::{Quat, Vec3};

/// Which axis of a file points up.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum UpAxis {
    /// Detect from the file (its skeleton, or an OBJ mesh's shape; an unskinned glTF mesh is
    /// Y up as the format says).
    #[default]
    #[serde(alias = "Auto")]
    Auto,
    /// Y up (glTF, most game and DCC exports).
    #[serde(alias = "Y")]
    Y,
    /// Z up (3ds Max, Blender scenes, some motion capture).
    #[serde(alias = "Z")]
    Z,
}

impl UpAxis {
    /// The rotation that turns this axis's coordinates Y up: identity for Y (and Auto), -90
    /// degrees about X for Z.
    pub fn to_y_up(self) -> Quat {
        match self {
            UpAxis::Z => Quat::from_axis_angle(&Vec3::x_axis(), -std::f32::consts::FRAC_PI_2),
            UpAxis::Y | UpAxis::Auto => Quat::identity(),
        }
    }

    /// Short name: `auto`, `Y` or `Z`.
    pub fn label(self) -> &'static str {
        match self {
            UpAxis::Auto => "auto",
            UpAxis::Y => "Y",
            UpAxis::Z => "Z",
        }
    }

    /// Every choice, in the order a selector lists them.
    pub const ALL: [UpAxis; 3] = [UpAxis::Auto, UpAxis::Y, UpAxis::Z];
}

impl std::str::FromStr for UpAxis {
    type Err = String;

    /// `auto`, `y` or `z` (any case; `+y`, `+z`, `y-up`, `z-up` too).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s
            .to_ascii_lowercase()
            .trim_start_matches('+')
            .trim_end_matches("-up")
        {
            "auto" => Ok(UpAxis::Auto),
            "y" => Ok(UpAxis::Y),
            "z" => Ok(UpAxis::Z),
            other => Err(format!("unknown up axis '{other}' (auto, y or z)")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn z_up_turns_to_y_up_with_minus_y_forward_becoming_z() {
        let r = UpAxis::Z.to_y_up();
        assert!((r * Vec3::z() - Vec3::y()).norm() < 1e-6);
        assert!((r * -Vec3::y() - Vec3::z()).norm() < 1e-6);
        assert!((r * Vec3::x() - Vec3::x()).norm() < 1e-6);
        assert_eq!(UpAxis::Y.to_y_up(), Quat::identity());
    }

    #[test]
    fn up_axes_parse() {
        assert_eq!("Z".parse::<UpAxis>(), Ok(UpAxis::Z));
        assert_eq!("+y".parse::<UpAxis>(), Ok(UpAxis::Y));
        assert_eq!("z-up".parse::<UpAxis>(), Ok(UpAxis::Z));
        assert_eq!("auto".parse::<UpAxis>(), Ok(UpAxis::Auto));
        assert!("x".parse::<UpAxis>().unwrap_err().contains("auto, y or z"));
    }

    #[test]
    fn up_axes_serialise_lower_case_and_read_either_case() {
        #[derive(serde::Serialize, serde::Deserialize)]
        struct T {
            up: UpAxis,
        }
        assert_eq!(
            toml::to_string(&T { up: UpAxis::Z }).unwrap().trim(),
            "up = \"z\""
        );
        for (text, want) in [("z", UpAxis::Z), ("Y", UpAxis::Y), ("auto", UpAxis::Auto)] {
            let t: T = toml::from_str(&format!("up = \"{text}\"")).unwrap();
            assert_eq!(t.up, want);
        }
        assert!(toml::from_str::<T>("up = \"x\"").is_err());
    }
}
