//! How well a garment already placed on the avatar's rest pose fits it, for the training's
//! preflight check: the share of its vertices inside the body, the share outside the body's
//! bounding box, whether the boxes overlap at all, the scale and shift that fitting it
//! ([`super::align`], as `neural-cloth fit` does) would apply, and how far its sleeves (trouser
//! legs) are from the avatar's arm (leg) pose ([`super::repose`]).

use neural_cloth_core::geometry::{TriMesh, Vec3};
use neural_cloth_core::scene::Avatar;

use super::align::{AlignSettings, Placement, Points};
use super::probe::{BodyProbe, bounds_of};
use super::repose::LimbAngles;
use super::{FitError, FitOptions, openings, place};

/// Limits beyond which a garment is clearly wrong for the avatar.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitLimits {
    /// Largest share of vertices inside the body, in [0, 1]; default 0.1.
    pub max_inside_share: f32,
    /// Largest share of vertices outside the body's bounding box grown by
    /// `bounds_margin_m`, in [0, 1]; default 0.1.
    pub max_outside_share: f32,
    /// Margin added to every side of the body's bounding box, metres; default 0.1.
    pub bounds_margin_m: f32,
    /// Largest relative scale change the fit's refinement may suggest, in [0, 1]; default
    /// 0.15 (a garment 15 % too large or too small).
    pub max_scale_change: f32,
    /// Largest shift of the garment's centre the fit's refinement may suggest, metres;
    /// default 0.1.
    pub max_shift_m: f32,
    /// Largest angle between the garment's sleeves and the avatar's upper arms, degrees;
    /// default 15 (a T-pose shirt on an A-pose avatar is about 40 off).
    pub max_sleeve_deg: f32,
    /// Largest angle between the legs of trousers or shorts and the avatar's thighs,
    /// degrees; default 10 (trousers made on a body standing with its feet apart).
    pub max_legs_deg: f32,
}

impl Default for FitLimits {
    fn default() -> Self {
        Self {
            max_inside_share: 0.1,
            max_outside_share: 0.1,
            bounds_margin_m: 0.1,
            max_scale_change: 0.15,
            max_shift_m: 0.1,
            max_sleeve_deg: 15.0,
            max_legs_deg: 10.0,
        }
    }
}

/// Measurements of a placed garment against the avatar's rest-pose body.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitCheck {
    /// Garment vertices.
    pub vertices: usize,
    /// Share of vertices inside the body, in [0, 1].
    pub inside_share: f32,
    /// Share of vertices outside the body's bounding box grown by the limits' margin.
    pub outside_share: f32,
    /// Whether the garment's bounding box overlaps the body's.
    pub overlaps: bool,
    /// The scale fitting would apply (1 = its size fits; 1 when not measured).
    pub suggested_scale: f32,
    /// The shift of the garment's centre fitting would apply, metres (zero when not
    /// measured).
    pub suggested_shift_m: Vec3,
    /// How many degrees above the avatar's upper arms its sleeves were made (0 when they
    /// match, or not measured).
    pub sleeves_deg: f32,
    /// How many degrees beyond the avatar's thighs its legs were spread (0 when they match,
    /// when it has no leg openings, or not measured).
    pub legs_deg: f32,
}

/// Measures `mesh` (metres, on the rest pose) against `avatar`'s body; `limits` gives the
/// bounding-box margin. The fit's placement is only searched for when the garment overlaps
/// the body (about a second for a few thousand vertices).
pub fn check_fit(
    avatar: &Avatar,
    mesh: &TriMesh,
    limits: &FitLimits,
) -> Result<FitCheck, FitError> {
    let probe = BodyProbe::rest(avatar)?;
    let positions = &mesh.positions;
    let n = positions.len();
    let Some((lo, hi)) = bounds_of(positions) else {
        return Err(FitError::Body {
            avatar: avatar.name.clone(),
            reason: "the garment has no vertices to check".into(),
        });
    };
    let (body_lo, body_hi) = probe.bounds_m();
    let overlaps = (0..3).all(|k| lo[k] <= body_hi[k] && hi[k] >= body_lo[k]);
    let weights = mesh.vertex_areas();
    let options = FitOptions::default();
    let settings = AlignSettings {
        ease_m: options.ease_m,
        scale_range: options.scale_range,
        fixed_scale: None,
        fixed_offset_m: None,
        arm_openings: openings::has_arm_openings(mesh),
    };
    let start = Placement::identity((lo + hi) * 0.5);
    let points = Points {
        positions,
        weights: &weights,
    };
    let fitted = if overlaps {
        place::align(&probe, points, &start, &settings, options.scale_dead_zone)
    } else {
        None
    };
    let fitted = fitted.unwrap_or(start);
    let angles = if overlaps {
        LimbAngles::measure(avatar, mesh, positions, &weights, options.ease_m)?
    } else {
        LimbAngles::default()
    };
    Ok(FitCheck {
        vertices: n,
        inside_share: probe.inside_count(positions) as f32 / n.max(1) as f32,
        outside_share: probe.outside_bounds_share(positions, limits.bounds_margin_m),
        overlaps,
        suggested_scale: fitted.scale,
        suggested_shift_m: fitted.offset_m,
        sleeves_deg: angles.sleeves_deg,
        legs_deg: angles.legs_deg.unwrap_or(0.0),
    })
}

