//! "Check against simulation" in the Cost panel: iterations, which motions, start / cancel
//! with progress, and the comparison's tables (the state: [`super::sim_check::SimCheck`]).

use neural_cloth_train::compare::CompareReport;

use super::sim_check::{SimCheck, unavailable_reason};

impl super::NeuralClothApp {
    /// "Check against simulation": settings, start/cancel with progress, and the result.
    pub fn sim_check_ui(&mut self, ui: &mut egui::Ui) {
        ui.separator();
        ui.strong("Check against simulation");
        ui.label("The current run's network against the reference simulator on the same motion: distance, swing and the paper's metrics.");
        if self.cost.check.job.is_running() {
            check_progress_ui(ui, &self.cost.check);
        } else {
            let shown = self.state.current_motion().map(|m| m.name.clone());
            let run_dir = self.state.training.run_dir.clone();
            let reason = unavailable_reason(run_dir.as_deref());
            if check_settings_ui(ui, &mut self.cost.check, shown.as_deref(), reason) {
                self.cost
                    .check
                    .check_clicked(run_dir, shown, self.notify.clone());
            }
        }
        match &self.cost.check.job.result {
            Some(Ok(r)) => compare_table_ui(ui, r),
            Some(Err(e)) => {
                ui.colored_label(ui.visuals().error_fg_color, e.to_string());
            }
            None => {}
        }
    }
}

/// The running check's progress and its Cancel button.
fn check_progress_ui(ui: &mut egui::Ui, check: &SimCheck) {
    if let Some(p) = check.progress() {
        let text = format!("{}: {} ({}/{})", p.motion, p.phase.label(), p.done, p.total);
        ui.add(egui::ProgressBar::new(p.fraction() as f32).text(text));
    }
    if ui.button("Cancel check").clicked() {
        check.job.cancel();
    }
    ui.ctx()
        .request_repaint_after(std::time::Duration::from_millis(250));
}

/// Iterations per frame, "only the shown motion" (`shown`: its name), the spread and
/// sensitivity options and the start button, disabled with `unavailable` as its hover
/// text. Returns whether the button was clicked.
fn check_settings_ui(
    ui: &mut egui::Ui,
    check: &mut SimCheck,
    shown: Option<&str>,
    unavailable: Option<String>,
) -> bool {
    ui.horizontal(|ui| {
        let label = ui.label("iterations per frame");
        ui.add(egui::DragValue::new(&mut check.iterations).range(1..=10_000))
            .labelled_by(label.id);
    });
    let label = match shown {
        Some(name) => format!("only the shown motion ('{name}')"),
        None => "only the shown motion".into(),
    };
    ui.add_enabled(
        shown.is_some(),
        egui::Checkbox::new(&mut check.shown_motion_only, label),
    )
    .on_hover_text("Otherwise: every motion of the scene's validation split");
    ui.add_enabled(
        shown.is_some() && check.shown_motion_only,
        egui::Checkbox::new(&mut check.mirrored, "its left/right mirror image"),
    )
    .on_hover_text(
        "Check the shown motion mirrored left to right (a turn the other way): does the \
         network behave alike both ways",
    );
    ui.checkbox(&mut check.spread, "measure the reference's spread")
        .on_hover_text(
            "Also simulate with twice the iterations and show how far the two simulations \
             are apart: whether the reference is converged",
        );
    ui.checkbox(
        &mut check.sensitivity,
        "measure its sensitivity to the start",
    )
    .on_hover_text(
        "Also simulate from the settled garment moved by a micrometre and show how far \
             that is from the reference: a motion whose simulation forks on such a change \
             cannot be matched frame by frame by any model",
    );
    ui.add_enabled(
        unavailable.is_none(),
        egui::Button::new("Check against simulation"),
    )
    .on_disabled_hover_text(unavailable.unwrap_or_default())
    .clicked()
}

/// The comparison as one table per motion.
fn compare_table_ui(ui: &mut egui::Ui, r: &CompareReport) {
    ui.label(format!(
        "step {}, '{}' ({} vertices), {} fps, w = {}, reference {} iterations per frame",
        r.step, r.garment, r.vertices, r.fps, r.options.w, r.options.iterations
    ));
    for m in &r.motions {
        let s = &m.measures;
        ui.label(format!(
            "'{}': {} frames ({} still), reference {}",
            m.name,
            s.frames,
            s.still_frames,
            if m.reference.cached {
                "cached"
            } else {
                "simulated"
            }
        ));
        egui::Grid::new(("compare table", m.name.as_str()))
            .striped(true)
            .show(ui, |ui| {
                for h in ["", "all", "still", "moving"] {
                    ui.strong(h);
                }
                ui.end_row();
                for row in s.rows() {
                    ui.label(row.label);
                    for c in row.cells() {
                        ui.label(c);
                    }
                    ui.end_row();
                }
            });
        egui::Grid::new(("compare metrics", m.name.as_str()))
            .striped(true)
            .show(ui, |ui| {
                for h in ["metric", "network", "simulator"] {
                    ui.strong(h);
                }
                ui.end_row();
                for row in m.metric_rows() {
                    let d = row.decimals;
                    ui.label(row.label);
                    ui.label(format!("{:.d$}", row.network));
                    ui.label(format!("{:.d$}", row.simulator));
                    ui.end_row();
                }
            });
    }
}
