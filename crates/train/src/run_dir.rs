//! Run directories: everything needed to resume, evaluate or bake a trained model.
//!
//! ```text
//! RUN/run.json                  RunMeta: train + model + descriptor configs, training rate,
//!                               garment, garment skin and avatar fingerprints
//! RUN/scene.toml                the scene description (file paths absolute): the one home of
//!                               the run's fabric and effects
//! RUN/metrics.json              the metric history up to the newest checkpoint
//! RUN/latest.json               {"step": N} of the newest complete checkpoint
//! RUN/checkpoints/step-0000N/   model.bpk (burn record), optimizer.bpk, state.json
//! ```
//! Every file is written atomically (temporary + rename) and a checkpoint folder appears
//! only when complete, so a crash never leaves a half-written checkpoint behind; writing,
//! verifying and falling back over checkpoints is [`super::checkpoint`].

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use neural_cloth_core::io::export::atomic::write_atomic;
use neural_cloth_core::scene::config::DEFAULT_TRAINING_FPS;
use neural_cloth_core::scene::{Avatar, Garment};
use neural_cloth_model::network_config::PAPER_STATIC_HIDDEN;
use neural_cloth_model::{ClothNetConfig, DescriptorConfig};
use neural_cloth_physics::{Effects, FabricParams};

use super::TrainError;
use super::config::{PRE_ROUND_12_WINDOW_SECS, TrainConfig};
use super::metrics::MetricHistory;

/// How many checkpoints to keep (older ones are deleted).
pub const KEEP_CHECKPOINTS: usize = 3;
/// The newest run folder format this program reads and writes ([`RunMeta::version`]).
///
/// - 1: the training rate in `run.json` as `train.fps` (30 when left out).
/// - 2: the training rate as `training_fps` at the top of `run.json` (issue 14: the rate's one
///   home is the scene; `TrainConfig` has none). Version-1 files are converted when read
///   ([`RunDir::meta`]); a program that reads version 1 only refuses version 2 by its number
///   instead of taking its missing `train.fps` for 30.
/// - 3: `run.json` no longer copies the fabric and effects; `scene.toml` is their one home
///   (issue 14). Versions 1 and 2 kept copies in `run.json`: when their recorded scene is
///   read ([`RunDir::legacy_settings`], `resume::recorded_config`) the copies replace the
///   scene's, since they are what the run trained with.
pub const RUN_VERSION: u32 = 3;

/// The first format version whose `run.json` has no fabric and effects.
const SCENE_HOLDS_SETTINGS: u64 = 3;

/// Description of a run, written once at its start: what its recorded scene (`scene.toml`,
/// with the fabric and effects) does not say.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RunMeta {
    /// Format version of the run directory.
    pub version: u32,
    /// Training settings.
    pub train: TrainConfig,
    /// Frame rate the run trained at, frames per second (the scene's
    /// [`neural_cloth_core::scene::Scene::training_fps`], 5..=240): its model steps,
    /// evaluates, compares and bakes at this rate, and a resume must keep it. Read from
    /// `train.fps` in version-1 files ([`RunDir::meta`]).
    pub training_fps: f32,
    /// Network architecture.
    pub model: ClothNetConfig,
    /// Descriptor settings.
    pub descriptors: DescriptorConfig,
    /// Network input joints.
    pub input_joints: usize,
    /// Garment vertices (rows of the basis).
    pub garment_vertices: usize,
    /// Fingerprint of the garment template and faces, to refuse a checkpoint of another garment.
    pub garment_fingerprint: u64,
    /// Name of the garment.
    pub garment_name: String,
    /// Fingerprint of the avatar's rest body and skeleton ([`avatar_fingerprint`]), to refuse a
    /// run whose avatar changed; `None` in runs written before it was recorded.
    #[serde(default)]
    pub avatar_fingerprint: Option<u64>,
    /// Fingerprint of the garment's skin weights ([`garment_skin_fingerprint`]: what the
    /// model's offsets are skinned with, set by the smoothing passes), to refuse a scene that
    /// rebuilds the garment with other weights; `None` in runs written before it was recorded.
    #[serde(default)]
    pub garment_skin_fingerprint: Option<u64>,
}

/// The fabric and effects a run folder of version 1 or 2 copied into its `run.json`.
#[derive(Clone, Debug, PartialEq, Deserialize)]
pub struct LegacySettings {
    /// Fabric used for the losses.
    pub fabric: FabricParams,
    /// Effects simulated.
    pub effects: Effects,
}

/// Mutable state saved with each checkpoint.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct CheckpointState {
    /// Optimiser step.
    pub step: u64,
    /// Learning rate at that step.
    pub learning_rate: f64,
}

