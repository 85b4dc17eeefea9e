//! Fabric parameters as plain data: the cloth material model, its stiffnesses, density,
//! collision and gravity settings, named presets, validation and the `[fabric]` table of scene
//! files (a preset plus overrides). They live in the scene layer because a scene description
//! ([`super::SceneConfig`]) carries them; the physics layer re-exports them and evaluates them.
//!
//! # Stiffness convention (read this before comparing numbers)
//! The authors' official code weights every triangle term by `|cross|` (twice the triangle
//! area) and sums the bending denominator over `|cross|` of both faces. We keep that
//! convention so that the magnitudes stated in the paper (structural stiffness 5..15, shear
//! 0..1, bending 1e-5..1e-4, `k_c` similar to the structural stiffness) mean exactly what they
//! meant there:
//! - Baraff-Witkin: `E = k_stretch Σ_f 2A_f ((|w_u|-1)² + (|w_v|-1)²) + k_shear Σ_f 2A_f (w_u·w_v)²`
//! - StVK: `E = Σ_f 2A_f (μ tr(G²) + λ/2 tr(G)²)`, `G = ½(FᵀF - I)`
//! - mass-spring: `E = k_stretch Σ_e (l_e - l̄_e)²` (no area weight, resolution dependent)
//! - bending: `E = k_b Σ_h l̄_h² / (8 (2Ā_0 + 2Ā_1)) (θ_h - θ̄_h)²`, i.e. `l²/(16 a)` with `a` the
//!   true summed area (the paper's Eq. 6 written with the true area would be twice as stiff).
//!
//! In physical terms (regular mesh, small strain) the Baraff-Witkin stretch term is a membrane
//! with Young-like modulus `Y ≈ 4 k_stretch` N/m and the bending term a plate with bending
//! rigidity `B ≈ k_b / 16` N·m; the presets use these two relations to map published fabric
//! data onto the parameters.

use serde::{Deserialize, Serialize};

/// Errors of fabric parameters.
#[derive(Debug, thiserror::Error)]
pub enum FabricError {
    /// A fabric parameter is out of range or malformed.
    #[error("invalid fabric parameter '{field}': {reason}")]
    Invalid {
        /// Offending field.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// An unknown preset name.
    #[error("unknown fabric preset '{name}' (known: {known})")]
    UnknownPreset {
        /// Requested name.
        name: String,
        /// Known names.
        known: String,
    },
    /// The fabric table could not be read.
    #[error("fabric table: {0}")]
    Table(String),
}

/// In-plane cloth material model (paper §3.4, §4.3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ClothModel {
    /// Springs on mesh edges (PBNS); parameters depend on mesh resolution.
    #[serde(alias = "mass-spring", alias = "edge")]
    MassSpring,
    /// Squared Baraff-Witkin stretch and shear constraints (the official default).
    #[default]
    #[serde(alias = "baraff-witkin", alias = "baraff98")]
    BaraffWitkin,
    /// Saint Venant-Kirchhoff membrane with Lamé parameters.
    #[serde(alias = "StVK", alias = "st_vk")]
    Stvk,
}

/// Material and environment parameters of a garment. Every energy uses the convention of the
/// module docs (triangle terms weighted by twice the area).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FabricParams {
    /// In-plane model. Default `baraff_witkin`.
    pub cloth_model: ClothModel,
    /// Structural stiffness `k_stretch` in N/m: Baraff-Witkin stretch weight, or the per-edge
    /// spring weight of the mass-spring model. Range `[0, 1e6]`, default 10.
    pub stretch_stiffness: f32,
    /// Baraff-Witkin shear weight `k_shear` in N/m. Range `[0, 1e6]`, default 1.
    pub shear_stiffness: f32,
    /// StVK first Lamé parameter `λ` in N/m. Range `[0, 1e6]`, default 20.9.
    pub lame_lambda: f32,
    /// StVK second Lamé parameter (shear modulus) `μ` in N/m. Range `[0, 1e6]`, default 11.1.
    pub lame_mu: f32,
    /// Bending stiffness `k_b` in N·m (J per rad², before the `l²/(8·2a)` scaling).
    /// Range `[0, 10]`, default 2e-5.
    pub bending_stiffness: f32,
    /// Surface density in kg/m². Range `[1e-4, 100]`, default 0.15.
    pub density_kg_per_m2: f32,
    /// Collision weight `k_c` in N/m. Range `[0, 1e7]`, default 10.
    pub collision_stiffness: f32,
    /// Collision threshold `ε` in metres: vertices closer than this to the body are pushed out.
    /// Range `[0, 0.1]`, default 0.004.
    pub collision_threshold_m: f32,
    /// Pinning weight in N/m (pinned vertices to their target). Range `[0, 1e8]`, default 100.
    pub pinning_stiffness: f32,
    /// Gravity acceleration vector in m/s² (Y up). Length at most 1000, default `[0, -9.81, 0]`.
    pub gravity_m_per_s2: [f32; 3],
    /// Coulomb friction coefficient `μ` between cloth and skin (dimensionless), used when the
    /// scene's friction effect is on. Range `[0, 2]`, default 0.5.
    pub friction_coefficient: f32,
}

