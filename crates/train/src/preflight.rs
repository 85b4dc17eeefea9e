//! Checks before training (issue 11, "bad input"): scenes that are known not to learn get a
//! clear warning up front, instead of a silently dead model later.
//!
//! - A garment far from the body (mean distance of its vertices to the nearest body vertex at
//!   the rest pose above [`FAR_FROM_BODY_M`]) is probably placed for another avatar or in other
//!   units: gravity pulls it through empty space and the collision term never acts.
//! - Stiffnesses far from the presets (more than [`STIFFNESS_RATIO`] times the default, or
//!   less than its inverse) make the loss one term's alone: with stretch 1e4 the garment cannot
//!   move without a strain cost that dwarfs gravity, the gradient of every other term is lost
//!   in it, and Adam's steps only add noise to the template.
//!
//! A garment file that clearly does not fit the avatar (issue 13: many vertices inside the
//! body, far outside its bounding box, or a size or place that fitting would change a lot;
//! [`neural_cloth_fit::check`]) is refused by [`fit_refusal`], with what to do: run `neural-cloth
//! fit`, or train anyway with `--skip-fit-check`.

use std::path::Path;

use neural_cloth_core::geometry::KdTree;
use neural_cloth_core::scene::{Avatar, Garment};
use neural_cloth_fit::{FitError, FitLimits, check_fit};
use neural_cloth_physics::FabricParams;

/// Mean garment-to-body distance above which the garment counts as far from the body, metres.
pub const FAR_FROM_BODY_M: f64 = 0.10;
/// Factor by which a stiffness may differ from the default before it is flagged.
pub const STIFFNESS_RATIO: f32 = 1e3;

/// Warnings about a scene that training is unlikely to learn, in words (empty when fine).
pub fn preflight_warnings(
    avatar: &Avatar,
    garment: &Garment,
    fabric: &FabricParams,
) -> Vec<String> {
    let mut out = Vec::new();
    let body = avatar.pose_vertices(&avatar.skeleton.rest_pose());
    if !body.is_empty() && garment.vertex_count() > 0 {
        let tree = KdTree::new(&body);
        let total: f64 = garment
            .mesh
            .positions
            .iter()
            .filter_map(|p| tree.nearest(p))
            .map(|(_, d2)| f64::from(d2).sqrt())
            .sum();
        let mean = total / garment.vertex_count() as f64;
        if mean > FAR_FROM_BODY_M {
            out.push(format!(
                "the garment '{}' is on average {:.0} mm from the body at the rest pose \
                 (more than {:.0} mm): is it placed on this avatar, in the right units? \
                 Training will let it fall or float and is unlikely to learn a drape",
                garment.name,
                mean * 1e3,
                FAR_FROM_BODY_M * 1e3
            ));
        }
    }
    let base = FabricParams::default();
    let checks = [
        (
            "stretch_stiffness",
            fabric.stretch_stiffness,
            base.stretch_stiffness,
        ),
        (
            "shear_stiffness",
            fabric.shear_stiffness,
            base.shear_stiffness,
        ),
        (
            "bending_stiffness",
            fabric.bending_stiffness,
            base.bending_stiffness,
        ),
        ("lame_mu", fabric.lame_mu, base.lame_mu),
    ];
    for (name, value, default) in checks {
        if default > 0.0
            && value > 0.0
            && (value / default > STIFFNESS_RATIO || default / value > STIFFNESS_RATIO)
        {
            out.push(format!(
                "fabric {name} = {value:e} is more than {STIFFNESS_RATIO:e} times away from the \
                 default {default:e}: one term will dominate the loss and the network is \
                 unlikely to learn anything but the template"
            ));
        }
    }
    out
}

