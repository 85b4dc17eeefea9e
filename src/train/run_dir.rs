//! Run directories: everything needed to resume, evaluate or bake a trained model.
//!
//! ```text
//! RUN/run.json                  RunMeta: train + model + descriptor configs, fabric, effects,
//!                               garment fingerprint
//! RUN/scene.toml                the scene description (file paths absolute)
//! RUN/metrics.json              the metric history up to the newest checkpoint
//! RUN/latest.json               {"step": N} of the newest complete checkpoint
//! RUN/checkpoints/step-0000N/   model.bpk (burn record), optimizer.bpk, state.json
//! ```
//! Every file is written atomically (temporary + rename) and a checkpoint folder appears
//! only when complete, so a crash never leaves a half-written checkpoint behind.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::io::export::atomic::{AtomicDir, write_atomic};
use crate::model::{ClothNetConfig, DescriptorConfig};
use crate::physics::{Effects, FabricParams};
use crate::scene::{Avatar, Garment};

use super::TrainError;
use super::config::TrainConfig;
use super::metrics::MetricHistory;

/// How many checkpoints to keep (older ones are deleted).
pub const KEEP_CHECKPOINTS: usize = 3;

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

/// FNV-1a fingerprint of a garment's template positions and faces.
pub fn garment_fingerprint(garment: &Garment) -> u64 {
    let mut h: u64 = 0xcbf29ce484222325;
    let mut eat = |bytes: &[u8]| {
        for b in bytes {
            h ^= u64::from(*b);
            h = h.wrapping_mul(0x100000001b3);
        }
    };
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
    h
}

/// FNV-1a fingerprint of an avatar: its joint names and parents, the rest-pose joint
/// positions, and the rest body's positions and faces.
pub fn avatar_fingerprint(avatar: &Avatar) -> u64 {
    let mut h: u64 = 0xcbf29ce484222325;
    let mut eat = |bytes: &[u8]| {
        for b in bytes {
            h ^= u64::from(*b);
            h = h.wrapping_mul(0x100000001b3);
        }
    };
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
    h
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
        serde_json::from_slice(&bytes)
            .map_err(|e| TrainError::Checkpoint(format!("{e}: {}", path.display())))
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

    /// Step of the newest complete checkpoint, if any.
    pub fn latest_step(&self) -> Option<u64> {
        let text = std::fs::read_to_string(self.root.join("latest.json")).ok()?;
        let v: serde_json::Value = serde_json::from_str(&text).ok()?;
        let step = v.get("step")?.as_u64()?;
        self.checkpoint_path(step)
            .join("model.bpk")
            .is_file()
            .then_some(step)
    }

    /// Writes a checkpoint folder atomically, then the history and `latest.json`, then prunes
    /// old checkpoints. Returns the checkpoint folder.
    pub fn write_checkpoint(
        &self,
        state: CheckpointState,
        model_bytes: &[u8],
        optimizer_bytes: &[u8],
        history: &MetricHistory,
    ) -> Result<PathBuf, TrainError> {
        let path = self.checkpoint_path(state.step);
        let _ = std::fs::remove_dir_all(&path);
        let dir = AtomicDir::create(&path)?;
        write_atomic(&dir.temp_path().join("model.bpk"), model_bytes)?;
        write_atomic(&dir.temp_path().join("optimizer.bpk"), optimizer_bytes)?;
        let state_json =
            serde_json::to_vec_pretty(&state).map_err(|e| TrainError::Checkpoint(e.to_string()))?;
        write_atomic(&dir.temp_path().join("state.json"), &state_json)?;
        let path = dir.commit()?;
        let history_json =
            serde_json::to_vec(history).map_err(|e| TrainError::Checkpoint(e.to_string()))?;
        write_atomic(&self.root.join("metrics.json"), &history_json)?;
        write_atomic(
            &self.root.join("latest.json"),
            format!("{{\"step\": {}}}\n", state.step).as_bytes(),
        )?;
        self.prune();
        Ok(path)
    }

    /// Reads the model bytes, optimiser bytes and state of checkpoint `step`.
    pub fn read_checkpoint(
        &self,
        step: u64,
    ) -> Result<(Vec<u8>, Vec<u8>, CheckpointState), TrainError> {
        let dir = self.checkpoint_path(step);
        let read = |name: &str| {
            let p = dir.join(name);
            std::fs::read(&p).map_err(|e| TrainError::io(e, &p))
        };
        let state: CheckpointState = serde_json::from_slice(&read("state.json")?).map_err(|e| {
            TrainError::Checkpoint(format!("{e}: {}", dir.join("state.json").display()))
        })?;
        Ok((read("model.bpk")?, read("optimizer.bpk")?, state))
    }

    /// The metric history saved with the newest checkpoint (empty when none).
    pub fn history(&self) -> MetricHistory {
        std::fs::read(self.root.join("metrics.json"))
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok())
            .unwrap_or_default()
    }

    fn prune(&self) {
        let Ok(entries) = std::fs::read_dir(self.root.join("checkpoints")) else {
            return;
        };
        let mut steps: Vec<(u64, PathBuf)> = entries
            .filter_map(|e| e.ok())
            .filter_map(|e| {
                let name = e.file_name().to_string_lossy().into_owned();
                name.strip_prefix("step-")
                    .and_then(|s| s.parse().ok())
                    .map(|s| (s, e.path()))
            })
            .collect();
        steps.sort_by_key(|(s, _)| std::cmp::Reverse(*s));
        for (_, p) in steps.into_iter().skip(KEEP_CHECKPOINTS) {
            let _ = std::fs::remove_dir_all(p);
        }
    }
}
