//! End-to-end tests of training, checkpoints, baking and the CLI on a tiny built-in scene.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;
use std::time::Duration;

use burn::tensor::{Tensor, TensorData};
use neural_cloth::bake::{BakeFormat, BakeOptions, ModelSource, bake};
use neural_cloth::io::export::{read_mdd, read_pc2};
use neural_cloth::model::{
    ClothNetConfig, DescriptorConfig, InferenceEngine, InferenceOptions, ModelArtifact,
};
use neural_cloth::physics::{FabricParams, PhysicsTerms};
use neural_cloth::scene::Scene;
use neural_cloth::scene::config::SceneConfig;
use neural_cloth::scene::procedural::build_builtin;
use neural_cloth::train::handle::{LoopConfig, Session};
use neural_cloth::train::losses::inertia_through_past;
use neural_cloth::train::metrics::{MetricHistory, MetricRecord};
use neural_cloth::train::{
    RunLocation, TrainConfig, TrainError, TrainEvent, TrainSetup, Trainer, TrainerHandle,
    load_trained, prepare,
};

// Crash safety (kill, damaged files, full disk) and resuming: `pipeline/*.rs`.
#[path = "pipeline/artifact.rs"]
mod artifact;
#[path = "pipeline/corrupt.rs"]
mod corrupt;
#[path = "pipeline/crash.rs"]
mod crash;
#[path = "pipeline/disk_full.rs"]
mod disk_full;
#[path = "pipeline/filter.rs"]
mod filter;
#[path = "pipeline/fit_reference.rs"]
mod fit_reference;
#[path = "pipeline/fixture.rs"]
mod fixture;
#[path = "pipeline/resume.rs"]
mod resume;
#[path = "common/tiny_scene.rs"]
mod tiny_scene;
use tiny_scene::TINY;

fn tiny() -> (Scene, SceneConfig) {
    let config = SceneConfig::from_toml_str(TINY).unwrap();
    (build_builtin(&config).unwrap(), config)
}

/// A small network so the tests run in seconds.
fn small_model() -> ClothNetConfig {
    ClothNetConfig {
        static_hidden: vec![32, 32],
        joint_hidden: vec![16],
        dynamic_hidden: vec![64],
        latent: 64,
        decoder_hidden: vec![64, 64],
        ..Default::default()
    }
}

fn setup(dir: &Path, train: TrainConfig, location: Option<RunLocation>) -> TrainSetup {
    let (scene, scene_config) = tiny();
    TrainSetup {
        scene,
        scene_config,
        train,
        model: small_model(),
        descriptors: DescriptorConfig::default(),
        location: location.unwrap_or_else(|| RunLocation::At(dir.to_path_buf())),
    }
}

/// A fresh inference engine of a trained run on its own scene, at the training rate.
fn engine_of(trained: &neural_cloth::train::TrainedModel) -> InferenceEngine {
    trained.engine(InferenceOptions::default()).unwrap()
}

fn quick_config() -> TrainConfig {
    TrainConfig {
        batch_size: 4,
        window_secs: 0.2,
        seed: 7,
        learning_rate: 1e-3,
        ..Default::default()
    }
}

fn run_to_end(
    handle: TrainerHandle,
) -> (
    Vec<TrainEvent>,
    Result<neural_cloth::train::RunSummary, String>,
) {
    let mut events = Vec::new();
    loop {
        match handle.recv_timeout(Duration::from_secs(120)) {
            Some(TrainEvent::Finished(result)) => {
                return (events, result.map_err(|e| e.to_string()));
            }
            Some(e) => events.push(e),
            None => panic!("trainer went silent; events so far: {}", events.len()),
        }
    }
}

#[test]
fn training_lowers_the_loss_and_collisions() {
    let dir = tempfile::tempdir().unwrap();
    // A large basis initialisation: the untrained garment crumples into the body.
    let mut s = setup(dir.path(), quick_config(), None);
    s.model.basis_init_gain = 30.0;
    let (mut session, _) = prepare(s).unwrap();
    let before = session.validate().unwrap();
    eprintln!("before {before:?}");
    assert!(before.is_finite());
    for _ in 0..60 {
        let r = session.step().unwrap();
        assert!(r.is_finite(), "{r:?}");
    }
    let after = session.validate().unwrap();
    eprintln!("after {after:?}");
    assert!(after.is_finite(), "{after:?}");
    assert!(
        after.loss < before.loss,
        "loss {} -> {}",
        before.loss,
        after.loss
    );
    assert!(
        after.collision_pct < before.collision_pct
            || (before.collision_pct == 0.0 && after.collision_pct == 0.0),
        "collision {}% -> {}%",
        before.collision_pct,
        after.collision_pct
    );
    assert!(
        before.collision_pct > 0.0,
        "the random initial model should put some vertices inside the body"
    );
}

#[test]
fn inertia_gradient_reaches_only_the_current_frame_unless_snug() {
    let (scene, _) = tiny();
    let device = neural_cloth::train::device_for(neural_cloth::train::BackendKind::Cpu, true);
    let fabric = scene.fabric.clone();
    let terms = PhysicsTerms::new(&scene.garment, &fabric, &scene.effects, &device).unwrap();
    let v = scene.garment.vertex_count();
    let base: Vec<f32> = scene
        .garment
        .mesh
        .positions
        .iter()
        .flat_map(|p| [p.x, p.y, p.z])
        .collect();
    let make = |shift: f32| {
        let data: Vec<f32> = base
            .iter()
            .enumerate()
            .map(|(i, x)| x + shift * ((i % 7) as f32 - 3.0) * 1e-3)
            .collect();
        Tensor::<3>::from_data(TensorData::new(data, [1, v, 3]), &device).require_grad()
    };
    for snug in [false, true] {
        let (x_t, x_t1, x_t2) = (make(1.0), make(0.5), make(0.0));
        let loss = if snug {
            inertia_through_past(&terms, &x_t, &x_t1, &x_t2, 1.0 / 30.0).unwrap()
        } else {
            terms.inertia(&x_t, &x_t1, &x_t2, 1.0 / 30.0).unwrap()
        };
        let grads = loss.backward();
        let norm = |t: &Tensor<3>| {
            t.grad(&grads)
                .map(|g| g.abs().sum().into_scalar::<f32>())
                .unwrap_or(0.0)
        };
        assert!(norm(&x_t) > 0.0);
        if snug {
            assert!(
                norm(&x_t1) > 0.0 && norm(&x_t2) > 0.0,
                "snug mode must reach the past frames"
            );
        } else {
            assert_eq!(
                (norm(&x_t1), norm(&x_t2)),
                (0.0, 0.0),
                "ours must stop the gradient at the past frames"
            );
        }
    }
}

