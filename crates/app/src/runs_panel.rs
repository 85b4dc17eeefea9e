//! The Runs section (where new runs go, the run shown with its disk use, checkpoint
//! retention, Open run), what a chosen file or folder does, and the prompts
//! before quitting or resetting with unsaved work or a running training.

use std::path::Path;

use neural_cloth_train::retention::{MAX_KEEP_NEWEST, format_bytes};

use super::NeuralClothApp;
use super::export::ExportFormat;
use super::file_picker::PickPurpose;

/// A question the app asks before doing something that loses work.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Confirm {
    /// Quitting with unsaved changes or a training running.
    Quit,
    /// Resetting the training (the run is forgotten by the app; its folder stays).
    Reset,
}

impl NeuralClothApp {
    /// Does what a path chosen in a file dialog is for.
    pub fn apply_pick(&mut self, purpose: PickPurpose, path: &Path) {
        match purpose {
            PickPurpose::Load(kind) => {
                self.load_file(kind, path);
            }
            PickPurpose::OpenProject => {
                self.open_project(path);
            }
            PickPurpose::SaveProject => {
                self.state.save_project(path);
            }
            PickPurpose::OpenRun => {
                self.state.open_run(path, true);
            }
            PickPurpose::RunsFolder => self.state.set_runs_folder(path),
            PickPurpose::ExportPath(format) => {
                let export = &mut self.state.export;
                export.path = path.display().to_string();
                // A file's extension names its format; the OBJ sequence's folder names none.
                export.format = match format {
                    ExportFormat::ObjSequence => format,
                    _ => ExportFormat::from_path(&export.path).unwrap_or(format),
                };
                export.confirm_overwrite = None;
            }
        }
    }

    /// Shows the in-app file browser while open and applies what was chosen.
    pub fn file_picker_ui(&mut self, ui: &egui::Ui) {
        self.picker.browser_ui(ui.ctx());
        if let Some((purpose, path)) = self.picker.take_picked() {
            self.apply_pick(purpose, &path);
        }
    }

