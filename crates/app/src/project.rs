//! Project files: the whole setup (the scene description, the training config, runs folder,
//! the run shown, view settings) as one human-edited TOML file, plus the recent-files list
//! (machine-written JSON). The scene is a [`SceneConfig`], the same description a scene file
//! holds and a run records, under `[scene]`. Paths inside a project are stored relative to the
//! project file when they lie below its folder, and resolved against it when opened. Files of
//! the first layout (version 1) are read and converted ([`super::project_v1`]).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use neural_cloth_core::scene::SceneConfig;
use neural_cloth_render::DrawOptions;
use neural_cloth_train::TrainConfig;

use super::metrics::XAxis;

/// Current project format version (2: the scene is a [`SceneConfig`]; 1: scene sources,
/// fabric and effects apart, still read). Version-2 files written before issue 14 also carry
/// `training.fps` (equal to `scene.training_fps`): read and dropped (`take_training_fps`);
/// files without it stay version 2: earlier builds took the rate from the scene too, but
/// refuse any training setting they do not know (e.g. `precondition_stiffness`, round 7).
pub const PROJECT_VERSION: u32 = 2;
/// Extension offered for project files.
pub const PROJECT_EXTENSION: &str = "toml";
/// Entries kept in the recent-files list.
pub const MAX_RECENT: usize = 10;

/// Errors reading or writing project and recent-files files.
#[derive(Debug, thiserror::Error)]
pub enum ProjectError {
    /// The file could not be read.
    #[error("cannot read project ({source}): {}", path.display())]
    Read {
        /// The I/O error.
        #[source]
        source: std::io::Error,
        /// The file.
        path: PathBuf,
    },
    /// The file could not be written.
    #[error("cannot write project ({source}): {}", path.display())]
    Write {
        /// The I/O error.
        #[source]
        source: std::io::Error,
        /// The file.
        path: PathBuf,
    },
    /// The project (or the recent-files list) cannot be put into text to be written.
    #[error("cannot write the project: {reason}: {}", path.display())]
    Encode {
        /// What could not be encoded.
        #[source]
        reason: InvalidProject,
        /// The file.
        path: PathBuf,
    },
    /// The file is not a valid project.
    #[error("invalid project file: {reason}: {}", path.display())]
    Parse {
        /// What is wrong.
        #[source]
        reason: InvalidProject,
        /// The file.
        path: PathBuf,
    },
}

