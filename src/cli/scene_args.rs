//! The scene the command line describes: a scene file (default: the built-in scene) with the
//! avatar, garment, folder of motions, joint map and up axis the flags give in its place.

use std::path::{Path, PathBuf};

use anyhow::Context;

use neural_cloth::io::scene_loader::{folder_split, load_scene, load_scene_file};
use neural_cloth::io::{IoError, UpAxis};
use neural_cloth::scene::config::{AvatarSource, GarmentSource, MotionSource, SceneConfig};
use neural_cloth::scene::{Scene, SceneError};
use neural_cloth::train::preflight::fit_advice;

/// The scene parts named on the command line.
#[derive(Clone, Copy, Debug, Default)]
pub struct SceneArgs<'a> {
    /// Scene file (TOML); None: the built-in scene.
    pub scene: Option<&'a Path>,
    /// Avatar file (or `mannequin`) replacing the scene's; given with `garment`.
    pub avatar: Option<&'a Path>,
    /// Garment file replacing the scene's; given with `avatar`.
    pub garment: Option<&'a Path>,
    /// Folder of motion files replacing the scene's motions.
    pub motions: Option<&'a Path>,
    /// Joint map for every motion file without one of its own.
    pub joint_map: Option<&'a Path>,
    /// Up axis of every file source left on auto (the files named here and the scene file's).
    pub up: UpAxis,
    /// Training frame rate replacing the scene's `training_fps`, frames per second; None:
    /// the scene's own.
    pub training_fps: Option<f32>,
}

impl<'a> SceneArgs<'a> {
    /// The scene file `scene` (None: the built-in scene) as it is.
    pub fn file(scene: Option<&'a Path>) -> Self {
        Self {
            scene,
            ..Self::default()
        }
    }

    /// Whether the flags change the scene file's description.
    pub fn edits_scene(&self) -> bool {
        self.avatar.is_some()
            || self.motions.is_some()
            || self.joint_map.is_some()
            || self.up != UpAxis::Auto
            || self.training_fps.is_some()
    }
}

/// The scene and its (absolute-path) description from the arguments.
pub fn scene_from_args(args: &SceneArgs<'_>) -> anyhow::Result<(Scene, SceneConfig)> {
    let (config, dir) = scene_config_from_args(args)?;
    let loaded = match args.scene {
        Some(p) if !args.edits_scene() => load_scene_file(p),
        _ => load_scene(
            &config,
            &dir,
            args.scene.unwrap_or(Path::new("command line")),
        ),
    }
    .map_err(|e| with_fit_advice(e, &config))?;
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    Ok((loaded.scene, config))
}

/// A garment too far from the body to be bound to it says what to do: place it with `fit`
/// (`--skip-fit-check` cannot train it); the garment file stays last. Other errors pass as
/// they are.
fn with_fit_advice(error: IoError, config: &SceneConfig) -> anyhow::Error {
    match error {
        IoError::Scene {
            source: source @ SceneError::GarmentFarFromBody { .. },
            path,
        } => {
            let avatar = match &config.avatar {
                AvatarSource::File { path, .. } => Some(path.as_path()),
                AvatarSource::Builtin { .. } => None,
            };
            anyhow::anyhow!(
                "{source} {} (a garment this far from the body cannot be trained, not even with \
                 --skip-fit-check): {}",
                fit_advice(avatar, &path),
                path.display()
            )
        }
        other => other.into(),
    }
}

/// The scene description the arguments make (file paths absolute) and the folder its
/// relative paths were resolved against.
pub fn scene_config_from_args(args: &SceneArgs<'_>) -> anyhow::Result<(SceneConfig, PathBuf)> {
    let (mut config, dir) = match args.scene {
        Some(path) => {
            let config =
                SceneConfig::load(path).with_context(|| format!("reading {}", path.display()))?;
            (
                config,
                path.parent().map(Path::to_path_buf).unwrap_or_default(),
            )
        }
        None => (SceneConfig::default_scene(), std::env::current_dir()?),
    };
    if let (Some(a), Some(g)) = (args.avatar, args.garment) {
        replace_body(&mut config, a, g);
    }
    if let Some(folder) = args.motions {
        config.motions = motions_of_folder(folder)?;
    }
    for m in &mut config.motions {
        if let (Some(map), MotionSource::File { joint_map, .. }) = (args.joint_map, m)
            && joint_map.is_none()
        {
            *joint_map = Some(absolute(map));
        }
    }
    set_up_where_auto(&mut config, args.up);
    if let Some(fps) = args.training_fps {
        config.training_fps = fps;
    }
    // Paths stored in the run must not depend on the working directory.
    config.map_paths(|p| absolute(&SceneConfig::resolve_path(&dir, p)));
    Ok((config, dir))
}