    /// The Runs section: runs folder, the run shown and its disk use, retention, open/recent.
    pub fn runs_ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Runs")
            .default_open(true)
            .show(ui, |ui| {
                let folder = self.state.runs_folder();
                ui.horizontal_wrapped(|ui| {
                    ui.label("New runs go to");
                    ui.monospace(folder.display().to_string())
                        .on_hover_text("each training writes a run-<time> folder here");
                    if ui.button("Change…").clicked() {
                        self.picker.request(PickPurpose::RunsFolder, Some(&folder));
                    }
                });
                self.current_run_ui(ui);
                self.retention_ui(ui);
                if ui
                    .button("Open run…")
                    .on_hover_text("show a run folder's trained model (File > Recent runs)")
                    .clicked()
                {
                    self.picker.request(PickPurpose::OpenRun, Some(&folder));
                }
            });
    }

    /// The run shown, its step and what it uses on disk.
    fn current_run_ui(&mut self, ui: &mut egui::Ui) {
        if self.state.is_loading_run() {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label("opening the run…");
            });
            return;
        }
        let Some(run) = self.state.training.run_dir.clone() else {
            ui.weak("No run yet: train, or open a run folder.");
            return;
        };
        ui.label(format!("Run: {}", run.display()));
        if let Some(usage) = self.state.run_disk_usage() {
            ui.label(format!(
                "{} checkpoints, {} on disk ({} in checkpoints)",
                usage.checkpoints,
                format_bytes(usage.total_bytes),
                format_bytes(usage.checkpoint_bytes)
            ));
        }
    }

    /// Retention settings and pruning the current run by them.
    fn retention_ui(&mut self, ui: &mut egui::Ui) {
        let retention = &mut self.state.runs.retention;
        ui.horizontal(|ui| {
            ui.label("keep the newest");
            ui.add(
                egui::DragValue::new(&mut retention.keep_newest)
                    .range(1..=MAX_KEEP_NEWEST)
                    .suffix(" checkpoints"),
            );
        });
        ui.checkbox(&mut retention.keep_best, "and the best by validation")
            .on_hover_text("the checkpoint with the lowest validation loss is never deleted");
        let can_prune =
            self.state.training.run_dir.is_some() && !self.state.training.state().is_active();
        if ui
            .add_enabled(can_prune, egui::Button::new("Prune run now"))
            .on_hover_text("delete the run's checkpoints these settings do not keep")
            .clicked()
        {
            self.state.prune_run();
        }
    }

    /// Whether quitting now would lose something: unsaved changes or a live training.
    pub fn quit_needs_confirmation(&self) -> bool {
        self.state.training.state().is_active() || self.state.has_unsaved_changes()
    }

    /// File > Quit and the window's close button: asks first when work would be lost.
    pub fn request_quit(&mut self, ctx: &egui::Context) {
        if self.quit_confirmed || !self.quit_needs_confirmation() {
            self.quit_confirmed = true;
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        } else {
            self.confirm = Some(Confirm::Quit);
        }
    }

    /// Reset in the Training section: asks first while training runs or when the run shown is
    /// not in a saved project.
    pub fn request_reset(&mut self) {
        if self.state.training.state().is_active() || self.state.has_unsaved_changes() {
            self.confirm = Some(Confirm::Reset);
        } else {
            self.reset_training();
        }
    }

    fn reset_training(&mut self) {
        self.state.training.reset();
        self.state.preview.reset_scene();
    }

    /// Intercepts the window's close button while a question is due (once per frame).
    pub fn handle_close_request(&mut self, ui: &egui::Ui) {
        if ui.input(|i| i.viewport().close_requested()) && !self.quit_confirmed {
            if self.quit_needs_confirmation() {
                ui.ctx()
                    .send_viewport_cmd(egui::ViewportCommand::CancelClose);
                self.confirm = Some(Confirm::Quit);
            } else {
                self.quit_confirmed = true;
            }
        }
    }

    /// The pending question, as a modal window.
    pub fn confirm_ui(&mut self, ui: &egui::Ui) {
        let Some(question) = self.confirm else {
            return;
        };
        let active = self.state.training.state().is_active();
        let unsaved = self.state.has_unsaved_changes();
        let mut answer = None;
        egui::Modal::new(egui::Id::unique("neural-cloth confirm")).show(ui.ctx(), |ui| {
            ui.set_max_width(420.0);
            match question {
                Confirm::Quit => ui.heading("Quit neural-cloth?"),
                Confirm::Reset => ui.heading("Reset the training?"),
            };
            if active {
                ui.label("A training is running: it stops at its next step (its last checkpoint stays in the run folder).");
            }
            if unsaved {
                ui.label("The project has unsaved changes (settings, or the run it shows).");
            }
            if question == Confirm::Reset {
                ui.label("The curves and the trained preview are cleared; the run folder stays on disk.");
            }
            ui.horizontal(|ui| {
                if unsaved && ui.button("Save project").clicked() {
                    answer = Some(false);
                    self.save_project_clicked();
                }
                let go = match question {
                    Confirm::Quit if unsaved => "Quit without saving",
                    Confirm::Quit => "Quit",
                    Confirm::Reset => "Reset training",
                };
                if ui.button(go).clicked() {
                    answer = Some(true);
                }
                if ui.button("Cancel").clicked() {
                    answer = Some(false);
                }
            });
        });
        match (answer, question) {
            (Some(true), Confirm::Quit) => {
                self.confirm = None;
                self.state.training.reset();
                self.quit_confirmed = true;
                ui.ctx().send_viewport_cmd(egui::ViewportCommand::Close);
            }
            (Some(true), Confirm::Reset) => {
                self.confirm = None;
                self.reset_training();
            }
            (Some(false), _) => self.confirm = None,
            (None, _) => {}
        }
    }
}
