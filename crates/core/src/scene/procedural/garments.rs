//! Built-in garments around the mannequin's rest pose: a t-shirt (an offset surface of the
//! body clipped at neck, sleeves and hem), a skirt (the body's offset surface smoothly joined
//! to an elliptic bell from the waist to above the knees) and a dress (both together).
//!
//! Every garment is an iso-surface extracted by marching tetrahedra and clipped, so it is an
//! edge-manifold, consistently wound (outward) mesh at least [`OFFSET_M`] outside the body
//! field, open where the body comes out, left/right symmetric, and deterministic.

use serde::{Deserialize, Serialize};

use crate::geometry::{TriMesh, Vec3};

use super::super::{Avatar, Garment, GarmentOptions, SceneError};
use super::body::{BodySdf, left_arm_dir, left_shoulder_pos, smin};
use super::remesh::Field;
use super::surface::{self, SurfaceSpec};

/// Distance of the garments' iso-surface outside the body field, metres.
pub const OFFSET_M: f32 = 0.015;
/// Height of the t-shirt hem, metres.
const TSHIRT_HEM_Y: f32 = 0.96;
/// Height of the skirt's waistband, metres.
const WAIST_Y: f32 = 1.0;
/// Height of the skirt and dress hem (above the knees at 0.50 m), metres.
const HEM_Y: f32 = 0.56;

/// Which built-in garment.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GarmentKind {
    /// Short-sleeved t-shirt from the neck to the hips.
    #[serde(rename = "tshirt")]
    TShirt,
    /// Bell skirt from the waist to above the knees.
    Skirt,
    /// Sleeveless dress from the shoulders to above the knees.
    Dress,
}

impl GarmentKind {
    /// All kinds.
    pub const ALL: [GarmentKind; 3] = [GarmentKind::TShirt, GarmentKind::Skirt, GarmentKind::Dress];

    /// Name used in configs ("tshirt", "skirt", "dress").
    pub fn name(self) -> &'static str {
        match self {
            GarmentKind::TShirt => "tshirt",
            GarmentKind::Skirt => "skirt",
            GarmentKind::Dress => "dress",
        }
    }

    /// Parses a config name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Recommended skin-transfer options: loose garments get many smoothing passes so the
    /// cloth does not follow one leg.
    pub fn recommended_options(self) -> GarmentOptions {
        let smoothing_passes = match self {
            GarmentKind::TShirt => 5,
            GarmentKind::Skirt | GarmentKind::Dress => 30,
        };
        GarmentOptions {
            smoothing_passes,
            ..GarmentOptions::default()
        }
    }

    /// Rough surface area in m² (first guess for the grid spacing).
    fn area_estimate_m2(self) -> f32 {
        match self {
            GarmentKind::TShirt => 0.65,
            GarmentKind::Skirt => 0.75,
            GarmentKind::Dress => 1.3,
        }
    }
}

/// Default resolution of built-in garments: about 10K degrees of freedom.
pub const DEFAULT_VERTICES: usize = 3400;
/// Smallest accepted vertex target.
pub const MIN_VERTICES: usize = 200;
/// Largest accepted vertex target (about 1.5M degrees of freedom).
pub const MAX_VERTICES: usize = 500_000;

/// Region outside a sleeve or armhole: positive beyond `s_cut_m` along the upper arm and
/// within 11 cm of its axis (points taken on the left side).
fn beyond_sleeve(q: &Vec3, s_cut_m: f32) -> f32 {
    let (s0, d) = (left_shoulder_pos(), left_arm_dir());
    let rel = q - s0;
    let s = rel.dot(&d);
    let perp = (rel - d * s).norm();
    (s - s_cut_m).min(0.11 - perp)
}

/// Region outside the neck opening and above the shoulders.
fn beyond_neck(q: &Vec3) -> f32 {
    let rho = (q.x * q.x + (q.z - 0.005) * (q.z - 0.005)).sqrt();
    (0.085 - rho).min(q.y - 1.34).max(q.y - 1.52)
}

