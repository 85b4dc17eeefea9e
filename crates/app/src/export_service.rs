//! The export service behind the export dialog ([`super::export_dialog`]): what the dialog's
//! buttons do (ask before overwriting, build the request from the app's state, start the bake
//! on the named thread `neural-cloth-export`, cancel it), the estimate shown before writing,
//! and the outcome of the last export. A failed or cancelled export leaves no file and the
//! app runs on.

use std::path::PathBuf;
use std::sync::Arc;

use super::background::{BackgroundJob, poll_job};
use super::error::AppError;
use super::export::{ExportEstimate, ExportFormat, ExportRequest, ExportSettings, Exporter};
use super::file_picker::{FilePicker, PickPurpose};
use super::state::{AppState, Level};

/// The running export, if any.
#[derive(Default)]
pub struct ExportJob {
    job: Option<BackgroundJob<(usize, usize), String>>,
}

impl ExportJob {
    /// Starts `request` on its own thread; `notify` requests a repaint as frames are written.
    pub fn start(
        &mut self,
        exporter: Arc<dyn Exporter>,
        request: ExportRequest,
        notify: Arc<dyn Fn() + Send + Sync>,
    ) -> Result<(), AppError> {
        if self.job.is_some() {
            return Err(AppError::AlreadyRunning("an export"));
        }
        self.job = Some(BackgroundJob::spawn(
            "neural-cloth-export",
            (0, 0),
            notify,
            move |reporter| {
                exporter.export(request, &mut |done, total| reporter.report((done, total)))
            },
        )?);
        Ok(())
    }

    /// True while an export runs.
    pub fn is_running(&self) -> bool {
        self.job.is_some()
    }

    /// Asks the export to stop after the current frame (its partial files are removed).
    pub fn cancel(&self) {
        if let Some(job) = &self.job {
            job.cancel();
        }
    }

    /// Frames done and total of the running export.
    pub fn progress(&self) -> Option<(usize, usize)> {
        self.job.as_ref().and_then(BackgroundJob::progress)
    }

    /// The result of a finished export (never blocks on a running one).
    pub fn poll(&mut self) -> Option<Result<String, AppError>> {
        poll_job(&mut self.job)
    }
}

/// What the user did in the export dialog during one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ExportClicks {
    /// "Export".
    pub export: bool,
    /// "Overwrite" (the answer to the overwrite question).
    pub overwrite: bool,
    /// "Keep the existing files" (the other answer).
    pub keep: bool,
    /// "Cancel" of a running export.
    pub cancel: bool,
    /// "Browse…" for the path.
    pub browse: bool,
    /// The window's close button.
    pub close: bool,
}

/// The export service: the exporter, the running export and the last outcome.
pub struct ExportService {
    exporter: Option<Arc<dyn Exporter>>,
    job: ExportJob,
    /// Outcome of the last export: its summary, or the error that ended it (shown by the
    /// dialog and, as a message, in the status bar).
    pub last_result: Option<Result<String, AppError>>,
}

impl ExportService {
    /// A service exporting with `exporter` (None: exporting reports that it is unavailable).
    pub fn new(exporter: Option<Arc<dyn Exporter>>) -> Self {
        Self {
            exporter,
            job: ExportJob::default(),
            last_result: None,
        }
    }

    /// True while an export runs.
    pub fn is_running(&self) -> bool {
        self.job.is_running()
    }

    /// Frames done and total of the running export.
    pub fn progress(&self) -> Option<(usize, usize)> {
        self.job.progress()
    }

    /// Collects a finished export (once per frame): its summary or error goes to the status
    /// messages and to [`Self::last_result`].
    pub fn poll(&mut self, state: &mut AppState) {
        if let Some(result) = self.job.poll() {
            match &result {
                Ok(s) => state.message(Level::Info, s.clone()),
                Err(e) => state.message(Level::Error, format!("export failed: {e}")),
            }
            self.last_result = Some(result);
        }
    }

