//! The timeline row (play/pause, scrubbing, speed, the `w` slider), the menu bar (project
//! files, recent files, export) and the export dialog.

use std::path::PathBuf;

use super::NeuralClothApp;
use super::export::{ExportFormat, ExportRequest};
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

    /// Menu bar: project files, recent files, export, view.
    pub fn menu_ui(&mut self, ui: &mut egui::Ui) {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                if ui.button("Open project…").clicked() {
                    let picked = rfd::FileDialog::new()
                        .add_filter("neural-cloth project", &[PROJECT_EXTENSION])
                        .pick_file();
                    if let Some(path) = picked {
                        self.open_project(&path);
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
                    if let Some(path) = path {
                        self.state.save_project(&path);
                    }
                }
                if ui.button("Save project as…").clicked()
                    && let Some(path) = save_as(self)
                {
                    self.state.save_project(&path);
                }
                ui.separator();
                ui.label("Project path:");
                ui.text_edit_singleline(&mut self.state.typed.project);
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
                    self.state.export.open = true;
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

    /// Opens a project (the built-in scene fills in the parts it does not name).
    pub fn open_project(&mut self, path: &std::path::Path) -> bool {
        self.state.training.reset();
        self.state
            .open_project(path, || super::default_scene().ok())
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
        let mut run = false;
        egui::Window::new("Export baked sequence")
            .open(&mut open)
            .collapsible(false)
            .show(ui.ctx(), |ui| {
                let settings = &mut self.state.export;
                egui::ComboBox::from_label("format")
                    .selected_text(settings.format.label())
                    .show_ui(ui, |ui| {
                        for f in ExportFormat::ALL {
                            ui.selectable_value(&mut settings.format, f, f.label());
                        }
                    });
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
                    ui.label("path");
                    ui.text_edit_singleline(&mut settings.path);
                    if ui.button("Browse…").clicked() {
                        let ext = settings.format.extension();
                        if let Some(p) = rfd::FileDialog::new()
                            .add_filter(settings.format.label(), &[ext])
                            .save_file()
                        {
                            settings.path = p.display().to_string();
                        }
                    }
                });
                ui.label(format!("w = {:.2} (from the timeline)", self.state.w));
                run = ui.button("Export").clicked();
                match &settings.last_result {
                    Some(Ok(s)) => {
                        ui.label(s);
                    }
                    Some(Err(e)) => {
                        ui.colored_label(egui::Color32::from_rgb(255, 100, 90), e);
                    }
                    None => {}
                }
            });
        self.state.export.open = open;
        if run {
            self.run_export();
        }
    }

    /// Builds the export request from the state and hands it to the exporter.
    fn run_export(&mut self) {
        let settings = self.state.export.clone();
        let result = match (&self.state.scene.garment, self.exporter.as_mut()) {
            (None, _) => Err("load a garment first".to_string()),
            (_, None) => Err("export is not available in this build".to_string()),
            (Some(garment), Some(exporter)) => exporter.export(ExportRequest {
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
                fps: self.state.train_config.fps,
                format: settings.format,
                path: PathBuf::from(settings.path.trim()),
            }),
        };
        match &result {
            Ok(s) => self.state.message(Level::Info, s.clone()),
            Err(e) => self
                .state
                .message(Level::Error, format!("export failed: {e}")),
        }
        self.state.export.last_result = Some(result);
    }
}