/// Paths of a run directory.
#[derive(Clone, Debug)]
pub struct RunDir {
    /// The folder.
    pub root: PathBuf,
}

/// FNV-1a hash state for the fingerprints below.
struct Fnv(u64);

impl Default for Fnv {
    fn default() -> Self {
        Self(0xcbf29ce484222325)
    }
}

impl Fnv {
    fn eat(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.0 ^= u64::from(*b);
            self.0 = self.0.wrapping_mul(0x100000001b3);
        }
    }
}

/// FNV-1a fingerprint of a garment's template positions and faces.
pub fn garment_fingerprint(garment: &Garment) -> u64 {
    let mut fnv = Fnv::default();
    let mut eat = |bytes: &[u8]| fnv.eat(bytes);
    for p in &garment.mesh.positions {
        for c in p.iter() {
            eat(&c.to_le_bytes());
        }
    }
    for f in &garment.mesh.faces {
        for i in f {
            eat(&i.to_le_bytes());
        }
    }
    fnv.0
}

/// FNV-1a fingerprint of a garment's skin weights (joints and weights of every vertex) and
/// the smoothing passes they were made with.
pub fn garment_skin_fingerprint(garment: &Garment) -> u64 {
    let mut fnv = Fnv::default();
    let mut eat = |bytes: &[u8]| fnv.eat(bytes);
    eat(&(garment.smoothing_passes as u64).to_le_bytes());
    for (joints, weights) in garment.skin.joints.iter().zip(&garment.skin.weights) {
        for j in joints {
            eat(&j.to_le_bytes());
        }
        for w in weights {
            eat(&w.to_le_bytes());
        }
    }
    fnv.0
}

/// FNV-1a fingerprint of an avatar: its joint names and parents, the rest-pose joint
/// positions, and the rest body's positions and faces.
pub fn avatar_fingerprint(avatar: &Avatar) -> u64 {
    let mut fnv = Fnv::default();
    let mut eat = |bytes: &[u8]| fnv.eat(bytes);
    let skeleton = &avatar.skeleton;
    for (name, parent) in skeleton.names.iter().zip(&skeleton.parents) {
        eat(name.as_bytes());
        eat(&parent.map_or(u64::MAX, |p| p as u64).to_le_bytes());
    }
    for m in skeleton.world_from_joint(&skeleton.rest_pose()) {
        for c in [m[(0, 3)], m[(1, 3)], m[(2, 3)]] {
            eat(&c.to_le_bytes());
        }
    }
    for p in &avatar.rest_mesh.positions {
        for c in p.iter() {
            eat(&c.to_le_bytes());
        }
    }
    for f in &avatar.rest_mesh.faces {
        for i in f {
            eat(&i.to_le_bytes());
        }
    }
    fnv.0
}

/// A `run.json` of version 1 in the layout of version 2: its training rate moves from
/// `train.fps` (the old `TrainConfig` field; 30, its default, when left out) to
/// `training_fps`, and a run from before the gradient filter (no
/// `train.precondition_stiffness`) keeps it off (0). Other versions and values are returned
/// unchanged.
fn upgrade_v1(mut meta: serde_json::Value) -> serde_json::Value {
    let Some(map) = meta.as_object_mut() else {
        return meta;
    };
    if map
        .get("version")
        .and_then(serde_json::Value::as_u64)
        .is_none_or(|v| v >= 2)
    {
        return meta;
    }
    let train = map
        .get_mut("train")
        .and_then(serde_json::Value::as_object_mut);
    let fps = match train {
        Some(train) => {
            train
                .entry("precondition_stiffness")
                .or_insert(serde_json::Value::from(0.0));
            train.remove("fps")
        }
        None => None,
    }
    .unwrap_or_else(|| DEFAULT_TRAINING_FPS.into());
    map.entry("training_fps").or_insert(fps);
    meta
}

/// The settings whose defaults changed in docs/TRAINING.md round 12, with the values a run
/// saved before then trained with: `(section, field, value)` of `run.json`.
fn pre_round_12_defaults() -> [(&'static str, &'static str, serde_json::Value); 3] {
    [
        ("train", "window_secs", PRE_ROUND_12_WINDOW_SECS.into()),
        ("train", "precondition_moving_only", false.into()),
        (
            "model",
            "static_hidden",
            PAPER_STATIC_HIDDEN.to_vec().into(),
        ),
    ]
}

