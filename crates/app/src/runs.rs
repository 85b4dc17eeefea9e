//! Runs belong to the project: where new runs go (a folder the user sees and can change), the
//! run the project shows (opened from a run folder, or reopened with the project, on a
//! background thread), the recent runs, checkpoint retention with the disk use, and whether
//! there is unsaved work to ask about before quitting or resetting.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use neural_cloth_core::scene::SceneConfig;
use neural_cloth_train::resume::recorded_config;
use neural_cloth_train::retention::{DiskUsage, Retention};
use neural_cloth_train::trained::refuse_changed_parts;
use neural_cloth_train::{RunDir, TrainedModel, load_trained};

use super::background::BackgroundJob;
use super::project::{ProjectFile, RecentFiles};
use super::state::{AppState, Level, SceneParts};

/// File of the recent-runs list, beside the recent-projects list.
pub const RECENT_RUNS_FILE: &str = "recent_runs.json";
/// How often the shown disk use of the current run is measured again.
pub const DISK_REFRESH_SECS: f64 = 2.0;

/// A run folder's trained model loading on its own thread.
struct RunLoad {
    job: BackgroundJob<(), TrainedModel>,
    path: PathBuf,
    /// Show the run's own scene (Open run); otherwise keep the project's scene and take the
    /// weights only when they were trained on its garment.
    replace_scene: bool,
}

/// The runs part of the app's state.
#[derive(Default)]
pub struct RunsState {
    /// The folder new runs are written under, as chosen; None: [`AppState::default_runs_folder`].
    pub folder: Option<PathBuf>,
    /// Which checkpoints a run keeps (written into the current run's folder).
    pub retention: Retention,
    /// Recently opened or trained runs, newest first.
    pub recent: RecentFiles,
    /// The run the project refers to while none is shown (being opened, or failed to open).
    pub linked: Option<PathBuf>,
    load: Option<RunLoad>,
    /// The run and policy last written to its `retention.json`.
    synced: Option<(PathBuf, Retention)>,
    /// The current run's disk use, when it was measured.
    disk: Option<(PathBuf, Instant, DiskUsage)>,
    /// The project as last saved or opened (None: as the app started).
    pub(crate) saved: Option<ProjectFile>,
    /// Requests a repaint when a run finished loading.
    pub notify: Option<Arc<dyn Fn() + Send + Sync>>,
}

impl std::fmt::Debug for RunsState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RunsState")
            .field("folder", &self.folder)
            .field("retention", &self.retention)
            .field("linked", &self.linked)
            .field("loading", &self.load.as_ref().map(|l| l.path.clone()))
            .finish_non_exhaustive()
    }
}

impl RunsState {
    /// Runs state whose recent-runs list is kept beside the recent-projects list `store`.
    pub fn new(recent_projects_store: Option<&Path>) -> Self {
        let store = recent_projects_store.map(|s| s.with_file_name(RECENT_RUNS_FILE));
        Self {
            recent: RecentFiles::load(store),
            ..Default::default()
        }
    }
}

/// The user's data folder for neural-cloth: `$XDG_DATA_HOME/neural-cloth` or
/// `~/.local/share/neural-cloth`; None when neither variable is set.
pub fn user_data_dir() -> Option<PathBuf> {
    let data = std::env::var_os("XDG_DATA_HOME")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".local/share")))?;
    Some(data.join("neural-cloth"))
}

/// Whether two scene descriptions name the same avatar, garment and motions (with their
/// splits), whatever their name, effects, fabric and training rate.
fn same_sources(a: &SceneConfig, b: &SceneConfig) -> bool {
    a.avatar == b.avatar && a.garment == b.garment && a.motions == b.motions
}

impl AppState {
    /// Where new runs go unless the user chose a folder: `runs/` beside the saved project,
    /// else `runs/` in the user data folder, else `runs/` in the working folder.
    pub fn default_runs_folder(&self) -> PathBuf {
        let beside_project = self
            .project_path
            .as_ref()
            .and_then(|p| p.parent())
            .map(|d| d.join("runs"));
        beside_project
            .or_else(|| user_data_dir().map(|d| d.join("runs")))
            .unwrap_or_else(|| PathBuf::from("runs"))
    }

