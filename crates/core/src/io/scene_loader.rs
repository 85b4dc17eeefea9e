//! The one scene loader: builds a [`Scene`] (or one part of it, [`SceneLoader`]) from a
//! [`SceneConfig`], for the CLI, a run's recorded scene and the app alike. Built-in sources
//! come from `scene::procedural`, file sources from the importers of this layer (glTF/GLB
//! avatars, OBJ or glTF garments, BVH motions and glTF animations of other rigs retargeted onto
//! the avatar, with an optional joint map per motion).

use std::path::{Path, PathBuf};

use crate::scene::config::{
    AvatarSource, GarmentSource, LengthUnit, MotionSource, SceneConfig, Split,
};
use crate::scene::procedural::{builtin_garment, builtin_motion, mannequin};
use crate::scene::{Avatar, Garment, GarmentOptions, Motion, Scene, SceneError};

use super::{
    ImportOptions, IoError, JointMap, RetargetOptions, SourceMotion, Units, UpAxis, load_avatar,
    load_bvh, load_gltf_mesh, load_obj, retarget, retarget_bvh,
};

/// A loaded scene and the importers' warnings.
#[derive(Clone, Debug)]
pub struct LoadedScene {
    /// The scene.
    pub scene: Scene,
    /// Non-fatal problems, each prefixed with the file it concerns.
    pub warnings: Vec<String>,
}

/// Loads the scene file at `path`.
pub fn load_scene_file(path: &Path) -> Result<LoadedScene, IoError> {
    let config = SceneConfig::load(path).map_err(|e| IoError::Unsupported {
        what: format!("scene file: {e}"),
        path: path.to_path_buf(),
    })?;
    let dir = path.parent().unwrap_or(Path::new("."));
    load_scene(&config, dir, path)
}

/// Loads every source of `config`; relative paths are resolved against `config_dir`.
/// `config_path` is only used in error messages about the configuration itself.
pub fn load_scene(
    config: &SceneConfig,
    config_dir: &Path,
    config_path: &Path,
) -> Result<LoadedScene, IoError> {
    SceneLoader::new(config, config_dir, config_path).scene()
}

/// Builds the parts of a scene from its description, one source at a time: the avatar, the
/// garment on it, each motion source retargeted onto it. [`SceneLoader::scene`] loads them all
/// (the CLI, a run's recorded scene); the app loads one part when the user loads one file, and
/// keeps what loads when it opens a project.
#[derive(Clone, Copy, Debug)]
pub struct SceneLoader<'a> {
    config: &'a SceneConfig,
    dir: &'a Path,
    config_path: &'a Path,
}

impl<'a> SceneLoader<'a> {
    /// A loader of `config`, whose relative paths are resolved against `dir`; `config_path`
    /// (the file the description came from) is named in errors about the description itself.
    pub fn new(config: &'a SceneConfig, dir: &'a Path, config_path: &'a Path) -> Self {
        Self {
            config,
            dir,
            config_path,
        }
    }

    /// The whole scene, after validating the description (fails at the first part that does
    /// not load).
    pub fn scene(&self) -> Result<LoadedScene, IoError> {
        self.config
            .validate()
            .map_err(|e| self.bad_config(format!("scene file: {e}")))?;
        let mut warnings = Vec::new();
        let avatar = self.avatar(&mut warnings)?;
        let garment = self.garment(&avatar, &mut warnings)?;
        let mut motions: Vec<(Motion, Split)> = Vec::new();
        for (k, source) in self.config.motions.iter().enumerate() {
            for m in self.motions(k, &avatar, &mut warnings)? {
                motions.push((m, source.split()));
            }
        }
        let scene = self
            .config
            .assemble(avatar, garment, motions)
            .map_err(|e| self.scene_error(e))?;
        Ok(LoadedScene { scene, warnings })
    }

