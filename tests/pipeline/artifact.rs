//! A trained model travels with what it needs to run (issue 14): the app's export steps a
//! model at its own training rate, and a garment loaded in the app is rebuilt by `eval` and
//! `bake` with the skin-weight smoothing it was trained with.

use std::path::Path;
use std::sync::Arc;

use neural_cloth::app::export::{ExportFormat, ExportRequest, Exporter, ModelExporter};
use neural_cloth::app::project::RecentFiles;
use neural_cloth::app::{AppState, SceneParts, TrainingControl};
use neural_cloth::bake::{BakeOptions, ModelSource, bake};
use neural_cloth::geometry::Vec3;
use neural_cloth::io::export::read_pc2;
use neural_cloth::model::{DescriptorConfig, ModelArtifact};
use neural_cloth::scene::GarmentOptions;
use neural_cloth::scene::config::SceneConfig;
use neural_cloth::scene::procedural::{GarmentKind, build_builtin, builtin_garment};
use neural_cloth::train::handle::Session;
use neural_cloth::train::{
    RunDir, RunLocation, TrainConfig, TrainSetup, Trainer, load_trained, prepare,
};

/// Settings of a run that only needs a few steps (at its scene's training rate).
fn few_steps() -> TrainConfig {
    TrainConfig {
        max_steps: Some(2),
        predrape_secs: 0.0,
        fit_check: false,
        ..super::quick_config()
    }
}

/// The PC2 frames of `model` baked over the first motion of `scene` at 30 fps, through the
/// bake layer directly.
fn baked(model: &ModelArtifact, scene: &neural_cloth::scene::Scene, out: &Path) -> Vec<Vec<Vec3>> {
    let options = neural_cloth::model::InferenceOptions {
        skin_body: false,
        ..Default::default()
    };
    let engine = model
        .engine(&scene.avatar, &scene.garment, options)
        .unwrap();
    let bake_options = BakeOptions {
        out: out.to_path_buf(),
        fps: 30.0,
        ..Default::default()
    };
    bake(
        &scene.avatar,
        &scene.garment,
        &scene.motions[0].0,
        &mut ModelSource::new(engine),
        &bake_options,
        &mut |_, _| true,
    )
    .unwrap();
    read_pc2(out).unwrap().frames
}

fn max_distance(a: &[Vec<Vec3>], b: &[Vec<Vec3>]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .flat_map(|(fa, fb)| fa.iter().zip(fb).map(|(p, q)| (p - q).norm()))
        .fold(0.0, f32::max)
}

#[test]
fn bake_of_a_60_fps_model_steps_at_60_fps() {
    let dir = tempfile::tempdir().unwrap();
    let text = super::TINY.replace("training_fps = 30.0", "training_fps = 60.0");
    let scene_config = SceneConfig::from_toml_str(&text).unwrap();
    let scene = build_builtin(&scene_config).unwrap();
    let (mut session, _) = prepare(TrainSetup {
        scene: scene.clone(),
        scene_config,
        train: few_steps(),
        model: super::small_model(),
        descriptors: DescriptorConfig::default(),
        location: RunLocation::At(dir.path().join("run")),
    })
    .unwrap();
    session.step().unwrap();
    // What the trainer sends the app: the weights with the rate they are trained at.
    let mut snapshot = session.snapshot().unwrap();
    assert_eq!(snapshot.fps, 60.0);
    // The run records the rate it trains at, for eval, compare, bake and resume.
    let meta = RunDir::open(&dir.path().join("run"))
        .unwrap()
        .meta()
        .unwrap();
    assert_eq!(meta.training_fps, 60.0);
    // A fresh network's offsets are micrometres; make them large enough to compare.
    snapshot
        .weights
        .basis
        .weight
        .iter_mut()
        .for_each(|v| *v *= 100.0);
    let out = dir.path().join("export.pc2");
    // The app's avatar carries the motions the export dialog offers.
    let mut avatar = scene.avatar.clone();
    avatar.motions = vec![scene.motions[0].0.clone()];
    let request = ExportRequest {
        avatar: Arc::new(avatar),
        garment: Arc::new(scene.garment.clone()),
        motion: 0,
        weights: Some(Arc::new(snapshot.clone())),
        w: 1.0,
        fps: 30.0,
        format: ExportFormat::Pc2,
        path: out.clone(),
        preset: None,
        include_body: false,
        rest_obj: false,
    };
    ModelExporter.export(request, &mut |_, _| true).unwrap();
    let exported = read_pc2(&out).unwrap().frames;

    let at_60 = baked(&snapshot, &scene, &dir.path().join("60.pc2"));
    assert_eq!(exported.len(), at_60.len());
    assert!(
        max_distance(&exported, &at_60) == 0.0,
        "the export must step the model at 60 fps: {} m from the 60 fps bake",
        max_distance(&exported, &at_60)
    );
    // The same weights stepped at the default 30 fps give another sequence, so the
    // comparison above can tell the two rates apart.
    let at_30 = ModelArtifact {
        fps: 30.0,
        ..snapshot
    };
    let wrong = baked(&at_30, &scene, &dir.path().join("30.pc2"));
    assert!(
        max_distance(&exported, &wrong) > 1e-5,
        "the 30 fps bake should differ from the 60 fps one"
    );
}