    /// The folder new runs are written under.
    pub fn runs_folder(&self) -> PathBuf {
        self.runs
            .folder
            .clone()
            .unwrap_or_else(|| self.default_runs_folder())
    }

    /// Chooses the folder new runs are written under (the current run stays where it is).
    pub fn set_runs_folder(&mut self, folder: &Path) {
        let folder = std::path::absolute(folder).unwrap_or_else(|_| folder.to_path_buf());
        self.message(Level::Info, format!("new runs go to {}", folder.display()));
        self.runs.folder = Some(folder);
    }

    /// The run shown (trained here or opened), or the one the project refers to.
    pub fn current_run(&self) -> Option<PathBuf> {
        self.training
            .run_dir
            .clone()
            .or_else(|| self.runs.linked.clone())
    }

    /// True while a run folder is being opened.
    pub fn is_loading_run(&self) -> bool {
        self.runs.load.is_some()
    }

    /// Opens the trained model of the run folder `path` on a background thread (see
    /// [`Self::poll_run_load`]). With `replace_scene` the app shows the run's own scene
    /// (avatar, garment, motions with their splits) and settings (fabric, effects, training);
    /// otherwise (a project reopening its run) it keeps its settings, takes the run's scene
    /// when the run was trained on the same files, and otherwise shows the weights only when
    /// they were trained on its garment (with its skin weights) and avatar. Refused while a
    /// training runs.
    pub fn open_run(&mut self, path: &Path, replace_scene: bool) -> bool {
        if self.training.state().is_active() {
            self.message(Level::Error, "stop the training before opening another run");
            return false;
        }
        let path = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
        let notify = self.runs.notify.clone().unwrap_or_else(|| Arc::new(|| {}));
        let folder = path.clone();
        let job = BackgroundJob::spawn("neural-cloth-open-run", (), notify, move |_| {
            Ok(load_trained(&folder)?)
        });
        match job {
            Ok(job) => {
                self.runs.linked = Some(path.clone());
                self.message(Level::Info, format!("opening run {}", path.display()));
                self.runs.load = Some(RunLoad {
                    job,
                    path,
                    replace_scene,
                });
                true
            }
            Err(e) => {
                self.message(Level::Error, format!("cannot open the run: {e}"));
                false
            }
        }
    }

    /// Waits (up to `timeout`) for a run being opened, then applies it; for tests and tools.
    pub fn wait_for_run(&mut self, timeout: Duration) -> bool {
        let end = Instant::now() + timeout;
        while self.runs.load.is_some() && Instant::now() < end {
            self.poll_run_load();
            std::thread::sleep(Duration::from_millis(20));
        }
        self.runs.load.is_none()
    }

    /// Applies a run that finished loading (never blocks on one still loading).
    pub fn poll_run_load(&mut self) {
        if !self.runs.load.as_ref().is_some_and(|l| l.job.is_finished()) {
            return;
        }
        let Some(load) = self.runs.load.take() else {
            return;
        };
        match load.job.join() {
            Ok(trained) => self.apply_trained(trained, load.replace_scene),
            Err(e) => self.message(Level::Error, format!("cannot open the run: {e}")),
        }
    }