/// What makes a project's content invalid (the file it came from is added by
/// [`ProjectError::Parse`]).
#[derive(Debug, thiserror::Error)]
pub enum InvalidProject {
    /// The text is not TOML, or not a project's layout.
    #[error(transparent)]
    Toml(#[from] toml::de::Error),
    /// The project cannot be written as TOML.
    #[error(transparent)]
    Serialize(#[from] toml::ser::Error),
    /// The recent-files list cannot be written as JSON.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// A format version this build does not read.
    #[error("version {found} (this build reads versions 1 to {PROJECT_VERSION})")]
    Version {
        /// The `version` value as written (empty when it is not a number).
        found: String,
    },
    /// The `training.fps` of an earlier file is not a number.
    #[error("training.fps = {found} is not a number")]
    TrainingFps {
        /// The value as written.
        found: String,
    },
    /// The scene description holds a value out of range.
    #[error("scene: {0}")]
    Scene(#[from] neural_cloth_core::scene::config::ConfigError),
    /// A training setting is out of range.
    #[error("training: {0}")]
    Training(#[from] neural_cloth_train::config::ConfigError),
    /// The view's dynamic weight is out of range.
    #[error("view.w = {0} is outside [0, 2]")]
    ViewW(f32),
    /// The playback speed is not a finite number.
    #[error("view.playback_speed = {0} is not a finite number")]
    PlaybackSpeed(f32),
    /// A version-1 project could not be converted.
    #[error("version 1 project: {0}")]
    Version1(Box<InvalidProject>),
}

/// Viewport and panel settings saved with a project.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ViewSettings {
    /// Dynamic-code weight `w` of the preview, in [0, 2]; default 1.
    pub w: f32,
    /// Viewport toggles.
    pub draw: DrawOptions,
    /// X axis of the metric curves.
    pub x_axis: XAxis,
    /// Playback speed (× real time), in [0.1, 4]; default 1.
    pub playback_speed: f32,
}

impl Default for ViewSettings {
    fn default() -> Self {
        Self {
            w: 1.0,
            draw: DrawOptions::default(),
            x_axis: XAxis::Step,
            playback_speed: 1.0,
        }
    }
}

/// A saved authoring session.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ProjectFile {
    /// Format version, [`PROJECT_VERSION`].
    pub version: u32,
    /// The scene: avatar, garment and motions (built in or files, motions with their splits),
    /// effects, fabric and the training frame rate.
    pub scene: SceneConfig,
    /// Training configuration (window, batch, schedule); the frame rate is the scene's
    /// `training_fps` (a `fps` key of earlier files is dropped when read).
    pub training: TrainConfig,
    /// Folder new runs are written under; None = `runs/` beside the project file. Read from
    /// `run_dir` too (its name in earlier files).
    #[serde(alias = "run_dir")]
    pub runs_folder: Option<PathBuf>,
    /// The run whose trained model the project shows (reopened with the project).
    pub run: Option<PathBuf>,
    /// `[retention]` of earlier project files: read and ignored, never written (a run's
    /// checkpoint retention lives in its own folder, `RUN/retention.json`).
    #[serde(rename = "retention", skip_serializing)]
    pub old_retention: Option<serde::de::IgnoredAny>,
    /// View settings.
    pub view: ViewSettings,
}

impl Default for ProjectFile {
    fn default() -> Self {
        Self {
            version: PROJECT_VERSION,
            scene: SceneConfig::default_scene(),
            training: TrainConfig::default(),
            runs_folder: None,
            run: None,
            old_retention: None,
            view: ViewSettings::default(),
        }
    }
}

/// `path` relative to `base` when it lies below it, else unchanged.
fn relative_to(path: &Path, base: &Path) -> PathBuf {
    path.strip_prefix(base)
        .map(Path::to_path_buf)
        .unwrap_or_else(|_| path.to_path_buf())
}

/// `path` resolved against `base` when relative.
fn resolve(path: &Path, base: &Path) -> PathBuf {
    if path.is_relative() {
        base.join(path)
    } else {
        path.to_path_buf()
    }
}

/// Writes `bytes` to a temporary file beside `path`, then renames it over `path`.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ProjectError> {
    let err = |source| ProjectError::Write {
        source,
        path: path.to_path_buf(),
    };
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(err)?;
    }
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    std::fs::write(&tmp, bytes).map_err(err)?;
    std::fs::rename(&tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        err(e)
    })
}

impl ProjectFile {
    /// Applies `f` to every path in the project.
    fn map_paths(&mut self, f: impl Fn(&Path) -> PathBuf) {
        self.scene.map_paths(&f);
        for p in self.runs_folder.iter_mut().chain(self.run.iter_mut()) {
            *p = f(p);
        }
    }

    /// Serialises to TOML with paths as given.
    pub fn to_toml(&self) -> Result<String, InvalidProject> {
        Ok(toml::to_string_pretty(self)?)
    }