/// A `run.json` that leaves out a setting whose default changed in round 12 trained with the
/// old default (every program writes every field, so only files from before the field
/// existed lack one): it is filled in, so that a resumed or loaded run keeps what it trained
/// with. Other values are returned unchanged.
fn fill_pre_round_12_defaults(mut meta: serde_json::Value) -> serde_json::Value {
    let Some(map) = meta.as_object_mut() else {
        return meta;
    };
    for (section, field, value) in pre_round_12_defaults() {
        // A missing section stays missing (and the file is refused for it).
        if let Some(fields) = map
            .get_mut(section)
            .and_then(serde_json::Value::as_object_mut)
        {
            fields.entry(field).or_insert(value);
        }
    }
    meta
}

impl RunDir {
    /// A run directory at `root` (created if missing).
    pub fn create(root: &Path) -> Result<Self, TrainError> {
        std::fs::create_dir_all(root.join("checkpoints")).map_err(|e| TrainError::io(e, root))?;
        Ok(Self {
            root: root.to_path_buf(),
        })
    }

    /// An existing run directory.
    pub fn open(root: &Path) -> Result<Self, TrainError> {
        if !root.join("run.json").is_file() {
            return Err(TrainError::Checkpoint(format!(
                "not a run directory (no run.json): {}",
                root.display()
            )));
        }
        Ok(Self {
            root: root.to_path_buf(),
        })
    }

