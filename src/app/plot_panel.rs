//! The training section (window, fps, train/pause/resume/stop/reset, progress) and the live
//! metric curves (egui_plot; train and validation; x axis step or wall-clock time).

use egui_plot::{Line, LineStyle, Plot};

use super::NeuralClothApp;
use super::metrics::{Metric, Split, XAxis, series};
use super::training::TrainingState;

/// Colour of each metric's curve, in [`Metric::ALL`] order.
pub const METRIC_COLORS: [egui::Color32; 6] = [
    egui::Color32::from_rgb(90, 170, 255),
    egui::Color32::from_rgb(250, 170, 60),
    egui::Color32::from_rgb(240, 90, 90),
    egui::Color32::from_rgb(120, 210, 120),
    egui::Color32::from_rgb(200, 130, 230),
    egui::Color32::from_rgb(160, 160, 160),
];

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
                    egui::Slider::new(&mut self.state.train_config.fps, 5.0..=120.0)
                        .integer()
                        .text("fps"),
                );
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
                        self.state.training.reset();
                        self.state.preview.reset_scene();
                    }
                });
                let p = self.state.training.progress;
                ui.label(format!("State: {}", state.label()));
                let fraction = match p.max_steps {
                    Some(m) if m > 0 => (p.step as f32 / m as f32).clamp(0.0, 1.0),
                    _ => 0.0,
                };
                let text = format!(
                    "step {} · {:.1} steps/s · {:.0} s",
                    p.step, p.steps_per_sec, p.elapsed_secs
                );
                ui.add(
                    egui::ProgressBar::new(fraction)
                        .text(text)
                        .animate(state == TrainingState::Running),
                );
                if let TrainingState::Finished(Err(e)) = &state {
                    ui.colored_label(egui::Color32::from_rgb(255, 100, 90), e);
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
            });
    }

    /// Metric curves of the current run: one small plot per shown metric (each with its own
    /// scale), training solid and validation dashed.
    pub fn plot_ui(&mut self, ui: &mut egui::Ui) {
        let curves = &mut self.state.curves;
        ui.horizontal_wrapped(|ui| {
            ui.strong("Metrics");
            for (k, metric) in Metric::ALL.iter().enumerate() {
                if let Some(shown) = curves.shown.get_mut(k) {
                    ui.checkbox(shown, metric.label());
                }
            }
        });
        ui.horizontal(|ui| {
            ui.checkbox(&mut curves.validation, "validation (dashed)");
            ui.separator();
            ui.label("x axis:");
            ui.selectable_value(&mut curves.x_axis, XAxis::Step, "step");
            ui.selectable_value(&mut curves.x_axis, XAxis::WallClock, "wall-clock (s)");
        });
        let history = &self.state.training.history;
        if history.train.is_empty() && history.validation.is_empty() {
            ui.centered_and_justified(|ui| {
                ui.weak("No metrics yet: press Train.");
            });
            return;
        }
        let x_axis = curves.x_axis;
        let shown: Vec<(usize, Metric)> = Metric::ALL
            .iter()
            .copied()
            .enumerate()
            .filter(|(_, m)| curves.is_shown(*m))
            .collect();
        if shown.is_empty() {
            return;
        }
        let validation = curves.validation;
        ui.columns(shown.len(), |columns| {
            for (column, (k, metric)) in columns.iter_mut().zip(&shown) {
                let color = METRIC_COLORS
                    .get(*k)
                    .copied()
                    .unwrap_or(egui::Color32::GRAY);
                column.vertical_centered(|ui| ui.small(metric.label()));
                let train = Line::new("train", series(history, Split::Train, *metric, x_axis))
                    .color(color)
                    .width(1.5);
                let val_points = series(history, Split::Validation, *metric, x_axis);
                let height = column.available_height().max(40.0);
                Plot::new(metric.label())
                    .height(height)
                    .y_axis_min_width(28.0)
                    .allow_scroll(false)
                    .show(column, |plot| {
                        plot.line(train);
                        if validation && !val_points.is_empty() {
                            plot.line(
                                Line::new("validation", val_points)
                                    .color(color)
                                    .style(LineStyle::dashed_dense())
                                    .width(1.5),
                            );
                        }
                    });
            }
        });
    }
}