    /// The avatar: the built-in mannequin, or a skinned glTF/GLB file with its animations
    /// resampled to the scene's training rate.
    pub fn avatar(&self, warnings: &mut Vec<String>) -> Result<Avatar, IoError> {
        match &self.config.avatar {
            AvatarSource::Builtin { .. } => mannequin().map_err(|e| self.scene_error(e)),
            AvatarSource::File { path, units, up } => {
                let file = self.resolve(path);
                match extension(&file).as_str() {
                    "glb" | "gltf" => {}
                    other => {
                        return Err(IoError::UnsupportedFormat {
                            extension: other.into(),
                            path: file,
                        });
                    }
                }
                let options = ImportOptions {
                    units: units_of(*units),
                    fps: self.config.training_fps,
                    up: *up,
                };
                let loaded = load_avatar(&file, &options)?;
                warnings.extend(note_all(&file, &loaded.warnings));
                Ok(loaded.avatar)
            }
        }
    }

    /// The garment bound to `avatar` (built from this description's avatar source): a
    /// built-in garment (on the built-in mannequin only) or an OBJ/glTF file, its skin weights
    /// smoothed as given or, by default, by [`GarmentOptions::for_name`] of its name (more
    /// passes for skirts and dresses); the passes used are [`Garment::smoothing_passes`].
    pub fn garment(&self, avatar: &Avatar, warnings: &mut Vec<String>) -> Result<Garment, IoError> {
        match &self.config.garment {
            GarmentSource::Builtin {
                builtin,
                resolution,
                smoothing_passes,
            } => {
                if let AvatarSource::File { path, .. } = &self.config.avatar {
                    return Err(IoError::Unsupported {
                        what: format!(
                            "the built-in garment '{}' fits the built-in mannequin only; give a \
                             garment file",
                            builtin.name()
                        ),
                        path: self.resolve(path),
                    });
                }
                builtin_garment(avatar, *builtin, *resolution, *smoothing_passes)
                    .map_err(|e| self.scene_error(e))
            }
            GarmentSource::File {
                path,
                units,
                up,
                smoothing_passes,
            } => {
                let file = self.resolve(path);
                let options = ImportOptions {
                    units: units_of(*units),
                    up: *up,
                    ..Default::default()
                };
                load_garment(&file, avatar, &options, *smoothing_passes, warnings)
            }
        }
    }

    /// The motions of `config.motions[k]` on `avatar`: a built-in motion (the built-in
    /// mannequin only), or every animation of a BVH or glTF file (or the one named) retargeted
    /// onto the avatar (the avatar file's own animations are taken as they are).
    pub fn motions(
        &self,
        k: usize,
        avatar: &Avatar,
        warnings: &mut Vec<String>,
    ) -> Result<Vec<Motion>, IoError> {
        let Some(source) = self.config.motions.get(k) else {
            return Err(self.bad_config(format!("no motion source {k}")));
        };
        let fps = self.config.training_fps;
        match source {
            MotionSource::Builtin {
                builtin,
                duration_secs,
                speed,
                fps: motion_fps,
                name,
                mirrored,
                ..
            } => {
                if let AvatarSource::File { path, .. } = &self.config.avatar {
                    return Err(IoError::Unsupported {
                        what: format!(
                            "the built-in motion '{}' drives the built-in mannequin only; give \
                             motion files",
                            builtin.name()
                        ),
                        path: self.resolve(path),
                    });
                }
                let m = builtin_motion(
                    *builtin,
                    motion_fps.unwrap_or(fps),
                    *duration_secs,
                    *speed,
                    name.as_deref(),
                    mirrored.then_some(&avatar.skeleton),
                )
                .map_err(|e| self.scene_error(e))?;
                Ok(vec![m])
            }
            MotionSource::File {
                path,
                units,
                up,
                name,
                joint_map,
                mirrored,
                ..
            } => {
                let file = self.resolve(path);
                let joint_map = joint_map
                    .as_ref()
                    .map(|p| JointMap::load(&self.resolve(p)))
                    .transpose()?;
                let how = MotionImport {
                    units: units_of(*units),
                    up: *up,
                    fps,
                    only: name.as_deref(),
                    joint_map: joint_map.as_ref(),
                };
                let motions = load_motions(&file, avatar, &how, warnings)?;
                if !*mirrored {
                    return Ok(motions);
                }
                Ok(motions
                    .iter()
                    .map(|m| m.mirrored_for_scene(&avatar.skeleton, false))
                    .collect())
            }
        }
    }