    /// Does what the dialog's buttons asked, in the order a user can ask it.
    pub fn apply(
        &mut self,
        clicks: ExportClicks,
        state: &mut AppState,
        picker: &mut FilePicker,
        notify: Arc<dyn Fn() + Send + Sync>,
    ) {
        if clicks.keep {
            state.export.confirm_overwrite = None;
        }
        if clicks.close {
            // A running export keeps its dialog open (its progress and Cancel).
            state.export.open = self.is_running();
        }
        if clicks.cancel {
            self.job.cancel();
        }
        if clicks.browse {
            let (purpose, start) = browse_request(&state.export);
            picker.request(purpose, Some(&start));
        }
        if clicks.export {
            self.export_clicked(state, notify.clone());
        }
        if clicks.overwrite {
            state.export.confirm_overwrite = None;
            self.start(state, notify);
        }
    }

    /// Export pressed: asks first when an output exists, otherwise starts.
    pub fn export_clicked(&mut self, state: &mut AppState, notify: Arc<dyn Fn() + Send + Sync>) {
        let existing: Vec<PathBuf> = state
            .export
            .outputs()
            .into_iter()
            .filter(|p| p.exists())
            .collect();
        match existing.is_empty() {
            true => self.start(state, notify),
            false => state.export.confirm_overwrite = Some(existing),
        }
    }

    /// Builds the export request from the state and starts it on the export thread; why it
    /// cannot start becomes the outcome.
    pub fn start(&mut self, state: &mut AppState, notify: Arc<dyn Fn() + Send + Sync>) {
        let started = match (request(state), self.exporter.clone()) {
            (Err(e), _) => Err(e),
            (_, None) => Err(AppError::Missing("export is not available in this build")),
            (Ok(request), Some(exporter)) => self.job.start(exporter, request, notify),
        };
        match started {
            Ok(()) => self.last_result = None,
            Err(e) => {
                state.message(Level::Error, format!("export failed: {e}"));
                self.last_result = Some(Err(e));
            }
        }
    }
}

/// The export request of the state's garment, avatar, newest weights, `w` and training rate
/// under its export settings.
pub fn request(state: &AppState) -> Result<ExportRequest, AppError> {
    let garment = state
        .scene
        .garment
        .as_ref()
        .ok_or(AppError::Missing("load a garment first"))?;
    let settings = &state.export;
    Ok(ExportRequest {
        avatar: state.scene.avatar.clone(),
        garment: garment.clone(),
        motion: settings.motion,
        weights: state
            .training
            .latest_weights
            .as_ref()
            .map(|(_, w)| w.clone()),
        w: state.w,
        fps: state.scene.config.training_fps,
        format: settings.format,
        path: PathBuf::from(settings.path.trim()),
        preset: settings.preset.filter(|_| settings.format.takes_preset()),
        include_body: settings.include_body,
        rest_obj: settings.rest_obj && settings.format.is_point_cache(),
    })
}

/// Frames and size of the dialog's current choice.
pub fn estimate(state: &AppState) -> Result<ExportEstimate, AppError> {
    let garment = state
        .scene
        .garment
        .as_ref()
        .ok_or(AppError::Missing("load a garment first"))?;
    let avatar = &state.scene.avatar;
    let motion = avatar
        .motions
        .get(state.export.motion)
        .ok_or(AppError::Missing("choose a motion"))?;
    ExportEstimate::of(
        &state.export,
        motion,
        state.scene.config.training_fps,
        garment,
        avatar,
    )
}

/// What "Browse…" opens: a picker for the chosen format, starting at the typed path.
pub fn browse_request(settings: &ExportSettings) -> (PickPurpose, PathBuf) {
    (
        PickPurpose::ExportPath(settings.format),
        PathBuf::from(settings.path.trim()),
    )
}