/// Elliptic bell from the waist down, as a signed distance (approximate), metres.
fn bell(p: &Vec3) -> f32 {
    let drop = (WAIST_Y - p.y).max(0.0);
    let rx = 0.125 + 0.40 * drop;
    let rz = 0.105 + 0.34 * drop;
    let e = ((p.x / rx).powi(2) + (p.z / rz).powi(2)).sqrt();
    let side = (e - 1.0) * rx.min(rz);
    side.max(p.y - WAIST_Y - 0.1).max(HEM_Y - 0.08 - p.y)
}

/// Builds the template mesh of a built-in garment with about `vertices` vertices, in the
/// mannequin's rest pose.
pub fn garment_mesh(kind: GarmentKind, vertices: usize) -> Result<TriMesh, SceneError> {
    let invalid = |reason: String| SceneError::InvalidGarment {
        name: kind.name().into(),
        reason,
    };
    if !(MIN_VERTICES..=MAX_VERTICES).contains(&vertices) {
        return Err(invalid(format!(
            "resolution {vertices} is outside {MIN_VERTICES}..={MAX_VERTICES} vertices"
        )));
    }
    let body = BodySdf::mannequin();
    let offset_body = |p: &Vec3| body.distance(p) - OFFSET_M;
    let with_bell = |p: &Vec3| smin(offset_body(p), bell(p), 0.04);
    let left = |p: &Vec3| Vec3::new(p.x.abs(), p.y, p.z);
    let tshirt_region = |p: &Vec3| {
        let q = left(p);
        (TSHIRT_HEM_Y - q.y)
            .max(beyond_neck(&q))
            .max(beyond_sleeve(&q, 0.20))
    };
    let skirt_region = |p: &Vec3| (HEM_Y - p.y).max(p.y - WAIST_Y);
    let dress_region = |p: &Vec3| {
        let q = left(p);
        (HEM_Y - q.y)
            .max(beyond_neck(&q))
            .max(beyond_sleeve(&q, 0.03))
    };
    let (field, region, lo, hi): (Field, Field, Vec3, Vec3) = match kind {
        GarmentKind::TShirt => (
            &offset_body,
            &tshirt_region,
            Vec3::new(0.0, 0.90, -0.22),
            Vec3::new(0.45, 1.60, 0.22),
        ),
        GarmentKind::Skirt => (
            &with_bell,
            &skirt_region,
            Vec3::new(0.0, 0.50, -0.36),
            Vec3::new(0.42, 1.06, 0.36),
        ),
        GarmentKind::Dress => (
            &with_bell,
            &dress_region,
            Vec3::new(0.0, 0.50, -0.36),
            Vec3::new(0.45, 1.60, 0.36),
        ),
    };
    let spec = SurfaceSpec {
        field,
        region: Some(region),
        lo,
        hi,
        target_vertices: vertices,
        area_estimate_m2: kind.area_estimate_m2(),
    };
    surface::build(&spec).map_err(invalid)
}

/// Builds a built-in garment on `avatar` (which must be the mannequin) with the kind's
/// recommended options unless `options` is given.
pub fn garment(
    avatar: &Avatar,
    kind: GarmentKind,
    vertices: usize,
    options: Option<&GarmentOptions>,
) -> Result<Garment, SceneError> {
    let mesh = garment_mesh(kind, vertices)?;
    let options = options
        .cloned()
        .unwrap_or_else(|| kind.recommended_options());
    let mut garment = Garment::new(kind.name(), mesh, avatar, &options)?;
    if kind == GarmentKind::Skirt {
        garment.pinned = waistband(&garment.mesh, WAISTBAND_M);
    }
    Ok(garment)
}

/// Height of the skirt's pinned waistband below its top edge, metres.
pub const WAISTBAND_M: f32 = 0.015;

/// Vertices within `band_m` of the mesh's highest point: the waistband that holds a skirt up
/// and turns it with the hips (contact alone has no friction). Used when pinning is enabled.
pub fn waistband(mesh: &TriMesh, band_m: f32) -> Vec<u32> {
    let Some((_, hi)) = mesh.bounds() else {
        return Vec::new();
    };
    mesh.positions
        .iter()
        .enumerate()
        .filter(|(_, p)| p.y >= hi.y - band_m)
        .map(|(i, _)| i as u32)
        .collect()
}