    fn resolve(&self, path: &Path) -> PathBuf {
        SceneConfig::resolve_path(self.dir, path)
    }

    fn bad_config(&self, what: String) -> IoError {
        IoError::Unsupported {
            what,
            path: self.config_path.to_path_buf(),
        }
    }

    fn scene_error(&self, source: SceneError) -> IoError {
        IoError::Scene {
            source,
            path: self.config_path.to_path_buf(),
        }
    }
}

fn note_all(file: &Path, warnings: &[String]) -> Vec<String> {
    warnings
        .iter()
        .map(|w| format!("{}: {w}", file.display()))
        .collect()
}

/// Loads a garment template (OBJ, glTF or GLB by extension) read with `options` (units, up
/// axis) and fits it to `avatar` with `smoothing_passes` of skin-weight smoothing (default:
/// [`GarmentOptions::for_name`] of the garment's name).
pub fn load_garment(
    file: &Path,
    avatar: &Avatar,
    options: &ImportOptions,
    smoothing_passes: Option<usize>,
    warnings: &mut Vec<String>,
) -> Result<Garment, IoError> {
    let loaded = match extension(file).as_str() {
        "obj" => load_obj(file, options)?,
        "gltf" | "glb" => load_gltf_mesh(file, options)?,
        other => {
            return Err(IoError::UnsupportedFormat {
                extension: other.into(),
                path: file.to_path_buf(),
            });
        }
    };
    warnings.extend(
        loaded
            .warnings
            .iter()
            .map(|w| format!("{}: {w}", file.display())),
    );
    let mut options = GarmentOptions::for_name(&loaded.name);
    if let Some(passes) = smoothing_passes {
        options.smoothing_passes = passes;
    }
    let garment =
        Garment::new(loaded.name, loaded.mesh, avatar, &options).map_err(|e| IoError::Scene {
            source: e,
            path: file.to_path_buf(),
        })?;
    warnings.extend(
        garment
            .warnings
            .iter()
            .map(|w| format!("{}: {w}", file.display())),
    );
    Ok(garment)
}

/// How [`load_motions`] reads a motion file.
#[derive(Clone, Copy, Debug)]
pub struct MotionImport<'a> {
    /// Length unit of a glTF file ([`Units::Auto`]: detected); BVH lengths are scaled by
    /// the ratio of leg lengths.
    pub units: Units,
    /// Up axis of the file ([`UpAxis::Auto`]: detected from its rig); a Z-up rig is turned Y
    /// up before retargeting.
    pub up: UpAxis,
    /// Frame rate of the motions, frames per second.
    pub fps: f32,
    /// Only the animation of this name (glTF files hold several).
    pub only: Option<&'a str>,
    /// The user's joint map, overriding the automatic joint mapping.
    pub joint_map: Option<&'a JointMap>,
}