#[test]
fn checkpoints_reload_identically_and_resume_continues() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let config = TrainConfig {
        max_steps: Some(6),
        checkpoint_every: 3,
        validate_every: 3,
        snapshot_every: 2,
        ..quick_config()
    };
    let (events, result) =
        run_to_end(Trainer::spawn(setup(&run, config.clone(), None), None).unwrap());
    let summary = result.unwrap();
    assert_eq!(summary.steps, 6);
    let snapshot = events
        .iter()
        .rev()
        .find_map(|e| match e {
            TrainEvent::Snapshot { step: 6, weights } => Some(weights.clone()),
            _ => None,
        })
        .expect("a final snapshot");
    assert!(
        events
            .iter()
            .any(|e| matches!(e, TrainEvent::Checkpoint { step: 3, .. }))
    );

    // The checkpoint reloads to exactly the weights the trainer had.
    let trained = load_trained(&run).unwrap();
    assert_eq!(trained.step, 6);
    assert_eq!(trained.artifact, *snapshot);
    let predict = |model: &ModelArtifact| {
        let mut engine = model
            .engine(
                &trained.scene.avatar,
                &trained.scene.garment,
                InferenceOptions::default(),
            )
            .unwrap();
        let motion = &trained.scene.motions[0].0;
        for pose in motion.frames.iter().take(10) {
            engine.step(pose, 1.0).unwrap();
        }
        engine.garment_positions().to_vec()
    };
    assert_eq!(predict(&trained.artifact), predict(&snapshot));

    // Regression (a checkpoint folder loaded the run's newest checkpoint): naming the folder
    // of step 3 loads step 3, whose weights are not those of step 6.
    let older = load_trained(&run.join("checkpoints").join("step-00000003")).unwrap();
    assert_eq!(older.step, 3);
    assert_ne!(predict(&older.artifact), predict(&snapshot));
    assert!(load_trained(&run.join("checkpoints").join("step-00000005")).is_err());
    // Neither a run nor a checkpoint folder: refused, not the run's newest checkpoint.
    assert!(load_trained(&run.join("checkpoints")).is_err());

    // Resume: the step count and the metric history continue.
    let resumed = TrainConfig {
        max_steps: Some(9),
        ..config
    };
    let (events, result) = run_to_end(
        Trainer::spawn(
            setup(&run, resumed, Some(RunLocation::Resume(run.clone()))),
            None,
        )
        .unwrap(),
    );
    assert!(
        matches!(events.first(), Some(TrainEvent::Started { step: 6, .. })),
        "{:?}",
        events.first()
    );
    assert_eq!(result.unwrap().steps, 9);
    let history = neural_cloth::train::RunDir::open(&run).unwrap().history();
    let steps: Vec<u64> = history.train.iter().map(|r| r.step).collect();
    assert_eq!(steps, (1..=9).collect::<Vec<_>>());
}

/// Delegates to the real session but poisons the loss of one step.
struct Poisoned<S: Session> {
    inner: S,
    calls: u64,
    poison_at: u64,
}

impl<S: Session> Session for Poisoned<S> {
    fn step(&mut self) -> Result<MetricRecord, TrainError> {
        self.calls += 1;
        let mut r = self.inner.step()?;
        if self.calls == self.poison_at {
            r.loss = f64::NAN;
        }
        Ok(r)
    }
    fn validate(&mut self) -> Result<MetricRecord, TrainError> {
        self.inner.validate()
    }
    fn weights_finite(&self) -> bool {
        self.inner.weights_finite()
    }
    fn snapshot(&self) -> Result<neural_cloth::model::ModelArtifact, TrainError> {
        self.inner.snapshot()
    }
    fn checkpoint(&mut self, step: u64, history: &MetricHistory) -> Result<PathBuf, TrainError> {
        self.inner.checkpoint(step, history)
    }
    fn restore_last_checkpoint(&mut self) -> Result<u64, TrainError> {
        self.inner.restore_last_checkpoint()
    }
    fn learning_rate(&self) -> f64 {
        self.inner.learning_rate()
    }
    fn set_learning_rate(&mut self, lr: f64) {
        self.inner.set_learning_rate(lr)
    }
    fn set_fabric(&mut self, fabric: FabricParams) -> Result<(), TrainError> {
        self.inner.set_fabric(fabric)
    }
    fn set_window(&mut self, window_secs: f32) -> Result<(), TrainError> {
        self.inner.set_window(window_secs)
    }
    fn activity_summary(&self) -> Option<String> {
        self.inner.activity_summary()
    }
    fn revive_dead_units(&mut self) -> Result<usize, TrainError> {
        self.inner.revive_dead_units()
    }
}

#[test]
fn a_non_finite_loss_rolls_back_and_lowers_the_learning_rate() {
    let dir = tempfile::tempdir().unwrap();
    let config = TrainConfig {
        max_steps: Some(8),
        checkpoint_every: 4,
        validate_every: 100,
        ..quick_config()
    };
    let (session, loop_config): (_, LoopConfig) = prepare(setup(dir.path(), config, None)).unwrap();
    let poisoned = Poisoned {
        inner: session,
        calls: 0,
        poison_at: 6,
    };
    let (events, result) =
        run_to_end(TrainerHandle::spawn_session(poisoned, loop_config, None).unwrap());
    let rollback = events.iter().find_map(|e| match e {
        TrainEvent::RolledBack {
            diverged_at,
            restored_step,
            learning_rate,
        } => Some((*diverged_at, *restored_step, *learning_rate)),
        _ => None,
    });
    let (diverged_at, restored, lr) = rollback.expect("a rollback event");
    assert_eq!((diverged_at, restored), (6, 4));
    assert!((lr - 5e-4).abs() < 1e-12, "learning rate {lr}");
    let summary = result.unwrap();
    assert_eq!((summary.steps, summary.rollbacks), (8, 1));
}

#[test]
fn baked_caches_round_trip_and_bad_requests_leave_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let config = TrainConfig {
        max_steps: Some(2),
        ..quick_config()
    };
    run_to_end(Trainer::spawn(setup(&run, config, None), None).unwrap())
        .1
        .unwrap();
    let trained = load_trained(&run).unwrap();
    let scene = &trained.scene;
    let motion = scene.motions[0].0.clone();
    let engine = || engine_of(&trained);
    // Reference frames straight from the engine at the training rate.
    let mut reference = engine();
    let expected: Vec<Vec<_>> = motion
        .frames
        .iter()
        .map(|p| {
            reference.step(p, 1.0).unwrap();
            reference.garment_positions().to_vec()
        })
        .collect();
    for format in [BakeFormat::Pc2, BakeFormat::Mdd] {
        let out = dir.path().join(format!("walk.{}", format.extension()));
        let options = BakeOptions {
            format,
            out: out.clone(),
            fps: 30.0,
            ..Default::default()
        };
        let mut source = ModelSource::new(engine());
        let report = bake(
            &scene.avatar,
            &scene.garment,
            &motion,
            &mut source,
            &options,
            &mut |_, _| true,
        )
        .unwrap();
        assert_eq!(report.frames, expected.len());
        let frames = match format {
            BakeFormat::Pc2 => read_pc2(&out).unwrap().frames,
            _ => read_mdd(&out).unwrap().frames,
        };
        assert_eq!(frames, expected, "{format:?} must round-trip bit for bit");
    }
    // w outside [0, 2], a missing folder and a cancelled bake leave no file behind.
    let before = std::fs::read_dir(dir.path()).unwrap().count();
    for options in [
        BakeOptions {
            w: 2.5,
            out: dir.path().join("bad.pc2"),
            ..Default::default()
        },
        BakeOptions {
            out: dir.path().join("missing/bad.pc2"),
            ..Default::default()
        },
    ] {
        let mut source = ModelSource::new(engine());
        assert!(
            bake(
                &scene.avatar,
                &scene.garment,
                &motion,
                &mut source,
                &options,
                &mut |_, _| true
            )
            .is_err()
        );
    }
    let mut source = ModelSource::new(engine());
    let cancelled = bake(
        &scene.avatar,
        &scene.garment,
        &motion,
        &mut source,
        &BakeOptions {
            out: dir.path().join("c.pc2"),
            ..Default::default()
        },
        &mut |done, _| done < 5,
    );
    assert!(cancelled.is_err());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), before);
}

