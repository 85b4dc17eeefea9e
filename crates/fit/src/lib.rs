//! Fit layer: puts a garment made for another body, in other units or with another origin
//! onto the avatar's rest pose (issue 13, "garment fitting"), and measures how well a garment
//! fits for the training's preflight check.
//!
//! [`fit_mesh`] (and [`fit_file`] for a file):
//! 1. **units**: the file's unit is given or chosen from its size against the avatar's
//!    height ([`choose_units`]);
//! 2. **alignment** ([`align`]): a uniform scale about the garment's centre (within limits;
//!    a change below [`FitOptions::scale_dead_zone`] is not made) and a translation that put
//!    the garment's surface at the ease outside the body where it is close to it;
//! 3. **mirror**: faces turning towards the body mean the file was mirrored left/right (the
//!    positions reflected, the faces not): it is mirrored back;
//! 4. **limbs** ([`repose`]): a garment made for other arms (a T-pose shirt on an A-pose
//!    avatar) or another stance (trousers made with the feet apart) is carried back to the
//!    avatar's rest pose by inverse skinning;
//! 5. **relax** ([`relax`]): the reference simulator lets the garment settle on the rest pose
//!    (the warm start's pre-drape), which pushes out what is left inside the body.
//!
//! Layer: above `physics` (it runs the simulator), below `train` (whose preflight uses
//! [`check`]).

pub mod align;
pub mod check;
pub mod openings;
mod place;
pub mod probe;
pub mod relax;
pub mod repose;
#[cfg(test)]
mod test_support;
mod units;
mod write;

use std::path::{Path, PathBuf};

use neural_cloth_core::geometry::{TriMesh, Vec3};
use neural_cloth_core::io::export::ExportError;
use neural_cloth_core::io::{ImportOptions, IoError, Units, UpAxis};
use neural_cloth_core::scene::{Avatar, SceneError};
use neural_cloth_physics::PhysicsError;

pub use align::{AlignSettings, Placement};
pub use check::{FitCheck, FitLimits, check_fit};
pub use place::align;
pub use probe::BodyProbe;
pub use relax::RelaxSettings;
pub use units::choose_units;
pub use write::{format_m, write_obj};

/// Errors of the fit layer.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// Reading the garment file failed.
    #[error(transparent)]
    Io(#[from] IoError),
    /// Writing the fitted garment failed.
    #[error(transparent)]
    Export(#[from] ExportError),
    /// The avatar's body cannot be measured.
    #[error("avatar '{avatar}': {reason}")]
    Body {
        /// Avatar name.
        avatar: String,
        /// What is wrong.
        reason: String,
    },
    /// The garment cannot be placed on the body.
    #[error("cannot fit the garment on avatar '{avatar}': {reason}: {}", path.display())]
    NoFit {
        /// Avatar name.
        avatar: String,
        /// Why.
        reason: String,
        /// The garment file.
        path: PathBuf,
    },
    /// An option is out of range.
    #[error("fit option {0}")]
    Options(String),
    /// The garment failed a scene-layer check while being relaxed.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The simulator refused.
    #[error(transparent)]
    Physics(#[from] PhysicsError),
}

/// Whether the fit may mirror the garment left/right.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MirrorMode {
    /// Mirror when the garment's faces turn towards the body (default).
    #[default]
    Auto,
    /// Always mirror.
    Flip,
    /// Never mirror.
    Keep,
}

/// How [`fit_mesh`] places a garment.
#[derive(Clone, Debug, PartialEq)]
pub struct FitOptions {
    /// Length unit of the garment's file; `Auto` (default) chooses from its size.
    pub units: Units,
    /// Up axis of the garment's file; `Auto` (default) detects it from its shape.
    pub up: UpAxis,
    /// A fixed uniform scale (after the unit conversion) instead of an estimated one; > 0.
    pub scale: Option<f32>,
    /// Smallest and largest estimated scale, in (0, 100] with lo <= hi; default (0.7, 1.45): a garment made for a person of 1.2 to 2.5 m on one of 1.75 m.
    pub scale_range: (f32, f32),
    /// An estimated scale within this relative distance of 1 is taken as 1 (the garment is
    /// kept at its size, with its own ease); [0, 0.5], default 0.05.
    pub scale_dead_zone: f32,
    /// A fixed translation of the garment's centre (metres) instead of an estimated one.
    pub offset_m: Option<Vec3>,
    /// Left/right mirroring; default [`MirrorMode::Auto`].
    pub mirror: MirrorMode,
    /// Clearance aimed at between garment and body where they are close, metres; [0, 0.1],
    /// default 0.015 (the built-in garments' offset).
    pub ease_m: f32,
    /// Relaxation by the simulator after the alignment; `None` skips it. Default: on.
    pub relax: Option<RelaxSettings>,
    /// Carry a garment made for other arms (a T-pose shirt on an A-pose avatar) or another
    /// stance (trousers made with the feet apart) back to the avatar's rest pose
    /// ([`repose`]); default true.
    pub repose: bool,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            units: Units::Auto,
            up: UpAxis::Auto,
            scale: None,
            scale_range: (0.7, 1.45),
            scale_dead_zone: 0.05,
            offset_m: None,
            mirror: MirrorMode::Auto,
            ease_m: 0.015,
            relax: Some(RelaxSettings::default()),
            repose: true,
        }
    }
}