/// Follows an edit of the dialog's settings (`before`: as they were before the frame):
/// another format gives the path its extension; a typed path with another format's extension
/// selects that format; any change of what is written withdraws a pending overwrite question.
pub fn settings_edited(settings: &mut ExportSettings, before: &ExportSettings) {
    if settings.format != before.format {
        settings.path = settings.format.with_extension(&settings.path);
    } else if settings.path != before.path
        && let Some(f) = ExportFormat::from_path(&settings.path)
    {
        settings.format = f;
    }
    let changed = settings.format != before.format
        || settings.path != before.path
        || settings.include_body != before.include_body
        || settings.rest_obj != before.rest_obj;
    if changed {
        settings.confirm_overwrite = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use neural_cloth_bake::Preset;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::time::{Duration, Instant};

    /// Pretends to bake `frames` frames, one per millisecond, honouring cancel.
    struct SlowExporter {
        frames: usize,
        calls: AtomicUsize,
    }

    impl Exporter for SlowExporter {
        fn export(
            &self,
            _request: ExportRequest,
            progress: &mut dyn FnMut(usize, usize) -> bool,
        ) -> Result<String, AppError> {
            self.calls.fetch_add(1, Ordering::Relaxed);
            for k in 1..=self.frames {
                std::thread::sleep(Duration::from_millis(1));
                if !progress(k, self.frames) {
                    return Err(neural_cloth_bake::BakeError::Cancelled.into());
                }
            }
            Ok(format!("wrote {} frames", self.frames))
        }
    }

    fn request() -> ExportRequest {
        let scene = neural_cloth_core::scene::procedural::default_scene().unwrap();
        ExportRequest {
            avatar: Arc::new(scene.avatar),
            garment: Arc::new(scene.garment),
            motion: 0,
            weights: None,
            w: 1.0,
            fps: 30.0,
            format: ExportFormat::Usd,
            path: PathBuf::from("x.usda"),
            preset: Some(Preset::Unreal),
            include_body: false,
            rest_obj: false,
        }
    }

    fn wait(job: &mut ExportJob) -> Result<String, AppError> {
        let start = Instant::now();
        loop {
            if let Some(r) = job.poll() {
                return r;
            }
            assert!(start.elapsed() < Duration::from_secs(30), "export hangs");
            std::thread::sleep(Duration::from_millis(2));
        }
    }

    #[test]
    fn export_runs_on_its_thread_reports_progress_and_cancels() {
        let exporter = Arc::new(SlowExporter {
            frames: 20,
            calls: AtomicUsize::new(0),
        });
        let notify: Arc<dyn Fn() + Send + Sync> = Arc::new(|| {});
        let mut job = ExportJob::default();
        job.start(exporter.clone(), request(), notify.clone())
            .unwrap();
        assert!(job.is_running());
        assert!(
            job.start(exporter.clone(), request(), notify.clone())
                .is_err()
        );
        assert_eq!(wait(&mut job).unwrap(), "wrote 20 frames");
        assert!(!job.is_running());

        let long = Arc::new(SlowExporter {
            frames: 100_000,
            calls: AtomicUsize::new(0),
        });
        job.start(long, request(), notify).unwrap();
        let start = Instant::now();
        while job.progress().is_none_or(|(done, _)| done == 0) {
            assert!(start.elapsed() < Duration::from_secs(30));
            std::thread::sleep(Duration::from_millis(1));
        }
        let (done, total) = job.progress().unwrap();
        assert!(done >= 1 && total == 100_000);
        job.cancel();
        let cancelled = wait(&mut job);
        assert!(
            matches!(
                cancelled,
                Err(AppError::Bake(neural_cloth_bake::BakeError::Cancelled))
            ),
            "{cancelled:?}"
        );
        assert_eq!(exporter.calls.load(Ordering::Relaxed), 1);
    }

    #[test]
    fn an_edit_keeps_format_and_extension_together_and_withdraws_the_question() {
        let before = ExportSettings {
            confirm_overwrite: Some(vec![PathBuf::from("garment.glb")]),
            ..Default::default()
        };
        let mut format = before.clone();
        format.format = ExportFormat::Usd;
        settings_edited(&mut format, &before);
        assert_eq!(format.path, ExportFormat::Usd.with_extension(&before.path));
        assert_eq!(format.confirm_overwrite, None);

        let mut typed = before.clone();
        typed.path = "out/walk.pc2".into();
        settings_edited(&mut typed, &before);
        assert_eq!(Some(typed.format), ExportFormat::from_path("out/walk.pc2"));
        assert_eq!(typed.confirm_overwrite, None);

        let mut motion = before.clone();
        motion.motion = 1;
        settings_edited(&mut motion, &before);
        assert_eq!(motion.confirm_overwrite, before.confirm_overwrite);
    }

    #[test]
    fn without_an_exporter_the_outcome_says_so() {
        let mut state = AppState::new(
            crate::default_scene().unwrap(),
            crate::TrainingControl::new(None),
            Default::default(),
        );
        let mut service = ExportService::new(None);
        service.start(&mut state, Arc::new(|| {}));
        assert!(!service.is_running());
        assert!(matches!(
            service.last_result,
            Some(Err(AppError::Missing(_)))
        ));
        assert!(
            state
                .last_error()
                .is_some_and(|e| e.contains("not available"))
        );
    }
}
