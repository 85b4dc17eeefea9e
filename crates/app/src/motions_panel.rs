//! The Motions panel: every motion of the scene with its length and split, all rows visible;
//! clicking one shows it on the timeline.

use neural_cloth_core::scene::Split;

use super::NeuralClothApp;

/// The split's name as the motion list shows it.
pub fn split_name(split: Split) -> &'static str {
    match split {
        Split::Train => "train",
        Split::Validation => "validation",
        Split::Test => "test",
    }
}

impl NeuralClothApp {
    /// The motion list: every motion with its split (train, validation, test), all rows
    /// visible (the side panel scrolls, the list does not hide rows); click one to show it.
    pub fn motions_ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Motions")
            .default_open(true)
            .show(ui, |ui| {
                let avatar = self.state.scene.avatar.clone();
                let mut chosen = None;
                for (k, m) in avatar.motions.iter().enumerate() {
                    let split = self
                        .state
                        .scene
                        .splits
                        .get(k)
                        .copied()
                        .unwrap_or(Split::Train);
                    let selected = k == self.state.playback.motion;
                    let text = format!(
                        "{} ({:.1} s) · {}",
                        m.name,
                        m.duration_secs(),
                        split_name(split)
                    );
                    if ui.selectable_label(selected, text).clicked() {
                        chosen = Some(k);
                    }
                }
                if avatar.motions.is_empty() {
                    ui.weak("no motions: load a BVH file");
                }
                if let Some(k) = chosen {
                    self.state.playback.select_motion(k, avatar.motions.len());
                }
            });
    }
}