#[test]
fn skirt_loaded_in_the_app_evaluates_from_the_cli_with_the_same_smoothing() {
    let dir = tempfile::tempdir().unwrap();
    // A skirt file: the app smooths the skin weights of garments named so more.
    let (mut scene, config) = super::tiny();
    let skirt = builtin_garment(&scene.avatar, GarmentKind::Skirt, 300, None).unwrap();
    let path = dir.path().join("skirt.obj");
    let text = neural_cloth::io::export::obj_seq::obj_text(
        &skirt.mesh.positions,
        &skirt.mesh.faces,
        None,
        "a skirt",
    );
    std::fs::write(&path, text).unwrap();
    let mut app = AppState::new(
        SceneParts::from_scene(scene.clone(), config),
        TrainingControl::new(None),
        RecentFiles::default(),
    );
    assert!(app.load_garment(&path), "{:?}", app.messages);
    let garment = app.scene.garment.as_deref().unwrap().clone();
    assert_eq!(
        garment.smoothing_passes,
        GarmentOptions::LOOSE_SMOOTHING_PASSES
    );

    // Train on it as the app does: the run records the app's scene description.
    scene.garment = garment.clone();
    let run = dir.path().join("run");
    let setup = TrainSetup {
        scene,
        scene_config: app.scene.config.clone(),
        train: few_steps(),
        model: super::small_model(),
        descriptors: DescriptorConfig::default(),
        location: RunLocation::At(run.clone()),
    };
    let (_, result) = super::run_to_end(Trainer::spawn(setup, None).unwrap());
    result.unwrap();

    // `eval` and `bake` load the run this way: the same garment, skin weights included.
    let trained = load_trained(&run).unwrap();
    assert_eq!(
        trained.scene.garment.smoothing_passes,
        garment.smoothing_passes
    );
    assert_eq!(trained.scene.garment.skin, garment.skin);
    trained.garment_engine().unwrap();

    // A scene description that rebuilds the skirt with other smoothing is refused.
    let toml_path = run.join("scene.toml");
    let mut recorded = SceneConfig::load(&toml_path).unwrap();
    if let neural_cloth::scene::config::GarmentSource::File {
        smoothing_passes, ..
    } = &mut recorded.garment
    {
        *smoothing_passes = Some(3);
    }
    std::fs::write(&toml_path, recorded.to_toml_string().unwrap()).unwrap();
    let refused = load_trained(&run)
        .err()
        .expect("a garment with other skin weights");
    assert!(refused.to_string().contains("skin weights"), "{refused}");
}
