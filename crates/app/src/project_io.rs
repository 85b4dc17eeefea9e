//! Saving and opening project files from the app state (the file format itself is in
//! [`super::project`]).

use std::path::Path;

use super::project::{ProjectError, ProjectFile, ViewSettings};
use super::state::{AppState, Level};

impl AppState {
    /// The project file describing the current setup.
    pub fn to_project(&self) -> ProjectFile {
        ProjectFile {
            scene: self.scene.config.clone(),
            training: self.train_config.clone(),
            runs_folder: self.runs.folder.clone(),
            run: self.current_run(),
            view: ViewSettings {
                w: self.w,
                draw: self.draw,
                x_axis: self.curves.x_axis,
                playback_speed: self.playback.speed,
            },
            ..Default::default()
        }
    }

    /// Saves the setup as a project file and remembers it in the recent files.
    pub fn save_project(&mut self, path: &Path) -> bool {
        let result = self
            .to_project()
            .save(path)
            .and_then(|()| self.recent.push(path));
        let saved = self.project_done(path, result, "saved");
        if saved {
            self.mark_saved();
        }
        saved
    }

    fn project_done(&mut self, path: &Path, result: Result<(), ProjectError>, verb: &str) -> bool {
        match result {
            Ok(()) => {
                self.project_path = Some(path.to_path_buf());
                self.message(Level::Info, format!("{verb} project {}", path.display()));
                true
            }
            Err(e) => {
                self.message(Level::Error, e.to_string());
                false
            }
        }
    }

    /// Opens a project (a version-1 file is converted): shows its scene (avatar, garment and
    /// motions, built in or files, through the io scene loader), applies its settings and
    /// reopens its run (in the background). A file that does not read as a project is refused
    /// before anything changes (the running training and the scene stay); otherwise the
    /// training is reset first. Load errors are shown; what loads is kept.
    pub fn open_project(&mut self, path: &Path) -> bool {
        let project = match ProjectFile::open(path) {
            Ok(p) => p,
            Err(e) => {
                self.message(Level::Error, e.to_string());
                return false;
            }
        };
        self.training.reset();
        self.project_path = Some(path.to_path_buf());
        self.train_config = project.training.clone();
        self.runs.folder = project.runs_folder.clone();
        // Retention is the run's own (RUN/retention.json, read when the run opens); new runs
        // start with the default.
        self.runs.retention = Default::default();
        self.runs.linked = None;
        self.w = project.view.w;
        self.draw = project.view.draw;
        self.curves.x_axis = project.view.x_axis;
        self.playback.speed = project
            .view
            .playback_speed
            .clamp(super::playback::MIN_SPEED, super::playback::MAX_SPEED);
        if !self.open_scene(project.scene.clone()) {
            // The avatar did not load: the scene stays, with the project's settings.
            let config = &mut self.scene.config;
            config.fabric = project.scene.fabric.clone();
            config.effects = project.scene.effects;
            config.training_fps = project.scene.training_fps;
        }
        let result = self.recent.push(path);
        let opened = self.project_done(path, result, "opened");
        // The run is reopened in the background; the project counts as unchanged meanwhile.
        if let Some(run) = &project.run {
            self.open_run(run, false);
        }
        self.mark_saved();
        opened
    }
}
