//! Edits of the app's scene description: loading an avatar, garment or motion file changes the
//! [`SceneConfig`] and loads the changed part through the io layer's scene loader
//! ([`SceneLoader`], the one loader the CLI and runs use too); opening a description (a
//! project's scene) loads every part, keeping what loads. Every failure is a message naming
//! the file, never a panic; a failed load leaves the scene as it was. [`LoadKind`] names the
//! part a load targets (the Scene panel's rows, the file dialogs).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use neural_cloth_core::io::scene_loader::SceneLoader;
use neural_cloth_core::io::{IoError, JointMap};
use neural_cloth_core::scene::config::{AvatarSource, GarmentSource, MotionSource};
use neural_cloth_core::scene::{Avatar, Motion, SceneConfig, Split, UpAxis};

use super::state::{AppState, Level, SceneParts};

/// Which scene part a load targets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoadKind {
    /// Avatar (glTF/GLB).
    Avatar,
    /// Garment (OBJ/glTF).
    Garment,
    /// Motion (BVH).
    Motion,
}

impl LoadKind {
    /// Dialog title.
    pub fn title(self) -> &'static str {
        match self {
            Self::Avatar => "Load avatar (glTF/GLB)",
            Self::Garment => "Load garment (OBJ/glTF)",
            Self::Motion => "Load motion (BVH)",
        }
    }

    /// Extensions the dialog offers.
    pub fn extensions(self) -> &'static [&'static str] {
        match self {
            Self::Avatar => &["glb", "gltf"],
            Self::Garment => &["obj", "glb", "gltf"],
            Self::Motion => &["bvh"],
        }
    }
}

/// A training motion source for the file at `path` (up axis `up`), retargeted with
/// `joint_map`.
fn motion_file(path: PathBuf, up: UpAxis, joint_map: Option<PathBuf>) -> MotionSource {
    MotionSource::File {
        path,
        units: None,
        up,
        split: Split::Train,
        name: None,
        joint_map,
        mirrored: false,
    }
}

fn absolute(path: &Path) -> PathBuf {
    std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf())
}

/// What opening a description loaded, with the problems met (the scene shows what loaded).
struct OpenedScene {
    parts: SceneParts,
    warnings: Vec<String>,
    errors: Vec<String>,
}

impl AppState {
    /// The file named in errors about the scene description itself: the project's, or a
    /// stand-in before it is saved.
    fn scene_origin(&self) -> PathBuf {
        self.project_path
            .clone()
            .unwrap_or_else(|| PathBuf::from("(unsaved project)"))
    }

    /// The file the scene's `kind` part came from (the last motion file for motions); None
    /// for a built-in part.
    pub fn scene_file(&self, kind: LoadKind) -> Option<PathBuf> {
        let config = &self.scene.config;
        match kind {
            LoadKind::Avatar => match &config.avatar {
                AvatarSource::File { path, .. } => Some(path.clone()),
                AvatarSource::Builtin { .. } => None,
            },
            LoadKind::Garment => match &config.garment {
                GarmentSource::File { path, .. } => Some(path.clone()),
                GarmentSource::Builtin { .. } => None,
            },
            LoadKind::Motion => config.motions.iter().rev().find_map(|m| match m {
                MotionSource::File { path, .. } => Some(path.clone()),
                MotionSource::Builtin { .. } => None,
            }),
        }
    }

    /// Shows `parts` as the scene.
    pub(crate) fn show_parts(&mut self, parts: SceneParts) {
        self.scene.config = parts.config;
        self.scene.avatar = parts.avatar;
        self.scene.splits = parts.splits;
        self.scene.garment = parts.garment;
        self.scene_changed();
    }

