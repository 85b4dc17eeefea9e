//! Project files of the first layout (version 1, before the scene became a [`SceneConfig`]):
//! `[scene]` named the avatar, garment and extra BVH motion files (none: the built-in parts),
//! with `[fabric]`, `[effects]` and the training rate apart (`[training] fps`, default 30).
//! They are read and converted to the current layout, the rate into `scene.training_fps`; the
//! app saves them in the current one.

use std::path::PathBuf;

use serde::Deserialize;

use neural_cloth_core::scene::config::{
    AvatarSource, DEFAULT_TRAINING_FPS, GarmentSource, MotionSource, SceneConfig, Split,
};
use neural_cloth_core::scene::{Effects, FabricParams, UpAxis};
use neural_cloth_train::TrainConfig;

use super::project::{
    InvalidProject, PROJECT_VERSION, ProjectFile, ViewSettings, take_training_fps,
};

/// Where a version-1 scene came from: `None` means the built-in default.
#[derive(Debug, Default, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct SceneSources {
    avatar: Option<PathBuf>,
    garment: Option<PathBuf>,
    motions: Vec<PathBuf>,
    /// The preset the fabric started from, for display (now told from the values).
    #[serde(rename = "fabric_preset")]
    _fabric_preset: Option<String>,
}

/// A version-1 project file.
#[derive(Debug, Default, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct ProjectFileV1 {
    #[serde(rename = "version")]
    _version: u32,
    scene: SceneSources,
    fabric: FabricParams,
    effects: Effects,
    /// The training settings without their `fps` (taken out before: [`take_training_fps`]).
    training: TrainConfig,
    #[serde(alias = "run_dir")]
    runs_folder: Option<PathBuf>,
    run: Option<PathBuf>,
    #[serde(rename = "retention")]
    _retention: Option<serde::de::IgnoredAny>,
    view: ViewSettings,
}

/// Whether a project table without a `version` key has the first layout: `[fabric]` or
/// `[effects]` at the top, or a `[scene]` naming its avatar, garment or motions as plain paths.
pub fn looks_like_v1(table: &toml::Table) -> bool {
    if table.contains_key("fabric") || table.contains_key("effects") {
        return true;
    }
    let Some(scene) = table.get("scene").and_then(toml::Value::as_table) else {
        return false;
    };
    let is_path = |key: &str| scene.get(key).is_some_and(toml::Value::is_str);
    let motion_paths = scene
        .get("motions")
        .and_then(toml::Value::as_array)
        .is_some_and(|m| m.iter().any(toml::Value::is_str));
    is_path("avatar") || is_path("garment") || motion_paths || scene.contains_key("fabric_preset")
}

