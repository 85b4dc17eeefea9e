//! Project files: the whole setup (scene sources, fabric, effects, training config, runs
//! folder, the run shown, view settings) as one human-edited TOML file, plus the recent-files list
//! (machine-written JSON). Paths inside a project are stored relative to the project file
//! when they lie below its folder, and resolved against it when opened.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::physics::FabricParams;
use crate::render::DrawOptions;
use crate::scene::Effects;
use crate::train::TrainConfig;

use super::metrics::XAxis;

/// Current project format version.
pub const PROJECT_VERSION: u32 = 1;
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
    /// The file is not a valid project.
    #[error("invalid project file: {reason}: {}", path.display())]
    Parse {
        /// What is wrong.
        reason: String,
        /// The file.
        path: PathBuf,
    },
}

/// Where the scene comes from. `None` means the built-in default.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SceneSources {
    /// Avatar file (glTF/GLB); None = built-in mannequin.
    pub avatar: Option<PathBuf>,
    /// Garment file (OBJ/glTF); None = built-in garment.
    pub garment: Option<PathBuf>,
    /// Extra BVH motions retargeted onto the avatar, in load order.
    pub motions: Vec<PathBuf>,
    /// Name of the fabric preset the fabric started from, for display.
    pub fabric_preset: Option<String>,
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
    /// Scene sources.
    pub scene: SceneSources,
    /// Fabric parameters.
    pub fabric: FabricParams,
    /// Effects the scene declares.
    pub effects: Effects,
    /// Training configuration (window, fps, batch, schedule).
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
            scene: SceneSources::default(),
            fabric: FabricParams::default(),
            effects: Effects::default(),
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
        let s = &mut self.scene;
        for p in s
            .avatar
            .iter_mut()
            .chain(s.garment.iter_mut())
            .chain(s.motions.iter_mut())
            .chain(self.runs_folder.iter_mut())
            .chain(self.run.iter_mut())
        {
            *p = f(p);
        }
    }

    /// Serialises to TOML with paths as given.
    pub fn to_toml(&self) -> Result<String, String> {
        toml::to_string_pretty(self).map_err(|e| e.to_string())
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
        let text = copy.to_toml().map_err(|reason| ProjectError::Parse {
            reason,
            path: path.to_path_buf(),
        })?;
        write_atomic(path, format!("# neural-cloth project\n{text}").as_bytes())
    }

    /// Reads a project, checks its version and values, and resolves its paths against its
    /// folder.
    pub fn open(path: &Path) -> Result<Self, ProjectError> {
        let text = std::fs::read_to_string(path).map_err(|source| ProjectError::Read {
            source,
            path: path.to_path_buf(),
        })?;
        let parse = |reason: String| ProjectError::Parse {
            reason,
            path: path.to_path_buf(),
        };
        let mut project: ProjectFile = toml::from_str(&text).map_err(|e| parse(e.to_string()))?;
        if project.version != PROJECT_VERSION {
            return Err(parse(format!(
                "version {} (this build reads version {PROJECT_VERSION})",
                project.version
            )));
        }
        project
            .fabric
            .validate()
            .map_err(|e| parse(format!("fabric: {e}")))?;
        project
            .training
            .validate()
            .map_err(|e| parse(format!("training: {e}")))?;
        let w = project.view.w;
        if !(w.is_finite() && (0.0..=2.0).contains(&w)) {
            return Err(parse(format!("view.w = {w} is outside [0, 2]")));
        }
        let speed = project.view.playback_speed;
        if !speed.is_finite() {
            // The app clamps the speed into its range, and a clamp keeps NaN.
            return Err(parse(format!(
                "view.playback_speed = {speed} is not a finite number"
            )));
        }
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        project.map_paths(|p| resolve(p, &base));
        Ok(project)
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
                    serde_json::to_vec_pretty(&self.paths).map_err(|e| ProjectError::Parse {
                        reason: e.to_string(),
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

    #[test]
    fn round_trip_keeps_everything_and_relativises_paths() {
        let dir = tempfile::tempdir().unwrap();
        let mut p = ProjectFile::default();
        p.scene.garment = Some(dir.path().join("garments/shirt.obj"));
        p.scene.motions = vec![PathBuf::from("/elsewhere/walk.bvh")];
        p.fabric.density_kg_per_m2 = 0.3;
        p.training.window_secs = 1.0;
        p.training.max_steps = Some(500);
        p.view.w = 1.5;
        p.view.draw.wireframe = true;
        p.run = Some(dir.path().join("runs/run-1"));
        let file = dir.path().join("my.ncproj.toml");
        p.save(&file).unwrap();
        let text = std::fs::read_to_string(&file).unwrap();
        assert!(
            text.contains("garments/shirt.obj")
                && text.contains("runs/run-1")
                && !text.contains(&*dir.path().to_string_lossy()),
            "{text}"
        );
        let back = ProjectFile::open(&file).unwrap();
        assert_eq!(back, p);
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
        assert!(
            ProjectFile::open(&file)
                .unwrap_err()
                .to_string()
                .contains("version 99")
        );
        std::fs::write(&file, "nonsense = [\n").unwrap();
        assert!(matches!(
            ProjectFile::open(&file),
            Err(ProjectError::Parse { .. })
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
