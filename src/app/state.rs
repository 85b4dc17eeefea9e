//! The authoring app's state, independent of any window: scene, fabric, effects, training
//! settings and control, playback, the dynamic weight `w`, view toggles, messages, project and
//! recent files. Every user action is a method here; the panels only call them.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::physics::FabricParams;
use crate::render::{DrawOptions, SceneFrame};
use crate::scene::{Avatar, Effects, Garment, Motion, Scene, Split};
use crate::train::TrainConfig;

use super::export::ExportSettings;
use super::loading;
use super::metrics::{Metric, XAxis};
use super::playback::Playback;
use super::preview::Preview;
use super::project::{RecentFiles, SceneSources};
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

/// The loaded scene.
#[derive(Clone, Debug)]
pub struct SceneState {
    /// Display name.
    pub name: String,
    /// The avatar; its `motions` are every motion of the scene (the timeline's list).
    pub avatar: Arc<Avatar>,
    /// Split of each motion, parallel to `avatar.motions` (loaded motions train).
    pub splits: Vec<Split>,
    /// The garment, if any.
    pub garment: Option<Arc<Garment>>,
    /// Where avatar, garment and extra motions came from.
    pub sources: SceneSources,
    /// Incremented on every change of avatar, garment or motions.
    pub revision: u64,
}

/// A scene to start from (the built-in default scene, or the parts a project does not name).
#[derive(Clone, Debug)]
pub struct SceneParts {
    /// Display name.
    pub name: String,
    /// The avatar; its `motions` are all the scene's motions.
    pub avatar: Arc<Avatar>,
    /// Split of each motion.
    pub splits: Vec<Split>,
    /// The garment.
    pub garment: Option<Arc<Garment>>,
    /// Declared effects.
    pub effects: Effects,
    /// Fabric parameters.
    pub fabric: FabricParams,
    /// Training frame rate, fps.
    pub training_fps: f32,
}