/// Why training refuses the garment from `garment_file` on `avatar` (the avatar's file, or
/// `None` for the built-in mannequin), saying what to do; `None` when it fits. The message
/// ends with the garment file.
pub fn fit_refusal(
    avatar: &Avatar,
    avatar_file: Option<&Path>,
    garment: &Garment,
    garment_file: &Path,
) -> Result<Option<String>, FitError> {
    let limits = FitLimits::default();
    let problems = check_fit(avatar, &garment.mesh, &limits)?.problems(&limits);
    if problems.is_empty() {
        return Ok(None);
    }
    Ok(Some(format!(
        "the garment '{}' does not fit avatar '{}': {}. {}; or train on it as it is: `train \
         --skip-fit-check` (in the app: untick \"check the garment's fit\"): {}",
        garment.name,
        avatar.name,
        problems.join("; "),
        fit_advice(avatar_file, garment_file),
        garment_file.display()
    )))
}

/// What to do with a garment file that does not fit the avatar (the avatar's file, or `None`
/// for the built-in mannequin): fit it first with `neural-cloth fit --avatar A --garment G
/// --out G-fitted.obj` (in the app: Fit garment), then train on `G-fitted.obj`.
pub fn fit_advice(avatar_file: Option<&Path>, garment_file: &Path) -> String {
    let stem = garment_file
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "garment".into());
    let fitted = garment_file.with_file_name(format!("{stem}-fitted.obj"));
    format!(
        "Fit it first: `neural-cloth fit --avatar {} --garment {} --out {}` (in the app: Fit \
         garment), then train on {}",
        avatar_file.map_or_else(|| "mannequin".into(), |p| p.display().to_string()),
        garment_file.display(),
        fitted.display(),
        fitted.display(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use neural_cloth_core::geometry::Vec3;
    use neural_cloth_core::scene::config::SceneConfig;
    use neural_cloth_core::scene::procedural::build_builtin;

    fn scene() -> neural_cloth_core::scene::Scene {
        let mut config = SceneConfig::default_scene();
        if let neural_cloth_core::scene::config::GarmentSource::Builtin { resolution, .. } =
            &mut config.garment
        {
            *resolution = 300;
        }
        build_builtin(&config).unwrap()
    }

    #[test]
    fn a_garment_far_from_the_body_and_a_stiff_fabric_are_flagged() {
        let mut s = scene();
        let fabric = FabricParams::default();
        assert!(
            preflight_warnings(&s.avatar, &s.garment, &fabric).is_empty(),
            "{:?}",
            preflight_warnings(&s.avatar, &s.garment, &fabric)
        );
        let stiff = FabricParams {
            stretch_stiffness: 1e5,
            ..FabricParams::default()
        };
        let w = preflight_warnings(&s.avatar, &s.garment, &stiff);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("stretch_stiffness"), "{w:?}");
        s.garment
            .mesh
            .positions
            .iter_mut()
            .for_each(|p| *p += Vec3::new(0.0, 0.0, 0.5));
        let w = preflight_warnings(&s.avatar, &s.garment, &fabric);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("from the body"), "{w:?}");
    }

    #[test]
    fn a_garment_below_the_body_is_refused_with_what_to_do_and_a_builtin_one_is_not() {
        let mut s = scene();
        let file = Path::new("/shirts/shirt.obj");
        assert_eq!(
            fit_refusal(&s.avatar, None, &s.garment, file).unwrap(),
            None
        );
        s.garment
            .mesh
            .positions
            .iter_mut()
            .for_each(|p| *p -= Vec3::new(0.0, 0.6, 0.0));
        let why = fit_refusal(&s.avatar, None, &s.garment, file)
            .unwrap()
            .unwrap();
        for needle in [
            "neural-cloth fit --avatar mannequin --garment /shirts/shirt.obj",
            "--skip-fit-check",
            "away from where fitting would put it",
        ] {
            assert!(why.contains(needle), "no '{needle}' in {why}");
        }
        assert!(why.ends_with("/shirts/shirt.obj"), "{why}");
        assert_eq!(
            fit_advice(Some(Path::new("/a/hero.glb")), file),
            "Fit it first: `neural-cloth fit --avatar /a/hero.glb --garment /shirts/shirt.obj \
             --out /shirts/shirt-fitted.obj` (in the app: Fit garment), then train on \
             /shirts/shirt-fitted.obj"
        );
    }
}