impl Default for FabricParams {
    fn default() -> Self {
        Self {
            cloth_model: ClothModel::BaraffWitkin,
            stretch_stiffness: 10.0,
            shear_stiffness: 1.0,
            lame_lambda: 20.9,
            lame_mu: 11.1,
            bending_stiffness: 2e-5,
            density_kg_per_m2: 0.15,
            collision_stiffness: 10.0,
            collision_threshold_m: 0.004,
            pinning_stiffness: 100.0,
            gravity_m_per_s2: [0.0, -9.81, 0.0],
            friction_coefficient: 0.5,
        }
    }
}

/// Names accepted by [`FabricParams::preset`].
pub const PRESET_NAMES: [&str; 5] = ["default", "silk", "cotton", "denim", "leather"];

/// Kawabata bending rigidity unit gf·cm²/cm expressed in N·m.
const GF_CM2_PER_CM_IN_NM: f32 = 9.806_65e-5;

impl FabricParams {
    /// A named preset; see [`PRESET_NAMES`].
    ///
    /// Densities are typical areal weights; bending rigidities `B` are typical Kawabata (KES-FB2)
    /// values mapped with `k_b = 16 B`; structural stiffness stays near the paper's training
    /// range (real cloth is stiffer, `Y` = 1e2..1e4 N/m; raise it for near-inextensible
    /// reference simulations at the price of slower convergence):
    /// - `default`: the official code's configuration (Baraff-Witkin 10/1, `k_b` 2e-5, 0.15 kg/m²).
    /// - `silk`: habotai/charmeuse, 60 g/m², `B` ≈ 0.015 gf·cm²/cm, light shear resistance.
    /// - `cotton`: single jersey t-shirt knit, 160 g/m², `B` ≈ 0.04 gf·cm²/cm.
    /// - `denim`: 12 oz/yd² twill, 410 g/m², `B` ≈ 0.8 gf·cm²/cm, stiffer in-plane.
    /// - `leather`: 0.8 mm garment lambskin, 700 g/m², `B` ≈ 4 gf·cm²/cm, resists shear.
    pub fn preset(name: &str) -> Result<Self, FabricError> {
        let base = Self::default();
        let with = |density: f32, bending_gf_cm2: f32, stretch: f32, shear: f32| Self {
            density_kg_per_m2: density,
            bending_stiffness: 16.0 * bending_gf_cm2 * GF_CM2_PER_CM_IN_NM,
            stretch_stiffness: stretch,
            shear_stiffness: shear,
            collision_stiffness: stretch,
            ..Self::default()
        };
        match name.trim().to_ascii_lowercase().as_str() {
            "default" | "" => Ok(base),
            "silk" => Ok(with(0.06, 0.015, 10.0, 0.5)),
            "cotton" => Ok(with(0.16, 0.04, 10.0, 1.0)),
            "denim" => Ok(with(0.41, 0.8, 30.0, 3.0)),
            "leather" => Ok(with(0.70, 4.0, 50.0, 10.0)),
            other => Err(FabricError::UnknownPreset {
                name: other.to_string(),
                known: PRESET_NAMES.join(", "),
            }),
        }
    }