    /// Writes the project to `path` (atomically), storing paths relative to its folder.
    pub fn save(&self, path: &Path) -> Result<(), ProjectError> {
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let base = std::path::absolute(&base).unwrap_or(base);
        let mut copy = self.clone();
        copy.map_paths(|p| {
            relative_to(
                &std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf()),
                &base,
            )
        });
        let text = copy.to_toml().map_err(|reason| ProjectError::Encode {
            reason,
            path: path.to_path_buf(),
        })?;
        write_atomic(path, format!("# neural-cloth project\n{text}").as_bytes())
    }

    /// Reads a project (converting the version-1 layout), checks its version and values, and
    /// resolves its paths against its folder.
    pub fn open(path: &Path) -> Result<Self, ProjectError> {
        let text = std::fs::read_to_string(path).map_err(|source| ProjectError::Read {
            source,
            path: path.to_path_buf(),
        })?;
        let parse = |reason: InvalidProject| ProjectError::Parse {
            reason,
            path: path.to_path_buf(),
        };
        let mut table: toml::Table = text.parse().map_err(|e: toml::de::Error| parse(e.into()))?;
        let version = match table.get("version") {
            // Version 1 wrote every key but let a hand-edited file leave any out: its layout
            // (fabric and effects at the top, the scene's sources as plain strings) tells.
            None if super::project_v1::looks_like_v1(&table) => Some(1),
            None => Some(PROJECT_VERSION),
            Some(v) => v.as_integer().and_then(|v| u32::try_from(v).ok()),
        };
        let mut project = match version {
            Some(1) => super::project_v1::convert(table).map_err(parse)?,
            Some(PROJECT_VERSION) => {
                // The rate's one home is `scene.training_fps`.
                take_training_fps(&mut table).map_err(parse)?;
                toml::Value::Table(table)
                    .try_into::<ProjectFile>()
                    .map_err(|e| parse(e.into()))?
            }
            _ => {
                return Err(parse(InvalidProject::Version {
                    found: table
                        .get("version")
                        .map_or_else(String::new, |v| v.to_string()),
                }));
            }
        };
        project.check().map_err(parse)?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        project.map_paths(|p| resolve(p, &base));
        Ok(project)
    }

    /// Checks the values a project may hold (a scene being edited may not be trainable yet:
    /// no motion, a garment dropped by another avatar).
    fn check(&self) -> Result<(), InvalidProject> {
        self.scene.validate_values()?;
        self.training.validate(self.scene.training_fps)?;
        let w = self.view.w;
        if !(w.is_finite() && (0.0..=2.0).contains(&w)) {
            return Err(InvalidProject::ViewW(w));
        }
        let speed = self.view.playback_speed;
        if !speed.is_finite() {
            // The app clamps the speed into its range, and a clamp keeps NaN.
            return Err(InvalidProject::PlaybackSpeed(speed));
        }
        Ok(())
    }
}

/// Removes the `training.fps` key earlier project files wrote (the training rate before it
/// had one home, the scene's `training_fps`) and returns its value, frames per second; `None`
/// when the file has none. A value that is not a number is an error naming the key.
pub(crate) fn take_training_fps(table: &mut toml::Table) -> Result<Option<f32>, InvalidProject> {
    let Some(training) = table
        .get_mut("training")
        .and_then(toml::Value::as_table_mut)
    else {
        return Ok(None);
    };
    match training.remove("fps") {
        None => Ok(None),
        Some(toml::Value::Float(f)) => Ok(Some(f as f32)),
        Some(toml::Value::Integer(i)) => Ok(Some(i as f32)),
        Some(other) => Err(InvalidProject::TrainingFps {
            found: other.to_string(),
        }),
    }
}

/// Most-recently-used project files, newest first, optionally persisted as JSON.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RecentFiles {
    /// The files, newest first, at most [`MAX_RECENT`], no duplicates.
    pub paths: Vec<PathBuf>,
    /// Where the list is stored; None = not persisted (tests).
    pub store: Option<PathBuf>,
}