fn absolute(p: &Path) -> PathBuf {
    std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf())
}

/// Puts the avatar `avatar` (a file, or `mannequin` for the built-in one) and the garment
/// file `garment` in the description.
fn replace_body(config: &mut SceneConfig, avatar: &Path, garment: &Path) {
    config.avatar = if avatar == Path::new("mannequin") && !avatar.exists() {
        AvatarSource::Builtin {
            builtin: neural_cloth::scene::config::BuiltinAvatar::Mannequin,
        }
    } else {
        AvatarSource::File {
            path: absolute(avatar),
            units: None,
            up: UpAxis::Auto,
        }
    };
    config.garment = GarmentSource::File {
        path: absolute(garment),
        units: None,
        up: UpAxis::Auto,
        smoothing_passes: None,
    };
}

/// The BVH and glTF files of `folder`, sorted by name, with the folder's splits
/// ([`folder_split`]).
fn motions_of_folder(folder: &Path) -> anyhow::Result<Vec<MotionSource>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(folder)
        .with_context(|| format!("listing {}", folder.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension().is_some_and(|e| {
                e.eq_ignore_ascii_case("bvh")
                    || e.eq_ignore_ascii_case("glb")
                    || e.eq_ignore_ascii_case("gltf")
            })
        })
        .collect();
    files.sort();
    anyhow::ensure!(
        !files.is_empty(),
        "no BVH or glTF motions in {}",
        folder.display()
    );
    if files.len() == 1 {
        eprintln!(
            "warning: one motion in {}: it trains, and no motion is left to validate or \
             test (eval --split train)",
            folder.display()
        );
    }
    Ok(files
        .iter()
        .enumerate()
        .map(|(k, p)| MotionSource::File {
            path: absolute(p),
            units: None,
            up: UpAxis::Auto,
            split: folder_split(k, files.len()),
            name: None,
            joint_map: None,
            mirrored: false,
        })
        .collect())
}

/// Sets the up axis of every file source of `config` still on auto to `up` (a source's own
/// setting in the scene file wins).
pub fn set_up_where_auto(config: &mut SceneConfig, up: UpAxis) {
    let set = |axis: &mut UpAxis| {
        if *axis == UpAxis::Auto {
            *axis = up;
        }
    };
    if let AvatarSource::File { up, .. } = &mut config.avatar {
        set(up);
    }
    if let GarmentSource::File { up, .. } = &mut config.garment {
        set(up);
    }
    for m in &mut config.motions {
        if let MotionSource::File { up, .. } = m {
            set(up);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn up_sets_the_file_sources_left_on_auto() {
        let mut config = SceneConfig::default_scene();
        replace_body(
            &mut config,
            Path::new("/a/body.glb"),
            Path::new("/a/shirt.obj"),
        );
        config.motions = vec![MotionSource::File {
            path: "/a/walk.bvh".into(),
            units: None,
            up: UpAxis::Y,
            split: neural_cloth::scene::Split::Train,
            name: None,
            joint_map: None,
            mirrored: false,
        }];
        set_up_where_auto(&mut config, UpAxis::Z);
        assert!(matches!(
            config.avatar,
            AvatarSource::File { up: UpAxis::Z, .. }
        ));
        assert!(matches!(
            config.garment,
            GarmentSource::File { up: UpAxis::Z, .. }
        ));
        // The scene file's own setting stays.
        assert!(matches!(
            config.motions[0],
            MotionSource::File { up: UpAxis::Y, .. }
        ));
        let args = SceneArgs {
            up: UpAxis::Z,
            ..SceneArgs::file(None)
        };
        assert!(args.edits_scene() && !SceneArgs::file(None).edits_scene());
    }

    #[test]
    fn fps_sets_the_scene_training_rate() {
        let args = SceneArgs {
            training_fps: Some(60.0),
            ..SceneArgs::file(None)
        };
        assert!(args.edits_scene());
        let (config, _) = scene_config_from_args(&args).unwrap();
        assert_eq!(config.training_fps, 60.0);
        let (config, _) = scene_config_from_args(&SceneArgs::file(None)).unwrap();
        assert_eq!(config.training_fps, 30.0);
    }
}
