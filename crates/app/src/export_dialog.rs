//! The export dialog: format, destination preset, motion and path; the frame count and an
//! estimated size before writing; a progress bar and Cancel while the bake runs. What its
//! buttons do is [`super::export_service`].

use std::path::PathBuf;

use super::NeuralClothApp;
use super::export::{ExportFormat, ExportSettings};
use super::export_service::{ExportClicks, estimate, settings_edited};
use neural_cloth_bake::Preset;

impl NeuralClothApp {
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
        let estimate = estimate(&self.state);
        let running = self.export.is_running();
        let progress = self.export.progress();
        let mut clicks = ExportClicks::default();
        egui::Window::new("Export baked sequence")
            .open(&mut open)
            .collapsible(false)
            .show(ui.ctx(), |ui| {
                let settings = &mut self.state.export;
                clicks.browse = ui
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
                        clicks.overwrite = ui.button("Overwrite").clicked();
                        clicks.keep = ui.button("Keep the existing files").clicked();
                    });
                } else if running {
                    progress_ui(ui, progress.unwrap_or((0, 0)));
                    clicks.cancel = ui.button("Cancel").clicked();
                } else {
                    clicks.export = ui.button("Export").clicked();
                }
                match &self.export.last_result {
                    Some(Ok(s)) => {
                        ui.label(s);
                    }
                    Some(Err(e)) => {
                        ui.colored_label(ui.visuals().error_fg_color, e.to_string());
                    }
                    None => {}
                }
            });
        clicks.close = !open;
        let notify = self.notifier();
        self.export
            .apply(clicks, &mut self.state, &mut self.picker, notify);
    }
}

/// The bar of a running export: frames done of the total.
fn progress_ui(ui: &mut egui::Ui, (done, total): (usize, usize)) {
    let fraction = if total > 0 {
        done as f32 / total as f32
    } else {
        0.0
    };
    ui.add(egui::ProgressBar::new(fraction).text(format!("{done} / {total} frames")));
}

/// Format, preset, extra outputs, motion and path, followed by [`settings_edited`] (format
/// and extension kept together). Returns whether "Browse…" was clicked.
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
        settings_edited(settings, &before);
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
        ui.text_edit_singleline(&mut settings.path)
            .labelled_by(label.id);
        browse = ui.button("Browse…").clicked();
    });
    settings_edited(settings, &before);
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
