//! The reference simulation of a run's motion, simulated once and kept under `RUN/reference/`:
//!
//! ```text
//! RUN/reference/<motion>-<N>it-<fps>fps-<key>.pc2          the simulation, one frame per
//!                                                           motion frame at the training rate
//! RUN/reference/<motion>-<N>it-<fps>fps-<key>.static.pc2   the quasi-static solve of each frame
//! RUN/reference/<motion>-<N>it-<fps>fps-<key>.json         what the key covers, for people
//! ```
//! (the sensitivity check's simulations have `<N>it-jitter<J>um`, `J` the start jitter in
//! micrometres). `<key>` is a 64-bit FNV-1a hash of everything the result depends on: the
//! motion's name and poses, the iterations, frame rate, settling time, tolerance and start
//! jitter (when set), the garment (template,
//! faces, skin weights, pinned and collision-exempt vertices), the avatar, the fabric and the
//! effects. A changed input gives another file; a file whose frame or vertex count does not
//! match is simulated again. Files are written atomically (temporary + rename). A file not in
//! the run's cache but of the same name in another run beside it (`RUN/../*/reference/`) is
//! the same simulation and is copied over instead of simulated again.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use neural_cloth_core::geometry::Vec3;
use neural_cloth_core::io::export::{Pc2Writer, atomic::write_atomic, read_pc2};
use neural_cloth_core::scene::{Avatar, Garment, Motion, Scene};
use neural_cloth_physics::simulator::{SimOptions, SimProgress, simulate};
use neural_cloth_physics::{Effects, FabricParams, PhysicsError};

use super::super::run_dir::{avatar_fingerprint, garment_fingerprint};
use super::super::trained::TrainedModel;
use super::super::{BackendKind, TrainError, device_for};
use super::{CompareOptions, ComparePhase};

/// Format version of the cached files (part of the key). v2: quasi-static solves ride along
/// with the body ([`neural_cloth_physics::simulator::StepInput::skinned`]).
const CACHE_VERSION: &str = "neural-cloth reference v2";

/// L-BFGS tolerance of the reference (as the report's accuracy experiment: effectively none,
/// so every frame spends its iteration budget).
pub const REFERENCE_TOLERANCE: f64 = 1e-6;

/// The reference simulation of one motion.
#[derive(Clone, Debug)]
pub struct Reference {
    /// The simulation, one frame per motion frame.
    pub dynamic: Vec<Vec<Vec3>>,
    /// The quasi-static solve of each frame (dynamics off).
    pub quasi_static: Vec<Vec<Vec3>>,
    /// The cached simulation file.
    pub path: PathBuf,
    /// True when read from the cache, false when simulated now.
    pub cached: bool,
    /// Seconds spent simulating now (0 when cached).
    pub simulate_secs: f64,
}

/// What a reference simulation depends on besides the motion and the options: the body, the
/// garment, the fabric and the effects a run trains with.
#[derive(Clone, Copy, Debug)]
pub struct SimulatedScene<'a> {
    /// The avatar.
    pub avatar: &'a Avatar,
    /// The garment.
    pub garment: &'a Garment,
    /// The fabric.
    pub fabric: &'a FabricParams,
    /// The effects.
    pub effects: Effects,
}

impl<'a> From<&'a Scene> for SimulatedScene<'a> {
    fn from(scene: &'a Scene) -> Self {
        Self {
            avatar: &scene.avatar,
            garment: &scene.garment,
            fabric: &scene.fabric,
            effects: scene.effects,
        }
    }
}

/// What a cache key covers, written next to the frames.
#[derive(Serialize)]
struct KeyRecord<'a> {
    version: &'a str,
    motion: &'a str,
    frames: usize,
    iterations: usize,
    fps: f32,
    settle_secs: f32,
    tolerance: f64,
    /// The start jitter ([`CompareOptions::start_jitter_m`]), metres; absent when none.
    #[serde(skip_serializing_if = "is_zero")]
    start_jitter_m: f64,
    garment: &'a str,
    garment_fingerprint: u64,
    garment_vertices: usize,
    avatar: &'a str,
    avatar_fingerprint: u64,
    fabric: &'a neural_cloth_physics::FabricParams,
    effects: Effects,
    key: String,
}

