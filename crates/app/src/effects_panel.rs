//! The "Effects & view" panel: the scene's physical effects (fixed while training runs; an
//! edit goes through [`super::state::AppState::effects_changed`]) and the viewport's overlay
//! and camera toggles.

use super::NeuralClothApp;

impl NeuralClothApp {
    /// Effects and viewport overlay toggles.
    pub fn effects_ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Effects & view")
            .default_open(false)
            .show(ui, |ui| {
                let active = self.state.training.state().is_active();
                ui.add_enabled_ui(!active, |ui| {
                    let e = &mut self.state.scene.config.effects;
                    let mut changed = false;
                    changed |= ui.checkbox(&mut e.gravity, "gravity").changed();
                    changed |= ui.checkbox(&mut e.bending, "bending").changed();
                    changed |= ui.checkbox(&mut e.collision, "collision").changed();
                    changed |= ui.checkbox(&mut e.dynamics, "dynamics (inertia)").changed();
                    changed |= ui.checkbox(&mut e.pinning, "pinning").changed();
                    let can_rub = e.collision && e.dynamics;
                    changed |= ui
                        .add_enabled(can_rub, egui::Checkbox::new(&mut e.friction, "friction"))
                        .on_disabled_hover_text("friction needs collision and dynamics")
                        .changed();
                    if changed {
                        self.state.effects_changed();
                    }
                });
                ui.separator();
                let d = &mut self.state.draw;
                ui.checkbox(&mut d.heat_map, "strain heat-map");
                ui.checkbox(&mut d.collision_points, "collision points");
                ui.checkbox(&mut d.wireframe, "wireframe");
                ui.checkbox(&mut d.show_body, "body");
                ui.checkbox(&mut d.show_garment, "garment");
                ui.checkbox(&mut d.grid, "ground grid");
                ui.checkbox(&mut self.viewport.follow, "camera follows body");
                ui.checkbox(&mut self.viewport.show_timing, "frame time");
                if ui.button("Reset camera").clicked() {
                    self.viewport.reset_camera();
                }
            });
    }
}