/// Loads the motions of a BVH file or of a glTF/GLB file's animations, retargeted onto
/// `avatar` (a glTF rig with exactly the avatar's joint names, and no joint map, is taken
/// as is).
pub fn load_motions(
    file: &Path,
    avatar: &Avatar,
    how: &MotionImport<'_>,
    warnings: &mut Vec<String>,
) -> Result<Vec<Motion>, IoError> {
    let options = RetargetOptions {
        fps: how.fps,
        joint_map: how.joint_map.cloned(),
        ..Default::default()
    };
    let note = |w: &String| format!("{}: {w}", file.display());
    let mut motions = match extension(file).as_str() {
        "bvh" => {
            let mut bvh = load_bvh(file)?;
            bvh.up = how.up;
            let (mut motion, w) = retarget_bvh(&bvh, &avatar.skeleton, &options)?;
            warnings.extend(w.iter().map(note));
            motion.name = file
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or(motion.name);
            vec![motion]
        }
        "gltf" | "glb" => {
            let loaded = load_avatar(
                file,
                &ImportOptions {
                    units: how.units,
                    fps: how.fps,
                    up: how.up,
                },
            )?;
            warnings.extend(loaded.warnings.iter().map(note));
            let rig = &loaded.avatar.skeleton;
            let mut animations = loaded.avatar.motions.clone();
            if let Some(name) = how.only {
                animations.retain(|m| m.name == name);
            }
            if rig.names == avatar.skeleton.names && how.joint_map.is_none() {
                animations
            } else {
                let mut out = Vec::with_capacity(animations.len());
                for animation in &animations {
                    let source = SourceMotion::from_rig(rig, animation, file);
                    let (motion, w) = retarget(&source, &avatar.skeleton, &options)?;
                    for w in w.iter().map(note) {
                        if !warnings.contains(&w) {
                            warnings.push(w);
                        }
                    }
                    out.push(motion);
                }
                out
            }
        }
        other => {
            return Err(IoError::UnsupportedFormat {
                extension: other.into(),
                path: file.to_path_buf(),
            });
        }
    };
    if let Some(name) = how.only {
        motions.retain(|m| m.name == name);
        if motions.is_empty() {
            return Err(IoError::Unsupported {
                what: format!("no animation named '{name}'"),
                path: file.to_path_buf(),
            });
        }
    }
    Ok(motions)
}

/// Lower-case extension of `file` ("" when it has none).
pub fn extension(file: &Path) -> String {
    file.extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default()
}

fn units_of(unit: Option<LengthUnit>) -> Units {
    match unit {
        None => Units::Auto,
        Some(LengthUnit::Metres) => Units::Metres,
        Some(LengthUnit::Centimetres) => Units::Centimetres,
        Some(LengthUnit::Millimetres) => Units::Millimetres,
        Some(LengthUnit::Inches) => Units::Inches,
    }
}

/// The split of file `k` of `n` motion files taken from a folder (sorted by name), so that
/// every folder of three or more gives a validation and a test motion, deterministically:
/// one file trains; of two, the last tests; of 3 to 9, the last tests and the one before
/// validates; of 10 or more, the 9th of each ten tests and the 10th validates.
pub fn folder_split(k: usize, n: usize) -> Split {
    match n {
        0..=1 => Split::Train,
        2 if k == 1 => Split::Test,
        2 => Split::Train,
        3..=9 if k + 1 == n => Split::Test,
        3..=9 if k + 2 == n => Split::Validation,
        3..=9 => Split::Train,
        _ => match k % 10 {
            8 => Split::Test,
            9 => Split::Validation,
            _ => Split::Train,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folders_of_three_or_more_get_validation_and_test_motions() {
        let splits = |n: usize| (0..n).map(|k| folder_split(k, n)).collect::<Vec<_>>();
        assert_eq!(splits(1), vec![Split::Train]);
        assert_eq!(splits(2), vec![Split::Train, Split::Test]);
        assert_eq!(
            splits(4),
            vec![Split::Train, Split::Train, Split::Validation, Split::Test]
        );
        for n in 3..40 {
            let s = splits(n);
            let count = |x: Split| s.iter().filter(|&&y| y == x).count();
            assert!(
                count(Split::Test) >= 1 && count(Split::Validation) >= 1,
                "{n}"
            );
            if n < 10 {
                assert_eq!(count(Split::Train), n - 2, "{n}");
            } else {
                assert!(count(Split::Train) * 5 >= n * 4, "{n}: {s:?}");
            }
        }
    }
}