impl FitOptions {
    /// Checks the documented ranges.
    pub fn validate(&self) -> Result<(), FitError> {
        let bad = |what: String| Err(FitError::Options(what));
        let (lo, hi) = self.scale_range;
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo <= hi && hi <= 100.0) {
            return bad(format!("scale range {lo}..{hi}: needs 0 < lo <= hi <= 100"));
        }
        if let Some(s) = self.scale
            && !(s.is_finite() && s > 0.0 && s <= 100.0)
        {
            return bad(format!("scale {s}: needs 0 < scale <= 100"));
        }
        if let Some(o) = self.offset_m
            && !o.iter().all(|c| c.is_finite())
        {
            return bad(format!("offset {o:?}: needs finite metres"));
        }
        if !(0.0..=0.5).contains(&self.scale_dead_zone) || !(0.0..=0.1).contains(&self.ease_m) {
            return bad(format!(
                "scale dead zone {} (0..=0.5) or ease {} m (0..=0.1) out of range",
                self.scale_dead_zone, self.ease_m
            ));
        }
        if let Some(r) = &self.relax
            && !(r.settle_secs > 0.0
                && r.settle_secs <= 60.0
                && (1.0..=1000.0).contains(&r.fps)
                && (1..=10_000).contains(&r.iterations))
        {
            return bad(format!(
                "relax {r:?}: needs settle_secs in (0, 60], fps in [1, 1000], iterations in \
                 1..=10000"
            ));
        }
        Ok(())
    }
}

/// What [`fit_mesh`] did.
#[derive(Clone, Debug, PartialEq)]
pub struct FitReport {
    /// The unit the file was read in (never `Auto`).
    pub units: Units,
    /// Whether the unit was chosen by the fit (not given).
    pub units_detected: bool,
    /// The file's up axis, as given or detected (a Z-up garment is turned Y up first).
    pub up: UpAxis,
    /// How many degrees above the avatar's upper arms the garment's sleeves were made (0
    /// when they match); see [`repose`].
    pub sleeves_deg: f32,
    /// How many degrees beyond the avatar's thighs the garment's legs were spread (0 when
    /// they match; `None` when it has no opening for each leg or the avatar no two legs);
    /// see [`repose`].
    pub legs_deg: Option<f32>,
    /// Whether the garment was carried back to the avatar's rest pose for its sleeves or
    /// legs.
    pub reposed: bool,
    /// The placement after the unit conversion: mirror, scale about the garment's centre,
    /// translation of the centre (metres).
    pub placement: Placement,
    /// Share of the garment's area within 3 cm of the ease from the body after the
    /// alignment, in [0, 1].
    pub fit_share: f32,
    /// Garment vertices.
    pub vertices: usize,
    /// Vertices inside the body as the file places them (after the unit conversion).
    pub inside_given: usize,
    /// Vertices inside the body after the alignment.
    pub inside_aligned: usize,
    /// Vertices inside the body after relaxing (`None` when not relaxed).
    pub inside_relaxed: Option<usize>,
}