    /// Builds parameters from a scene file's `[fabric]` table: an optional `preset` key (default
    /// `"default"`) plus overrides named like the fields of this struct, then validates.
    pub fn from_table(table: &toml::Table) -> Result<Self, FabricError> {
        let preset = match table.get("preset") {
            None => "default".to_string(),
            Some(toml::Value::String(s)) => s.clone(),
            Some(other) => {
                return Err(FabricError::Invalid {
                    field: "preset".into(),
                    reason: format!("must be a string, found {}", other.type_str()),
                });
            }
        };
        let base = Self::preset(&preset)?;
        let mut merged = toml::Table::try_from(&base)
            .map_err(|e| FabricError::Table(format!("cannot serialise preset: {e}")))?;
        for (key, value) in table {
            if key != "preset" {
                merged.insert(key.clone(), value.clone());
            }
        }
        let params: Self = merged
            .try_into()
            .map_err(|e: toml::de::Error| FabricError::Table(e.message().to_string()))?;
        params.validate()?;
        Ok(params)
    }

    /// Checks every field against its documented range.
    pub fn validate(&self) -> Result<(), FabricError> {
        let check = |field: &str, value: f32, lo: f32, hi: f32| -> Result<(), FabricError> {
            if !value.is_finite() {
                return Err(FabricError::Invalid {
                    field: field.into(),
                    reason: format!("{value} is not a finite number"),
                });
            }
            if value < lo || value > hi {
                return Err(FabricError::Invalid {
                    field: field.into(),
                    reason: format!("{value} is outside [{lo}, {hi}]"),
                });
            }
            Ok(())
        };
        check("stretch_stiffness", self.stretch_stiffness, 0.0, 1e6)?;
        check("shear_stiffness", self.shear_stiffness, 0.0, 1e6)?;
        check("lame_lambda", self.lame_lambda, 0.0, 1e6)?;
        check("lame_mu", self.lame_mu, 0.0, 1e6)?;
        check("bending_stiffness", self.bending_stiffness, 0.0, 10.0)?;
        check("density_kg_per_m2", self.density_kg_per_m2, 1e-4, 100.0)?;
        check("collision_stiffness", self.collision_stiffness, 0.0, 1e7)?;
        check(
            "collision_threshold_m",
            self.collision_threshold_m,
            0.0,
            0.1,
        )?;
        check("pinning_stiffness", self.pinning_stiffness, 0.0, 1e8)?;
        check("friction_coefficient", self.friction_coefficient, 0.0, 2.0)?;
        for (k, g) in self.gravity_m_per_s2.iter().enumerate() {
            check(
                [
                    "gravity_m_per_s2[0]",
                    "gravity_m_per_s2[1]",
                    "gravity_m_per_s2[2]",
                ][k],
                *g,
                -1000.0,
                1000.0,
            )?;
        }
        let in_plane = match self.cloth_model {
            ClothModel::MassSpring => self.stretch_stiffness,
            ClothModel::BaraffWitkin => self.stretch_stiffness + self.shear_stiffness,
            ClothModel::Stvk => self.lame_lambda + self.lame_mu,
        };
        if in_plane <= 0.0 {
            return Err(FabricError::Invalid {
                field: "cloth_model".into(),
                reason: format!(
                    "{:?} has all its stiffnesses at zero: the cloth would not hold together",
                    self.cloth_model
                ),
            });
        }
        Ok(())
    }

    /// Gravity as a vector.
    pub fn gravity(&self) -> crate::geometry::Vec3 {
        crate::geometry::Vec3::from(self.gravity_m_per_s2)
    }

    /// The preset these parameters are exactly, if any (the app shows "custom" otherwise).
    pub fn preset_name(&self) -> Option<&'static str> {
        PRESET_NAMES
            .into_iter()
            .find(|name| Self::preset(name).is_ok_and(|p| p == *self))
    }

    /// The `[fabric]` table of a scene file: `{ preset = "NAME" }` when the parameters are a
    /// preset, every field otherwise ([`Self::from_table`] reads both back).
    pub fn to_table(&self) -> Result<toml::Table, FabricError> {
        match self.preset_name() {
            Some(name) => {
                let mut table = toml::Table::new();
                table.insert("preset".into(), toml::Value::String(name.into()));
                Ok(table)
            }
            None => toml::Table::try_from(self).map_err(|e| FabricError::Table(e.to_string())),
        }
    }
}

