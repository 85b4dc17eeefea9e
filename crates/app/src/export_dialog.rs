//! The export dialog: format, destination preset, motion and path; the frame count and an
//! estimated size before writing; the bake on the named thread `neural-cloth-export` with a
//! progress bar and Cancel. A failed or cancelled export leaves no file and the app runs on.

use std::path::PathBuf;
use std::sync::Arc;

use super::NeuralClothApp;
use super::background::{BackgroundJob, poll_job};
use super::error::AppError;
use super::export::{ExportEstimate, ExportFormat, ExportRequest, ExportSettings, Exporter};
use super::file_picker::PickPurpose;
use super::state::Level;
use neural_cloth_bake::Preset;

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

impl NeuralClothApp {
    /// Collects a finished export (once per frame): its summary or error goes to the status
    /// messages and the dialog.
    pub(crate) fn poll_export(&mut self) {
        if let Some(result) = self.export_job.poll() {
            match &result {
                Ok(s) => self.state.message(Level::Info, s.clone()),
                Err(e) => self
                    .state
                    .message(Level::Error, format!("export failed: {e}")),
            }
            self.state.export.last_result = Some(result.map_err(|e| e.to_string()));
        }
    }

    /// The export dialog.
    pub fn export_ui(&mut self, ui: &mut egui::Ui) {
        if !self.state.export.open {
            return;
        }
        let mut open = true;
        let motions: Vec<String> = self
            .state
            .scene
            .avatar
            .motions
            .iter()
            .map(|m| m.name.clone())
            .collect();
        let estimate = self.export_estimate();
        let running = self.export_job.is_running();
        let progress = self.export_job.progress();
        let (mut run, mut cancel, mut overwrite, mut browse) = (false, false, false, false);
        egui::Window::new("Export baked sequence")
            .open(&mut open)
            .collapsible(false)
            .show(ui.ctx(), |ui| {
                let settings = &mut self.state.export;
                browse = ui
                    .add_enabled_ui(!running, |ui| settings_ui(ui, settings, &motions))
                    .inner;
                match &estimate {
                    Ok(e) => ui.label(e.summary()),
                    Err(e) => ui.colored_label(ui.visuals().error_fg_color, e.to_string()),
                };
                outputs_ui(ui, &settings.outputs());
                ui.label(format!("w = {:.2} (from the timeline)", self.state.w));
                if let Some(existing) = &settings.confirm_overwrite {
                    let names: Vec<String> =
                        existing.iter().map(|p| p.display().to_string()).collect();
                    ui.colored_label(
                        ui.visuals().warn_fg_color,
                        format!("{} already exists. Overwrite?", names.join(", ")),
                    );
                    ui.horizontal(|ui| {
                        overwrite = ui.button("Overwrite").clicked();
                        if ui.button("Keep the existing files").clicked() {
                            settings.confirm_overwrite = None;
                        }
                    });
                } else if running {
                    let (done, total) = progress.unwrap_or((0, 0));
                    let fraction = if total > 0 {
                        done as f32 / total as f32
                    } else {
                        0.0
                    };
                    ui.add(
                        egui::ProgressBar::new(fraction).text(format!("{done} / {total} frames")),
                    );
                    cancel = ui.button("Cancel").clicked();
                } else {
                    run = ui.button("Export").clicked();
                }
                match &settings.last_result {
                    Some(Ok(s)) => {
                        ui.label(s);
                    }
                    Some(Err(e)) => {
                        ui.colored_label(ui.visuals().error_fg_color, e);
                    }
                    None => {}
                }
            });
        self.state.export.open = open || running;
        if cancel {
            self.export_job.cancel();
        }
        if browse {
            let purpose = PickPurpose::ExportPath(self.state.export.format);
            let start = PathBuf::from(self.state.export.path.trim());
            self.picker.request(purpose, Some(&start));
        }
        if run {
            self.export_clicked();
        }
        if overwrite {
            self.state.export.confirm_overwrite = None;
            self.start_export();
        }
    }

    /// Export pressed: asks first when an output exists, otherwise starts.
    fn export_clicked(&mut self) {
        let existing: Vec<PathBuf> = self
            .state
            .export
            .outputs()
            .into_iter()
            .filter(|p| p.exists())
            .collect();
        match existing.is_empty() {
            true => self.start_export(),
            false => self.state.export.confirm_overwrite = Some(existing),
        }
    }

    /// Frames and size of the dialog's current choice.
    fn export_estimate(&self) -> Result<ExportEstimate, AppError> {
        let settings = &self.state.export;
        let garment = self
            .state
            .scene
            .garment
            .as_ref()
            .ok_or(AppError::Missing("load a garment first"))?;
        let avatar = &self.state.scene.avatar;
        let motion = avatar
            .motions
            .get(settings.motion)
            .ok_or(AppError::Missing("choose a motion"))?;
        ExportEstimate::of(
            settings,
            motion,
            self.state.scene.config.training_fps,
            garment,
            avatar,
        )
    }

