//! The Runs panel: where new runs go, the run shown with its disk use, checkpoint retention
//! (prune now) and Open run.

use neural_cloth_train::retention::{MAX_KEEP_NEWEST, format_bytes};

use super::NeuralClothApp;
use super::file_picker::PickPurpose;

impl NeuralClothApp {
    /// The Runs section: runs folder, the run shown and its disk use, retention, open/recent.
    pub fn runs_ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Runs")
            .default_open(true)
            .show(ui, |ui| {
                let folder = self.state.runs_folder();
                ui.horizontal_wrapped(|ui| {
                    ui.label("New runs go to");
                    ui.monospace(folder.display().to_string())
                        .on_hover_text("each training writes a run-<time> folder here");
                    if ui.button("Change…").clicked() {
                        self.picker.request(PickPurpose::RunsFolder, Some(&folder));
                    }
                });
                self.current_run_ui(ui);
                self.retention_ui(ui);
                if ui
                    .button("Open run…")
                    .on_hover_text("show a run folder's trained model (File > Recent runs)")
                    .clicked()
                {
                    self.picker.request(PickPurpose::OpenRun, Some(&folder));
                }
            });
    }

    /// The run shown, its step and what it uses on disk.
    fn current_run_ui(&mut self, ui: &mut egui::Ui) {
        if self.state.is_loading_run() {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label("opening the run…");
            });
            return;
        }
        let Some(run) = self.state.training.run_dir.clone() else {
            ui.weak("No run yet: train, or open a run folder.");
            return;
        };
        ui.label(format!("Run: {}", run.display()));
        if let Some(usage) = self.state.run_disk_usage() {
            ui.label(format!(
                "{} checkpoints, {} on disk ({} in checkpoints)",
                usage.checkpoints,
                format_bytes(usage.total_bytes),
                format_bytes(usage.checkpoint_bytes)
            ));
        }
    }

    /// Retention settings and pruning the current run by them.
    fn retention_ui(&mut self, ui: &mut egui::Ui) {
        let retention = &mut self.state.runs.retention;
        ui.horizontal(|ui| {
            ui.label("keep the newest");
            ui.add(
                egui::DragValue::new(&mut retention.keep_newest)
                    .range(1..=MAX_KEEP_NEWEST)
                    .suffix(" checkpoints"),
            );
        });
        ui.checkbox(&mut retention.keep_best, "and the best by validation")
            .on_hover_text("the checkpoint with the lowest validation loss is never deleted");
        let can_prune =
            self.state.training.run_dir.is_some() && !self.state.training.state().is_active();
        if ui
            .add_enabled(can_prune, egui::Button::new("Prune run now"))
            .on_hover_text("delete the run's checkpoints these settings do not keep")
            .clicked()
        {
            self.state.prune_run();
        }
    }
}
