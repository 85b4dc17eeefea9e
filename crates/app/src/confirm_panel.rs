//! The prompts before losing work: quitting (File > Quit or the window's close button) or
//! resetting the training while a training runs or the project has unsaved changes, as a
//! modal window with Save project, go ahead and Cancel.

use super::NeuralClothApp;

/// A question the app asks before doing something that loses work.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Confirm {
    /// Quitting with unsaved changes or a training running.
    Quit,
    /// Resetting the training (the run is forgotten by the app; its folder stays).
    Reset,
}

impl NeuralClothApp {
    /// Whether quitting now would lose something: unsaved changes or a live training.
    pub fn quit_needs_confirmation(&self) -> bool {
        self.state.training.state().is_active() || self.state.has_unsaved_changes()
    }

    /// File > Quit and the window's close button: asks first when work would be lost.
    pub fn request_quit(&mut self, ctx: &egui::Context) {
        if self.quit_confirmed || !self.quit_needs_confirmation() {
            self.quit_confirmed = true;
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        } else {
            self.confirm = Some(Confirm::Quit);
        }
    }

    /// Reset in the Training section: asks first while training runs or when the run shown is
    /// not in a saved project.
    pub fn request_reset(&mut self) {
        if self.state.training.state().is_active() || self.state.has_unsaved_changes() {
            self.confirm = Some(Confirm::Reset);
        } else {
            self.state.reset_training();
        }
    }

    /// Intercepts the window's close button while a question is due (once per frame).
    pub fn handle_close_request(&mut self, ui: &egui::Ui) {
        if ui.input(|i| i.viewport().close_requested()) && !self.quit_confirmed {
            if self.quit_needs_confirmation() {
                ui.ctx()
                    .send_viewport_cmd(egui::ViewportCommand::CancelClose);
                self.confirm = Some(Confirm::Quit);
            } else {
                self.quit_confirmed = true;
            }
        }
    }

    /// The pending question, as a modal window.
    pub fn confirm_ui(&mut self, ui: &egui::Ui) {
        let Some(question) = self.confirm else {
            return;
        };
        let active = self.state.training.state().is_active();
        let unsaved = self.state.has_unsaved_changes();
        let mut answer = None;
        egui::Modal::new(egui::Id::unique("neural-cloth confirm")).show(ui.ctx(), |ui| {
            ui.set_max_width(420.0);
            match question {
                Confirm::Quit => ui.heading("Quit neural-cloth?"),
                Confirm::Reset => ui.heading("Reset the training?"),
            };
            if active {
                ui.label("A training is running: it stops at its next step (its last checkpoint stays in the run folder).");
            }
            if unsaved {
                ui.label("The project has unsaved changes (settings, or the run it shows).");
            }
            if question == Confirm::Reset {
                ui.label("The curves and the trained preview are cleared; the run folder stays on disk.");
            }
            ui.horizontal(|ui| {
                if unsaved && ui.button("Save project").clicked() {
                    answer = Some(false);
                    self.save_project_clicked();
                }
                let go = match question {
                    Confirm::Quit if unsaved => "Quit without saving",
                    Confirm::Quit => "Quit",
                    Confirm::Reset => "Reset training",
                };
                if ui.button(go).clicked() {
                    answer = Some(true);
                }
                if ui.button("Cancel").clicked() {
                    answer = Some(false);
                }
            });
        });
        match (answer, question) {
            (Some(true), Confirm::Quit) => {
                self.confirm = None;
                self.state.training.reset();
                self.quit_confirmed = true;
                ui.ctx().send_viewport_cmd(egui::ViewportCommand::Close);
            }
            (Some(true), Confirm::Reset) => {
                self.confirm = None;
                self.state.reset_training();
            }
            (Some(false), _) => self.confirm = None,
            (None, _) => {}
        }
    }
}
