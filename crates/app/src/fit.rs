//! "Fit garment" in the Scene section: fits the garment file (the loaded one, or the typed
//! path when it did not load, e.g. a garment so misplaced that it cannot be bound to the
//! body) onto the current avatar's rest pose on a background thread, as `neural-cloth fit`
//! does, writes `NAME-fitted.obj` beside it and loads that as the scene's garment, so the
//! viewport shows the fitted garment on the avatar before training. What the fit did (units,
//! scale, offset, mirror, vertices inside the body) goes to the status messages.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use neural_cloth_core::scene::{Avatar, UpAxis};
use neural_cloth_fit::{FitOptions, fit_file, write_obj};

use super::background::{BackgroundJob, poll_job};
use super::error::AppError;
use super::state::{AppState, Level};

/// A finished fit: where the fitted garment was written and what was done, in words.
#[derive(Clone, Debug, PartialEq)]
pub struct FitOutcome {
    /// The fitted OBJ.
    pub fitted: PathBuf,
    /// One line: units, scale, offset, mirror, vertices inside the body.
    pub summary: String,
}

/// `GARMENT-fitted.obj` beside `garment`.
pub fn fitted_path(garment: &Path) -> PathBuf {
    let stem = garment
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "garment".into());
    garment.with_file_name(format!("{stem}-fitted.obj"))
}

/// Fits `garment` onto `avatar` with the default options and the up axis `up` (the app's Up
/// axis selector) and writes it beside the garment ([`fitted_path`]). Errors name the file.
pub fn fit_to_file(avatar: &Avatar, garment: &Path, up: UpAxis) -> Result<FitOutcome, AppError> {
    let options = FitOptions {
        up,
        ..FitOptions::default()
    };
    let fitted = fit_file(avatar, garment, &options)?;
    let out = fitted_path(garment);
    write_obj(&fitted, &out)?;
    Ok(FitOutcome {
        fitted: out,
        summary: fitted.report.summary(),
    })
}

/// State of the fit: the job running, if any.
#[derive(Default)]
pub struct FitState {
    job: Option<BackgroundJob<(), FitOutcome>>,
}

impl FitState {
    /// True while a fit runs.
    pub fn is_running(&self) -> bool {
        self.job.is_some()
    }

    /// Starts fitting `garment` (up axis `up`) onto `avatar` on the thread `neural-cloth-fit`.
    pub fn start(
        &mut self,
        avatar: Arc<Avatar>,
        garment: PathBuf,
        up: UpAxis,
        notify: Arc<dyn Fn() + Send + Sync>,
    ) -> Result<(), AppError> {
        if self.job.is_some() {
            return Err(AppError::AlreadyRunning("a fit"));
        }
        self.job = Some(BackgroundJob::spawn(
            "neural-cloth-fit",
            (),
            notify,
            move |_| fit_to_file(&avatar, &garment, up),
        )?);
        Ok(())
    }

    /// The finished fit's outcome, once (never blocks on a running one).
    pub fn poll(&mut self) -> Option<Result<FitOutcome, AppError>> {
        poll_job(&mut self.job)
    }

    /// Whether "Fit garment" can start: a garment file to fit, no fit running, no training.
    pub fn can_start(&self, state: &AppState) -> bool {
        state.garment_to_fit().is_some()
            && !self.is_running()
            && !state.training.state().is_active()
    }

    /// "Fit garment" pressed: fits the state's garment file ([`AppState::garment_to_fit`])
    /// onto its avatar with the Up axis selector's axis; why it cannot start goes to the
    /// status messages.
    pub fn fit_clicked(&mut self, state: &mut AppState, notify: Arc<dyn Fn() + Send + Sync>) {
        let Some(path) = state.garment_to_fit() else {
            return;
        };
        let avatar = state.scene.avatar.clone();
        if let Err(e) = self.start(avatar, path, state.typed.up, notify) {
            state.message(Level::Error, format!("fit: {e}"));
        }
    }
}

impl AppState {
    /// The garment file a fit would read: the typed path when it names another file (one
    /// that may not have loaded), else the loaded garment's file.
    pub fn garment_to_fit(&self) -> Option<PathBuf> {
        let typed = self.typed.garment.trim();
        if !typed.is_empty() {
            return Some(PathBuf::from(typed));
        }
        self.scene_file(super::scene_edit::LoadKind::Garment)
    }

