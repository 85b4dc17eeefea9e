//! The status bar: the latest message, coloured by severity, and the time between viewport
//! frames while it redraws.

use super::NeuralClothApp;
use super::state::Level;

impl NeuralClothApp {
    /// The status line: the latest message, coloured by severity.
    pub fn status_ui(&mut self, ui: &mut egui::Ui) {
        let animating = self.state.playback.playing || self.state.training.state().is_active();
        let frame_time = match animating {
            true => self.viewport.frame_time_text(),
            false => Some("viewport idle (paused)".to_owned()),
        };
        ui.horizontal(|ui| {
            match self.state.messages.last() {
                Some(m) => {
                    let color = match m.level {
                        Level::Info => ui.visuals().text_color(),
                        Level::Warning => egui::Color32::from_rgb(230, 180, 60),
                        Level::Error => egui::Color32::from_rgb(255, 100, 90),
                    };
                    ui.colored_label(color, &m.text);
                }
                None => {
                    ui.weak("ready");
                }
            }
            if let Some(text) = frame_time {
                ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
                    ui.weak(text)
                        .on_hover_text("time between viewport frames while it redraws");
                });
            }
        });
    }
}