fn cli(args: &[&str], cwd: &Path) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_neural-cloth"))
        .args(args)
        .current_dir(cwd)
        .output()
        .unwrap();
    (
        out.status.success(),
        format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ),
    )
}

/// Issue 15: checkpoint retention from the command line (it was only in the app's Runs panel).
#[test]
fn cli_train_keeps_the_checkpoints_it_is_told_to() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tiny.toml"), TINY).unwrap();
    let args = |keep: &'static str| {
        [
            "train",
            "--scene",
            "tiny.toml",
            "--steps",
            "4",
            "--batch",
            "2",
            "--predrape-secs",
            "0",
            "--checkpoint-every",
            "1",
            "--out",
            "run",
            "--keep-checkpoints",
            keep,
            "--no-keep-best",
        ]
    };
    let (ok, log) = cli(&args("0"), dir.path());
    assert!(
        !ok && log.contains("--keep-checkpoints 0 is outside"),
        "{log}"
    );
    let (ok, log) = cli(&args("1"), dir.path());
    assert!(ok, "{log}");
    assert!(log.contains("keeping the newest 1 checkpoint(s)"), "{log}");
    let kept: Vec<_> = std::fs::read_dir(dir.path().join("run/checkpoints"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|name| name.starts_with("step-"))
        .collect();
    assert_eq!(kept, ["step-00000004"], "{log}");
    let policy = std::fs::read_to_string(dir.path().join("run/retention.json")).unwrap();
    assert!(policy.contains("\"keep_best\": false"), "{policy}");
}

#[test]
fn cli_trains_bakes_and_refuses_a_foreign_garment() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tiny.toml"), TINY).unwrap();
    let (ok, log) = cli(
        &[
            "train",
            "--scene",
            "tiny.toml",
            "--steps",
            "2",
            "--batch",
            "2",
            "--out",
            "run",
        ],
        dir.path(),
    );
    assert!(ok, "{log}");
    assert!(log.contains("\"steps\": 2"), "{log}");
    let (ok, log) = cli(
        &[
            "bake", "run", "--motion", "walk", "--format", "obj", "--out", "walk-obj",
        ],
        dir.path(),
    );
    assert!(ok, "{log}");
    assert_eq!(
        std::fs::read_dir(dir.path().join("walk-obj"))
            .unwrap()
            .count(),
        31
    );
    let (ok, log) = cli(&["bake", "run", "--motion", "nope"], dir.path());
    assert!(!ok && log.contains("unknown motion 'nope'"), "{log}");
    // Swap the garment in the run's scene: the checkpoint must be refused.
    let scene_toml = std::fs::read_to_string(dir.path().join("run/scene.toml")).unwrap();
    std::fs::write(
        dir.path().join("run/scene.toml"),
        scene_toml.replace("resolution = 400", "resolution = 500"),
    )
    .unwrap();
    let (ok, log) = cli(
        &["bake", "run", "--motion", "walk", "--out", "x.pc2"],
        dir.path(),
    );
    assert!(!ok && log.contains("no longer matches"), "{log}");
    assert!(!dir.path().join("x.pc2").exists());
    let _ = Arc::new(0);
}

/// Reads accessor `index` of a GLB as f32 values (tightly packed, as our exporter writes).
fn accessor_f32(doc: &gltf::Gltf, index: usize) -> Vec<f32> {
    let acc = doc.accessors().nth(index).unwrap();
    let view = acc.view().unwrap();
    let blob = doc.blob.as_ref().unwrap();
    let start = view.offset() + acc.offset();
    let len = acc.count() * acc.size();
    match acc.data_type() {
        gltf::accessor::DataType::F32 => {
            bytemuck::cast_slice::<u8, f32>(&blob[start..start + len]).to_vec()
        }
        gltf::accessor::DataType::U16 => blob[start..start + len]
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]) as f32)
            .collect(),
        other => panic!("unexpected accessor type {other:?}"),
    }
}

