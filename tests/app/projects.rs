//! One scene description (issue 14): the project embeds the app's [`SceneConfig`], so a
//! built-in garment is saved by kind, a training run records the app's own description, and a
//! project file of the first layout (version 1) still opens as the scene it described.

use std::sync::Arc;

use neural_cloth::app::LoadKind;
use neural_cloth::physics::FabricParams;
use neural_cloth::scene::config::{GarmentSource, MotionSource, SceneConfig};
use neural_cloth::scene::procedural::{GarmentKind, build_builtin};
use neural_cloth::scene::{Split, procedural};

use super::{FakeLauncher, assets, click, harness, wait_for_preview};

/// The default scene with the built-in skirt (a coarse one, so it builds quickly).
fn skirt_scene() -> SceneConfig {
    let mut config = SceneConfig::default_scene();
    config.garment = GarmentSource::Builtin {
        builtin: GarmentKind::Skirt,
        resolution: 600,
        smoothing_passes: None,
    };
    config
}

#[test]
fn a_project_with_the_built_in_skirt_reopens_with_the_skirt() {
    let dir = tempfile::tempdir().expect("temp dir");
    let file = dir.path().join("skirt.toml");
    let mut h = harness(None);
    {
        let s = &mut h.state_mut().state;
        assert!(s.open_scene(skirt_scene()), "{:?}", s.messages);
        assert_eq!(
            s.scene.garment.as_ref().map(|g| g.name.as_str()),
            Some("skirt")
        );
        assert!(s.save_project(&file), "{:?}", s.last_error());
    }
    let text = std::fs::read_to_string(&file).expect("saved");
    assert!(text.contains("builtin = \"skirt\""), "{text}");

    let mut again = harness(None);
    assert!(again.state_mut().open_project(&file));
    wait_for_preview(&mut again);
    let s = &again.state().state;
    let garment = s.scene.garment.as_ref().expect("a garment");
    assert_eq!(garment.name, "skirt", "{:?}", s.messages);
    assert_eq!(s.scene.config.garment, skirt_scene().garment);
    // The same skirt the built-in scene makes, skin weights included.
    let built = build_builtin(&skirt_scene()).expect("builds");
    assert_eq!(garment.skin, built.garment.skin);
    assert!(!s.has_unsaved_changes());
}

#[test]
fn a_run_records_the_apps_own_scene_description() {
    let requests = Arc::new(std::sync::Mutex::new(Vec::new()));
    let mut h = harness(Some(Box::new(FakeLauncher {
        requests: requests.clone(),
    })));
    let walk = assets().join("motions/cmu_02_01_walk.bvh");
    assert!(h.state_mut().state.load_file(LoadKind::Motion, &walk));
    h.state_mut().state.apply_preset("denim");
    h.run();
    click(&mut h, "Train");
    h.step();
    let request = requests
        .lock()
        .expect("requests")
        .first()
        .cloned()
        .expect("a request");
    let config = &request.scene_config;
    assert_eq!(*config, h.state().state.scene.config);
    config.validate().expect("a trainable description");
    // The built-in motions with their splits, then the BVH file (training).
    let default = SceneConfig::default_scene();
    assert_eq!(config.motions[..default.motions.len()], default.motions[..]);
    assert!(matches!(
        config.motions.last(),
        Some(MotionSource::File { path, split: Split::Train, .. }) if path.ends_with("cmu_02_01_walk.bvh")
    ));
    assert_eq!(
        request.scene.motions.len(),
        default.motions.len() + 1,
        "one loaded motion per source"
    );
    // One fabric: the scene's, in the description and the scene built from it.
    let denim = FabricParams::preset("denim").expect("preset");
    assert_eq!((&config.fabric, &request.scene.fabric), (&denim, &denim));
    assert_eq!(request.scene.training_fps, config.training_fps);
    click(&mut h, "Stop");
}

/// A project as the version-1 app saved it: the built-in scene with a garment file and a BVH
/// motion, the denim fabric edited, dynamics off, 60 fps training.
fn old_project(garment: &str, motion: &str) -> String {
    format!(
        r#"# neural-cloth project
version = 1

[scene]
garment = "{garment}"
motions = ["{motion}"]
fabric_preset = "custom"

[fabric]
cloth_model = "baraff_witkin"
stretch_stiffness = 30.0
shear_stiffness = 3.0
lame_lambda = 20.9
lame_mu = 11.1
bending_stiffness = 0.000125
density_kg_per_m2 = 0.5
collision_stiffness = 30.0
collision_threshold_m = 0.004
pinning_stiffness = 100.0
gravity_m_per_s2 = [0.0, -9.81, 0.0]

[effects]
dynamics = false

[training]
fps = 60.0
window_secs = 0.75

[view]
w = 1.25
"#
    )
}

#[test]
fn a_version_1_project_opens_as_the_scene_it_described() {
    let dir = tempfile::tempdir().expect("temp dir");
    // The garment file: the built-in t-shirt's mesh.
    let tshirt = procedural::default_scene().expect("default scene").garment;
    let garment = dir.path().join("shirt.obj");
    let text = neural_cloth::io::export::obj_seq::obj_text(
        &tshirt.mesh.positions,
        &tshirt.mesh.faces,
        None,
        "shirt",
    );
    std::fs::write(&garment, text).expect("write");
    let walk = std::path::absolute(assets().join("motions/cmu_02_01_walk.bvh")).expect("path");
    let file = dir.path().join("old.toml");
    std::fs::write(&file, old_project("shirt.obj", &walk.display().to_string())).expect("write");

    let mut h = harness(None);
    assert!(
        h.state_mut().open_project(&file),
        "{:?}",
        h.state().state.messages
    );
    wait_for_preview(&mut h);
    let s = &h.state().state;
    assert_eq!(s.last_error(), None, "{:?}", s.messages);
    assert_eq!(s.scene_file(LoadKind::Garment), Some(garment.clone()));
    assert_eq!(
        s.scene.garment.as_ref().map(|g| g.vertex_count()),
        Some(tshirt.vertex_count())
    );
    let motions = &s.scene.avatar.motions;
    assert_eq!(
        motions.last().map(|m| m.name.as_str()),
        Some("cmu_02_01_walk")
    );
    assert_eq!(s.scene.splits.last(), Some(&Split::Train));
    assert!(s.scene.splits.contains(&Split::Validation) && s.scene.splits.contains(&Split::Test));
    assert_eq!(s.fabric().density_kg_per_m2, 0.5);
    assert_eq!(s.fabric_preset(), "custom");
    assert!(!s.scene.config.effects.dynamics);
    assert_eq!(s.scene.config.training_fps, 60.0);
    assert_eq!((s.train_config.window_secs, s.w), (0.75, 1.25));

    // Saved again, it is a current project that opens the same.
    let saved = dir.path().join("new.toml");
    assert!(h.state_mut().state.save_project(&saved));
    let text = std::fs::read_to_string(&saved).expect("saved");
    assert!(
        text.contains("version = 2") && text.contains("path = \"shirt.obj\""),
        "{text}"
    );
    let mut again = harness(None);
    assert!(again.state_mut().open_project(&saved));
    assert_eq!(
        again.state().state.scene.config,
        h.state().state.scene.config
    );
}
