//! Presets for where a baked cache goes: the axis, units, handedness and frame numbering that
//! Blender, Unreal, Unity, Maya and Houdini expect. The program works in metres, Y up,
//! right-handed (as glTF); a preset turns those coordinates into the target's convention with
//! exact operations (an axis swap, one `f32` multiply for the units, a sign flip for a mirror).
//!
//! From Y up to Z up the rotation is the one Blender's glTF importer uses:
//! `(x, y, z) -> (x, -z, y)`, which keeps the frame right-handed. A left-handed target mirrors
//! X: `x -> -x`, as Unity's FBX, OBJ and glTF importers do on their side.

use std::fmt;
use std::str::FromStr;

use crate::geometry::Vec3;

/// A destination tool. No preset (the default) keeps the program's own convention.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// Blender: Z up, metres, right-handed, frames from 1.
    Blender,
    /// Unreal Engine: Z up, centimetres, right-handed (its FBX/USD/Alembic importers mirror Y
    /// into its left-handed space), frames from 0.
    Unreal,
    /// Unity: Y up, metres, left-handed (X mirrored) where the format carries raw
    /// coordinates, frames from 0.
    Unity,
    /// Maya: Y up, centimetres (its default working unit), right-handed, frames from 1.
    Maya,
    /// Houdini: Y up, metres, right-handed, frames from 1.
    Houdini,
}

/// A preset name that is not one of ours.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown preset '{0}' (blender, unreal, unity, maya, houdini)")]
pub struct UnknownPreset(pub String);

impl Preset {
    /// Every preset, in menu order.
    pub const ALL: [Preset; 5] = [
        Preset::Blender,
        Preset::Unreal,
        Preset::Unity,
        Preset::Maya,
        Preset::Houdini,
    ];

    /// The name used on the command line (`blender`, `unreal`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Preset::Blender => "blender",
            Preset::Unreal => "unreal",
            Preset::Unity => "unity",
            Preset::Maya => "maya",
            Preset::Houdini => "houdini",
        }
    }

    /// A menu label that says what the preset sets.
    pub fn label(self) -> &'static str {
        match self {
            Preset::Blender => "Blender (Z up, m, frames from 1)",
            Preset::Unreal => "Unreal (Z up, cm, frames from 0)",
            Preset::Unity => "Unity (Y up, m, left-handed caches, frames from 0)",
            Preset::Maya => "Maya (Y up, cm, frames from 1)",
            Preset::Houdini => "Houdini (Y up, m, frames from 1)",
        }
    }

    /// Parses a name, ignoring ASCII case.
    pub fn parse(name: &str) -> Result<Self, UnknownPreset> {
        Self::ALL
            .into_iter()
            .find(|p| p.name().eq_ignore_ascii_case(name.trim()))
            .ok_or_else(|| UnknownPreset(name.to_string()))
    }

    /// The convention this preset writes in.
    pub fn convention(self) -> Convention {
        let (up_axis, units_per_m, left_handed, frame_base) = match self {
            Preset::Blender => (UpAxis::Z, 1.0, false, 1),
            Preset::Unreal => (UpAxis::Z, 100.0, false, 0),
            Preset::Unity => (UpAxis::Y, 1.0, true, 0),
            Preset::Maya => (UpAxis::Y, 100.0, false, 1),
            Preset::Houdini => (UpAxis::Y, 1.0, false, 1),
        };
        Convention {
            up_axis,
            units_per_m,
            left_handed,
            frame_base,
        }
    }
}

impl fmt::Display for Preset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Preset {
    type Err = UnknownPreset;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::parse(s)
    }
}

/// The vertical axis of a convention.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UpAxis {
    /// +Y up (glTF, Maya, Houdini, Unity).
    Y,
    /// +Z up (Blender, Unreal).
    Z,
}

impl UpAxis {
    /// The USD token of the axis (`"Y"` or `"Z"`).
    pub fn token(self) -> &'static str {
        match self {
            UpAxis::Y => "Y",
            UpAxis::Z => "Z",
        }
    }
}

/// Axis, units, handedness and frame numbering of written coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Convention {
    /// The up axis.
    pub up_axis: UpAxis,
    /// Length units per metre: 1 (metres) or 100 (centimetres).
    pub units_per_m: f32,
    /// Mirror X into a left-handed frame.
    pub left_handed: bool,
    /// The frame number of the motion's frame 0 (0 or 1).
    pub frame_base: usize,
}