/// True for 0 (a field left out of the key record).
fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// FNV-1a over a stream of bytes.
struct Fnv(u64);

impl Fnv {
    fn eat(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.0 ^= u64::from(*b);
            self.0 = self.0.wrapping_mul(0x100000001b3);
        }
    }

    fn floats(&mut self, values: impl IntoIterator<Item = f32>) {
        for v in values {
            self.eat(&v.to_le_bytes());
        }
    }
}

/// `name` with every character outside `[A-Za-z0-9_-]` replaced by `_` (at most 40).
fn file_safe(name: &str) -> String {
    let safe: String = name
        .chars()
        .take(40)
        .map(
            |c| match c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                true => c,
                false => '_',
            },
        )
        .collect();
    if safe.is_empty() {
        "motion".into()
    } else {
        safe
    }
}

/// The key record of `motion` (already resampled to the training rate) under `options`.
fn key_record<'a>(
    scene: SimulatedScene<'a>,
    motion: &'a Motion,
    options: &CompareOptions,
) -> Result<KeyRecord<'a>, TrainError> {
    let garment = scene.garment;
    let mut h = Fnv(0xcbf29ce484222325);
    h.eat(CACHE_VERSION.as_bytes());
    h.eat(motion.name.as_bytes());
    for pose in &motion.frames {
        h.floats(pose.rotations.iter().flat_map(|q| q.coords.iter().copied()));
        h.floats(pose.root_translation.iter().copied());
    }
    h.eat(&(options.iterations as u64).to_le_bytes());
    h.floats([motion.fps, options.settle_secs]);
    h.eat(&REFERENCE_TOLERANCE.to_le_bytes());
    if options.start_jitter_m > 0.0 {
        // Only when set, so that the keys of the references cached before it existed stand.
        h.eat(b"start jitter");
        h.eat(&options.start_jitter_m.to_le_bytes());
    }
    let garment_fp = garment_fingerprint(garment);
    let avatar_fp = avatar_fingerprint(scene.avatar);
    h.eat(&garment_fp.to_le_bytes());
    h.eat(&avatar_fp.to_le_bytes());
    for (joints, weights) in garment.skin.joints.iter().zip(&garment.skin.weights) {
        joints.iter().for_each(|j| h.eat(&j.to_le_bytes()));
        h.floats(weights.iter().copied());
    }
    for list in [&garment.pinned, &garment.no_collide] {
        h.eat(&(list.len() as u64).to_le_bytes());
        list.iter().for_each(|i| h.eat(&i.to_le_bytes()));
    }
    let json = |e: serde_json::Error| TrainError::Checkpoint(e.to_string());
    h.eat(&serde_json::to_vec(scene.fabric).map_err(json)?);
    h.eat(&serde_json::to_vec(&scene.effects).map_err(json)?);
    Ok(KeyRecord {
        version: CACHE_VERSION,
        motion: &motion.name,
        frames: motion.frames.len(),
        iterations: options.iterations,
        fps: motion.fps,
        settle_secs: options.settle_secs,
        tolerance: REFERENCE_TOLERANCE,
        start_jitter_m: options.start_jitter_m,
        garment: &garment.name,
        garment_fingerprint: garment_fp,
        garment_vertices: garment.vertex_count(),
        avatar: &scene.avatar.name,
        avatar_fingerprint: avatar_fp,
        fabric: scene.fabric,
        effects: scene.effects,
        key: format!("{:016x}", h.0),
    })
}

/// The folder of a run's cached reference simulations.
pub fn reference_dir(run_root: &Path) -> PathBuf {
    run_root.join("reference")
}

/// Frames of a cached PC2 file when it holds exactly `frames` frames of `vertices` points.
fn read_cached(path: &Path, frames: usize, vertices: usize) -> Option<Vec<Vec<Vec3>>> {
    let cache = read_pc2(path).ok()?;
    let fits = cache.frames.len() == frames && cache.frames.iter().all(|f| f.len() == vertices);
    fits.then_some(cache.frames)
}