impl SceneParts {
    /// Splits a [`Scene`] into the app's parts (its motions move into the avatar's list); the
    /// fabric table is parsed by the physics layer.
    pub fn from_scene(scene: Scene) -> Result<Self, String> {
        let mut avatar = scene.avatar;
        let (motions, splits): (Vec<Motion>, Vec<Split>) = scene.motions.into_iter().unzip();
        avatar.motions.extend(motions);
        let mut all_splits = vec![Split::Train; avatar.motions.len() - splits.len()];
        all_splits.extend(splits);
        let fabric = FabricParams::from_table(&scene.fabric).map_err(|e| e.to_string())?;
        Ok(Self {
            name: scene.name,
            avatar: Arc::new(avatar),
            splits: all_splits,
            garment: Some(Arc::new(scene.garment)),
            effects: scene.effects,
            fabric,
            training_fps: scene.training_fps,
        })
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
    /// The scene.
    pub scene: SceneState,
    /// Fabric parameters.
    pub fabric: FabricParams,
    /// Preset the fabric started from.
    pub fabric_preset: String,
    /// Effects the scene declares.
    pub effects: Effects,
    /// Training configuration.
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
        let train_config = TrainConfig {
            fps: parts.training_fps,
            ..TrainConfig::default()
        };
        Self {
            scene: SceneState {
                name: parts.name,
                avatar: parts.avatar,
                splits: parts.splits,
                garment: parts.garment,
                sources: SceneSources::default(),
                revision: 1,
            },
            fabric: parts.fabric,
            fabric_preset: "default".into(),
            effects: parts.effects,
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

    fn warn_all(&mut self, what: &str, warnings: Vec<String>) {
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

    /// Loads an avatar (glTF/GLB) and re-binds the current garment to it. On failure the
    /// scene is unchanged and the error is shown; returns whether it worked.
    pub fn load_avatar(&mut self, path: &Path) -> bool {
        let loaded = match loading::load_avatar(path, self.train_config.fps) {
            Ok(l) => l,
            Err(e) => {
                self.message(Level::Error, e);
                return false;
            }
        };
        let avatar = loaded.value;
        // The old garment template was fitted to the old body: keep it only if it re-binds.
        let garment = match (&self.scene.garment, &self.scene.sources.garment) {
            (Some(_), Some(garment_path)) => match loading::load_garment(garment_path, &avatar) {
                Ok(g) => Some(g.value),
                Err(e) => {
                    self.message(Level::Warning, format!("garment dropped: {e}"));
                    None
                }
            },
            _ => None,
        };
        self.message(
            Level::Info,
            format!(
                "loaded avatar '{}' ({} motions)",
                avatar.name,
                avatar.motions.len()
            ),
        );
        self.warn_all("avatar", loaded.warnings);
        self.scene.splits = vec![Split::Train; avatar.motions.len()];
        self.scene.name = avatar.name.clone();
        self.scene.avatar = avatar;
        if garment.is_none() {
            self.scene.sources.garment = None;
        }
        self.scene.garment = garment;
        self.scene.sources.avatar = Some(path.to_path_buf());
        self.scene.sources.motions.clear();
        self.scene_changed();
        true
    }

    /// Loads a garment (OBJ/glTF) onto the current avatar; errors are shown, not raised.
    pub fn load_garment(&mut self, path: &Path) -> bool {
        match loading::load_garment(path, &self.scene.avatar) {
            Ok(loaded) => {
                self.message(
                    Level::Info,
                    format!(
                        "loaded garment '{}' ({} vertices)",
                        loaded.value.name,
                        loaded.value.vertex_count()
                    ),
                );
                self.warn_all("garment", loaded.warnings);
                self.scene.garment = Some(loaded.value);
                self.scene.sources.garment = Some(path.to_path_buf());
                self.scene_changed();
                true
            }
            Err(e) => {
                self.message(Level::Error, e);
                false
            }
        }
    }

    /// Loads a BVH motion, retargets it onto the avatar and shows it.
    pub fn load_motion(&mut self, path: &Path) -> bool {
        match loading::load_motion(path, &self.scene.avatar, self.train_config.fps) {
            Ok(loaded) => {
                let mut avatar = (*self.scene.avatar).clone();
                let motion: Motion = loaded.value;
                self.message(
                    Level::Info,
                    format!(
                        "loaded motion '{}' ({:.1} s)",
                        motion.name,
                        motion.duration_secs()
                    ),
                );
                self.warn_all("motion", loaded.warnings);
                avatar.motions.push(motion);
                self.scene
                    .splits
                    .resize(avatar.motions.len() - 1, Split::Train);
                self.scene.splits.push(Split::Train);
                let index = avatar.motions.len() - 1;
                self.scene.avatar = Arc::new(avatar);
                self.scene.sources.motions.push(path.to_path_buf());
                self.scene_changed();
                self.playback.select_motion(index, index + 1);
                true
            }
            Err(e) => {
                self.message(Level::Error, e);
                false
            }
        }
    }

    /// Replaces the fabric by a named preset.
    pub fn apply_preset(&mut self, name: &str) {
        match FabricParams::preset(name) {
            Ok(f) => {
                self.fabric = f;
                self.fabric_preset = name.to_string();
                self.fabric_changed();
            }
            Err(e) => self.message(Level::Error, e.to_string()),
        }
    }

    /// Sends the fabric to a live run after an edit (invalid values are reported instead).
    pub fn fabric_changed(&mut self) {
        match self.fabric.validate() {
            Ok(()) => self.training.set_fabric(&self.fabric),
            Err(e) => self.message(Level::Error, e.to_string()),
        }
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
        if let Err(e) = self.fabric.validate() {
            self.message(Level::Error, e.to_string());
            return;
        }
        if let Err(e) = self.train_config.validate() {
            self.message(Level::Error, e.to_string());
            return;
        }
        // The trainer makes a fresh `run-<time>` folder under the runs folder.
        let run_dir = self.runs_folder();
        let scene = match self.assemble_scene(&garment) {
            Ok(s) => s,
            Err(e) => {
                self.message(Level::Error, format!("cannot start training: {e}"));
                return;
            }
        };
        let request = TrainingRequest {
            scene: Arc::new(scene),
            fabric: self.fabric.clone(),
            config: self.train_config.clone(),
            run_dir,
            sources: self.scene.sources.clone(),
        };
        match self.training.start(request, notify) {
            Ok(()) => self.message(Level::Info, "training started"),
            Err(e) => self.message(Level::Error, format!("cannot start training: {e}")),
        }
    }

    /// The scene as the trainer sees it: avatar, garment, motions with their splits, effects,
    /// fabric and training frame rate.
    pub fn assemble_scene(&self, garment: &Garment) -> Result<Scene, String> {
        let mut avatar = (*self.scene.avatar).clone();
        let motions: Vec<(Motion, Split)> = std::mem::take(&mut avatar.motions)
            .into_iter()
            .enumerate()
            .map(|(k, m)| (m, self.scene.splits.get(k).copied().unwrap_or(Split::Train)))
            .collect();
        if !motions.iter().any(|(_, s)| *s == Split::Train) {
            return Err("no training motion: load a BVH motion".into());
        }
        let fabric = toml::Table::try_from(&self.fabric).map_err(|e| e.to_string())?;
        Scene::new(
            self.scene.name.clone(),
            avatar,
            garment.clone(),
            motions,
            self.effects,
            fabric,
            self.train_config.fps,
        )
        .map_err(|e| e.to_string())
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