impl FitCheck {
    /// What is clearly wrong, in words (empty when the garment passes `limits`).
    pub fn problems(&self, limits: &FitLimits) -> Vec<String> {
        if !self.overlaps {
            return vec!["its bounding box does not overlap the body's at all".into()];
        }
        let mut out = Vec::new();
        if self.inside_share > limits.max_inside_share {
            out.push(format!(
                "{:.0} % of its vertices are inside the body (limit {:.0} %)",
                self.inside_share * 100.0,
                limits.max_inside_share * 100.0
            ));
        }
        if self.outside_share > limits.max_outside_share {
            out.push(format!(
                "{:.0} % of its vertices are more than {:.0} mm outside the body's bounding box \
                 (limit {:.0} %)",
                self.outside_share * 100.0,
                limits.bounds_margin_m * 1e3,
                limits.max_outside_share * 100.0
            ));
        }
        if (self.suggested_scale - 1.0).abs() > limits.max_scale_change {
            out.push(format!(
                "it looks made for a body of another size: fitting would scale it by {:.2} \
                 (more than the {:.0} % allowed)",
                self.suggested_scale,
                limits.max_scale_change * 100.0
            ));
        }
        let shift = self.suggested_shift_m.norm();
        if shift > limits.max_shift_m {
            out.push(format!(
                "it sits {:.0} mm away from where fitting would put it (limit {:.0} mm)",
                shift * 1e3,
                limits.max_shift_m * 1e3
            ));
        }
        if self.sleeves_deg.abs() > limits.max_sleeve_deg {
            out.push(format!(
                "its sleeves were made {:.0} degrees {} the avatar's arms (for another arm pose, \
                 e.g. a T-pose; fitting re-poses it)",
                self.sleeves_deg.abs(),
                if self.sleeves_deg > 0.0 {
                    "above"
                } else {
                    "below"
                }
            ));
        }
        if self.legs_deg.abs() > limits.max_legs_deg {
            out.push(format!(
                "its legs were made {:.0} degrees {} than the avatar's (for another stance; \
                 fitting re-poses it)",
                self.legs_deg.abs(),
                if self.legs_deg > 0.0 {
                    "wider apart"
                } else {
                    "closer together"
                }
            ));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use neural_cloth_core::scene::procedural::{GarmentKind, builtin_garment, mannequin};

    #[test]
    fn builtin_garments_pass_and_moved_or_resized_ones_do_not() {
        let avatar = mannequin().unwrap();
        let limits = FitLimits::default();
        for kind in GarmentKind::ALL {
            let g = builtin_garment(&avatar, kind, 600, None).unwrap();
            let c = check_fit(&avatar, &g.mesh, &limits).unwrap();
            assert!(c.problems(&limits).is_empty(), "{kind:?}: {c:?}");
        }
        let g = builtin_garment(&avatar, GarmentKind::TShirt, 600, None).unwrap();
        let mut low = g.mesh.clone();
        low.map_positions(|p| p - Vec3::new(0.0, 0.5, 0.0));
        let c = check_fit(&avatar, &low, &limits).unwrap();
        assert!(!c.problems(&limits).is_empty(), "{c:?}");
        let mut far = g.mesh.clone();
        far.map_positions(|p| p + Vec3::new(3.0, 0.0, 0.0));
        let c = check_fit(&avatar, &far, &limits).unwrap();
        assert!(!c.overlaps);
        assert_eq!(c.problems(&limits).len(), 1);
        let (lo, hi) = g.mesh.bounds().unwrap();
        let centre = (lo + hi) * 0.5;
        for factor in [0.8f32, 1.25] {
            let mut resized = g.mesh.clone();
            resized.map_positions(|p| centre + (p - centre) * factor);
            let c = check_fit(&avatar, &resized, &limits).unwrap();
            assert!(!c.problems(&limits).is_empty(), "x{factor}: {c:?}");
        }
    }
}