impl FitReport {
    /// What was done, in one line: units, mirror, scale, offset, vertices inside the body
    /// as given, aligned and relaxed.
    pub fn summary(&self) -> String {
        let p = &self.placement;
        let relaxed = self
            .inside_relaxed
            .map_or_else(|| "not relaxed".to_string(), |n| format!("{n} relaxed"));
        let limb = |what: &str, d: f32, of: &str| {
            if d == 0.0 {
                String::new()
            } else if self.reposed {
                format!("{what} re-posed by {:.0} degrees, ", -d)
            } else {
                format!("{what} {d:.0} degrees off the {of} (not re-posed), ")
            }
        };
        let sleeves = limb("sleeves", self.sleeves_deg, "arms")
            + &limb("legs", self.legs_deg.unwrap_or(0.0), "thighs");
        format!(
            "units {}{}, {}{sleeves}scale {:.3}, offset {}; vertices inside the body: {} as \
             given, {} aligned, {relaxed} (of {})",
            self.units.label(),
            if self.units_detected {
                " (detected)"
            } else {
                ""
            },
            if p.mirrored { "mirrored, " } else { "" },
            p.scale,
            format_m(&p.offset_m),
            self.inside_given,
            self.inside_aligned,
            self.vertices
        )
    }
}

/// A fitted garment: the mesh (vertex order, faces and UVs of the file) in metres on the
/// avatar's rest pose, and what was done.
#[derive(Clone, Debug)]
pub struct Fitted {
    /// Garment name (file stem).
    pub name: String,
    /// The fitted mesh.
    pub mesh: TriMesh,
    /// The mesh after the alignment, before relaxing.
    pub aligned: Vec<Vec3>,
    /// What was done.
    pub report: FitReport,
}

/// Share of the area that a fitted garment must have near the body; below it, the garment
/// does not wrap the body and the fit is refused.
pub const MIN_FIT_SHARE: f32 = 0.2;

/// Loads the garment file at `path` (OBJ, glTF or GLB) in its own units and fits it to
/// `avatar` (see [`fit_mesh`]).
pub fn fit_file(avatar: &Avatar, path: &Path, options: &FitOptions) -> Result<Fitted, FitError> {
    let raw = ImportOptions {
        units: Units::Metres,
        up: options.up,
        ..Default::default()
    };
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let loaded = match ext.as_str() {
        "obj" => neural_cloth_core::io::load_obj(path, &raw)?,
        "gltf" | "glb" => neural_cloth_core::io::load_gltf_mesh(path, &raw)?,
        other => {
            return Err(IoError::UnsupportedFormat {
                extension: other.into(),
                path: path.to_path_buf(),
            }
            .into());
        }
    };
    let mut fitted = fit_mesh(avatar, &loaded.name, &loaded.mesh, path, options)?;
    fitted.report.up = loaded.up;
    Ok(fitted)
}

