//! The "Cost" panel: the budget, Measure / Cancel with the experiment's progress, and the
//! accuracy/time table of [`super::cost::CostState`]; below it "Check against simulation"
//! ([`super::sim_check_panel`]).

use neural_cloth_lab::report::accuracy::CostResult;

impl super::NeuralClothApp {
    /// The Cost panel: budget, run/cancel, progress and the accuracy/time table.
    pub fn cost_ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Cost").default_open(false).show(ui, |ui| {
            ui.label("What accuracy costs in time on this scene: the reference simulator at several iteration budgets against the network trained for a few durations.");
            ui.horizontal(|ui| {
                ui.add(egui::Slider::new(&mut self.cost.budget_secs, 30.0..=1800.0).logarithmic(true).suffix(" s").text("budget"));
            });
            if self.cost.job.is_running() {
                if let Some(p) = self.cost.job.progress() {
                    ui.add(egui::ProgressBar::new(p.fraction as f32).text(format!("{} {}", p.phase, p.detail)));
                }
                if ui.button("Cancel").clicked() {
                    self.cost.job.cancel();
                }
                ui.ctx().request_repaint_after(std::time::Duration::from_millis(250));
            } else if ui.button("Measure").clicked() {
                self.cost.measure(&self.state, self.notify.clone());
            }
            match &self.cost.job.result {
                Some(Ok(r)) => cost_table_ui(ui, r),
                Some(Err(e)) => {
                    ui.colored_label(ui.visuals().error_fg_color, e.to_string());
                }
                None => {}
            }
            self.sim_check_ui(ui);
        });
    }
}

/// The result as a table.
fn cost_table_ui(ui: &mut egui::Ui, r: &CostResult) {
    ui.label(format!(
        "{}: '{}', {} frames, {} vertices; reference {} iterations ({:.0} ms/frame)",
        r.scene,
        r.motion,
        r.clip_frames,
        r.vertices,
        r.reference_iterations,
        r.reference.ms_per_frame
    ));
    egui::Grid::new("cost table").striped(true).show(ui, |ui| {
        for h in [
            "method", "ms/frame", "mean mm", "p95 mm", "residual", "speed-up",
        ] {
            ui.strong(h);
        }
        ui.end_row();
        for p in &r.points {
            ui.label(&p.label);
            ui.label(format!("{:.2}", p.ms_per_frame));
            ui.label(format!("{:.1}", p.mean_mm));
            ui.label(format!("{:.1}", p.p95_mm));
            ui.label(format!("{:.1}", p.residual_rms));
            ui.label(
                p.speedup
                    .as_ref()
                    .map(|s| format!("{:.0}×", s.factor))
                    .unwrap_or_else(|| "—".into()),
            );
            ui.end_row();
        }
    });
}
