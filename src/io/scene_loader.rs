//! Loads a whole scene from a [`SceneConfig`]: built-in sources come from
//! `scene::procedural`, file sources from the importers of this layer (glTF/GLB avatars, OBJ or
//! glTF garments, BVH motions retargeted onto the avatar, glTF animations of the same rig).

use std::path::Path;

use crate::scene::config::{
    AvatarSource, GarmentSource, LengthUnit, MotionSource, SceneConfig, Split,
};
use crate::scene::procedural::{builtin_garment, builtin_motion, mannequin};
use crate::scene::{Avatar, Garment, GarmentOptions, Motion, Scene};

use super::{
    ImportOptions, IoError, RetargetOptions, Units, load_avatar, load_bvh, load_gltf_mesh,
    load_obj, retarget_bvh,
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
    let bad_config = |what: String| IoError::Unsupported {
        what,
        path: config_path.to_path_buf(),
    };
    config
        .validate()
        .map_err(|e| bad_config(format!("scene file: {e}")))?;
    let mut warnings = Vec::new();
    let fps = config.training_fps;
    let builtin_avatar = matches!(config.avatar, AvatarSource::Builtin { .. });
    let avatar: Avatar = match &config.avatar {
        AvatarSource::Builtin { .. } => mannequin().map_err(|e| IoError::Scene {
            source: e,
            path: config_path.to_path_buf(),
        })?,
        AvatarSource::File { path, units } => {
            let file = SceneConfig::resolve_path(config_dir, path);
            let loaded = load_avatar(
                &file,
                &ImportOptions {
                    units: units_of(*units, &file)?,
                    fps,
                },
            )?;
            warnings.extend(
                loaded
                    .warnings
                    .iter()
                    .map(|w| format!("{}: {w}", file.display())),
            );
            loaded.avatar
        }
    };
    let garment: Garment = match &config.garment {
        GarmentSource::Builtin {
            builtin,
            resolution,
            smoothing_passes,
        } => {
            if !builtin_avatar {
                return Err(bad_config(
                    "built-in garments fit the built-in mannequin only; give a garment file".into(),
                ));
            }
            builtin_garment(&avatar, *builtin, *resolution, *smoothing_passes).map_err(|e| {
                IoError::Scene {
                    source: e,
                    path: config_path.to_path_buf(),
                }
            })?
        }
        GarmentSource::File {
            path,
            units,
            smoothing_passes,
        } => {
            let file = SceneConfig::resolve_path(config_dir, path);
            load_garment(
                &file,
                &avatar,
                units_of(*units, &file)?,
                smoothing_passes.unwrap_or(GarmentOptions::default().smoothing_passes),
                &mut warnings,
            )?
        }
    };
    let mut motions: Vec<(Motion, Split)> = Vec::new();
    for source in &config.motions {
        match source {
            MotionSource::Builtin {
                builtin,
                duration_secs,
                fps: motion_fps,
                split,
                name,
            } => {
                if !builtin_avatar {
                    return Err(bad_config(
                        "built-in motions drive the built-in mannequin only; give motion files"
                            .into(),
                    ));
                }
                let m = builtin_motion(
                    *builtin,
                    motion_fps.unwrap_or(fps),
                    *duration_secs,
                    name.as_deref(),
                )
                .map_err(|e| IoError::Scene {
                    source: e,
                    path: config_path.to_path_buf(),
                })?;
                motions.push((m, *split));
            }
            MotionSource::File {
                path,
                units,
                split,
                name,
            } => {
                let file = SceneConfig::resolve_path(config_dir, path);
                for m in load_motions(
                    &file,
                    &avatar,
                    units_of(*units, &file)?,
                    fps,
                    name.as_deref(),
                    &mut warnings,
                )? {
                    motions.push((m, *split));
                }
            }
        }
    }
    let scene = config
        .assemble(avatar, garment, motions)
        .map_err(|e| IoError::Scene {
            source: e,
            path: config_path.to_path_buf(),
        })?;
    Ok(LoadedScene { scene, warnings })
}

/// Loads a garment template (OBJ, glTF or GLB by extension) and fits it to `avatar`.
pub fn load_garment(
    file: &Path,
    avatar: &Avatar,
    units: Units,
    smoothing_passes: usize,
    warnings: &mut Vec<String>,
) -> Result<Garment, IoError> {
    let options = ImportOptions {
        units,
        ..Default::default()
    };
    let loaded = match extension(file).as_str() {
        "obj" => load_obj(file, &options)?,
        "gltf" | "glb" => load_gltf_mesh(file, &options)?,
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
    let options = GarmentOptions {
        smoothing_passes,
        ..Default::default()
    };
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

/// Loads the motions of a BVH file (retargeted onto `avatar`) or of a glTF/GLB file with the
/// same skeleton (same joint names in the same order), at `fps`. `only` picks one animation.
pub fn load_motions(
    file: &Path,
    avatar: &Avatar,
    units: Units,
    fps: f32,
    only: Option<&str>,
    warnings: &mut Vec<String>,
) -> Result<Vec<Motion>, IoError> {
    let mut motions = match extension(file).as_str() {
        "bvh" => {
            let bvh = load_bvh(file)?;
            let _ = units; // BVH units are taken from the hip-height ratio during retargeting.
            let (mut motion, w) = retarget_bvh(
                &bvh,
                &avatar.skeleton,
                &RetargetOptions {
                    fps,
                    ..Default::default()
                },
            )?;
            warnings.extend(w.iter().map(|w| format!("{}: {w}", file.display())));
            motion.name = file
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or(motion.name);
            vec![motion]
        }
        "gltf" | "glb" => {
            let loaded = load_avatar(file, &ImportOptions { units, fps })?;
            if loaded.avatar.skeleton.names != avatar.skeleton.names {
                return Err(IoError::JointCountMismatch {
                    what: format!(
                        "animations must drive the avatar's skeleton ({} joints with the same names)",
                        avatar.skeleton.len()
                    ),
                    expected: avatar.skeleton.len(),
                    found: loaded.avatar.skeleton.len(),
                    path: file.to_path_buf(),
                });
            }
            warnings.extend(
                loaded
                    .warnings
                    .iter()
                    .map(|w| format!("{}: {w}", file.display())),
            );
            loaded.avatar.motions
        }
        other => {
            return Err(IoError::UnsupportedFormat {
                extension: other.into(),
                path: file.to_path_buf(),
            });
        }
    };
    if let Some(name) = only {
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

fn extension(file: &Path) -> String {
    file.extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default()
}

fn units_of(unit: Option<LengthUnit>, _file: &Path) -> Result<Units, IoError> {
    Ok(match unit {
        None => Units::Auto,
        Some(LengthUnit::Metres) => Units::Metres,
        Some(LengthUnit::Centimetres) => Units::Centimetres,
        Some(LengthUnit::Millimetres) => Units::Millimetres,
        Some(LengthUnit::Inches) => Units::Inches,
    })
}