    /// Loads an avatar (glTF/GLB) with its animations (the scene's motions then, all
    /// training) and binds the garment to it again (a garment file re-binds; the built-in
    /// garments fit the built-in mannequin only). On failure the scene is unchanged and the
    /// error is shown; returns whether it worked.
    pub fn load_avatar(&mut self, path: &Path) -> bool {
        let file = absolute(path);
        let mut config = self.scene.config.clone();
        let up = self.typed.up;
        config.avatar = AvatarSource::File {
            path: file.clone(),
            units: None,
            up,
        };
        config.motions = vec![motion_file(file, up, None)];
        let origin = self.scene_origin();
        let loader = SceneLoader::new(&config, Path::new("."), &origin);
        let mut warnings = Vec::new();
        let loaded = loader.avatar(&mut warnings).and_then(|avatar| {
            let motions = loader.motions(0, &avatar, &mut warnings)?;
            Ok((avatar, motions))
        });
        let (mut avatar, motions) = match loaded {
            Ok(l) => l,
            Err(e) => {
                self.message(Level::Error, e.to_string());
                return false;
            }
        };
        let garment = match loader.garment(&avatar, &mut warnings) {
            Ok(g) => Some(Arc::new(g)),
            Err(e) => {
                self.message(Level::Warning, format!("garment dropped: {e}"));
                None
            }
        };
        if motions.is_empty() {
            config.motions.clear();
        }
        config.name = avatar.name.clone();
        self.message(
            Level::Info,
            format!(
                "loaded avatar '{}' ({} motions)",
                avatar.name,
                motions.len()
            ),
        );
        self.warn_all("avatar", warnings);
        avatar.motions = motions;
        let splits = vec![Split::Train; avatar.motions.len()];
        self.show_parts(SceneParts {
            config,
            avatar: Arc::new(avatar),
            splits,
            garment,
        });
        true
    }

    /// Loads a garment (OBJ/glTF) onto the current avatar; errors are shown, not raised. The
    /// skin-weight smoothing it was bound with is recorded in the description.
    pub fn load_garment(&mut self, path: &Path) -> bool {
        let mut config = self.scene.config.clone();
        config.garment = GarmentSource::File {
            path: absolute(path),
            units: None,
            up: self.typed.up,
            smoothing_passes: None,
        };
        let origin = self.scene_origin();
        let mut warnings = Vec::new();
        let loaded = SceneLoader::new(&config, Path::new("."), &origin)
            .garment(&self.scene.avatar, &mut warnings);
        match loaded {
            Ok(garment) => {
                if let GarmentSource::File {
                    smoothing_passes, ..
                } = &mut config.garment
                {
                    *smoothing_passes = Some(garment.smoothing_passes);
                }
                self.message(
                    Level::Info,
                    format!(
                        "loaded garment '{}' ({} vertices)",
                        garment.name,
                        garment.vertex_count()
                    ),
                );
                self.warn_all("garment", warnings);
                self.scene.config = config;
                self.scene.garment = Some(Arc::new(garment));
                self.scene_changed();
                true
            }
            Err(e) => {
                self.message(Level::Error, e.to_string());
                false
            }
        }
    }

    /// Loads `path` as `kind` (a motion with the typed joint map, if any): the single path
    /// used by the file dialogs, the typed fields and tests. Returns whether it loaded.
    pub fn load_file(&mut self, kind: LoadKind, path: &Path) -> bool {
        match kind {
            LoadKind::Avatar => self.load_avatar(path),
            LoadKind::Garment => self.load_garment(path),
            LoadKind::Motion => {
                let map = self.typed.joint_map.trim();
                let map = (!map.is_empty()).then(|| PathBuf::from(map));
                self.load_motion_mapped(path, map.as_deref())
            }
        }
    }

    /// Checks the typed joint map (when its field is left): `typed.joint_map_error` says why
    /// the file does not read, None when it reads or the field is empty.
    pub fn check_joint_map(&mut self) {
        let text = self.typed.joint_map.trim();
        self.typed.joint_map_error = match text.is_empty() {
            true => None,
            false => JointMap::load(Path::new(text)).err().map(|e| e.to_string()),
        };
    }

    /// Loads a motion file (BVH, or the animations of a glTF file), retargets it onto the
    /// avatar, adds it to the scene's training motions and shows it.
    pub fn load_motion(&mut self, path: &Path) -> bool {
        self.load_motion_mapped(path, None)
    }