    /// Builds the export request from the state and starts it on the export thread.
    fn start_export(&mut self) {
        let settings = self.state.export.clone();
        let started = match (&self.state.scene.garment, self.exporter.clone()) {
            (None, _) => Err(AppError::Missing("load a garment first")),
            (_, None) => Err(AppError::Missing("export is not available in this build")),
            (Some(garment), Some(exporter)) => {
                let request = ExportRequest {
                    avatar: self.state.scene.avatar.clone(),
                    garment: garment.clone(),
                    motion: settings.motion,
                    weights: self
                        .state
                        .training
                        .latest_weights
                        .as_ref()
                        .map(|(_, w)| w.clone()),
                    w: self.state.w,
                    fps: self.state.scene.config.training_fps,
                    format: settings.format,
                    path: PathBuf::from(settings.path.trim()),
                    preset: settings.preset.filter(|_| settings.format.takes_preset()),
                    include_body: settings.include_body,
                    rest_obj: settings.rest_obj && settings.format.is_point_cache(),
                };
                self.export_job
                    .start(exporter, request, self.notify.clone())
            }
        };
        match started {
            Ok(()) => self.state.export.last_result = None,
            Err(e) => {
                self.state
                    .message(Level::Error, format!("export failed: {e}"));
                self.state.export.last_result = Some(Err(e.to_string()));
            }
        }
    }
}

/// Format, preset, extra outputs, motion and path. Changing the format gives the path its
/// extension; typing a path with another format's extension selects that format. Any change
/// withdraws a pending overwrite question. Returns whether "Browse…" was clicked.
fn settings_ui(ui: &mut egui::Ui, settings: &mut ExportSettings, motions: &[String]) -> bool {
    let mut browse = false;
    let before = settings.clone();
    egui::ComboBox::from_label("format")
        .selected_text(settings.format.label())
        .show_ui(ui, |ui| {
            for f in ExportFormat::ALL {
                ui.selectable_value(&mut settings.format, f, f.label());
            }
        });
    if settings.format != before.format {
        settings.path = settings.format.with_extension(&settings.path);
    }
    ui.add_enabled_ui(settings.format.takes_preset(), |ui| {
        egui::ComboBox::from_label("preset")
            .selected_text(preset_label(settings.preset))
            .show_ui(ui, |ui| {
                ui.selectable_value(&mut settings.preset, None, preset_label(None));
                for p in Preset::ALL {
                    ui.selectable_value(&mut settings.preset, Some(p), p.label());
                }
            });
    });
    if !settings.format.takes_preset() {
        ui.weak("glTF is always Y up, metres; importers convert it.");
    }
    let body_hint = match settings.format.body_is_a_sibling() {
        true => "a second file beside the garment's, NAME.body.EXT",
        false => "a second mesh in the same file",
    };
    ui.checkbox(&mut settings.include_body, "also write the body")
        .on_hover_text(body_hint);
    if settings.format.is_point_cache() {
        ui.checkbox(&mut settings.rest_obj, "also write the rest-pose OBJ")
            .on_hover_text(
                "The garment's mesh in the cache's vertex order, NAME.obj: import it (keep the \
                 vertex order) and put Blender's Mesh Cache modifier on it.",
            );
    }
    let motion_name = motions
        .get(settings.motion)
        .cloned()
        .unwrap_or_else(|| "none".into());
    egui::ComboBox::from_label("motion")
        .selected_text(motion_name)
        .show_ui(ui, |ui| {
            for (k, name) in motions.iter().enumerate() {
                ui.selectable_value(&mut settings.motion, k, name);
            }
        });
    ui.horizontal(|ui| {
        let label = ui.label("path");
        let edit = ui
            .text_edit_singleline(&mut settings.path)
            .labelled_by(label.id);
        if edit.changed()
            && let Some(f) = ExportFormat::from_path(&settings.path)
        {
            settings.format = f;
        }
        browse = ui.button("Browse…").clicked();
    });
    let changed = settings.format != before.format
        || settings.path != before.path
        || settings.include_body != before.include_body
        || settings.rest_obj != before.rest_obj;
    if changed {
        settings.confirm_overwrite = None;
    }
    browse
}

/// Where the files go: every output with its full path, existing ones marked.
fn outputs_ui(ui: &mut egui::Ui, outputs: &[PathBuf]) {
    let here = std::env::current_dir().ok();
    ui.label("writes:");
    for p in outputs {
        let full = match (&here, p.is_absolute()) {
            (Some(dir), false) => dir.join(p),
            _ => p.clone(),
        };
        let exists = if p.exists() { " (exists)" } else { "" };
        ui.weak(format!("  {}{exists}", full.display()));
    }
}

/// The menu text of a preset choice.
fn preset_label(preset: Option<Preset>) -> &'static str {
    preset.map_or("none (Y up, m, frames from 0)", Preset::label)
}

#[cfg(test)]
mod tests {
    use super::*;
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
}