#[test]
fn gltf_export_validates_and_reproduces_the_baked_frames() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    run_to_end(
        Trainer::spawn(
            setup(
                &run,
                TrainConfig {
                    max_steps: Some(3),
                    ..quick_config()
                },
                None,
            ),
            None,
        )
        .unwrap(),
    )
    .1
    .unwrap();
    let trained = load_trained(&run).unwrap();
    let scene = &trained.scene;
    let motion = scene.motions[1].0.clone(); // the spin: large offsets from the dynamics
    let engine = || engine_of(&trained);
    let glb = dir.path().join("spin.glb");
    let pc2 = dir.path().join("spin.pc2");
    let mut reports = Vec::new();
    for (format, out) in [(BakeFormat::Gltf, &glb), (BakeFormat::Pc2, &pc2)] {
        let options = BakeOptions {
            format,
            out: out.clone(),
            fps: 30.0,
            morph_targets: 8,
            include_body: true,
            ..Default::default()
        };
        let mut source = ModelSource::new(engine());
        reports.push(
            bake(
                &scene.avatar,
                &scene.garment,
                &motion,
                &mut source,
                &options,
                &mut |_, _| true,
            )
            .unwrap(),
        );
    }
    let report = reports.swap_remove(0);
    let max_error = report.max_error_m.unwrap();
    let baked = read_pc2(&pc2).unwrap().frames;

    // 1. The Khronos validator finds no error (installed by scripts/setup.sh).
    let validator = Path::new("scripts/gltf-validate.js");
    let out = Command::new("node")
        .arg(validator)
        .arg(&glb)
        .output()
        .expect("node must be installed (scripts/setup.sh)");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "glTF validator: {text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("\"errors\": 0"), "{text}");

    // 2. Our importer reads the skeleton and the animation back.
    let loaded = neural_cloth::io::load_avatar(
        &glb,
        &neural_cloth::io::ImportOptions {
            fps: 30.0,
            ..Default::default()
        },
    )
    .unwrap()
    .avatar;
    assert_eq!(loaded.skeleton.len(), scene.avatar.skeleton.len());
    assert_eq!(loaded.motions.len(), 1);
    assert_eq!(loaded.motions[0].frame_count(), baked.len());

    // 3. Skin + morph weights at frame k reproduce baked frame k within the stated error.
    let doc = gltf::Gltf::from_slice(&std::fs::read(&glb).unwrap()).unwrap();
    let mesh = doc.meshes().next().unwrap();
    let prim = mesh.primitives().next().unwrap();
    let attr = |name: gltf::Semantic| accessor_f32(&doc, prim.get(&name).unwrap().index());
    let base = attr(gltf::Semantic::Positions);
    let joints = attr(gltf::Semantic::Joints(0));
    let weights = attr(gltf::Semantic::Weights(0));
    let targets: Vec<Vec<f32>> = prim
        .morph_targets()
        .map(|t| accessor_f32(&doc, t.positions().unwrap().index()))
        .collect();
    assert_eq!(targets.len(), report.morph_targets.unwrap());
    assert!(!targets.is_empty(), "the spin must need morph targets");
    let skin = doc.skins().next().unwrap();
    let ibm = accessor_f32(&doc, skin.inverse_bind_matrices().unwrap().index());
    let node_of: Vec<usize> = skin.joints().map(|j| j.index()).collect();
    let anim = doc.animations().next().unwrap();
    let weight_channel = anim
        .channels()
        .find(|c| c.target().property() == gltf::animation::Property::MorphTargetWeights)
        .unwrap();
    let frame_weights = accessor_f32(&doc, weight_channel.sampler().output().index());
    // Joint names of the skin, in skin order, mapped onto the loaded skeleton.
    let names: Vec<String> = node_of
        .iter()
        .map(|&n| doc.nodes().nth(n).unwrap().name().unwrap().to_string())
        .collect();
    let loaded_index: Vec<usize> = names
        .iter()
        .map(|n| loaded.skeleton.index_of(n).unwrap())
        .collect();
    let v = scene.garment.vertex_count();
    let mut worst = 0.0f32;
    for k in [0, baked.len() / 2, baked.len() - 1] {
        let world = loaded
            .skeleton
            .world_from_joint(&loaded.motions[0].frames[k]);
        let mats: Vec<nalgebra::Matrix4<f32>> = (0..names.len())
            .map(|j| {
                world[loaded_index[j]]
                    * nalgebra::Matrix4::from_column_slice(&ibm[j * 16..j * 16 + 16])
            })
            .collect();
        for i in 0..v {
            let mut p = nalgebra::Vector3::new(base[3 * i], base[3 * i + 1], base[3 * i + 2]);
            for (t, target) in targets.iter().enumerate() {
                let w = frame_weights[k * targets.len() + t];
                p +=
                    nalgebra::Vector3::new(target[3 * i], target[3 * i + 1], target[3 * i + 2]) * w;
            }
            let mut m = nalgebra::Matrix4::zeros();
            for c in 0..4 {
                m += mats[joints[4 * i + c] as usize] * weights[4 * i + c];
            }
            let posed = m.transform_point(&p.into()).coords;
            worst = worst.max((posed - baked[k][i]).norm());
        }
    }
    assert!(
        worst <= max_error + 1e-4,
        "posed error {worst} m above the stated compression error {max_error} m"
    );
}

/// The tiny scene with the built-in skirt (waistband pinned) and `effects` applied.
fn tiny_skirt(edit: impl Fn(&mut neural_cloth::scene::config::Effects)) -> (Scene, SceneConfig) {
    let text = TINY
        .replace("builtin = \"tshirt\"", "builtin = \"skirt\"")
        .replace("resolution = 400", "resolution = 300");
    let mut config = SceneConfig::from_toml_str(&text).unwrap();
    config.effects.pinning = true;
    edit(&mut config.effects);
    (build_builtin(&config).unwrap(), config)
}

/// Validation losses of 3 steps of training the tiny skirt with `edit` applied to its effects.
fn skirt_losses(edit: impl Fn(&mut neural_cloth::scene::config::Effects)) -> Vec<f64> {
    let dir = tempfile::tempdir().unwrap();
    let (scene, scene_config) = tiny_skirt(edit);
    let (mut session, _) = prepare(TrainSetup {
        scene,
        scene_config,
        train: quick_config(),
        model: small_model(),
        descriptors: DescriptorConfig::default(),
        location: RunLocation::At(dir.path().to_path_buf()),
    })
    .unwrap();
    let mut out = Vec::new();
    for _ in 0..3 {
        let step = session.step().unwrap();
        let v = session.validate().unwrap();
        assert!(step.is_finite() && v.is_finite(), "{step:?} {v:?}");
        out.push(step.loss);
        out.push(v.loss);
    }
    out
}

