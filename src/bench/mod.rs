//! Benchmarks behind `neural-cloth bench` (paper Tab. 4 protocol): frames per second from raw
//! pose to garment and body meshes at 10K and 250K degrees of freedom on 1 thread and all
//! threads, the memory-bandwidth floor of streaming the 250K basis, the training step time and
//! the cost of each physics term. Every figure that is compared is compared against a
//! baseline measured in the same run (the machine is shared and noisy).

pub mod memory;
pub mod suite;

use std::time::Instant;

use serde::Serialize;

use crate::model::{ClothNetConfig, DescriptorConfig, InferenceEngine, InferenceOptions, InferenceWeights};
use crate::scene::procedural::{GarmentKind, MotionKind, builtin_garment, mannequin, motion};
use crate::scene::{Avatar, Garment};

pub use memory::{MemoryBandwidth, measure_bandwidth, peak_rss_bytes, reset_peak_rss};
pub use suite::{BenchOptions, BenchReport, TrainBench, bench_training, run_suite};

/// Inference speed at one garment size and thread count.
#[derive(Clone, Debug, Serialize)]
pub struct InferenceBench {
    /// Degrees of freedom (3 × garment vertices).
    pub dof: usize,
    /// Worker threads (1, or all cores).
    pub threads: usize,
    /// Median milliseconds per frame (pose → garment + body meshes).
    pub ms_per_frame: f64,
    /// Frames per second from the median.
    pub fps: f64,
    /// Frames per second with the dynamic branch skipped (a still body).
    pub still_fps: f64,
    /// Size of the weights in bytes.
    pub weight_bytes: usize,
    /// Peak resident memory while running, minus the resident memory before the engine was
    /// built, in bytes (Linux only; 0 elsewhere).
    pub engine_peak_bytes: usize,
}

/// A mannequin and a t-shirt of about `dof` degrees of freedom.
pub fn scene_with_dof(avatar: &Avatar, dof: usize) -> Result<Garment, String> {
    builtin_garment(avatar, GarmentKind::TShirt, (dof / 3).max(200), None).map_err(|e| e.to_string())
}

/// Randomly initialised weights of the default architecture for `vertices` vertices.
pub fn random_weights(input_joints: usize, vertices: usize) -> Result<InferenceWeights, String> {
    let device = crate::train::device_for(crate::train::BackendKind::Cpu, false);
    let net = ClothNetConfig::default().init(input_joints, vertices, &device).map_err(|e| e.to_string())?;
    InferenceWeights::from_module(&net).map_err(|e| e.to_string())
}

/// Times the inference engine on the walk motion for `frames` frames after a warm-up.
pub fn bench_inference(avatar: &Avatar, garment: &Garment, weights: &InferenceWeights, threads: usize, frames: usize) -> Result<InferenceBench, String> {
    let walk = motion(MotionKind::Walk, 30.0, 4.0).map_err(|e| e.to_string())?;
    let options = InferenceOptions { threads, parallel_min_values: 0, skin_body: true };
    reset_peak_rss();
    let before = peak_rss_bytes();
    let mut engine = InferenceEngine::from_scene(weights.clone(), avatar, garment, &DescriptorConfig::default(), 30.0, options).map_err(|e| e.to_string())?;
    let mut times = Vec::with_capacity(frames);
    for k in 0..frames + 5 {
        let pose = &walk.frames[k % walk.frames.len()];
        let start = Instant::now();
        engine.step(pose, 1.0).map_err(|e| e.to_string())?;
        std::hint::black_box(engine.garment_positions());
        if k >= 5 {
            times.push(start.elapsed().as_secs_f64());
        }
    }
    let engine_peak_bytes = peak_rss_bytes().saturating_sub(before);
    let still_pose = &walk.frames[0];
    engine.reset();
    let mut still = Vec::with_capacity(frames);
    for k in 0..frames + 5 {
        let start = Instant::now();
        engine.step(still_pose, 1.0).map_err(|e| e.to_string())?;
        std::hint::black_box(engine.garment_positions());
        if k >= 5 {
            still.push(start.elapsed().as_secs_f64());
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let ms = median(&mut times) * 1e3;
    let still_ms = median(&mut still) * 1e3;
    let weight_bytes = weights.parameter_count() * 4;
    Ok(InferenceBench {
        dof: garment.vertex_count() * 3,
        threads,
        ms_per_frame: ms,
        fps: 1e3 / ms,
        still_fps: 1e3 / still_ms,
        weight_bytes,
        engine_peak_bytes,
    })
}

/// The mannequin used by every benchmark.
pub fn bench_avatar() -> Result<Avatar, String> {
    mannequin().map_err(|e| e.to_string())
}
