//! What a path chosen in a file dialog does (load a scene part, open or save a project, open
//! a run, set the runs folder or the export path), and the in-app file browser while it is
//! open ([`super::file_picker`]).

use std::path::Path;

use super::NeuralClothApp;
use super::file_picker::PickPurpose;

impl NeuralClothApp {
    /// Does what a path chosen in a file dialog is for.
    pub fn apply_pick(&mut self, purpose: PickPurpose, path: &Path) {
        match purpose {
            PickPurpose::Load(kind) => {
                self.state.load_file(kind, path);
            }
            PickPurpose::OpenProject => {
                self.open_project(path);
            }
            PickPurpose::SaveProject => {
                self.state.save_project(path);
            }
            PickPurpose::OpenRun => {
                self.state.open_run(path, true);
            }
            PickPurpose::RunsFolder => self.state.set_runs_folder(path),
            PickPurpose::ExportPath(format) => self.state.export.set_picked_path(path, format),
        }
    }

    /// Shows the in-app file browser while open and applies what was chosen.
    pub fn file_picker_ui(&mut self, ui: &egui::Ui) {
        self.picker.browser_ui(ui.ctx());
        if let Some((purpose, path)) = self.picker.take_picked() {
            self.apply_pick(purpose, &path);
        }
    }
}