/// Fits the garment `mesh` (in its file's units, as read) to `avatar`'s rest pose. `name`
/// names the garment, `path` is its file (for messages).
pub fn fit_mesh(
    avatar: &Avatar,
    name: &str,
    mesh: &TriMesh,
    path: &Path,
    options: &FitOptions,
) -> Result<Fitted, FitError> {
    options.validate()?;
    let probe = BodyProbe::rest(avatar)?;
    let no_fit = |reason: String| FitError::NoFit {
        avatar: avatar.name.clone(),
        reason,
        path: path.to_path_buf(),
    };
    let extent = neural_cloth_core::io::units::largest_extent(&mesh.positions);
    let units = choose_units(options.units, extent, probe.height_m());
    let metres_per_unit = units.metres_per_unit().unwrap_or(1.0);
    let mut given = mesh.clone();
    given.map_positions(|p| p * metres_per_unit);
    if given.bounds().is_none() {
        return Err(no_fit("the garment has no vertices".into()));
    }
    let inside_given = probe.inside_count(&given.positions);
    let weights = vertex_weights(&given);
    let place = |given: &TriMesh| {
        let (lo, hi) = probe::bounds_of(&given.positions)?;
        place::place_mesh(&probe, given, &weights, (lo + hi) * 0.5, options)
    };
    let not_placed = || no_fit("no scale and height put it around the body".into());
    let mut placement = place(&given).ok_or_else(not_placed)?;
    // Sleeves or legs made for other limbs: re-posed in the file's frame, then placed again.
    let (angles, reposed) = repose::repose_given(
        avatar,
        &given,
        &placement,
        &weights,
        options.ease_m,
        options.repose,
    )?;
    if let Some(reposed) = &reposed {
        given = reposed.clone();
        // Carried back at `placement`, the garment lies on the rest pose there. A shirt is
        // placed again (the first placement had its sleeves out). Trousers keep theirs: they
        // were placed by their seat, and their legs, once on the thighs, would let the whole
        // garment slide down and grow alike (a thigh is a cone).
        if !angles.legs_deg.is_some_and(|d| d != 0.0) {
            placement = place(&given).ok_or_else(not_placed)?;
        }
    }
    let mut placed = given.clone();
    placed.positions = placement.apply_all(&given.positions);
    let fit_share = check_placed(
        &probe,
        &placed.positions,
        &weights,
        &placement,
        options,
        &no_fit,
    )?;
    let aligned = placed.positions.clone();
    let inside_aligned = probe.inside_count(&aligned);
    let inside_relaxed = match &options.relax {
        Some(settings) => {
            placed.positions = relax::relax(avatar, name, &placed, settings)?;
            Some(probe.inside_count(&placed.positions))
        }
        None => None,
    };
    Ok(Fitted {
        name: name.to_string(),
        report: FitReport {
            units,
            units_detected: options.units == Units::Auto,
            up: UpAxis::Y,
            sleeves_deg: angles.sleeves_deg,
            legs_deg: angles.legs_deg,
            reposed: reposed.is_some(),
            placement,
            fit_share,
            vertices: given.vertex_count(),
            inside_given,
            inside_aligned,
            inside_relaxed,
        },
        mesh: placed,
        aligned,
    })
}

/// Checks the placed garment: it must overlap the body's bounding box (only a fixed offset
/// can put it elsewhere), go around the body and lie near it. Returns the share of its area
/// near the body.
fn check_placed(
    probe: &BodyProbe,
    placed: &[Vec3],
    weights: &[f32],
    placement: &Placement,
    options: &FitOptions,
    no_fit: &impl Fn(String) -> FitError,
) -> Result<f32, FitError> {
    let (body_lo, body_hi) = probe.bounds_m();
    let Some((lo, hi)) = probe::bounds_of(placed) else {
        return Err(no_fit("the garment has no vertices".into()));
    };
    let at = format!(
        "(scale {:.3}, offset {})",
        placement.scale,
        format_m(&placement.offset_m)
    );
    let overlaps = (0..3).all(|k| lo[k] <= body_hi[k] && hi[k] >= body_lo[k]);
    if !overlaps {
        let how = if options.offset_m.is_some() {
            "with the given --offset"
        } else {
            "at the best placement found"
        };
        return Err(no_fit(format!(
            "{how} {at} its bounding box {}..{} does not overlap the body's {}..{}",
            format_m(&lo),
            format_m(&hi),
            format_m(&body_lo),
            format_m(&body_hi)
        )));
    }
    let coverage = probe.azimuth_coverage(placed);
    if coverage < place::MIN_AZIMUTH_COVERAGE {
        return Err(no_fit(format!(
            "at the best placement found {at} it does not go around the body: it covers \
             {:.0} % of the directions around it (at least {:.0} % needed)",
            coverage * 100.0,
            place::MIN_AZIMUTH_COVERAGE * 100.0
        )));
    }
    let fit_share = near_share(probe, placed, weights, options.ease_m);
    if fit_share < MIN_FIT_SHARE {
        return Err(no_fit(format!(
            "only {:.0} % of its area lies near the body at the best placement found {at} (at \
             least {:.0} % needed): it does not wrap the body (a garment made for another \
             pose, e.g. a T-pose on an A-pose avatar, cannot be fitted by scaling and moving \
             it)",
            fit_share * 100.0,
            MIN_FIT_SHARE * 100.0
        )));
    }
    Ok(fit_share)
}

