//! Run directories: everything needed to resume, evaluate or bake a trained model.
//!
//! ```text
//! RUN/run.json                  RunMeta: train + model + descriptor configs, fabric, effects,
//!                               garment, garment skin and avatar fingerprints
//! RUN/scene.toml                the scene description (file paths absolute)
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
use neural_cloth_core::scene::{Avatar, Garment};
use neural_cloth_model::{ClothNetConfig, DescriptorConfig};
use neural_cloth_physics::{Effects, FabricParams};

use super::TrainError;
use super::config::TrainConfig;
use super::metrics::MetricHistory;

/// How many checkpoints to keep (older ones are deleted).
pub const KEEP_CHECKPOINTS: usize = 3;
/// The newest run folder format this program reads and writes ([`RunMeta::version`]).
pub const RUN_VERSION: u32 = 1;

/// Description of a run, written once at its start.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RunMeta {
    /// Format version of the run directory.
    pub version: u32,
    /// Training settings.
    pub train: TrainConfig,
    /// Network architecture.
    pub model: ClothNetConfig,
    /// Descriptor settings.
    pub descriptors: DescriptorConfig,
    /// Fabric used for the losses.
    pub fabric: FabricParams,
    /// Effects simulated.
    pub effects: Effects,
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

    /// Reads `run.json`.
    pub fn meta(&self) -> Result<RunMeta, TrainError> {
        let path = self.root.join("run.json");
        let bytes = std::fs::read(&path).map_err(|e| TrainError::io(e, &path))?;
        let meta: RunMeta = serde_json::from_slice(&bytes).map_err(|e| TrainError::Corrupt {
            reason: format!("unreadable run description ({e})"),
            path: path.clone(),
        })?;
        if meta.version > RUN_VERSION {
            return Err(TrainError::Corrupt {
                reason: format!(
                    "the run folder has format version {}, newer than this program reads ({RUN_VERSION})",
                    meta.version
                ),
                path,
            });
        }
        Ok(meta)
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