/// Reads a version-1 project (paths as written) in the current layout, describing the scene
/// the app of that version showed: the built-in scene with the named files in place of its
/// avatar and garment; a loaded avatar brought its own animations (all training) and replaced
/// the built-in motions; extra BVH motions trained; a garment file's skin weights were
/// smoothed by its name's rule (the loader's default).
pub fn convert(mut table: toml::Table) -> Result<ProjectFile, InvalidProject> {
    let v1 = |e: InvalidProject| InvalidProject::Version1(Box::new(e));
    let training_fps = take_training_fps(&mut table)
        .map_err(v1)?
        .unwrap_or(DEFAULT_TRAINING_FPS);
    let old: ProjectFileV1 = toml::Value::Table(table)
        .try_into()
        .map_err(|e: toml::de::Error| v1(e.into()))?;
    let mut scene = SceneConfig::default_scene();
    let file_motion = |path: PathBuf| MotionSource::File {
        path,
        units: None,
        up: UpAxis::Auto,
        split: Split::Train,
        name: None,
        joint_map: None,
        mirrored: false,
    };
    if let Some(avatar) = &old.scene.avatar {
        scene.name = avatar
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .filter(|s| !s.trim().is_empty())
            .unwrap_or_else(|| "avatar".into());
        scene.avatar = AvatarSource::File {
            path: avatar.clone(),
            units: None,
            up: UpAxis::Auto,
        };
        scene.motions = vec![file_motion(avatar.clone())];
    }
    if let Some(garment) = &old.scene.garment {
        scene.garment = GarmentSource::File {
            path: garment.clone(),
            units: None,
            up: UpAxis::Auto,
            smoothing_passes: None,
        };
    }
    scene
        .motions
        .extend(old.scene.motions.iter().cloned().map(file_motion));
    scene.effects = old.effects;
    scene.fabric = old.fabric;
    scene.training_fps = training_fps;
    Ok(ProjectFile {
        version: PROJECT_VERSION,
        scene,
        training: old.training,
        runs_folder: old.runs_folder,
        run: old.run,
        old_retention: None,
        view: old.view,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use neural_cloth_core::scene::procedural::GarmentKind;

    /// A project as the version-1 app saved it.
    const OLD: &str = r#"# neural-cloth project
version = 1
run = "runs/run-1"

[scene]
garment = "garments/skirt.obj"
motions = ["motions/walk.bvh"]
fabric_preset = "custom"

[fabric]
cloth_model = "baraff_witkin"
stretch_stiffness = 30.0
shear_stiffness = 3.0
lame_lambda = 20.9
lame_mu = 11.1
bending_stiffness = 0.0001
density_kg_per_m2 = 0.41
collision_stiffness = 30.0
collision_threshold_m = 0.004
pinning_stiffness = 100.0
gravity_m_per_s2 = [0.0, -9.81, 0.0]

[effects]
gravity = true
bending = true
collision = true
dynamics = false
pinning = false

[training]
fps = 60.0
window_secs = 1.0

[retention]
keep_newest = 5

[view]
w = 1.5
"#;

    #[test]
    fn a_version_1_project_opens_as_the_scene_it_described() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("old.toml");
        std::fs::write(&file, OLD).unwrap();
        let p = ProjectFile::open(&file).unwrap();
        assert_eq!(p.version, PROJECT_VERSION);
        let s = &p.scene;
        assert!(matches!(s.avatar, AvatarSource::Builtin { .. }));
        assert_eq!(
            s.garment,
            GarmentSource::File {
                path: dir.path().join("garments/skirt.obj"),
                units: None,
                up: UpAxis::Auto,
                smoothing_passes: None,
            }
        );
        // The built-in motions with their splits, then the BVH file (training).
        let default = SceneConfig::default_scene();
        assert_eq!(s.motions[..default.motions.len()], default.motions[..]);
        assert_eq!(
            s.motions.last(),
            Some(&MotionSource::File {
                path: dir.path().join("motions/walk.bvh"),
                units: None,
                up: UpAxis::Auto,
                split: Split::Train,
                name: None,
                joint_map: None,
                mirrored: false,
            })
        );
        assert_eq!(s.fabric.density_kg_per_m2, 0.41);
        assert_eq!(s.fabric.bending_stiffness, 1e-4);
        assert!(!s.effects.dynamics);
        assert_eq!(s.training_fps, 60.0);
        assert_eq!(p.training.window_secs, 1.0);
        assert_eq!(p.run, Some(dir.path().join("runs/run-1")));
        assert_eq!(p.view.w, 1.5);
        // Saved again, it is a current project describing the same.
        p.save(&file).unwrap();
        let text = std::fs::read_to_string(&file).unwrap();
        assert!(text.contains("version = 2"), "{text}");
        assert_eq!(ProjectFile::open(&file).unwrap(), p);
    }

    #[test]
    fn a_version_1_avatar_brings_its_animations_and_the_garment_stays_built_in() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("old.toml");
        std::fs::write(
            &file,
            "version = 1\n[scene]\navatar = \"/a/CesiumMan.glb\"\nmotions = [\"/m/walk.bvh\"]\n",
        )
        .unwrap();
        let s = ProjectFile::open(&file).unwrap().scene;
        assert_eq!(s.name, "CesiumMan");
        assert!(
            matches!(&s.avatar, AvatarSource::File { path, .. } if path.ends_with("CesiumMan.glb"))
        );
        let paths: Vec<_> = s
            .motions
            .iter()
            .map(|m| match m {
                MotionSource::File { path, split, .. } => (path.clone(), *split),
                MotionSource::Builtin { .. } => panic!("no built-in motion on a file avatar"),
            })
            .collect();
        assert_eq!(
            paths,
            vec![
                (PathBuf::from("/a/CesiumMan.glb"), Split::Train),
                (PathBuf::from("/m/walk.bvh"), Split::Train)
            ]
        );
        // The version-1 app had no garment then (the built-in one fits the mannequin only);
        // the converted scene keeps the built-in one, which the app reports as not fitting.
        assert!(matches!(
            s.garment,
            GarmentSource::Builtin {
                builtin: GarmentKind::TShirt,
                ..
            }
        ));
    }

    #[test]
    fn a_broken_version_1_project_names_the_problem_and_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("old.toml");
        std::fs::write(&file, "version = 1\n[fabric]\ndensity_kg_per_m2 = -3.0\n").unwrap();
        let err = ProjectFile::open(&file).unwrap_err().to_string();
        assert!(
            err.contains("density_kg_per_m2") && err.ends_with("old.toml"),
            "{err}"
        );
        std::fs::write(&file, "version = 1\n[scene]\nfabrik = 1\n").unwrap();
        let err = ProjectFile::open(&file).unwrap_err().to_string();
        assert!(err.contains("fabrik") && err.contains("version 1"), "{err}");
    }
}

#[cfg(test)]
mod layout_tests {
    use super::*;

    fn table(text: &str) -> toml::Table {
        text.parse().unwrap()
    }

    #[test]
    fn a_first_layout_is_told_without_its_version_key() {
        assert!(looks_like_v1(&table("[fabric]\ndensity_kg_per_m2 = 0.5\n")));
        assert!(looks_like_v1(&table("[effects]\ndynamics = false\n")));
        assert!(looks_like_v1(&table("[scene]\ngarment = \"shirt.obj\"\n")));
        assert!(looks_like_v1(&table("[scene]\nmotions = [\"walk.bvh\"]\n")));
        // The current layout: sources are tables, fabric and effects live in the scene.
        assert!(!looks_like_v1(&table(
            "[scene]\nname = \"s\"\n[scene.garment]\nbuiltin = \"skirt\"\n[scene.effects]\ndynamics = true\n"
        )));
        assert!(!looks_like_v1(&table("[view]\nw = 1.0\n")));
    }

    /// Review: a version-1 project without its `version` key was read as version 2 and refused
    /// with an unknown-field message.
    #[test]
    fn a_version_1_project_without_its_version_key_opens() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("old.toml");
        std::fs::write(
            &path,
            "[scene]\ngarment = \"shirt.obj\"\n[effects]\ndynamics = false\n[training]\nfps = 60.0\n",
        )
        .unwrap();
        let project = ProjectFile::open(&path).unwrap();
        assert!(!project.scene.effects.dynamics);
        assert!(matches!(project.scene.garment, GarmentSource::File { .. }));
        assert_eq!(project.scene.training_fps, 60.0);
    }
}