/// Per-vertex weights: the vertex areas, or 1 each when the mesh has no area.
fn vertex_weights(mesh: &TriMesh) -> Vec<f32> {
    let areas = mesh.vertex_areas();
    let total: f32 = areas.iter().sum();
    if total > 0.0 && total.is_finite() {
        areas
    } else {
        vec![1.0; mesh.vertex_count()]
    }
}

/// Share of the weight of `placed` whose clearance is within 3 cm of `ease_m`, in [0, 1].
fn near_share(probe: &BodyProbe, placed: &[Vec3], weights: &[f32], ease_m: f32) -> f32 {
    let (mut near, mut total) = (0.0f64, 0.0f64);
    for (p, &w) in placed.iter().zip(weights) {
        if (probe.clearance_m(p) - ease_m).abs() < 0.03 {
            near += f64::from(w);
        }
        total += f64::from(w);
    }
    if total > 0.0 {
        (near / total) as f32
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_out_of_range_are_refused() {
        assert!(FitOptions::default().validate().is_ok());
        let bad = [
            FitOptions {
                scale: Some(0.0),
                ..Default::default()
            },
            FitOptions {
                scale_range: (2.0, 1.0),
                ..Default::default()
            },
            FitOptions {
                offset_m: Some(Vec3::new(f32::NAN, 0.0, 0.0)),
                ..Default::default()
            },
            FitOptions {
                relax: Some(RelaxSettings {
                    settle_secs: 0.0,
                    ..Default::default()
                }),
                ..Default::default()
            },
        ];
        for o in bad {
            assert!(matches!(o.validate(), Err(FitError::Options(_))), "{o:?}");
        }
    }

    #[test]
    fn a_moved_and_enlarged_tshirt_comes_back_and_a_far_fixed_one_is_refused() {
        use neural_cloth_core::scene::procedural::{GarmentKind, builtin_garment, mannequin};
        let avatar = mannequin().unwrap();
        let original = builtin_garment(&avatar, GarmentKind::TShirt, 500, None)
            .unwrap()
            .mesh;
        let (lo, hi) = original.bounds().unwrap();
        let centre = (lo + hi) * 0.5;
        let mut given = original.clone();
        given.map_positions(|p| centre + (p - centre) * 1.2 + Vec3::new(0.1, -0.4, 0.0));
        let options = FitOptions {
            relax: None,
            ..Default::default()
        };
        let path = Path::new("shirt.obj");
        let fitted = fit_mesh(&avatar, "shirt", &given, path, &options).unwrap();
        let mean = fitted
            .mesh
            .positions
            .iter()
            .zip(&original.positions)
            .map(|(p, q)| (p - q).norm())
            .sum::<f32>()
            / original.vertex_count() as f32;
        assert!(mean < 0.01, "{mean} m: {:?}", fitted.report);
        assert!((fitted.report.placement.scale - 1.0 / 1.2).abs() < 0.03);
        assert_eq!(fitted.report.inside_aligned, 0);
        let far = FitOptions {
            scale: Some(1.0),
            offset_m: Some(Vec3::new(0.0, 4.0, 0.0)),
            ..options
        };
        let err = fit_mesh(&avatar, "shirt", &original, path, &far).unwrap_err();
        assert!(err.to_string().ends_with("shirt.obj"), "{err}");
    }
}
