//! The timeline row (play/pause, scrubbing, speed, the `w` slider) and the menu bar (project
//! files, runs, recent files, export, quit; the export dialog is [`super::export_dialog`],
//! the Runs section and the quit prompt [`super::runs_panel`]).

use std::path::PathBuf;

use super::NeuralClothApp;
use super::file_picker::{DialogMode, PickPurpose};
use super::playback::{MAX_SPEED, MIN_SPEED};

/// Extension offered for project files.
pub const PROJECT_EXTENSION: &str = "toml";

impl NeuralClothApp {
    /// Play/pause, time slider, speed and the dynamic weight `w` (0–2).
    pub fn timeline_ui(&mut self, ui: &mut egui::Ui) {
        let duration = self
            .state
            .current_motion()
            .map_or(0.0, |m| m.duration_secs());
        ui.horizontal(|ui| {
            let playing = self.state.playback.playing;
            if ui
                .button(if playing { "Pause playback" } else { "Play" })
                .clicked()
            {
                self.state.playback.playing = !playing;
            }
            let mut t = self.state.playback.time_secs;
            let slider = egui::Slider::new(&mut t, 0.0..=duration.max(1e-3))
                .text("time (s)")
                .fixed_decimals(2);
            if ui.add_enabled(duration > 0.0, slider).changed() {
                self.state.playback.seek(t, duration);
            }
            ui.add(
                egui::Slider::new(&mut self.state.playback.speed, MIN_SPEED..=MAX_SPEED)
                    .logarithmic(true)
                    .text("speed")
                    .fixed_decimals(2),
            );
            let mut w = self.state.w;
            let w_slider = egui::Slider::new(&mut w, 0.0..=2.0)
                .text("w (dynamics)")
                .fixed_decimals(2);
            if ui
                .add(w_slider)
                .on_hover_text("0 = static, 1 = trained behaviour, 2 = exaggerated dynamics")
                .changed()
            {
                self.state.set_w(w);
            }
        });
    }

    /// "Save project": to the open project's file, else asks where.
    pub fn save_project_clicked(&mut self) {
        match self.state.project_path.clone() {
            Some(path) => {
                self.state.save_project(&path);
            }
            None => self.picker.request(PickPurpose::SaveProject, None),
        }
    }

    /// Menu bar: project files, runs, recent files, export, quit; view settings.
    pub fn menu_ui(&mut self, ui: &mut egui::Ui) {
        egui::MenuBar::new().ui(ui, |ui| {
            // Clicks inside the File menu (its path fields) must not close it.
            let config = egui::containers::menu::MenuConfig::new()
                .close_behavior(egui::PopupCloseBehavior::CloseOnClickOutside);
            egui::containers::menu::MenuButton::new("File")
                .config(config)
                .ui(ui, |ui| self.file_menu_ui(ui));
            ui.menu_button("View", |ui| {
                ui.checkbox(&mut self.show_curves, "metric curves");
                ui.checkbox(&mut self.viewport.show_timing, "frame time overlay");
                let mut in_app = self.picker.mode == DialogMode::InApp;
                if ui
                    .checkbox(&mut in_app, "in-app file browser")
                    .on_hover_text("use the app's own file browser instead of the desktop's")
                    .changed()
                {
                    self.picker.mode = if in_app {
                        DialogMode::InApp
                    } else {
                        DialogMode::Auto
                    };
                }
                if ui.button("Reset camera").clicked() {
                    self.viewport.reset_camera();
                }
            });
            if let Some(p) = &self.state.project_path {
                ui.weak(p.display().to_string());
            }
            if self.state.has_unsaved_changes() {
                ui.weak("(unsaved changes)");
            }
        });
    }

    /// The File menu: every button closes it; the typed-path rows keep it open while typed.
    fn file_menu_ui(&mut self, ui: &mut egui::Ui) {
        let start = self.state.project_path.clone();
        if ui.button("Open project…").clicked() {
            ui.close();
            self.picker
                .request(PickPurpose::OpenProject, start.as_deref());
        }
        if ui.button("Save project").clicked() {
            ui.close();
            self.save_project_clicked();
        }
        if ui.button("Save project as…").clicked() {
            ui.close();
            self.picker
                .request(PickPurpose::SaveProject, start.as_deref());
        }
        let label = ui.label("Project path:");
        ui.text_edit_singleline(&mut self.state.typed.project)
            .labelled_by(label.id);
        ui.horizontal(|ui| {
            let typed = PathBuf::from(self.state.typed.project.trim());
            let has_path = !self.state.typed.project.trim().is_empty();
            if ui
                .add_enabled(has_path, egui::Button::new("Open"))
                .clicked()
            {
                ui.close();
                self.open_project(&typed);
            }
            if ui
                .add_enabled(has_path, egui::Button::new("Save"))
                .clicked()
            {
                ui.close();
                self.state.save_project(&typed);
            }
        });
        ui.menu_button("Recent projects", |ui| {
            let recent = self.state.recent.paths.clone();
            if recent.is_empty() {
                ui.weak("none");
            }
            for path in recent {
                if ui.button(path.display().to_string()).clicked() {
                    ui.close();
                    self.open_project(&path);
                }
            }
        });
        ui.separator();
        if ui.button("Open run…").clicked() {
            ui.close();
            let folder = self.state.runs_folder();
            self.picker.request(PickPurpose::OpenRun, Some(&folder));
        }
        let label = ui.label("Run folder:");
        ui.text_edit_singleline(&mut self.state.typed.run)
            .labelled_by(label.id);
        let typed = PathBuf::from(self.state.typed.run.trim());
        let has_path = !self.state.typed.run.trim().is_empty();
        if ui
            .add_enabled(has_path, egui::Button::new("Open typed run"))
            .clicked()
        {
            ui.close();
            self.state.open_run(&typed, true);
        }
        ui.menu_button("Recent runs", |ui| {
            let recent = self.state.runs.recent.paths.clone();
            if recent.is_empty() {
                ui.weak("none");
            }
            for path in recent {
                if ui.button(path.display().to_string()).clicked() {
                    ui.close();
                    self.state.open_run(&path, true);
                }
            }
        });
        ui.separator();
        if ui.button("Export baked sequence…").clicked() {
            ui.close();
            let on_screen = self.state.playback.motion;
            self.state.export.show_for(on_screen);
        }
        ui.separator();
        if ui.button("Quit").clicked() {
            ui.close();
            self.request_quit(ui.ctx());
        }
    }

    /// Opens a project; see [`super::state::AppState::open_project`].
    pub fn open_project(&mut self, path: &std::path::Path) -> bool {
        self.state.open_project(path)
    }
}
