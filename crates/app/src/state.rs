//! The authoring app's state, independent of any window: the scene (its description with
//! fabric, effects and training rate, and the parts loaded from it), training settings and
//! control, playback, the dynamic weight `w`, view toggles, messages, project and recent files.
//! Every user action is a method here (loading files in [`super::scene_edit`]); the panels only
//! call them.

use std::path::PathBuf;
use std::sync::Arc;

use neural_cloth_core::scene::{Avatar, Garment, Motion, Scene, SceneConfig, Split};
use neural_cloth_physics::FabricParams;
use neural_cloth_render::{DrawOptions, SceneFrame};
use neural_cloth_train::TrainConfig;

use super::error::AppError;
use super::export::ExportSettings;
use super::metrics::{Metric, XAxis};
use super::playback::Playback;
use super::preview::Preview;
use super::project::RecentFiles;
use super::training::{TrainingControl, TrainingRequest};

/// Severity of a message in the status area.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    /// Something happened.
    Info,
    /// Something was repaired or ignored.
    Warning,
    /// Something failed.
    Error,
}

/// A message shown in the status area.
#[derive(Clone, Debug, PartialEq)]
pub struct Message {
    /// Severity.
    pub level: Level,
    /// Text (errors name their file last).
    pub text: String,
}

/// The scene: its description and the parts loaded from it.
#[derive(Clone, Debug)]
pub struct SceneState {
    /// The scene's one description: where avatar, garment and motions come from (motions with
    /// their splits, file paths absolute), effects, fabric and training frame rate. The
    /// project saves it, a run records it, the io scene loader builds the parts from it.
    pub config: SceneConfig,
    /// The avatar; its `motions` are every motion of the scene (the timeline's list).
    pub avatar: Arc<Avatar>,
    /// Split of each motion, parallel to `avatar.motions`.
    pub splits: Vec<Split>,
    /// The garment; None when the description's garment did not load (or does not fit the
    /// avatar).
    pub garment: Option<Arc<Garment>>,
    /// Incremented on every change of avatar, garment or motions.
    pub revision: u64,
}

/// A scene to show: its description and the parts loaded from it.
#[derive(Clone, Debug)]
pub struct SceneParts {
    /// The description.
    pub config: SceneConfig,
    /// The avatar; its `motions` are all the scene's motions.
    pub avatar: Arc<Avatar>,
    /// Split of each motion.
    pub splits: Vec<Split>,
    /// The garment.
    pub garment: Option<Arc<Garment>>,
}

impl SceneParts {
    /// The app's parts of a [`Scene`] loaded from `config`: the scene's motions become the
    /// avatar's list (an avatar file's animations that the scene does not name are not shown).
    pub fn from_scene(scene: Scene, config: SceneConfig) -> Self {
        let mut avatar = scene.avatar;
        let (motions, splits): (Vec<Motion>, Vec<Split>) = scene.motions.into_iter().unzip();
        avatar.motions = motions;
        Self {
            config,
            avatar: Arc::new(avatar),
            splits,
            garment: Some(Arc::new(scene.garment)),
        }
    }
}

/// Text of the typed-path fields (for desktops without a file-dialog service).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TypedPaths {
    /// Avatar file path.
    pub avatar: String,
    /// Garment file path.
    pub garment: String,
    /// Motion file path.
    pub motion: String,
    /// Joint map (TOML) applied when motions load; empty for none.
    pub joint_map: String,
    /// Why the typed joint map was refused (shown under its field); None when it is fine.
    pub joint_map_error: Option<String>,
    /// Up axis of the avatar, garment and motion files loaded next (recorded on each file's
    /// source in the scene description); auto detects it.
    pub up: neural_cloth_core::scene::UpAxis,
    /// Project file path.
    pub project: String,
    /// Run folder path.
    pub run: String,
}

/// Which curves the plot panel shows.
#[derive(Clone, Debug, PartialEq)]
pub struct CurveSettings {
    /// Metrics shown, in [`Metric::ALL`] order.
    pub shown: [bool; 6],
    /// Also draw validation curves.
    pub validation: bool,
    /// Plot a metric whose values span more than a decade on a log axis.
    pub log_scale: bool,
    /// X axis.
    pub x_axis: XAxis,
}

impl Default for CurveSettings {
    fn default() -> Self {
        Self {
            shown: [true, true, true, false, false, false],
            validation: true,
            log_scale: true,
            x_axis: XAxis::Step,
        }
    }
}

impl CurveSettings {
    /// Whether `metric` is shown.
    pub fn is_shown(&self, metric: Metric) -> bool {
        Metric::ALL
            .iter()
            .position(|m| *m == metric)
            .and_then(|k| self.shown.get(k))
            .copied()
            .unwrap_or(false)
    }
}