    /// [`Self::load_motion`] with the user's `joint_map` file (recorded in the scene
    /// description). A map that does not read, or names joints the avatar or the motion
    /// lacks, is refused with the error also kept in `typed.joint_map_error`.
    pub fn load_motion_mapped(&mut self, path: &Path, joint_map: Option<&Path>) -> bool {
        let joint_map = joint_map.map(absolute);
        if let Some(map) = &joint_map
            && let Err(e) = JointMap::load(map)
        {
            self.typed.joint_map_error = Some(e.to_string());
            self.message(Level::Error, e.to_string());
            return false;
        }
        let mut config = self.scene.config.clone();
        let up = self.typed.up;
        config
            .motions
            .push(motion_file(absolute(path), up, joint_map));
        let origin = self.scene_origin();
        let mut warnings = Vec::new();
        let loaded = SceneLoader::new(&config, Path::new("."), &origin).motions(
            config.motions.len() - 1,
            &self.scene.avatar,
            &mut warnings,
        );
        let motions: Vec<Motion> = match loaded {
            Ok(m) => m,
            Err(e) => {
                if matches!(e, IoError::JointMap { .. }) {
                    self.typed.joint_map_error = Some(e.to_string());
                }
                self.message(Level::Error, e.to_string());
                return false;
            }
        };
        self.typed.joint_map_error = None;
        for m in &motions {
            self.message(
                Level::Info,
                format!("loaded motion '{}' ({:.1} s)", m.name, m.duration_secs()),
            );
        }
        self.warn_all("motion", warnings);
        let mut avatar = (*self.scene.avatar).clone();
        let first = avatar.motions.len();
        self.scene.splits.resize(first, Split::Train);
        self.scene
            .splits
            .extend(motions.iter().map(|_| Split::Train));
        avatar.motions.extend(motions);
        let count = avatar.motions.len();
        self.scene.avatar = Arc::new(avatar);
        self.scene.config = config;
        self.scene_changed();
        self.playback.select_motion(first, count);
        true
    }

    /// Shows the scene `config` describes (a project's scene; its paths absolute): the avatar
    /// and every part that loads onto it. An avatar that does not load leaves the scene as it
    /// was (false); a garment that does not load leaves none; a motion source that does not
    /// load is left out of the description. Each problem is shown.
    pub fn open_scene(&mut self, config: SceneConfig) -> bool {
        let origin = self.scene_origin();
        match load_parts(config, &origin) {
            Ok(opened) => {
                for e in opened.errors {
                    self.message(Level::Error, e);
                }
                self.warn_all("scene", opened.warnings);
                self.show_parts(opened.parts);
                true
            }
            Err(e) => {
                self.message(Level::Error, format!("the project's avatar: {e}"));
                false
            }
        }
    }
}

/// Loads every part of `config` that loads (see [`AppState::open_scene`]); fails only when
/// the avatar does not load.
fn load_parts(mut config: SceneConfig, origin: &Path) -> Result<OpenedScene, IoError> {
    let mut warnings = Vec::new();
    let mut errors = Vec::new();
    let (avatar, garment, loaded) = {
        let loader = SceneLoader::new(&config, Path::new("."), origin);
        let avatar: Avatar = loader.avatar(&mut warnings)?;
        let garment = match loader.garment(&avatar, &mut warnings) {
            Ok(g) => Some(Arc::new(g)),
            Err(e) => {
                errors.push(format!("garment not loaded: {e}"));
                None
            }
        };
        let loaded: Vec<Result<Vec<Motion>, IoError>> = (0..config.motions.len())
            .map(|k| loader.motions(k, &avatar, &mut warnings))
            .collect();
        (avatar, garment, loaded)
    };
    let mut kept = Vec::new();
    let mut motions = Vec::new();
    let mut splits = Vec::new();
    for (source, result) in config.motions.drain(..).zip(loaded) {
        match result {
            Ok(list) => {
                splits.extend(list.iter().map(|_| source.split()));
                motions.extend(list);
                kept.push(source);
            }
            Err(e) => errors.push(format!("motion left out: {e}")),
        }
    }
    config.motions = kept;
    let mut avatar = avatar;
    avatar.motions = motions;
    Ok(OpenedScene {
        parts: SceneParts {
            config,
            avatar: Arc::new(avatar),
            splits,
            garment,
        },
        warnings,
        errors,
    })
}