/// Issue 11: a scene's `pinning = true` was silently ignored by the trainer (the same skirt
/// trained bit-identically with pinning on and off). Every effect a scene declares must change
/// what training does.
#[test]
fn pinning_and_every_other_effect_act_in_training() {
    use neural_cloth::scene::config::Effects;
    let all = skirt_losses(|e| e.friction = true);
    type Toggle = (&'static str, fn(&mut Effects));
    // Friction needs collision and dynamics: turning either off turns it off too.
    let toggles: [Toggle; 6] = [
        ("pinning", |e| e.pinning = false),
        ("gravity", |e| e.gravity = false),
        ("bending", |e| e.bending = false),
        ("collision", |e| {
            e.collision = false;
            e.friction = false;
        }),
        ("dynamics", |e| {
            e.dynamics = false;
            e.friction = false;
        }),
        ("friction", |e| e.friction = false),
    ];
    for (name, toggle) in toggles {
        let without = skirt_losses(|e| {
            e.friction = true;
            toggle(e);
        });
        assert_ne!(
            all, without,
            "turning {name} off changed nothing in training"
        );
    }
}

/// Issue 11: the loss on several trailing frames of each window (`loss_frames`) trains the
/// pinned skirt with every effect on, finite, and changes what a step optimises.
#[test]
fn several_loss_frames_train_the_pinned_skirt_with_every_effect() {
    let losses = |loss_frames: usize, history_propagation: f64, history_adjoint: f64| {
        let dir = tempfile::tempdir().unwrap();
        let (scene, scene_config) = tiny_skirt(|_| {});
        let (mut session, _) = prepare(TrainSetup {
            scene,
            scene_config,
            // No warm start: the simulator's settle is the one part of preparing a run whose
            // result depends on thread timing in a full test run.
            train: TrainConfig {
                loss_frames,
                history_propagation,
                history_adjoint,
                predrape_secs: 0.0,
                ..quick_config()
            },
            model: small_model(),
            descriptors: DescriptorConfig::default(),
            location: RunLocation::At(dir.path().to_path_buf()),
        })
        .unwrap();
        let before = session.validate().unwrap();
        let mut steps = Vec::new();
        for _ in 0..3 {
            let step = session.step().unwrap();
            assert!(step.is_finite(), "{step:?}");
            steps.push(step.loss);
        }
        let after = session.validate().unwrap();
        assert!(after.is_finite(), "{after:?}");
        (before.loss, steps, after.loss)
    };
    let (before_one, one, after_one) = losses(1, 0.0, 0.0);
    let (before_three, three, after_three) = losses(3, 0.0, 0.0);
    // Validation reads the last frame only, so the untrained model scores the same.
    let relative = |a: f64, b: f64| (a - b).abs() / a.abs().max(b.abs()).max(1e-12);
    assert!(
        relative(before_one, before_three) < 1e-6,
        "{before_one} against {before_three}"
    );
    assert!(
        relative(one[0], three[0]) > 1e-4,
        "three loss frames gave the first step's loss of one: {} against {}",
        three[0],
        one[0]
    );
    // The history propagation (round 17) changes the update, not the losses it starts from.
    let (before_carried, carried, after_carried) = losses(3, 1.0, 0.0);
    assert_eq!(before_carried, before_three);
    assert_eq!(carried[0], three[0]);
    assert!(
        relative(after_carried, after_three) > 1e-9,
        "the history propagation left training unchanged: {after_carried} against {after_three}"
    );
    // So does the history adjoint (round 18), with one loss frame (it acts on the two
    // frames before it) and with three.
    for (frames, plain, plain_after) in [(1, &one, after_one), (3, &three, after_three)] {
        let (_, handed, after_handed) = losses(frames, 0.0, 1.0);
        assert_eq!(handed[0], plain[0]);
        assert!(
            handed.iter().all(|l| l.is_finite()) && after_handed.is_finite(),
            "{handed:?}"
        );
        assert!(
            relative(after_handed, plain_after) > 1e-9,
            "the history adjoint left training unchanged ({frames} loss frames): \
             {after_handed} against {plain_after}"
        );
    }
    // A window too short for its loss frames is refused.
    let too_many = TrainConfig {
        loss_frames: 8,
        ..quick_config()
    };
    assert!(too_many.validate(30.0).is_err());
}

/// Issue 11: the pinned waistband of a skirt must stay at its skinned place in training, as it
/// does in the simulator: after training with a large initial basis, pinned vertices are
/// closer to the skinned template with pinning on than with it off.
#[test]
fn pinning_adds_a_positive_term_when_the_waistband_moves() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, scene_config) = tiny_skirt(|_| {});
    let mut model = small_model();
    model.basis_init_gain = 30.0;
    // Same initial network with and without pinning: no warm start, no data-dependent init.
    let isolated = TrainConfig {
        predrape_secs: 0.0,
        centre_init: false,
        ..quick_config()
    };
    let (mut session, _) = prepare(TrainSetup {
        scene,
        scene_config,
        train: isolated.clone(),
        model,
        descriptors: DescriptorConfig::default(),
        location: RunLocation::At(dir.path().to_path_buf()),
    })
    .unwrap();
    // A random basis moves the waistband: the pinning term is part of the loss.
    let with = session.validate().unwrap();
    let dir2 = tempfile::tempdir().unwrap();
    let (scene, scene_config) = tiny_skirt(|e| e.pinning = false);
    let mut model = small_model();
    model.basis_init_gain = 30.0;
    let (mut unpinned, _) = prepare(TrainSetup {
        scene,
        scene_config,
        train: isolated,
        model,
        descriptors: DescriptorConfig::default(),
        location: RunLocation::At(dir2.path().to_path_buf()),
    })
    .unwrap();
    let without = unpinned.validate().unwrap();
    assert!(
        with.loss > without.loss,
        "pinning adds a positive term: {} vs {}",
        with.loss,
        without.loss
    );
}

/// Issue 11: a network whose decoder died (all units of its last layer zero, so it outputs the
/// template for ever) must not go on silently: the loop reports it and revives the units.
#[test]
fn a_dead_decoder_is_reported_and_revived() {
    let dir = tempfile::tempdir().unwrap();
    let config = TrainConfig {
        max_steps: Some(6),
        validate_every: 2,
        ..quick_config()
    };
    let (mut session, loop_config) = prepare(setup(dir.path(), config, None)).unwrap();
    let mut model = session.model().clone();
    let last = model.decoder.mlp.layers.last_mut().unwrap();
    last.bias = last.bias.clone().map(|b| {
        b.map(|t| {
            let device = t.device();
            Tensor::<1>::from_data(t.zeros_like().add_scalar(-1e3).into_data(), &device)
                .require_grad()
        })
    });
    session.set_model(model);
    let dead = session.validate().unwrap();
    assert_eq!(dead.dead_units_pct, 100.0, "{dead:?}");
    let (events, result) =
        run_to_end(TrainerHandle::spawn_session(session, loop_config, None).unwrap());
    let stalled: Vec<(u64, String, String)> = events
        .iter()
        .filter_map(|e| match e {
            TrainEvent::Stalled {
                step,
                reason,
                remedy,
            } => Some((*step, reason.clone(), remedy.clone())),
            _ => None,
        })
        .collect();
    assert!(!stalled.is_empty(), "no stall event");
    assert_eq!(stalled[0].0, 2);
    assert!(stalled[0].1.contains("dead"), "{:?}", stalled[0]);
    assert!(stalled[0].2.contains("revived"), "{:?}", stalled[0]);
    let summary = result.unwrap();
    let last = summary.last_validation.unwrap();
    assert!(
        last.dead_units_pct < 90.0,
        "still dead after the remedy: {last:?}"
    );
}

/// `neural-cloth compare` and `neural_cloth::train::compare` on a tiny skirt.
mod compare {
    use std::path::Path;

    use neural_cloth::geometry::Vec3;
    use neural_cloth::physics::Effects;
    use neural_cloth::physics::simulator::{SimOptions, simulate};
    use neural_cloth::scene::config::SceneConfig;
    use neural_cloth::scene::procedural::build_builtin;
    use neural_cloth::train::compare::{
        CompareOptions, ComparePhase, Sequences, compare, compare_frames, measure_motion, one_step,
        reaches_below_hips, reference_dir, reference_for, state_drift, still_frames,
    };
    use neural_cloth::train::{
        BackendKind, RunLocation, TrainConfig, TrainSetup, Trainer, device_for, load_trained,
    };

    /// A 200-vertex skirt (held up by its pinned waistband), a 0.3 s walk to train on and a
    /// 0.3 s idle to validate on.
    const SKIRT: &str = r#"
name = "tiny skirt"
training_fps = 30.0
[avatar]
builtin = "mannequin"
[garment]
builtin = "skirt"
resolution = 200
[[motions]]
builtin = "walk"
duration_secs = 0.3
[[motions]]
builtin = "idle"
duration_secs = 0.3
split = "validation"
[effects]
pinning = true
"#;

    /// Cheap reference settings.
    fn quick() -> CompareOptions {
        CompareOptions {
            iterations: 8,
            settle_secs: 0.1,
            ..Default::default()
        }
    }

