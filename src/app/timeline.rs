//! The timeline row (play/pause, scrubbing, speed, the `w` slider) and the menu bar (project
//! files, recent files, export; the export dialog is [`super::export_dialog`]).

use std::path::PathBuf;

use super::NeuralClothApp;
use super::playback::{MAX_SPEED, MIN_SPEED};
use super::state::Level;

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

    /// Says what to do when a file dialog gave no file: cancelled, or no desktop dialog on
    /// this machine (rfd needs a portal), in which case the typed path below is the way.
    fn no_file_chosen(&mut self, verb: &str) {
        self.state.message(
            Level::Warning,
            format!(
                "no project file chosen to {verb}: without a desktop file dialog, type the path \
                 under \"Project path\" in the File menu and press {}",
                if verb == "open" { "Open" } else { "Save" }
            ),
        );
    }

    /// Menu bar: project files, recent files, export, view.
    pub fn menu_ui(&mut self, ui: &mut egui::Ui) {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                if ui.button("Open project…").clicked() {
                    let picked = rfd::FileDialog::new()
                        .add_filter("neural-cloth project", &[PROJECT_EXTENSION])
                        .pick_file();
                    match picked {
                        Some(path) => {
                            self.open_project(&path);
                        }
                        None => self.no_file_chosen("open"),
                    }
                }
                let save_as = |app: &Self| {
                    let mut dialog = rfd::FileDialog::new()
                        .add_filter("neural-cloth project", &[PROJECT_EXTENSION]);
                    if let Some(dir) = app.state.project_path.as_ref().and_then(|p| p.parent()) {
                        dialog = dialog.set_directory(dir);
                    }
                    dialog.save_file()
                };
                if ui.button("Save project").clicked() {
                    let path = self.state.project_path.clone().or_else(|| save_as(self));
                    match path {
                        Some(path) => {
                            self.state.save_project(&path);
                        }
                        None => self.no_file_chosen("save"),
                    }
                }
                if ui.button("Save project as…").clicked() {
                    match save_as(self) {
                        Some(path) => {
                            self.state.save_project(&path);
                        }
                        None => self.no_file_chosen("save"),
                    }
                }
                ui.separator();
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
                        self.open_project(&typed);
                    }
                    if ui
                        .add_enabled(has_path, egui::Button::new("Save"))
                        .clicked()
                    {
                        self.state.save_project(&typed);
                    }
                });
                ui.separator();
                ui.menu_button("Recent projects", |ui| {
                    let recent = self.state.recent.paths.clone();
                    if recent.is_empty() {
                        ui.weak("none");
                    }
                    for path in recent {
                        if ui.button(path.display().to_string()).clicked() {
                            self.open_project(&path);
                        }
                    }
                });
                ui.separator();
                if ui.button("Export baked sequence…").clicked() {
                    let on_screen = self.state.playback.motion;
                    self.state.export.show_for(on_screen);
                }
            });
            ui.menu_button("View", |ui| {
                ui.checkbox(&mut self.show_curves, "metric curves");
                ui.checkbox(&mut self.viewport.show_timing, "frame time overlay");
                if ui.button("Reset camera").clicked() {
                    self.viewport.reset_camera();
                }
            });
            if let Some(p) = &self.state.project_path {
                ui.weak(p.display().to_string());
            }
        });
    }

    /// Opens a project (the built-in scene fills in the parts it does not name); see
    /// [`super::state::AppState::open_project`].
    pub fn open_project(&mut self, path: &std::path::Path) -> bool {
        self.state
            .open_project(path, || super::default_scene().ok())
    }
}