/// The frames of `file` (a cache file of `run_root`, named `stem` + suffix) from another run
/// in the same folder as `run_root` that holds a file of that name, copied into this run's
/// cache with its key record. The name carries the key of everything the simulation depends
/// on, so a file of the same name is the same simulation: comparing a second run of a scene
/// simulates nothing again. `None` when no sibling run has it.
fn adopt_from_sibling(
    run_root: &Path,
    file: &Path,
    stem: &str,
    frames: usize,
    vertices: usize,
) -> Result<Option<Vec<Vec<Vec3>>>, TrainError> {
    let (Some(parent), Some(name)) = (run_root.parent(), file.file_name()) else {
        return Ok(None);
    };
    let Ok(entries) = std::fs::read_dir(parent) else {
        return Ok(None);
    };
    let own = run_root.file_name();
    for entry in entries.flatten() {
        if Some(entry.file_name().as_os_str()) == own {
            continue;
        }
        let theirs = reference_dir(&entry.path());
        let source = theirs.join(name);
        let Some(found) = read_cached(&source, frames, vertices) else {
            continue;
        };
        let bytes = std::fs::read(&source).map_err(|e| TrainError::io(e, &source))?;
        let dir = reference_dir(run_root);
        std::fs::create_dir_all(&dir).map_err(|e| TrainError::io(e, &dir))?;
        write_atomic(file, &bytes)?;
        let record = format!("{stem}.json");
        if let Ok(json) = std::fs::read(theirs.join(&record)) {
            write_atomic(&dir.join(&record), &json)?;
        }
        return Ok(Some(found));
    }
    Ok(None)
}

/// Writes `frames` to `path` atomically.
fn write_frames(path: &Path, frames: &[Vec<Vec3>]) -> Result<(), TrainError> {
    let vertices = frames.first().map_or(0, Vec::len);
    let mut writer = Pc2Writer::create(path, vertices, 0.0, 1.0)?;
    for frame in frames {
        writer.write_frame(frame)?;
    }
    writer.finish()?;
    Ok(())
}

/// Simulates `motion` (resampled to the training rate) with `effects`, reporting each frame
/// as `phase`.
fn simulate_with(
    scene: SimulatedScene<'_>,
    motion: &Motion,
    effects: &Effects,
    options: &CompareOptions,
    phase: ComparePhase,
    progress: &mut dyn FnMut(ComparePhase, usize, usize) -> bool,
) -> Result<Vec<Vec<Vec3>>, TrainError> {
    let sim = SimOptions {
        iterations_per_step: options.iterations,
        tolerance: REFERENCE_TOLERANCE,
        settle_secs: options.settle_secs,
        start_jitter_m: options.start_jitter_m,
        ..SimOptions::default()
    };
    let device = device_for(BackendKind::Cpu, false);
    let result = simulate(
        scene.avatar,
        scene.garment,
        scene.fabric,
        effects,
        motion,
        motion.fps,
        &sim,
        &device,
        &mut |p: &SimProgress| progress(phase, p.frame, p.total),
    )?;
    if result.frames.len() != motion.frames.len() {
        return Err(TrainError::Physics(PhysicsError::InvalidOptions(format!(
            "the simulation gave {} frames for {} motion frames",
            result.frames.len(),
            motion.frames.len()
        ))));
    }
    Ok(result.frames)
}

/// The reference simulation and quasi-static solve of `motion` (resampled to the training
/// rate), each read from `RUN/reference/` when cached there, else simulated and cached.
/// `progress(phase, done, total)` sees each simulated frame; returning false cancels.
pub fn reference_for(
    trained: &TrainedModel,
    motion: &Motion,
    options: &CompareOptions,
    progress: &mut dyn FnMut(ComparePhase, usize, usize) -> bool,
) -> Result<Reference, TrainError> {
    let started = Instant::now();
    let scene = SimulatedScene::from(&trained.scene);
    let mut solve = |dynamic: bool| {
        cached_or_simulated(scene, &trained.run.root, motion, options, dynamic, progress)
    };
    let (dynamic, path, dynamic_cached) = solve(true)?;
    let (quasi_static, _, static_cached) = solve(false)?;
    let cached = dynamic_cached && static_cached;
    Ok(Reference {
        dynamic,
        quasi_static,
        path,
        cached,
        simulate_secs: if cached {
            0.0
        } else {
            started.elapsed().as_secs_f64()
        },
    })
}