    /// Trains the skirt for two steps into `run`.
    fn train_tiny(run: &Path) {
        let config = SceneConfig::from_toml_str(SKIRT).unwrap();
        let scene = build_builtin(&config).unwrap();
        let setup = TrainSetup {
            scene,
            scene_config: config,
            train: TrainConfig {
                batch_size: 2,
                window_secs: 0.2,
                seed: 3,
                max_steps: Some(2),
                checkpoint_every: 2,
                validate_every: 2,
                ..Default::default()
            },
            model: super::small_model(),
            descriptors: Default::default(),
            location: RunLocation::At(run.to_path_buf()),
        };
        let (_, result) = super::run_to_end(Trainer::spawn(setup, None).unwrap());
        assert_eq!(result.unwrap().steps, 2);
    }

    #[test]
    fn one_step_from_the_simulators_own_frames_gives_its_frames() {
        let dir = tempfile::tempdir().unwrap();
        let run = dir.path().join("run");
        train_tiny(&run);
        let trained = load_trained(&run).unwrap();
        let motion = trained.scene.motions[0].0.resample(30.0).unwrap();
        let options = quick();
        let reference = reference_for(&trained, &motion, &options, &mut |_, _, _| true).unwrap();
        let bodies = trained.bodies_of(&motion).unwrap();
        let bodies = bodies.as_deref();
        let mut steps = 0;
        let sim = one_step(
            &trained,
            &motion,
            &reference.dynamic,
            bodies,
            options.iterations,
            &mut |phase, done, total| {
                assert_eq!(phase, ComparePhase::OneStep);
                assert!(done <= total);
                steps = done;
                true
            },
        )
        .unwrap()
        .expect("a dynamic scene with frames to check");
        assert_eq!(sim.frames, motion.frames.len() - 2);
        assert_eq!(steps, sim.frames, "progress reaches every frame");
        assert!(sim.mean_mm < 0.01, "the simulator obeys itself: {sim:?}");
        // Frames held back from where their history carries them are not physical: the step
        // from the two before puts each one away from where it is.
        let held: Vec<Vec<Vec3>> = (0..reference.dynamic.len())
            .map(|k| reference.dynamic[k / 3 * 3].clone())
            .collect();
        let jerky = one_step(
            &trained,
            &motion,
            &held,
            bodies,
            options.iterations,
            &mut |_, _, _| true,
        )
        .unwrap()
        .expect("checked");
        assert!(jerky.mean_mm > 10.0 * sim.mean_mm + 0.01, "{jerky:?}");
        assert!(jerky.shape_mm.is_finite() && jerky.height_mm.is_finite());
        // Cancelling stops it.
        let cancelled = one_step(&trained, &motion, &held, bodies, 1, &mut |_, _, _| false);
        assert!(cancelled.is_err());
        // compare measures it when asked.
        let asked = CompareOptions {
            one_step: true,
            ..quick()
        };
        let report = compare(&trained, Some("walk"), &asked, &mut |_| true).unwrap();
        let step = report.motions[0].measures.one_step.expect("asked for");
        assert!(step.mean_mm.is_finite() && step.mean_mm > 0.0, "{step:?}");
        let plain = compare(&trained, Some("walk"), &quick(), &mut |_| true).unwrap();
        assert!(plain.motions[0].measures.one_step.is_none());
        // Nor at w = 0 (frames not meant to follow the physics), nor with two frames.
        let quiet = CompareOptions { w: 0.0, ..asked };
        let at_rest = compare(&trained, Some("walk"), &quiet, &mut |_| true).unwrap();
        assert!(at_rest.motions[0].measures.one_step.is_none());
        let short = one_step(&trained, &motion, &held[..2], bodies, 1, &mut |_, _, _| {
            true
        })
        .unwrap();
        assert!(short.is_none());
    }

    #[test]
    fn compare_gives_finite_numbers_on_a_tiny_run() {
        let dir = tempfile::tempdir().unwrap();
        let run = dir.path().join("run");
        train_tiny(&run);
        let trained = load_trained(&run).unwrap();
        assert!(reaches_below_hips(
            &trained.scene.avatar,
            &trained.scene.garment
        ));
        let report = compare(&trained, Some("walk"), &quick(), &mut |_| true).unwrap();
        assert_eq!(report.motions.len(), 1);
        let m = &report.motions[0];
        let s = &m.measures;
        assert_eq!(s.frames, 10);
        let numbers = [
            s.all.mean_mm,
            s.all.p95_mm,
            s.amplitude.network.all_mm,
            s.amplitude.simulator.all_mm,
            m.metrics.network.strain,
            m.metrics.simulator.strain,
            m.metrics.network.gravity,
            m.metrics.simulator.gravity,
            m.metrics.network.loss,
            m.metrics.simulator.loss,
        ];
        assert!(numbers.iter().all(|v| v.is_finite()), "{report:?}");
        // The GRU state's drift is measured, over the run's window (0.2 s at 30 fps + 3).
        let drift = s.drift.expect("a dynamic network at w = 1 has a drift");
        assert_eq!(drift.window_frames, 9);
        assert!(drift.mean_mm.is_finite() && drift.max_frame_mm >= drift.mean_mm);
        // Not at w = 0, where the dynamic branch is off.
        let quiet = CompareOptions { w: 0.0, ..quick() };
        let at_rest = compare(&trained, Some("walk"), &quiet, &mut |_| true).unwrap();
        assert!(at_rest.motions[0].measures.drift.is_none());
        // The training objective is reported on both sides (it was left 0): at least the
        // gravity potential of the frames, which is positive above the origin.
        for side in [&m.metrics.network, &m.metrics.simulator] {
            assert!(side.loss != 0.0 && side.gravity > 0.0, "{side:?}");
            assert!(side.loss >= side.gravity - 1e-9, "{side:?}");
        }
        // Term by term, each side's objective sums to its loss, and the terms are there: the
        // in-plane energy of a stretched garment, its gravity, its inertia once it moves.
        for (side, terms) in [
            (&m.metrics.network, &m.objective.network),
            (&m.metrics.simulator, &m.objective.simulator),
        ] {
            assert!(
                (terms.total() - side.loss).abs() < 1e-9 * side.loss.abs().max(1.0),
                "{terms:?} vs {side:?}"
            );
            assert!(
                terms.fixed.cloth_j > 0.0 && terms.fixed.gravity_j > 0.0,
                "{terms:?}"
            );
            assert!(terms.inertia_j > 0.0, "{terms:?}");
        }
        // Both stay on the body: centimetres apart, not metres.
        assert!(
            s.all.mean_mm > 0.0 && s.all.mean_mm < 500.0 && s.all.p95_mm >= s.all.mean_mm,
            "{s:?}"
        );
        let hem = s.hem.expect("a skirt has a hem radius");
        let pairs = [hem.still, hem.moving];
        let radii = pairs
            .iter()
            .flatten()
            .flat_map(|p| [p.network_m, p.simulator_m]);
        assert!(radii.clone().count() > 0);
        assert!(
            radii
                .into_iter()
                .all(|r| r.is_finite() && r > 0.05 && r < 1.0)
        );
        // Without a motion: the validation split (idle), whose frames are all still.
        let idle = compare(&trained, None, &quick(), &mut |_| true).unwrap();
        assert_eq!(idle.motions[0].name, "idle");
        assert_eq!(idle.motions[0].measures.still_frames, 10);
        assert!(idle.motions[0].measures.moving.is_none());
        assert!(compare(&trained, Some("nope"), &quick(), &mut |_| true).is_err());
        // Cancelling stops it.
        let cancelled = compare(
            &trained,
            Some("walk"),
            &CompareOptions {
                use_cache: false,
                ..quick()
            },
            &mut |_| false,
        );
        assert!(cancelled.is_err());
    }

