//! The Training panel: window length, frame rate, the fit check, the warm start from
//! simulation and the mirrored copies; Train, Pause/Resume, Stop and Reset (asked first, [`super::confirm_panel`]);
//! the preparation's and the run's progress, dead units and what the preview shows. Training
//! runs on the trainer's thread ([`super::training`]).

use super::NeuralClothApp;
use super::training::TrainingState;

impl NeuralClothApp {
    /// Training settings, the control buttons and the progress indicator.
    pub fn training_ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Training")
            .default_open(true)
            .show(ui, |ui| {
                let state = self.state.training.state().clone();
                let cfg = &mut self.state.train_config;
                if ui
                    .add(egui::Slider::new(&mut cfg.window_secs, 0.05..=4.0).text("window (s)"))
                    .changed()
                {
                    self.state.window_changed();
                }
                ui.add_enabled(
                    !state.is_active(),
                    egui::Slider::new(
                        &mut self.state.scene.config.training_fps,
                        neural_cloth_train::config::TRAINING_FPS_RANGE,
                    )
                    .integer()
                    .text("fps"),
                );
                ui.add_enabled(
                    !state.is_active(),
                    egui::Checkbox::new(
                        &mut self.state.train_config.fit_check,
                        "check the garment's fit",
                    ),
                )
                .on_hover_text(
                    "Refuse a garment file that clearly does not fit the avatar (use Fit \
                     garment first); untick to train on it as it is",
                );
                ui.horizontal(|ui| {
                    let cfg = &mut self.state.train_config;
                    ui.add_enabled(
                        !state.is_active(),
                        egui::DragValue::new(&mut cfg.warm_start_steps)
                            .range(0..=100_000)
                            .prefix("warm start: ")
                            .suffix(" steps"),
                    )
                    .on_hover_text(
                        "Simulate the training motions once with the reference simulator and \
                         fit the network to them for this many steps at the start, alongside \
                         the paper's loss (0 = off). Costs a simulation of every training \
                         motion (minutes each); brings dynamics the paper's loss alone does \
                         not find from the template (docs/TRAINING.md rounds 21 and 22)",
                    );
                    ui.add_enabled(
                        !state.is_active(),
                        egui::Checkbox::new(&mut cfg.mirror_poses, "mirrored copies"),
                    )
                    .on_hover_text(
                        "Train on left/right mirrored copies of the motions too. With the warm \
                         start, untick it: the copies have no simulated frames and pull the \
                         swing back (docs/TRAINING.md round 22)",
                    );
                    mirror_start_ui(ui, cfg, !state.is_active());
                });
                ui.horizontal_wrapped(|ui| {
                    let can_start = !state.is_active();
                    if ui
                        .add_enabled(can_start, egui::Button::new("Train"))
                        .clicked()
                    {
                        self.state.start_training(self.notifier());
                    }
                    match state {
                        TrainingState::Running => {
                            if ui.button("Pause").clicked() {
                                self.state.training.pause();
                            }
                        }
                        TrainingState::Paused => {
                            if ui.button("Resume").clicked() {
                                self.state.training.resume();
                            }
                        }
                        _ => {
                            ui.add_enabled(false, egui::Button::new("Pause"));
                        }
                    }
                    if ui
                        .add_enabled(
                            matches!(state, TrainingState::Running | TrainingState::Paused),
                            egui::Button::new("Stop"),
                        )
                        .clicked()
                    {
                        self.state.training.stop();
                    }
                    if ui
                        .button("Reset")
                        .on_hover_text("Stop and forget the run (curves, preview weights)")
                        .clicked()
                    {
                        self.request_reset();
                    }
                    self.budget_ui(ui, !state.is_active());
                });
                let p = self.state.training.progress;
                ui.label(format!("State: {}", state.label()));
                let fraction = p.fraction();
                let text = format!(
                    "step {} · {:.1} steps/s · {:.0} s",
                    p.step, p.steps_per_sec, p.elapsed_secs
                );
                ui.add(
                    egui::ProgressBar::new(fraction)
                        .text(text)
                        .animate(matches!(state, TrainingState::Running)),
                );
                if let Some(prep) = &self.state.training.preparing {
                    ui.add(
                        egui::ProgressBar::new(prep.fraction() as f32)
                            .text(&prep.stage)
                            .animate(true),
                    );
                }
                if let TrainingState::Finished(Err(e)) = &state {
                    ui.colored_label(egui::Color32::from_rgb(255, 100, 90), e.to_string());
                }
                if let Some(v) = self.state.training.history.validation.last() {
                    let text = format!(
                        "dead units: {:.0} % (worst layer, step {})",
                        v.dead_units_pct, v.step
                    );
                    if v.dead_units_pct >= self.state.train_config.dead_limit_pct {
                        ui.colored_label(egui::Color32::from_rgb(255, 170, 60), text)
                            .on_hover_text(
                                "the trainer revives dead units when a layer passes the limit",
                            );
                    } else {
                        ui.weak(text);
                    }
                }
                ui.weak(format!("preview: {}", self.state.preview.describe()));
                if self.state.trains_another_scene() {
                    ui.colored_label(
                        egui::Color32::from_rgb(255, 170, 60),
                        "the run trains the scene as it was when Train was pressed; the preview \
                         shows the changed scene, untrained (Reset, then Train, to train it)",
                    );
                }
            });
    }

    /// The run's budget: minutes of training, 0 = until Stop; editable while no run is
    /// active.
    fn budget_ui(&mut self, ui: &mut egui::Ui, enabled: bool) {
        let cfg = &mut self.state.train_config;
        let mut minutes = cfg.max_minutes.unwrap_or(0.0);
        let changed = ui
            .add_enabled(
                enabled,
                egui::DragValue::new(&mut minutes)
                    .range(0.0..=24.0 * 60.0)
                    .speed(0.5)
                    .prefix("stop after: ")
                    .suffix(" min"),
            )
            .on_hover_text(
                "Minutes of training before the run stops on its own (0 = until Stop). A \
                 bounded run starts the mirrored copies part-way and can let its learning \
                 rate fall at the end",
            )
            .changed();
        if changed {
            cfg.max_minutes = (minutes > 0.0).then_some(minutes);
        }
    }
}

/// When the mirrored copies join a bounded run, as a share of it; editable while no run is
/// active and the run has copies and a limit.
fn mirror_start_ui(ui: &mut egui::Ui, cfg: &mut neural_cloth_train::TrainConfig, enabled: bool) {
    let mut percent = cfg.mirror_from_fraction * 100.0;
    let bounded = cfg.max_minutes.is_some() || cfg.max_steps.is_some();
    if ui
        .add_enabled(
            enabled && bounded && cfg.mirror_poses,
            egui::DragValue::new(&mut percent)
                .range(0.0..=90.0)
                .speed(1.0)
                .prefix("from ")
                .suffix(" %"),
        )
        .on_hover_text(
            "Share of a bounded run trained on the motions alone before their mirrored \
             copies join: learned one way first, the part of a motion that depends on its \
             direction (a skirt's twist) carries to the other (docs/TRAINING.md rounds 24 and \
             25). A run without a limit (stop after 0 min) has the copies from the start",
        )
        .changed()
    {
        cfg.mirror_from_fraction = percent / 100.0;
    }
}