impl Convention {
    /// The program's own convention: Y up, metres, right-handed, frames from 0.
    pub const NATIVE: Convention = Convention {
        up_axis: UpAxis::Y,
        units_per_m: 1.0,
        left_handed: false,
        frame_base: 0,
    };

    /// Metres per length unit (USD's `metersPerUnit`): 1 or 0.01.
    pub fn meters_per_unit(&self) -> f64 {
        1.0 / f64::from(self.units_per_m)
    }

    /// The same convention kept right-handed: for formats whose importers mirror into a
    /// left-handed space themselves (OBJ, USD), where pre-mirrored data would come in mirrored.
    pub fn right_handed(self) -> Self {
        Self {
            left_handed: false,
            ..self
        }
    }

    /// True when [`Self::apply`] returns its input unchanged.
    pub fn is_identity(&self) -> bool {
        self.up_axis == UpAxis::Y && self.units_per_m == 1.0 && !self.left_handed
    }

    /// One point from the program's space (metres, Y up, right-handed) into this convention.
    pub fn apply(&self, p: Vec3) -> Vec3 {
        let mut q = match self.up_axis {
            UpAxis::Y => p,
            UpAxis::Z => Vec3::new(p.x, -p.z, p.y),
        };
        if self.units_per_m != 1.0 {
            q *= self.units_per_m;
        }
        if self.left_handed {
            q.x = -q.x;
        }
        q
    }

    /// Every point of a frame through [`Self::apply`].
    pub fn apply_all(&self, points: &[Vec3]) -> Vec<Vec3> {
        points.iter().map(|&p| self.apply(p)).collect()
    }
}

impl Default for Convention {
    fn default() -> Self {
        Self::NATIVE
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_are_refused() {
        for p in Preset::ALL {
            assert_eq!(Preset::parse(p.name()), Ok(p));
            assert_eq!(p.to_string().parse::<Preset>(), Ok(p));
        }
        assert_eq!(Preset::parse(" Blender "), Ok(Preset::Blender));
        let err = Preset::parse("cinema4d").unwrap_err();
        assert_eq!(
            err.to_string(),
            "unknown preset 'cinema4d' (blender, unreal, unity, maya, houdini)"
        );
    }

    #[test]
    fn transforms_match_the_documented_table() {
        let p = Vec3::new(0.25, 1.5, -0.125);
        let expect = |preset: Preset| preset.convention().apply(p);
        assert_eq!(expect(Preset::Blender), Vec3::new(0.25, 0.125, 1.5));
        assert_eq!(expect(Preset::Unreal), Vec3::new(25.0, 12.5, 150.0));
        assert_eq!(expect(Preset::Unity), Vec3::new(-0.25, 1.5, -0.125));
        assert_eq!(expect(Preset::Maya), Vec3::new(25.0, 150.0, -12.5));
        assert_eq!(expect(Preset::Houdini), p);
        assert_eq!(Convention::NATIVE.apply(p), p);
        assert!(Convention::NATIVE.is_identity());
        assert!(Preset::Houdini.convention().is_identity());
        assert!(!Preset::Unity.convention().is_identity());
        assert!(Preset::Unity.convention().right_handed().is_identity());
        assert_eq!(Preset::Unreal.convention().meters_per_unit(), 0.01);
        assert_eq!(Preset::Blender.convention().meters_per_unit(), 1.0);
    }

    #[test]
    fn z_up_rotation_is_proper_and_keeps_handedness() {
        // The images of the axes form a right-handed frame: x' . (y' x z') = +1.
        let c = Preset::Blender.convention();
        let (x, y, z) = (c.apply(Vec3::x()), c.apply(Vec3::y()), c.apply(Vec3::z()));
        assert_eq!(x.dot(&y.cross(&z)), 1.0);
        // Y up becomes Z up.
        assert_eq!(y, Vec3::z());
        // Unity's mirror flips the frame.
        let u = Preset::Unity.convention();
        let (x, y, z) = (u.apply(Vec3::x()), u.apply(Vec3::y()), u.apply(Vec3::z()));
        assert_eq!(x.dot(&y.cross(&z)), -1.0);
    }
}