    #[test]
    fn the_simulator_against_itself_is_at_distance_zero() {
        let config = SceneConfig::from_toml_str(SKIRT).unwrap();
        let scene = build_builtin(&config).unwrap();
        let fabric = scene.fabric.clone();
        let motion = scene.motions[0].0.resample(30.0).unwrap();
        let device = device_for(BackendKind::Cpu, false);
        let sim_options = SimOptions {
            iterations_per_step: 8,
            settle_secs: 0.1,
            ..Default::default()
        };
        let run = |effects: &Effects| {
            simulate(
                &scene.avatar,
                &scene.garment,
                &fabric,
                effects,
                &motion,
                30.0,
                &sim_options,
                &device,
                &mut |_| true,
            )
            .unwrap()
            .frames
        };
        let sim = run(&scene.effects);
        let quiet = run(&Effects {
            dynamics: false,
            ..scene.effects
        });
        assert_eq!(sim.len(), motion.frames.len());
        let same = compare_frames(&sim, &sim).unwrap();
        assert_eq!((same.mean_mm, same.p95_mm, same.frames), (0.0, 0.0, 10));
        let offset = nalgebra::Vector3::new(0.002f32, 0.0, 0.0);
        let moved: Vec<Vec<_>> = sim
            .iter()
            .map(|f| f.iter().map(|p| p + offset).collect())
            .collect();
        let two = compare_frames(&sim, &moved).unwrap();
        assert!((two.mean_mm - 2.0).abs() < 1e-3, "{two:?}");
        assert!((two.p95_mm - 2.0).abs() < 1e-3, "{two:?}");
        // The whole measure with the simulator standing in for the network.
        let still = still_frames(&scene.avatar, &motion.frames, 30.0, 0.1, 0.5);
        let measures = measure_motion(
            &scene.avatar,
            &scene.garment,
            &motion.frames,
            &still,
            &Sequences {
                network: &sim,
                network_static: &quiet,
                simulator: &sim,
                simulator_static: &quiet,
            },
        )
        .unwrap();
        assert_eq!(measures.all.mean_mm, 0.0);
        assert_eq!(measures.amplitude.network, measures.amplitude.simulator);
        assert!(measures.amplitude.simulator.all_mm > 0.0);
        let hem = measures.hem.unwrap();
        for pair in [hem.still, hem.moving].into_iter().flatten() {
            assert_eq!(pair.network_m, pair.simulator_m);
            assert_eq!(pair.network_static_m, pair.simulator_static_m);
            assert!(pair.simulator_static_m > 0.0);
        }
    }

    #[test]
    fn state_drift_is_zero_when_the_window_holds_the_whole_motion() {
        let dir = tempfile::tempdir().unwrap();
        let run = dir.path().join("run");
        train_tiny(&run);
        let trained = load_trained(&run).unwrap();
        let (motion, _) = trained
            .scene
            .motions
            .iter()
            .find(|(m, _)| m.name == "walk")
            .unwrap();
        let motion = motion.resample(trained.meta.training_fps).unwrap();
        let poses = &motion.frames;
        let mut engine = trained.garment_engine().unwrap();
        let carried: Vec<Vec<Vec3>> = poses
            .iter()
            .map(|p| {
                engine.step(p, 1.0).unwrap();
                engine.garment_positions().to_vec()
            })
            .collect();
        let mut frames = 0;
        let mut say = |_: ComparePhase, done: usize, _: usize| {
            frames = done;
            true
        };
        let whole = state_drift(&trained, poses, 1.0, &carried, poses.len(), &mut say).unwrap();
        assert_eq!(frames, poses.len());
        assert_eq!((whole.mean_mm, whole.height_mm), (0.0, 0.0), "{whole:?}");
        // A one-frame window forgets the motion: the dynamic branch's output changes.
        let one = state_drift(&trained, poses, 1.0, &carried, 1, &mut |_, _, _| true).unwrap();
        assert!(
            one.mean_mm > 0.0 && one.max_frame_mm >= one.mean_mm,
            "{one:?}"
        );
        // Cancelling stops it.
        assert!(state_drift(&trained, poses, 1.0, &carried, 1, &mut |_, _, _| false).is_err());
    }

