//! The "Fit garment" row of the Scene section: the button (enabled when there is a garment
//! file to fit and nothing trains) and a spinner while the fit runs; the fit itself is
//! [`super::fit`].

impl super::NeuralClothApp {
    /// The "Fit garment" row of the Scene section.
    pub fn fit_ui(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            let clicked = ui
                .add_enabled(
                    self.fit.can_start(&self.state),
                    egui::Button::new("Fit garment"),
                )
                .on_hover_text(
                    "Fit the garment file onto this avatar (units, scale, position, mirror), \
                     relax it out of the body and load the fitted copy (NAME-fitted.obj)",
                )
                .clicked();
            if self.fit.is_running() {
                ui.spinner();
                ui.label("fitting…");
            }
            if clicked {
                let notify = self.notifier();
                self.fit.fit_clicked(&mut self.state, notify);
            }
        });
    }
}
