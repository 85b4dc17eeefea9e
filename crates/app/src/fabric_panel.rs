//! The Fabric panel: the preset and the main material parameters (stretch, shear, density,
//! bending, collision threshold, friction) of the scene's fabric; each edit goes to a live
//! run through [`super::state::AppState::fabric_changed`].

use neural_cloth_physics::fabric::PRESET_NAMES;

use super::NeuralClothApp;

impl NeuralClothApp {
    /// Fabric section: preset and the main material parameters.
    pub fn fabric_ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Fabric")
            .default_open(true)
            .show(ui, |ui| {
                let mut preset = None;
                let current = self.state.fabric_preset();
                egui::ComboBox::from_label("preset")
                    .selected_text(current)
                    .show_ui(ui, |ui| {
                        for name in PRESET_NAMES {
                            if ui.selectable_label(current == name, name).clicked() {
                                preset = Some(name);
                            }
                        }
                    });
                if let Some(name) = preset {
                    self.state.apply_preset(name);
                }
                let f = &mut self.state.scene.config.fabric;
                let mut changed = false;
                changed |= ui
                    .add(
                        egui::Slider::new(&mut f.stretch_stiffness, 0.1..=100.0)
                            .logarithmic(true)
                            .text("stretch (N/m)"),
                    )
                    .changed();
                changed |= ui
                    .add(egui::Slider::new(&mut f.shear_stiffness, 0.0..=50.0).text("shear (N/m)"))
                    .changed();
                changed |= ui
                    .add(
                        egui::Slider::new(&mut f.density_kg_per_m2, 0.01..=1.0)
                            .logarithmic(true)
                            .text("density (kg/m²)"),
                    )
                    .changed();
                changed |= ui
                    .add(
                        egui::Slider::new(&mut f.bending_stiffness, 1e-7..=1e-2)
                            .logarithmic(true)
                            .text("bending (N·m)")
                            .custom_formatter(|v, _| format!("{v:.1e}")),
                    )
                    .changed();
                let mut eps_mm = f.collision_threshold_m * 1000.0;
                if ui
                    .add(egui::Slider::new(&mut eps_mm, 0.0..=20.0).text("collision ε (mm)"))
                    .changed()
                {
                    f.collision_threshold_m = eps_mm / 1000.0;
                    changed = true;
                }
                changed |= ui
                    .add(
                        egui::Slider::new(&mut f.friction_coefficient, 0.0..=2.0)
                            .text("friction μ (with the friction effect)"),
                    )
                    .changed();
                if changed {
                    self.state.fabric_changed();
                }
            });
    }
}