    #[test]
    fn the_reference_is_cached_and_a_changed_garment_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let run = dir.path().join("run");
        train_tiny(&run);
        let trained = load_trained(&run).unwrap();
        let mut simulated = 0;
        let first = compare(&trained, Some("walk"), &quick(), &mut |p| {
            simulated += usize::from(matches!(
                p.phase,
                ComparePhase::Simulating | ComparePhase::SimulatingStatic
            ));
            true
        })
        .unwrap();
        assert_eq!(simulated, 20, "two simulations of 10 frames");
        let reference = &first.motions[0].reference;
        assert!(
            !reference.cached && reference.path.is_file(),
            "{reference:?}"
        );
        assert!(reference.path.starts_with(reference_dir(&run)));
        let mut events = Vec::new();
        let second = compare(&trained, Some("walk"), &quick(), &mut |p| {
            events.push(p.phase);
            true
        })
        .unwrap();
        assert!(second.motions[0].reference.cached);
        assert!(
            events.iter().all(|p| matches!(
                p,
                ComparePhase::Network | ComparePhase::Drift | ComparePhase::Metrics
            )),
            "{events:?}"
        );
        assert_eq!(first.motions[0].measures, second.motions[0].measures);
        // A second run of the same scene beside it takes the reference from the first run's
        // cache (the same file, bit for bit) and simulates nothing.
        let sibling = dir.path().join("sibling");
        train_tiny(&sibling);
        let sibling_trained = load_trained(&sibling).unwrap();
        let mut phases = Vec::new();
        let adopted = compare(&sibling_trained, Some("walk"), &quick(), &mut |p| {
            phases.push(p.phase);
            true
        })
        .unwrap();
        assert!(adopted.motions[0].reference.cached);
        assert!(
            !phases.contains(&ComparePhase::Simulating)
                && !phases.contains(&ComparePhase::SimulatingStatic),
            "{phases:?}"
        );
        let copied = &adopted.motions[0].reference.path;
        assert!(copied.starts_with(reference_dir(&sibling)), "{copied:?}");
        assert_eq!(
            std::fs::read(copied).unwrap(),
            std::fs::read(&reference.path).unwrap()
        );
        // Other settings simulate again.
        let other = CompareOptions {
            iterations: 9,
            ..quick()
        };
        let third = compare(&trained, Some("walk"), &other, &mut |_| true).unwrap();
        assert!(!third.motions[0].reference.cached);
        // The spread simulates the motion once more at twice the iterations (the dynamic
        // simulation only), cached beside the reference.
        let count = |options: &CompareOptions| {
            let mut phases = (0, 0);
            let report = compare(&trained, Some("walk"), options, &mut |p| {
                phases.0 += usize::from(p.phase == ComparePhase::Simulating);
                phases.1 += usize::from(p.phase == ComparePhase::SimulatingStatic);
                true
            })
            .unwrap();
            (report, phases)
        };
        let spread_options = CompareOptions {
            spread: true,
            ..quick()
        };
        let (with_spread, phases) = count(&spread_options);
        assert_eq!(phases, (10, 0), "the finer simulation alone");
        let spread = with_spread.motions[0].measures.spread.expect("asked for");
        assert_eq!(spread.iterations, 16);
        assert!(
            spread.mean_mm.is_finite() && spread.p95_mm >= spread.mean_mm,
            "{spread:?}"
        );
        assert!(first.motions[0].measures.spread.is_none());
        let (_, again) = count(&spread_options);
        assert_eq!(again, (0, 0), "the finer simulation is cached");
        // A comparison at those iterations reuses it and solves only the quasi-static frames.
        let finer = CompareOptions {
            iterations: 16,
            ..quick()
        };
        let (at_16, phases) = count(&finer);
        assert_eq!(phases, (0, 10));
        assert!(!at_16.motions[0].reference.cached);
        // The sensitivity simulates once more from a start moved by a micrometre, at the
        // reference's iterations, in its own cache file.
        let sensitive = CompareOptions {
            sensitivity: true,
            ..quick()
        };
        let (with_jitter, phases) = count(&sensitive);
        assert_eq!(phases, (10, 0), "the moved start's simulation alone");
        let moved = with_jitter.motions[0]
            .measures
            .sensitivity
            .expect("asked for");
        assert_eq!(moved.start_jitter_m, 1e-6);
        assert_eq!(moved.iterations, quick().iterations);
        assert!(
            moved.mean_mm > 0.0 && moved.mean_mm < 1.0 && moved.p95_mm >= moved.mean_mm,
            "a micrometre moves a tiny skirt on a walk by little, but not by nothing: {moved:?}"
        );
        let files = std::fs::read_dir(reference_dir(&run)).unwrap().count();
        let (_, again) = count(&sensitive);
        assert_eq!(again, (0, 0), "the moved start's simulation is cached");
        assert_eq!(
            std::fs::read_dir(reference_dir(&run)).unwrap().count(),
            files
        );
        assert!(
            std::fs::read_dir(reference_dir(&run)).unwrap().any(|f| f
                .unwrap()
                .file_name()
                .to_string_lossy()
                .contains("jitter1um")),
            "named by its jitter"
        );
        // Swap the garment in the run's scene: refused, naming the garment.
        let scene_toml = std::fs::read_to_string(run.join("scene.toml")).unwrap();
        std::fs::write(
            run.join("scene.toml"),
            scene_toml.replace("resolution = 200", "resolution = 240"),
        )
        .unwrap();
        let err = load_trained(&run)
            .err()
            .expect("a changed garment is refused");
        let text = err.to_string();
        assert!(
            text.contains("garment changed") && text.contains("skirt"),
            "{text}"
        );
        // Same garment, another avatar fingerprint in run.json: refused, naming the avatar.
        std::fs::write(run.join("scene.toml"), &scene_toml).unwrap();
        let meta = std::fs::read_to_string(run.join("run.json")).unwrap();
        let mut meta: serde_json::Value = serde_json::from_str(&meta).unwrap();
        assert!(meta["avatar_fingerprint"].is_u64(), "{meta}");
        meta["avatar_fingerprint"] = serde_json::json!(1);
        std::fs::write(run.join("run.json"), meta.to_string()).unwrap();
        let text = load_trained(&run).err().expect("refused").to_string();
        assert!(text.contains("avatar changed"), "{text}");
    }

    #[test]
    fn cli_compare_prints_a_table_and_json() {
        let dir = tempfile::tempdir().unwrap();
        let run = dir.path().join("run");
        train_tiny(&run);
        let args = [
            "compare",
            "run",
            "--motion",
            "walk",
            "--iterations",
            "8",
            "--settle",
            "0.1",
        ];
        let (ok, log) = super::cli(&args, dir.path());
        assert!(ok, "{log}");
        assert!(
            log.contains("distance mean, mm") && log.contains("hem radius"),
            "{log}"
        );
        println!("{log}");
        let mut json_args = args.to_vec();
        json_args.push("--json");
        let (ok, log) = super::cli(&json_args, dir.path());
        assert!(ok, "{log}");
        let start = log.find('{').unwrap();
        let v: serde_json::Value = serde_json::Deserializer::from_str(&log[start..])
            .into_iter()
            .next()
            .unwrap()
            .unwrap();
        assert_eq!(v["motions"][0]["reference"]["cached"], true, "{log}");
        assert!(
            v["motions"][0]["all"]["mean_mm"]
                .as_f64()
                .unwrap()
                .is_finite()
        );
        let (ok, log) = super::cli(&["compare", "run", "--motion", "nope"], dir.path());
        assert!(!ok && log.contains("unknown motion 'nope'"), "{log}");
    }
}

#[test]
fn warm_start_puts_the_effective_bias_at_the_drape_whatever_its_learning_rate_scale() {
    let (scene, _) = tiny();
    let garment = &scene.garment;
    let drape: Vec<_> = garment
        .mesh
        .positions
        .iter()
        .enumerate()
        .map(|(i, p)| p + neural_cloth::geometry::Vec3::new(0.0, -0.01 * (i % 3) as f32, 0.002))
        .collect();
    for scale in [1.0, 1.0 / 16.0] {
        let device = burn::tensor::Device::flex();
        // Random weights drawn here would take numbers from a run prepared beside this test.
        let rng = neural_cloth::train::device_rng_lock();
        let mut net = ClothNetConfig {
            basis_bias_lr_scale: scale,
            ..small_model()
        }
        .init(
            scene.avatar.skeleton.names.len(),
            garment.vertex_count(),
            &device,
        )
        .unwrap();
        drop(rng);
        neural_cloth::train::warm_start::set_basis_bias_to_drape(
            &mut net, garment, &drape, &device,
        )
        .unwrap();
        let weights = neural_cloth::model::InferenceWeights::from_module(&net).unwrap();
        let bias = weights.basis.bias.unwrap();
        for (v, (t, d)) in garment.mesh.positions.iter().zip(&drape).enumerate() {
            let want = d - t;
            for k in 0..3 {
                assert!(
                    (bias[3 * v + k] - want[k]).abs() < 1e-6,
                    "scale {scale}, vertex {v}: {} vs {}",
                    bias[3 * v + k],
                    want[k]
                );
            }
        }
    }
}