/// Everything the app shows and edits.
pub struct AppState {
    /// The scene (with its fabric, effects and training frame rate).
    pub scene: SceneState,
    /// Training configuration (the frame rate is the scene's, `scene.config.training_fps`).
    pub train_config: TrainConfig,
    /// Runs: the folder new runs go to, the run shown, recent runs, checkpoint retention.
    pub runs: super::runs::RunsState,
    /// Viewport toggles.
    pub draw: DrawOptions,
    /// Dynamic-code weight of the preview, in [0, 2].
    pub w: f32,
    /// Timeline.
    pub playback: Playback,
    /// Training state machine, progress and metric history.
    pub training: TrainingControl,
    /// The preview model (inference at `w`).
    pub preview: Preview,
    /// Curve panel settings.
    pub curves: CurveSettings,
    /// Export dialog.
    pub export: ExportSettings,
    /// Status messages, newest last (at most 100).
    pub messages: Vec<Message>,
    /// The open project file.
    pub project_path: Option<PathBuf>,
    /// Recent project files.
    pub recent: RecentFiles,
    /// Typed-path fields.
    pub typed: TypedPaths,
    /// Connectivity shared by the frames of one scene revision.
    pub(crate) topology: super::frame_builder::TopologyCache,
    frame: Option<(FrameKey, Arc<SceneFrame>)>,
    frame_revision: u64,
}

impl std::fmt::Debug for AppState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AppState")
            .field("avatar", &self.scene.avatar.name)
            .field(
                "garment",
                &self.scene.garment.as_ref().map(|g| g.name.clone()),
            )
            .field("w", &self.w)
            .field("training", &self.training)
            .finish_non_exhaustive()
    }
}

/// What the shown frame depends on.
#[derive(Clone, Copy, Debug, PartialEq)]
struct FrameKey {
    scene: u64,
    motion: usize,
    time_bits: u32,
    w_bits: u32,
    weights_step: Option<u64>,
    preview_generation: u64,
    heat_map: bool,
    collisions: bool,
}

impl AppState {
    /// A state showing `parts` (the built-in default scene at start-up).
    pub fn new(parts: SceneParts, training: TrainingControl, recent: RecentFiles) -> Self {
        let train_config = TrainConfig::default();
        Self {
            scene: SceneState {
                config: parts.config,
                avatar: parts.avatar,
                splits: parts.splits,
                garment: parts.garment,
                revision: 1,
            },
            train_config,
            runs: super::runs::RunsState::new(recent.store.as_deref()),
            draw: DrawOptions::default(),
            w: 1.0,
            playback: Playback::default(),
            training,
            preview: Preview::default(),
            curves: CurveSettings::default(),
            export: ExportSettings::default(),
            messages: Vec::new(),
            project_path: None,
            recent,
            typed: TypedPaths::default(),
            topology: Default::default(),
            frame: None,
            frame_revision: 0,
        }
    }

    /// Adds a status message.
    pub fn message(&mut self, level: Level, text: impl Into<String>) {
        self.messages.push(Message {
            level,
            text: text.into(),
        });
        if self.messages.len() > 100 {
            self.messages.remove(0);
        }
    }

    /// The most recent error, if the latest message is one.
    pub fn last_error(&self) -> Option<&str> {
        self.messages
            .iter()
            .rev()
            .find(|m| m.level == Level::Error)
            .map(|m| m.text.as_str())
    }

    pub(crate) fn warn_all(&mut self, what: &str, warnings: Vec<String>) {
        for w in warnings {
            self.message(Level::Warning, format!("{what}: {w}"));
        }
    }

    pub(crate) fn scene_changed(&mut self) {
        self.scene.revision += 1;
        self.preview.reset_scene();
        let count = self.scene.avatar.motions.len();
        self.playback.select_motion(self.playback.motion, count);
    }

    /// The scene's fabric.
    pub fn fabric(&self) -> &FabricParams {
        &self.scene.config.fabric
    }

