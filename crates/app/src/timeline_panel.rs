//! The timeline row: play/pause, scrubbing the shown motion, playback speed and the dynamic
//! weight `w` of the shown garment.

use super::NeuralClothApp;
use super::playback::{MAX_SPEED, MIN_SPEED};

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
}