    /// Shows a loaded run: its scene (with `replace_scene`), curves, step and weights.
    fn apply_trained(&mut self, trained: TrainedModel, replace_scene: bool) {
        let TrainedModel {
            meta,
            scene,
            artifact,
            step,
            run,
            warnings,
            ..
        } = trained;
        // The run's scene is the one its weights fit: shown when asked (Open run). A project
        // reopening its run shows the weights on its own parts when they are those the run
        // was trained on: the same sources, or (checked below) the same avatar and garment.
        let recorded = recorded_config(&run);
        let same_sources = recorded
            .as_ref()
            .is_ok_and(|r| same_sources(r, &self.scene.config));
        if replace_scene {
            let mut config = match recorded {
                Ok(config) => config,
                Err(e) => {
                    self.message(Level::Error, format!("cannot show the run's scene: {e}"));
                    return;
                }
            };
            // The rate it trained at (the recorded scene holds its fabric and effects).
            config.training_fps = meta.training_fps;
            self.train_config = meta.train.clone();
            self.show_parts(SceneParts::from_scene(scene, config));
        } else if !(same_sources && self.scene.garment.is_some()) {
            // The weights alone, on the project's own parts: only when they are the garment
            // (with its skin weights) and the avatar the run was trained on.
            let refused = match &self.scene.garment {
                Some(garment) => {
                    refuse_changed_parts(&meta, &self.scene.avatar, garment, &run.root)
                        .err()
                        .map(|e| e.to_string())
                }
                None => Some(format!(
                    "the project has no garment; the run was trained on '{}'",
                    meta.garment_name
                )),
            };
            if let Some(why) = refused {
                self.message(
                    Level::Warning,
                    format!(
                        "the run's weights do not fit the project's scene ({why}); open it with \
                         File > Open run to see its own scene"
                    ),
                );
                return;
            }
        }
        self.training
            .show_run(run.root.clone(), step, run.history(), Arc::new(artifact));
        match run.retention() {
            Ok(retention) => self.runs.retention = retention,
            Err(e) => self.message(
                Level::Warning,
                format!("checkpoints are kept until the policy is fixed or saved again: {e}"),
            ),
        }
        self.runs.synced = Some((run.root.clone(), self.runs.retention));
        self.runs.linked = Some(run.root.clone());
        self.runs.disk = None;
        for w in warnings {
            self.message(Level::Warning, format!("run: {w}"));
        }
        if let Err(e) = self.runs.recent.push(&run.root) {
            self.message(Level::Warning, e.to_string());
        }
        self.message(
            Level::Info,
            format!("opened run {} at step {step}", run.root.display()),
        );
    }

    /// Writes the retention policy into the current run's folder when it changed (the trainer
    /// follows it from its next checkpoint); called once per frame.
    pub fn sync_retention(&mut self) {
        let Some(run) = self.training.run_dir.clone().filter(|r| r.is_dir()) else {
            return;
        };
        let wanted = (run.clone(), self.runs.retention);
        if self.runs.synced.as_ref() == Some(&wanted) {
            return;
        }
        self.runs.synced = Some(wanted);
        if let Err(e) = (RunDir { root: run }).set_retention(self.runs.retention) {
            self.message(Level::Error, format!("cannot set the run's retention: {e}"));
        }
    }

    /// Disk use of the current run, measured at most every [`DISK_REFRESH_SECS`].
    pub fn run_disk_usage(&mut self) -> Option<DiskUsage> {
        let run = self.training.run_dir.clone().filter(|r| r.is_dir())?;
        let fresh =
            self.runs.disk.as_ref().is_some_and(|(p, at, _)| {
                *p == run && at.elapsed().as_secs_f64() < DISK_REFRESH_SECS
            });
        if !fresh {
            let usage = RunDir { root: run.clone() }.disk_usage();
            self.runs.disk = Some((run, Instant::now(), usage));
        }
        self.runs.disk.as_ref().map(|(_, _, u)| *u)
    }

    /// Deletes the current run's checkpoints that the retention policy does not keep (not
    /// while it trains: the trainer prunes by the same policy at its next checkpoint).
    pub fn prune_run(&mut self) {
        let Some(run) = self.training.run_dir.clone() else {
            return;
        };
        if self.training.state().is_active() {
            self.message(
                Level::Warning,
                "the running training prunes at its next checkpoint",
            );
            return;
        }
        let run = RunDir { root: run };
        let before = run.disk_usage().total_bytes;
        // Without a readable history no checkpoint would count as the best: prune nothing.
        let history = match run.try_history() {
            Ok(history) => history,
            Err(e) => {
                self.message(Level::Error, format!("nothing pruned: {e}"));
                return;
            }
        };
        let deleted = run.prune_with(self.runs.retention, &history);
        let freed = before.saturating_sub(run.disk_usage().total_bytes);
        self.runs.disk = None;
        self.message(
            Level::Info,
            format!(
                "deleted {} checkpoints, {} freed: {}",
                deleted.len(),
                neural_cloth_train::retention::format_bytes(freed),
                run.root.display()
            ),
        );
    }

    /// True when the setup or the shown run differs from the project as last saved or opened
    /// (or, before either, from the app's start).
    pub fn has_unsaved_changes(&self) -> bool {
        self.runs
            .saved
            .as_ref()
            .is_some_and(|saved| *saved != self.to_project())
    }

    /// Records the current setup as saved (after saving or opening a project, and at start).
    pub fn mark_saved(&mut self) {
        self.runs.saved = Some(self.to_project());
    }
}