/// Serde adapter for a scene file's `[fabric]` table (`#[serde(with = "fabric::table")]`):
/// reads a preset plus overrides and validates, writes [`FabricParams::to_table`].
pub mod table {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    use super::FabricParams;

    /// Writes the table of `fabric`.
    pub fn serialize<S: Serializer>(fabric: &FabricParams, s: S) -> Result<S::Ok, S::Error> {
        fabric
            .to_table()
            .map_err(serde::ser::Error::custom)?
            .serialize(s)
    }

    /// Reads a table: an optional preset (default "default") and overrides of its fields.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<FabricParams, D::Error> {
        let table = toml::Table::deserialize(d)?;
        FabricParams::from_table(&table).map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_official_and_valid() {
        let p = FabricParams::default();
        assert_eq!(p.cloth_model, ClothModel::BaraffWitkin);
        assert_eq!(
            (p.stretch_stiffness, p.shear_stiffness, p.bending_stiffness),
            (10.0, 1.0, 2e-5)
        );
        assert_eq!(
            (p.density_kg_per_m2, p.collision_threshold_m),
            (0.15, 0.004)
        );
        p.validate().unwrap();
        for name in PRESET_NAMES {
            FabricParams::preset(name).unwrap().validate().unwrap();
        }
        let denim = FabricParams::preset("Denim").unwrap();
        let silk = FabricParams::preset("silk").unwrap();
        assert!(denim.bending_stiffness > 10.0 * silk.bending_stiffness);
        assert!(denim.density_kg_per_m2 > silk.density_kg_per_m2);
        assert!(matches!(
            FabricParams::preset("tweed"),
            Err(FabricError::UnknownPreset { .. })
        ));
    }

    #[test]
    fn table_applies_preset_then_overrides() {
        let t: toml::Table = "preset = \"cotton\"\nbending_stiffness = 3e-5\ncloth_model = \"stvk\"\nstretch_stiffness = 12".parse().unwrap();
        let p = FabricParams::from_table(&t).unwrap();
        assert_eq!(p.cloth_model, ClothModel::Stvk);
        assert_eq!(p.bending_stiffness, 3e-5);
        assert_eq!(p.stretch_stiffness, 12.0);
        assert_eq!(p.density_kg_per_m2, 0.16);
        let empty = FabricParams::from_table(&toml::Table::new()).unwrap();
        assert_eq!(empty, FabricParams::default());
    }

    #[test]
    fn a_preset_is_written_by_name_and_anything_else_in_full() {
        let silk = FabricParams::preset("silk").unwrap();
        assert_eq!(silk.preset_name(), Some("silk"));
        let table = silk.to_table().unwrap();
        assert_eq!(table.len(), 1);
        assert_eq!(FabricParams::from_table(&table).unwrap(), silk);
        let custom = FabricParams {
            density_kg_per_m2: 0.2,
            ..silk
        };
        assert_eq!(custom.preset_name(), None);
        let table = custom.to_table().unwrap();
        assert!(table.get("preset").is_none() && table.len() > 5, "{table}");
        assert_eq!(FabricParams::from_table(&table).unwrap(), custom);
    }

    #[test]
    fn table_errors_name_the_problem() {
        let bad: toml::Table = "density_kg_per_m2 = -1.0".parse().unwrap();
        let e = FabricParams::from_table(&bad).unwrap_err().to_string();
        assert!(e.contains("density_kg_per_m2"), "{e}");
        let unknown: toml::Table = "stiffnes = 3.0".parse().unwrap();
        let e = FabricParams::from_table(&unknown).unwrap_err().to_string();
        assert!(e.contains("stiffnes"), "{e}");
        let nan = FabricParams {
            bending_stiffness: f32::NAN,
            ..FabricParams::default()
        };
        assert!(
            nan.validate()
                .unwrap_err()
                .to_string()
                .contains("bending_stiffness")
        );
        let limp = FabricParams {
            cloth_model: ClothModel::MassSpring,
            stretch_stiffness: 0.0,
            ..FabricParams::default()
        };
        assert!(limp.validate().is_err());
        let alias: toml::Table = "cloth_model = \"mass-spring\"".parse().unwrap();
        assert_eq!(
            FabricParams::from_table(&alias).unwrap().cloth_model,
            ClothModel::MassSpring
        );
    }
}