    /// The preset the fabric is, or "custom".
    pub fn fabric_preset(&self) -> &'static str {
        self.fabric().preset_name().unwrap_or("custom")
    }

    /// Replaces the fabric by a named preset.
    pub fn apply_preset(&mut self, name: &str) {
        match FabricParams::preset(name) {
            Ok(f) => {
                self.scene.config.fabric = f;
                self.fabric_changed();
            }
            Err(e) => self.message(Level::Error, e.to_string()),
        }
    }

    /// Sends the fabric to a live run after an edit (invalid values are reported instead).
    pub fn fabric_changed(&mut self) {
        match self.scene.config.fabric.validate() {
            Ok(()) => self.training.set_fabric(&self.scene.config.fabric),
            Err(e) => self.message(Level::Error, e.to_string()),
        }
    }

    /// Applies an edit of the effects: switches off what their needs no longer allow
    /// (friction needs collision and dynamics) and rebuilds the preview (dynamics changes
    /// the network's layout).
    pub fn effects_changed(&mut self) {
        self.scene.config.effects.drop_unmet_needs();
        self.preview.reset_scene();
        self.scene.revision += 1;
    }

    /// True while a run started here trains a scene that has changed since (another garment,
    /// avatar or motion, or other effects): its step counter runs, but its weights no longer
    /// fit the scene on screen, whose preview is untrained.
    pub fn trains_another_scene(&self) -> bool {
        self.training.state().is_active()
            && self
                .training
                .scene_revision
                .is_some_and(|r| r != self.scene.revision)
    }

    /// Stops and forgets the training run (curves, preview weights); its folder stays.
    pub fn reset_training(&mut self) {
        self.training.reset();
        self.preview.reset_scene();
    }

    /// Sends the window length to a live run after an edit.
    pub fn window_changed(&mut self) {
        self.training.set_window(self.train_config.window_secs);
    }

    /// Sets the dynamic weight `w` (clamped to [0, 2]); the shown garment follows at once.
    pub fn set_w(&mut self, w: f32) {
        if w.is_finite() {
            self.w = w.clamp(0.0, 2.0);
        }
    }

    /// The motion shown on the timeline, if the avatar has any.
    pub fn current_motion(&self) -> Option<&Motion> {
        self.scene.avatar.motions.get(self.playback.motion)
    }

    /// Advances playback by `dt_secs` of wall-clock time.
    pub fn advance(&mut self, dt_secs: f32) {
        let duration = self.current_motion().map_or(0.0, |m| m.duration_secs());
        self.playback.advance(dt_secs, duration);
    }

    /// Starts training from the current setup (errors are shown).
    pub fn start_training(&mut self, notify: Arc<dyn Fn() + Send + Sync>) {
        let Some(garment) = self.scene.garment.clone() else {
            self.message(Level::Error, "load a garment before training");
            return;
        };
        let config = self.train_config.clone();
        if let Err(e) = config.validate(self.scene.config.training_fps) {
            self.message(Level::Error, e.to_string());
            return;
        }
        // The trainer makes a fresh `run-<time>` folder under the runs folder.
        let run_dir = self.runs_folder();
        let scene = self.assemble_scene(&garment).and_then(|scene| {
            // What the run records: it must describe a trainable scene.
            self.scene.config.validate()?;
            Ok(scene)
        });
        let scene = match scene {
            Ok(s) => s,
            Err(e) => {
                self.message(Level::Error, format!("cannot start training: {e}"));
                return;
            }
        };
        let request = TrainingRequest {
            scene: Arc::new(scene),
            config,
            run_dir,
            scene_config: self.scene.config.clone(),
        };
        match self.training.start(request, notify) {
            Ok(()) => {
                self.training.scene_revision = Some(self.scene.revision);
                self.message(Level::Info, "training started");
            }
            Err(e) => self.message(Level::Error, format!("cannot start training: {e}")),
        }
    }

    /// The scene as the trainer sees it: avatar, garment, motions with their splits, and the
    /// description's name, effects, fabric and training frame rate.
    pub fn assemble_scene(&self, garment: &Garment) -> Result<Scene, AppError> {
        let mut avatar = (*self.scene.avatar).clone();
        let motions: Vec<(Motion, Split)> = std::mem::take(&mut avatar.motions)
            .into_iter()
            .enumerate()
            .map(|(k, m)| (m, self.scene.splits.get(k).copied().unwrap_or(Split::Train)))
            .collect();
        if !motions.iter().any(|(_, s)| *s == Split::Train) {
            return Err(AppError::Missing("no training motion: load a BVH motion"));
        }
        Ok(self
            .scene
            .config
            .assemble(avatar, garment.clone(), motions)?)
    }

    /// Drains trainer events (once per frame) and hands new weights to the preview.
    pub fn poll_training(&mut self) {
        self.training.poll();
        if let Some((step, weights)) = &self.training.latest_weights {
            self.preview.offer_weights(*step, weights.clone());
        }
    }

    /// The frame to show now, and its revision (unchanged while nothing it depends on
    /// changed, so the viewport uploads nothing).
    pub fn scene_frame(&mut self) -> (Arc<SceneFrame>, u64) {
        self.preview.poll_build();
        let key = FrameKey {
            scene: self.scene.revision,
            motion: self.playback.motion,
            time_bits: self.playback.time_secs.to_bits(),
            w_bits: self.w.to_bits(),
            weights_step: self.preview.weights_step(),
            preview_generation: self.preview.generation(),
            heat_map: self.draw.heat_map,
            collisions: self.draw.collision_points,
        };
        if let Some((k, frame)) = &self.frame
            && *k == key
        {
            return (frame.clone(), self.frame_revision);
        }
        let frame = Arc::new(super::frame_builder::build_frame(self));
        self.frame_revision += 1;
        self.frame = Some((key, frame.clone()));
        (frame, self.frame_revision)
    }
}