    /// Shows the outcome of a fit: loads the fitted garment (the viewport then shows it on
    /// the avatar) and reports what was done, or shows the error. Returns whether it loaded.
    pub fn apply_fit(&mut self, outcome: Result<FitOutcome, AppError>) -> bool {
        match outcome {
            Ok(outcome) => {
                if !self.load_garment(&outcome.fitted) {
                    return false;
                }
                self.typed.garment = outcome.fitted.display().to_string();
                self.message(
                    Level::Info,
                    format!(
                        "fitted garment written to {}: {}",
                        outcome.fitted.display(),
                        outcome.summary
                    ),
                );
                true
            }
            Err(e) => {
                self.message(Level::Error, format!("fit: {e}"));
                false
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use neural_cloth_core::geometry::Vec3;
    use neural_cloth_core::scene::procedural::{GarmentKind, builtin_garment, mannequin};

    #[test]
    fn a_misplaced_garment_is_fitted_written_beside_it_and_loaded() {
        let avatar = mannequin().unwrap();
        let shirt = builtin_garment(&avatar, GarmentKind::TShirt, 400, None).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("shirt.obj");
        let moved: Vec<Vec3> = shirt
            .mesh
            .positions
            .iter()
            .map(|p| (p - Vec3::new(0.0, 0.7, 0.0)) * 100.0)
            .collect();
        let text = neural_cloth_core::io::export::obj_seq::obj_text(
            &moved,
            &shirt.mesh.faces,
            None,
            "moved",
        );
        std::fs::write(&file, text).unwrap();
        let outcome = fit_to_file(&avatar, &file, UpAxis::Auto).unwrap();
        assert_eq!(outcome.fitted, dir.path().join("shirt-fitted.obj"));
        assert!(
            outcome.summary.contains("centimetres"),
            "{}",
            outcome.summary
        );
        let mut state = AppState::new(
            crate::default_scene().unwrap(),
            crate::TrainingControl::new(None),
            Default::default(),
        );
        state.typed.garment = file.display().to_string();
        assert_eq!(state.garment_to_fit(), Some(file.clone()));
        assert!(state.apply_fit(Ok(outcome)));
        let garment = state.scene.garment.clone().unwrap();
        assert_eq!(garment.vertex_count(), shirt.vertex_count());
        let mean = garment
            .mesh
            .positions
            .iter()
            .zip(&shirt.mesh.positions)
            .map(|(p, q)| (p - q).norm())
            .sum::<f32>()
            / shirt.vertex_count() as f32;
        assert!(mean < 0.01, "{mean} m");
        let failed = neural_cloth_core::io::IoError::NoMesh {
            path: "x.obj".into(),
        };
        assert!(!state.apply_fit(Err(failed.into())));
        assert!(state.last_error().is_some_and(|e| e.ends_with("x.obj")));
    }

    /// Issue 13: the app's "Fit garment" ignored the Up axis selector (it always detected).
    #[test]
    fn fit_garment_takes_the_up_axis_selector() {
        let avatar = mannequin().unwrap();
        let shirt = builtin_garment(&avatar, GarmentKind::TShirt, 400, None).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("lying.obj");
        // Z up: (x, y, z) -> (x, -z, y).
        let lying: Vec<Vec3> = shirt
            .mesh
            .positions
            .iter()
            .map(|p| Vec3::new(p.x, -p.z, p.y))
            .collect();
        let text = neural_cloth_core::io::export::obj_seq::obj_text(
            &lying,
            &shirt.mesh.faces,
            None,
            "z-up",
        );
        std::fs::write(&file, text).unwrap();
        let fitted = |up: UpAxis| {
            let outcome = fit_to_file(&avatar, &file, up).unwrap_or_else(|e| panic!("{up:?}: {e}"));
            let options = neural_cloth_core::io::ImportOptions {
                units: neural_cloth_core::io::Units::Metres,
                up: UpAxis::Y,
                ..Default::default()
            };
            let garment = neural_cloth_core::io::obj::load_obj(&outcome.fitted, &options)
                .unwrap()
                .mesh
                .positions;
            let height = |ps: &[Vec3]| {
                let (lo, hi) = ps.iter().fold((f32::MAX, f32::MIN), |(lo, hi), p| {
                    (lo.min(p.y), hi.max(p.y))
                });
                hi - lo
            };
            (height(&garment), height(&shirt.mesh.positions))
        };
        let (z_height, upright) = fitted(UpAxis::Z);
        assert!(
            (z_height - upright).abs() < 0.05 * upright,
            "fitted as Z up: {z_height} m tall against the shirt's {upright} m"
        );
        // Told Y up, the same file stays lying: the selector, not detection, decided.
        let (y_height, _) = fitted(UpAxis::Y);
        assert!(
            (y_height - upright).abs() > 0.2 * upright,
            "fitted as Y up: {y_height} m tall, as if upright ({upright} m)"
        );
    }
}