    /// A fresh, timestamped run folder under `parent`.
    pub fn fresh_under(parent: &Path) -> Result<Self, TrainError> {
        let stamp = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs())
            .unwrap_or(0);
        let mut k = 0;
        loop {
            let root = parent.join(format!(
                "run-{stamp}{}",
                if k == 0 {
                    String::new()
                } else {
                    format!("-{k}")
                }
            ));
            if !root.exists() {
                return Self::create(&root);
            }
            k += 1;
        }
    }

    /// Writes `run.json` and `scene.toml`.
    pub fn write_meta(&self, meta: &RunMeta, scene_toml: &str) -> Result<(), TrainError> {
        let json =
            serde_json::to_vec_pretty(meta).map_err(|e| TrainError::Checkpoint(e.to_string()))?;
        write_atomic(&self.root.join("run.json"), &json)?;
        write_atomic(&self.root.join("scene.toml"), scene_toml.as_bytes())?;
        Ok(())
    }

    /// Reads `run.json` (a version-1 file converted; the fabric and effects that versions 1
    /// and 2 copied are left out: [`RUN_VERSION`]; settings whose defaults changed that it
    /// leaves out read as the defaults it trained with); a newer version is refused by its
    /// number.
    pub fn meta(&self) -> Result<RunMeta, TrainError> {
        let value = self.meta_json()?;
        serde_json::from_value(fill_pre_round_12_defaults(upgrade_v1(value)))
            .map_err(|e| self.unreadable_meta(e))
    }

    /// The fabric and effects a `run.json` of version 1 or 2 copied beside its recorded scene
    /// (what the run trained with); `None` from version 3 on, where `scene.toml` is their one
    /// home, and in an older file without them.
    pub fn legacy_settings(&self) -> Result<Option<LegacySettings>, TrainError> {
        let value = self.meta_json()?;
        let version = value.get("version").and_then(serde_json::Value::as_u64);
        if version.is_some_and(|v| v >= SCENE_HOLDS_SETTINGS)
            || value.get("fabric").is_none()
            || value.get("effects").is_none()
        {
            return Ok(None);
        }
        serde_json::from_value(value)
            .map(Some)
            .map_err(|e| self.unreadable_meta(e))
    }

    /// `run.json` as JSON; a newer format version than [`RUN_VERSION`] is refused by its
    /// number.
    fn meta_json(&self) -> Result<serde_json::Value, TrainError> {
        let path = self.root.join("run.json");
        let bytes = std::fs::read(&path).map_err(|e| TrainError::io(e, &path))?;
        let value: serde_json::Value =
            serde_json::from_slice(&bytes).map_err(|e| self.unreadable_meta(e))?;
        if let Some(version) = value.get("version").and_then(serde_json::Value::as_u64)
            && version > u64::from(RUN_VERSION)
        {
            return Err(TrainError::Corrupt {
                reason: format!(
                    "the run folder has format version {version}, newer than this program reads ({RUN_VERSION})"
                ),
                path,
            });
        }
        Ok(value)
    }

    /// The error of a `run.json` that does not parse.
    fn unreadable_meta(&self, e: serde_json::Error) -> TrainError {
        TrainError::Corrupt {
            reason: format!("unreadable run description ({e})"),
            path: self.root.join("run.json"),
        }
    }

    /// The scene description text.
    pub fn scene_toml(&self) -> Result<String, TrainError> {
        let path = self.root.join("scene.toml");
        std::fs::read_to_string(&path).map_err(|e| TrainError::io(e, &path))
    }

    /// Folder of the checkpoint of `step`.
    pub fn checkpoint_path(&self, step: u64) -> PathBuf {
        self.root
            .join("checkpoints")
            .join(format!("step-{step:08}"))
    }

    /// The metric history saved with the newest checkpoint (empty when none or unreadable).
    pub fn history(&self) -> MetricHistory {
        self.try_history().unwrap_or_default()
    }

    /// The metric history saved with the newest checkpoint: empty when the run has none yet,
    /// an error naming `metrics.json` when it cannot be read.
    pub fn try_history(&self) -> Result<MetricHistory, TrainError> {
        let path = self.root.join("metrics.json");
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Default::default()),
            Err(e) => return Err(TrainError::io(e, &path)),
        };
        serde_json::from_slice(&bytes).map_err(|e| TrainError::Corrupt {
            reason: format!("unreadable metric history ({e})"),
            path,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn meta(training_fps: f32) -> RunMeta {
        RunMeta {
            version: RUN_VERSION,
            train: TrainConfig::default(),
            training_fps,
            model: ClothNetConfig::default(),
            descriptors: DescriptorConfig::default(),
            input_joints: 3,
            garment_vertices: 4,
            garment_fingerprint: 5,
            garment_name: "shirt".into(),
            avatar_fingerprint: Some(6),
            garment_skin_fingerprint: None,
        }
    }

    /// A run folder with `meta` as its `run.json`.
    fn run_with(dir: &Path, meta: &serde_json::Value) -> RunDir {
        let run = RunDir::create(dir).unwrap();
        std::fs::write(dir.join("run.json"), serde_json::to_vec(meta).unwrap()).unwrap();
        run
    }

    #[test]
    fn the_training_rate_is_written_once_and_read_back() {
        let dir = tempfile::tempdir().unwrap();
        let written = serde_json::to_value(meta(60.0)).unwrap();
        assert_eq!(written["training_fps"], 60.0);
        assert_eq!(written["version"], RUN_VERSION);
        assert!(written["train"].get("fps").is_none(), "{written}");
        let read = run_with(dir.path(), &written).meta().unwrap();
        assert_eq!(read.training_fps, 60.0);
    }

    /// Issue 14: runs written before the rate moved to `RunMeta::training_fps` carry it as
    /// `train.fps` (version 1); they still load at their own rate.
    #[test]
    fn an_old_run_json_keeps_its_training_rate() {
        let dir = tempfile::tempdir().unwrap();
        let mut old = serde_json::to_value(meta(0.0)).unwrap();
        let map = old.as_object_mut().unwrap();
        map.remove("training_fps");
        map.insert("version".into(), 1.into());
        map["train"]
            .as_object_mut()
            .unwrap()
            .insert("fps".into(), 60.0.into());
        let read = run_with(dir.path(), &old).meta().unwrap();
        assert_eq!((read.version, read.training_fps), (1, 60.0));
        assert_eq!(read.train, TrainConfig::default());
        assert_eq!(read.garment_name, "shirt");
        // A version-1 file from before the gradient filter keeps it off.
        old["train"]
            .as_object_mut()
            .unwrap()
            .remove("precondition_stiffness");
        let read = run_with(dir.path(), &old).meta().unwrap();
        assert_eq!(read.train.precondition_stiffness, 0.0);
        // A version-1 file that left the rate out had the old default.
        old["train"].as_object_mut().unwrap().remove("fps");
        let read = run_with(dir.path(), &old).meta().unwrap();
        assert_eq!(read.training_fps, 30.0);
        // A version-2 file must name its rate; a newer version is refused by its number.
        let mut new = serde_json::to_value(meta(60.0)).unwrap();
        new.as_object_mut().unwrap().remove("training_fps");
        let e = run_with(dir.path(), &new).meta().unwrap_err().to_string();
        assert!(e.contains("training_fps"), "{e}");
        new["version"] = 99.into();
        let e = run_with(dir.path(), &new).meta().unwrap_err().to_string();
        assert!(e.contains("format version 99"), "{e}");
    }

    /// Round 12 changed three defaults; a run saved before (its `run.json` without the
    /// fields) keeps what it trained with, and one that names them keeps its own values.
    #[test]
    fn a_run_saved_before_round_12_keeps_its_window_encoder_and_filter() {
        let dir = tempfile::tempdir().unwrap();
        let mut old = serde_json::to_value(meta(30.0)).unwrap();
        for (section, field) in [
            ("train", "window_secs"),
            ("train", "precondition_moving_only"),
            ("model", "static_hidden"),
        ] {
            old[section].as_object_mut().unwrap().remove(field);
        }
        let read = run_with(dir.path(), &old).meta().unwrap();
        assert_eq!(read.train.window_secs, 0.5);
        assert!(!read.train.precondition_moving_only);
        assert_eq!(read.model.static_hidden, vec![64, 128, 256]);
        assert_ne!(
            (
                TrainConfig::default().window_secs,
                ClothNetConfig::default().static_hidden
            ),
            (0.5, vec![64, 128, 256]),
            "the defaults moved"
        );
        // A file without the section is refused, as before (nothing is made up for it).
        let mut no_train = old.clone();
        no_train.as_object_mut().unwrap().remove("train");
        assert!(run_with(dir.path(), &no_train).meta().is_err());
        // A file that names them is read as written.
        let current = serde_json::to_value(meta(30.0)).unwrap();
        let read = run_with(dir.path(), &current).meta().unwrap();
        assert_eq!(read.train, TrainConfig::default());
        assert_eq!(read.model, ClothNetConfig::default());
    }

    /// A `run.json` of format version 2 as that program wrote it: fabric and effects copied
    /// beside the recorded scene (here they differ from `scene.toml`'s, as a hand edit or an
    /// old scene format could make them).
    const RUN_JSON_V2: &str = r#"{
  "version": 2,
  "train": {},
  "training_fps": 30.0,
  "model": {},
  "descriptors": {},
  "fabric": { "cloth_model": "stvk", "stretch_stiffness": 42.0, "lame_mu": 7.5 },
  "effects": { "gravity": true, "bending": true, "collision": false, "dynamics": true,
               "pinning": false, "friction": false },
  "input_joints": 24,
  "garment_vertices": 400,
  "garment_fingerprint": 123,
  "garment_name": "tshirt",
  "avatar_fingerprint": 456,
  "garment_skin_fingerprint": 789
}"#;

    const SCENE_TOML: &str = r#"
name = "tiny"
training_fps = 30.0
[avatar]
builtin = "mannequin"
[garment]
builtin = "tshirt"
resolution = 400
[[motions]]
builtin = "walk"
duration_secs = 1.0
[fabric]
preset = "default"
"#;

    /// Issue 14: `run.json` keeps no copy of the fabric and effects (the recorded scene is
    /// their one home); a version-2 run folder with the copies still loads, its recorded scene
    /// taking the copies, since they are what the run trained with.
    #[test]
    fn an_old_run_with_fabric_and_effects_copies_loads_from_its_scene() {
        let written = serde_json::to_value(meta(30.0)).unwrap();
        assert!(written.get("fabric").is_none(), "{written}");
        assert!(written.get("effects").is_none(), "{written}");

        let dir = tempfile::tempdir().unwrap();
        let run = RunDir::create(dir.path()).unwrap();
        std::fs::write(dir.path().join("run.json"), RUN_JSON_V2).unwrap();
        std::fs::write(dir.path().join("scene.toml"), SCENE_TOML).unwrap();
        let read = run.meta().unwrap();
        assert_eq!((read.version, read.training_fps), (2, 30.0));
        assert_eq!((read.input_joints, read.garment_vertices), (24, 400));
        assert_eq!(read.garment_skin_fingerprint, Some(789));
        let legacy = run.legacy_settings().unwrap().unwrap();
        assert!(!legacy.effects.collision);
        let scene = crate::resume::recorded_config(&run).unwrap();
        assert_eq!(
            scene.fabric.cloth_model,
            neural_cloth_physics::ClothModel::Stvk
        );
        assert_eq!(scene.fabric.stretch_stiffness, 42.0);
        assert_eq!(scene.fabric.lame_mu, 7.5);
        // Fields the old file left out take their defaults.
        assert_eq!(
            scene.fabric.density_kg_per_m2,
            FabricParams::default().density_kg_per_m2
        );
        assert_eq!(scene.effects, legacy.effects);

        // From version 3 on the scene is the one home: stray copies are not read.
        let mut v3: serde_json::Value = serde_json::from_str(RUN_JSON_V2).unwrap();
        v3["version"] = RUN_VERSION.into();
        std::fs::write(dir.path().join("run.json"), v3.to_string()).unwrap();
        assert_eq!(run.legacy_settings().unwrap(), None);
        let scene = crate::resume::recorded_config(&run).unwrap();
        assert_eq!(scene.fabric, FabricParams::default());
        assert_eq!(scene.effects, Effects::default());
    }
}
