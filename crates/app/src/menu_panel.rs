//! The menu bar: File (project files, runs, recent files, export, quit; the export dialog is
//! [`super::export_dialog`], the quit prompt [`super::confirm_panel`]) and View (curves, frame
//! time, file browser, camera).

use std::path::PathBuf;

use super::NeuralClothApp;
use super::file_picker::{DialogMode, PickPurpose};

impl NeuralClothApp {
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