/// The reference simulation of `motion` alone (no quasi-static solve), cached as
/// [`reference_for`] caches it; with its file and whether it was read from the cache.
pub fn simulation_for(
    trained: &TrainedModel,
    motion: &Motion,
    options: &CompareOptions,
    progress: &mut dyn FnMut(ComparePhase, usize, usize) -> bool,
) -> Result<(Vec<Vec<Vec3>>, PathBuf, bool), TrainError> {
    cached_or_simulated(
        (&trained.scene).into(),
        &trained.run.root,
        motion,
        options,
        true,
        progress,
    )
}

/// [`simulation_for`] of a run that has no checkpoint yet: `scene` as the run trains on it (at
/// its training rate), cached under `run_root/reference/` with the key `compare` uses, so
/// that a later `compare` of the run reads the same file (the training warm start,
/// [`crate::TrainConfig::warm_start_steps`]).
pub fn simulation_in(
    scene: SimulatedScene<'_>,
    run_root: &Path,
    motion: &Motion,
    options: &CompareOptions,
    progress: &mut dyn FnMut(ComparePhase, usize, usize) -> bool,
) -> Result<(Vec<Vec<Vec3>>, PathBuf, bool), TrainError> {
    cached_or_simulated(scene, run_root, motion, options, true, progress)
}

/// The simulation (`dynamic`) or the quasi-static solve of `motion`: read from its cache file
/// when it holds the motion's frames, else simulated and written there (with the key record).
fn cached_or_simulated(
    scene: SimulatedScene<'_>,
    run_root: &Path,
    motion: &Motion,
    options: &CompareOptions,
    dynamic: bool,
    progress: &mut dyn FnMut(ComparePhase, usize, usize) -> bool,
) -> Result<(Vec<Vec<Vec3>>, PathBuf, bool), TrainError> {
    let record = key_record(scene, motion, options)?;
    let jitter = match options.start_jitter_m > 0.0 {
        true => format!("-jitter{}um", options.start_jitter_m * 1e6),
        false => String::new(),
    };
    let stem = format!(
        "{}-{}it{jitter}-{}fps-{}",
        file_safe(&motion.name),
        options.iterations,
        motion.fps,
        record.key
    );
    let dir = reference_dir(run_root);
    let path = dir.join(format!("{stem}.pc2"));
    let file = match dynamic {
        true => path.clone(),
        false => dir.join(format!("{stem}.static.pc2")),
    };
    let (frames, vertices) = (motion.frames.len(), scene.garment.vertex_count());
    if options.use_cache
        && let Some(cached) = read_cached(&file, frames, vertices)
    {
        return Ok((cached, path, true));
    }
    if options.use_cache
        && let Some(cached) = adopt_from_sibling(run_root, &file, &stem, frames, vertices)?
    {
        return Ok((cached, path, true));
    }
    let effects = Effects {
        dynamics: dynamic && scene.effects.dynamics,
        ..scene.effects
    };
    let phase = match dynamic {
        true => ComparePhase::Simulating,
        false => ComparePhase::SimulatingStatic,
    };
    let simulated = simulate_with(scene, motion, &effects, options, phase, progress)?;
    if options.use_cache {
        std::fs::create_dir_all(&dir).map_err(|e| TrainError::io(e, &dir))?;
        write_frames(&file, &simulated)?;
        let json = serde_json::to_vec_pretty(&record)
            .map_err(|e| TrainError::Checkpoint(e.to_string()))?;
        write_atomic(&dir.join(format!("{stem}.json")), &json)?;
    }
    Ok((simulated, path, false))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_names_are_safe() {
        assert_eq!(file_safe("walk"), "walk");
        assert_eq!(file_safe("a b/c..d"), "a_b_c__d");
        assert_eq!(file_safe(""), "motion");
    }
}