impl RecentFiles {
    /// The default store: `$XDG_CONFIG_HOME/neural-cloth/recent.json` or
    /// `~/.config/neural-cloth/recent.json`; None when neither variable is set.
    pub fn default_store() -> Option<PathBuf> {
        let config = std::env::var_os("XDG_CONFIG_HOME")
            .map(PathBuf::from)
            .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".config")))?;
        Some(config.join("neural-cloth").join("recent.json"))
    }

    /// Loads the list from `store` (a missing or unreadable file gives an empty list).
    pub fn load(store: Option<PathBuf>) -> Self {
        let paths = store
            .as_deref()
            .and_then(|p| std::fs::read(p).ok())
            .and_then(|bytes| serde_json::from_slice::<Vec<PathBuf>>(&bytes).ok())
            .unwrap_or_default();
        let mut recent = Self {
            paths: Vec::new(),
            store,
        };
        for p in paths.into_iter().rev() {
            recent.insert(p);
        }
        recent
    }

    fn insert(&mut self, path: PathBuf) {
        self.paths.retain(|p| *p != path);
        self.paths.insert(0, path);
        self.paths.truncate(MAX_RECENT);
    }

    /// Moves `path` to the front and saves the list when it has a store.
    pub fn push(&mut self, path: &Path) -> Result<(), ProjectError> {
        self.insert(std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf()));
        match &self.store {
            Some(store) => {
                let json =
                    serde_json::to_vec_pretty(&self.paths).map_err(|e| ProjectError::Encode {
                        reason: e.into(),
                        path: store.clone(),
                    })?;
                write_atomic(store, &json)
            }
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use neural_cloth_core::scene::config::{AvatarSource, GarmentSource, MotionSource};
    use neural_cloth_core::scene::procedural::GarmentKind;
    use neural_cloth_core::scene::{Split, UpAxis};

    #[test]
    fn round_trip_keeps_everything_and_relativises_paths() {
        let dir = tempfile::tempdir().unwrap();
        let mut p = ProjectFile::default();
        p.scene.garment = GarmentSource::File {
            path: dir.path().join("garments/shirt.obj"),
            units: None,
            up: UpAxis::Z,
            smoothing_passes: Some(30),
        };
        p.scene.motions.push(MotionSource::File {
            path: PathBuf::from("/elsewhere/walk.bvh"),
            units: None,
            up: UpAxis::Y,
            split: Split::Validation,
            name: None,
            joint_map: Some(dir.path().join("maps/walk.toml")),
            mirrored: false,
        });
        p.scene.fabric.density_kg_per_m2 = 0.3;
        p.scene.training_fps = 60.0;
        p.training.window_secs = 1.0;
        p.training.max_steps = Some(500);
        p.view.w = 1.5;
        p.view.draw.wireframe = true;
        p.run = Some(dir.path().join("runs/run-1"));
        let file = dir.path().join("my.ncproj.toml");
        p.save(&file).unwrap();
        let text = std::fs::read_to_string(&file).unwrap();
        assert!(
            text.contains("\"garments/shirt.obj\"")
                && text.contains("\"maps/walk.toml\"")
                && text.contains("\"runs/run-1\"")
                && !text.contains(&*dir.path().to_string_lossy()),
            "{text}"
        );
        // The training rate has one home, the scene's.
        let table: toml::Table = text.parse().unwrap();
        assert_eq!(table["scene"]["training_fps"].as_float(), Some(60.0));
        assert!(table["training"].get("fps").is_none(), "{text}");
        let back = ProjectFile::open(&file).unwrap();
        assert_eq!(back, p);
    }

    /// Issue 14: version-2 projects written while the rate lived in the training config too
    /// carry `training.fps`, equal to the scene's; they still open, at the scene's rate.
    #[test]
    fn a_version_2_project_with_the_old_training_fps_opens_at_the_scene_rate() {
        let dir = tempfile::tempdir().unwrap();
        let mut p = ProjectFile::default();
        p.scene.training_fps = 60.0;
        p.training.window_secs = 1.0;
        let file = dir.path().join("old.toml");
        p.save(&file).unwrap();
        let text = std::fs::read_to_string(&file).unwrap();
        assert!(text.contains("[training]\n"), "{text}");
        for old in ["fps = 60.0", "fps = 60"] {
            let old = text.replace("[training]\n", &format!("[training]\n{old}\n"));
            std::fs::write(&file, old).unwrap();
            assert_eq!(ProjectFile::open(&file).unwrap(), p);
        }
        let bad = text.replace("[training]\n", "[training]\nfps = \"fast\"\n");
        std::fs::write(&file, bad).unwrap();
        let err = ProjectFile::open(&file).unwrap_err().to_string();
        assert!(err.contains("training.fps"), "{err}");
    }

    #[test]
    fn a_version_2_project_from_before_the_up_axis_still_opens() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("old.toml");
        // As the version-2 app wrote it before file sources had `up`.
        let old = "version = 2\n\n[scene]\nname = \"body\"\ntraining_fps = 30.0\n\n\
                   [scene.avatar]\npath = \"avatars/body.glb\"\n\n[scene.garment]\n\
                   path = \"garments/shirt.obj\"\nunits = \"cm\"\nsmoothing_passes = 3\n\n\
                   [[scene.motions]]\npath = \"avatars/body.glb\"\nsplit = \"train\"\n\n\
                   [scene.effects]\ngravity = true\nbending = true\ncollision = true\n\
                   dynamics = true\npinning = false\n\n[scene.fabric]\npreset = \"default\"\n";
        std::fs::write(&file, old).unwrap();
        let p = ProjectFile::open(&file).unwrap();
        assert_eq!(p.version, PROJECT_VERSION);
        assert!(matches!(
            &p.scene.avatar,
            AvatarSource::File { up: UpAxis::Auto, path, .. } if path == &dir.path().join("avatars/body.glb")
        ));
        assert!(matches!(
            p.scene.garment,
            GarmentSource::File {
                up: UpAxis::Auto,
                ..
            }
        ));
        assert!(matches!(
            p.scene.motions[0],
            MotionSource::File {
                up: UpAxis::Auto,
                ..
            }
        ));
        // Saved again, auto is left out, and a set axis is written and read back.
        p.save(&file).unwrap();
        assert!(!std::fs::read_to_string(&file).unwrap().contains("up ="));
        let mut p = p;
        if let GarmentSource::File { up, .. } = &mut p.scene.garment {
            *up = UpAxis::Z;
        }
        p.save(&file).unwrap();
        let text = std::fs::read_to_string(&file).unwrap();
        assert_eq!(text.matches("up = \"z\"").count(), 1, "{text}");
        assert_eq!(ProjectFile::open(&file).unwrap().scene, p.scene);
    }

    #[test]
    fn the_built_in_garment_is_saved_by_kind() {
        let dir = tempfile::tempdir().unwrap();
        let mut p = ProjectFile::default();
        p.scene.garment = GarmentSource::Builtin {
            builtin: GarmentKind::Skirt,
            resolution: 1200,
            smoothing_passes: None,
        };
        let file = dir.path().join("skirt.toml");
        p.save(&file).unwrap();
        let back = ProjectFile::open(&file).unwrap();
        assert_eq!(back.scene.garment, p.scene.garment);
    }

    #[test]
    fn retention_is_not_saved_and_old_files_with_it_still_open() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("old.toml");
        ProjectFile::default().save(&file).unwrap();
        let text = std::fs::read_to_string(&file).unwrap();
        assert!(!text.contains("retention"), "{text}");
        // A project saved before retention moved to the run folder.
        std::fs::write(
            &file,
            format!("{text}\n[retention]\nkeep_newest = 5\nkeep_best = false\n"),
        )
        .unwrap();
        let old = ProjectFile::open(&file).unwrap();
        assert_eq!(old.version, PROJECT_VERSION);
    }

    #[test]
    fn bad_projects_are_errors_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("bad.toml");
        std::fs::write(&file, "version = 1\n[view]\nw = 7.0\n").unwrap();
        let err = ProjectFile::open(&file).unwrap_err().to_string();
        assert!(err.contains("view.w") && err.ends_with("bad.toml"), "{err}");
        std::fs::write(&file, "version = 99\n").unwrap();
        let err = ProjectFile::open(&file).unwrap_err();
        assert!(err.to_string().contains("version 99"), "{err}");
        // The reason is typed; the text is made where it is shown.
        assert!(matches!(
            err,
            ProjectError::Parse {
                reason: InvalidProject::Version { .. },
                ..
            }
        ));
        std::fs::write(&file, "nonsense = [\n").unwrap();
        assert!(matches!(
            ProjectFile::open(&file),
            Err(ProjectError::Parse {
                reason: InvalidProject::Toml(_),
                ..
            })
        ));
        assert!(matches!(
            ProjectFile::open(&dir.path().join("missing.toml")),
            Err(ProjectError::Read { .. })
        ));
    }

    #[test]
    fn recent_files_are_unique_newest_first_and_persisted() {
        let dir = tempfile::tempdir().unwrap();
        let store = dir.path().join("recent.json");
        let mut r = RecentFiles::load(Some(store.clone()));
        for k in 0..12 {
            r.push(&dir.path().join(format!("p{k}.toml"))).unwrap();
        }
        r.push(&dir.path().join("p5.toml")).unwrap();
        assert_eq!(r.paths.len(), MAX_RECENT);
        assert!(r.paths[0].ends_with("p5.toml"));
        assert_eq!(r.paths.iter().filter(|p| p.ends_with("p5.toml")).count(), 1);
        let again = RecentFiles::load(Some(store));
        assert_eq!(again.paths, r.paths);
    }
}
