//! Benchmarks behind `neural-cloth bench` (paper Tab. 4 protocol): frames per second from raw
//! pose to garment and body meshes at 10K and 250K degrees of freedom on 1 thread and all
//! threads, the memory-bandwidth floor of streaming the 250K basis, the error of the f16
//! weights, the training step time and the cost of each physics term. Every figure that is
//! compared is compared against a baseline measured in the same run (the machine is shared
//! and noisy).

pub mod cost;
pub mod memory;
pub mod report;
pub mod suite;
pub mod training;
pub mod training_report;

use std::time::Instant;

use serde::Serialize;

use neural_cloth_core::scene::procedural::{
    GarmentKind, MotionKind, builtin_garment, mannequin, motion,
};
use neural_cloth_core::scene::{Avatar, Garment, Motion};
use neural_cloth_model::{
    ClothNetConfig, DescriptorConfig, EncoderKind, InferenceOptions, InferenceWeights,
    ModelArtifact, Precision,
};

pub use memory::{
    MemoryBandwidth, floor_buffer, measure_bandwidth, peak_rss_bytes, read_pass_secs,
    reset_peak_rss, rss_bytes, status_field,
};
pub use suite::{BenchOptions, BenchReport, TrainFloor, run_suite};
pub use training::{StepFlops, TrainBench, TrainCase, bench_training};

/// Frame rate of the benchmark motion and of the engines.
const FPS: f32 = 30.0;
/// Frames run before timing starts.
const WARM_UP: usize = 5;
/// Seconds of frames timed at least per run (more frames than asked for small garments).
const MIN_TIMED_SECS: f64 = 1.0;
/// Most frames timed per run.
const MAX_FRAMES: usize = 5000;

/// Inference speed at one garment size, model, precision and thread count.
#[derive(Clone, Debug, Serialize)]
pub struct InferenceBench {
    /// Degrees of freedom (3 × garment vertices).
    pub dof: usize,
    /// Body vertices posed per frame.
    pub body_vertices: usize,
    /// Encoder layout (`StaticOnly` = the scene has no dynamics).
    pub model: EncoderKind,
    /// Storage precision of the basis / of the other layers, e.g. `f16/f16`.
    pub precision: String,
    /// Worker threads (1, or all cores).
    pub threads: usize,
    /// True when the garment pass ran on the thread pool (`threads > 1` and at least
    /// `parallel_min_values` garment values; below that the engine stays on one thread).
    pub parallel: bool,
    /// Milliseconds to build the engine (including the in-place f16 conversion).
    pub build_ms: f64,
    /// Median milliseconds per frame (pose → garment + body meshes).
    pub ms_per_frame: f64,
    /// Frames per second from the median.
    pub fps: f64,
    /// Frames per second with the dynamic branch skipped (a still body).
    pub still_fps: f64,
    /// Size of the trained weights in f32 (as handed to the engine), bytes.
    pub weight_bytes: usize,
    /// Bytes of weights the engine stores (basis and layers at their precision).
    pub stored_bytes: usize,
    /// Bytes of the stored basis.
    pub basis_bytes: usize,
    /// Bytes of the basis in f32 (the buffer size of the bandwidth floor).
    pub basis_f32_bytes: usize,
    /// Mean fraction of basis rows read per frame (rows of nonzero decoder outputs).
    pub basis_rows_read: f64,
    /// Median milliseconds of a streaming read of a buffer the size of the f32 basis, one
    /// read after each timed frame with the run's thread count (the floor in the same time
    /// window as the frames; measured for the largest garment only).
    pub paired_floor_ms: Option<f64>,
    /// The same for a buffer the size of the basis as stored, when that differs (f16).
    pub paired_stored_floor_ms: Option<f64>,
    /// Peak resident memory from just before the engine was built to the last frame, minus
    /// the resident memory before (the weights already loaded), bytes (Linux; 0 elsewhere).
    pub engine_peak_bytes: usize,
}

impl InferenceBench {
    /// Peak memory of an inference process: the weights as loaded plus the engine's peak
    /// increase, as a multiple of the weights.
    pub fn peak_over_weights(&self) -> f64 {
        (self.weight_bytes + self.engine_peak_bytes) as f64 / self.weight_bytes.max(1) as f64
    }
}

/// A mannequin and a t-shirt of about `dof` degrees of freedom.
pub fn scene_with_dof(avatar: &Avatar, dof: usize) -> Result<Garment, String> {
    builtin_garment(avatar, GarmentKind::TShirt, (dof / 3).max(200), None)
        .map_err(|e| e.to_string())
}

/// Randomly initialised weights of the default architecture for `vertices` vertices.
pub fn random_weights(input_joints: usize, vertices: usize) -> Result<InferenceWeights, String> {
    random_weights_of(EncoderKind::Disentangled, input_joints, vertices)
}

/// Randomly initialised weights of the default architecture with encoder layout `kind`.
pub fn random_weights_of(
    kind: EncoderKind,
    input_joints: usize,
    vertices: usize,
) -> Result<InferenceWeights, String> {
    let device = neural_cloth_train::device_for(neural_cloth_train::BackendKind::Cpu, false);
    let config = ClothNetConfig {
        encoder: kind,
        ..ClothNetConfig::default()
    };
    let net = config
        .init(input_joints, vertices, &device)
        .map_err(|e| e.to_string())?;
    InferenceWeights::from_module(&net).map_err(|e| e.to_string())
}

/// The benchmark motion: the procedural walk at the engines' rate.
pub fn bench_motion() -> Result<Motion, String> {
    motion(MotionKind::Walk, FPS, 4.0).map_err(|e| e.to_string())
}

fn median_ms(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN) * 1e3
}

/// Times the inference engine on the walk motion for `frames` frames (more if they take less
/// than a second, up to 5000) after a warm-up, then as many on a still body. `weights` are moved into the engine (as an application would). With
/// `paired_floor`, a streaming read of a buffer the size of the f32 basis is timed after each
/// timed frame, so the floor and the frames see the same machine load.
pub fn bench_inference(
    avatar: &Avatar,
    garment: &Garment,
    weights: InferenceWeights,
    options: InferenceOptions,
    frames: usize,
    paired_floor: bool,
) -> Result<InferenceBench, String> {
    let artifact = ModelArtifact::new(weights, DescriptorConfig::default(), FPS);
    bench_artifact(
        avatar,
        garment,
        &bench_motion()?,
        artifact,
        options,
        frames,
        paired_floor,
    )
}

/// [`bench_inference`] of a model with its own descriptor settings and rate (e.g. trained
/// weights) on the poses of `walk`.
pub fn bench_artifact(
    avatar: &Avatar,
    garment: &Garment,
    walk: &Motion,
    artifact: ModelArtifact,
    options: InferenceOptions,
    frames: usize,
    paired_floor: bool,
) -> Result<InferenceBench, String> {
    let weights = &artifact.weights;
    let weight_bytes = weights.parameter_count() * 4;
    let basis_f32_bytes = weights.basis.weight.len() * 4;
    let model = weights.kind;
    let precision = format!(
        "{}/{}",
        options.basis_precision.name(),
        options.layer_precision.name()
    );
    let threads = match options.threads {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        n => n,
    };
    let parallel = threads > 1 && garment.vertex_count() * 3 >= options.parallel_min_values;
    // Allocated before the memory baseline: they are not part of the engine's peak.
    let floor_data = paired_floor.then(|| floor_buffer(basis_f32_bytes));
    let stored_floor_data = (paired_floor && options.basis_precision == Precision::F16)
        .then(|| floor_buffer(basis_f32_bytes / 2));
    let (mut floor_times, mut stored_floor_times) = (Vec::new(), Vec::new());
    reset_peak_rss();
    let before = rss_bytes();
    let build_start = Instant::now();
    let mut engine = artifact
        .into_engine(avatar, garment, options)
        .map_err(|e| e.to_string())?;
    let build_ms = build_start.elapsed().as_secs_f64() * 1e3;
    let mut frames = frames.max(1);
    let mut times = Vec::with_capacity(MAX_FRAMES);
    let mut rows_read = 0.0;
    let mut k = 0;
    while k < frames + WARM_UP {
        let Some(pose) = walk.frames.get(k % walk.frames.len().max(1)) else {
            return Err("the benchmark motion has no frames".into());
        };
        let start = Instant::now();
        engine.step(pose, 1.0).map_err(|e| e.to_string())?;
        std::hint::black_box(engine.garment_positions());
        if k + 1 == WARM_UP {
            // Time at least MIN_TIMED_SECS of frames, so that a short burst of load from
            // other processes cannot decide the median.
            let per_frame = start.elapsed().as_secs_f64().max(1e-6);
            frames = frames
                .max((MIN_TIMED_SECS / per_frame) as usize)
                .min(MAX_FRAMES);
        }
        if k >= WARM_UP {
            times.push(start.elapsed().as_secs_f64());
            let h = engine.basis_input();
            rows_read += h.iter().filter(|v| **v != 0.0).count() as f64 / h.len().max(1) as f64;
            // With two buffers, frames alternate between them.
            let readers = if parallel { threads } else { 1 };
            match (&floor_data, &stored_floor_data) {
                (_, Some(data)) if k % 2 == 1 => {
                    stored_floor_times.push(read_pass_secs(data, readers))
                }
                (Some(data), _) => floor_times.push(read_pass_secs(data, readers)),
                _ => {}
            }
        }
        k += 1;
    }
    let engine_peak_bytes = peak_rss_bytes().saturating_sub(before);
    drop(floor_data);
    drop(stored_floor_data);
    let Some(still_pose) = walk.frames.first() else {
        return Err("the benchmark motion has no frames".into());
    };
    engine.reset();
    let mut still = Vec::with_capacity(frames);
    for k in 0..frames + WARM_UP {
        let start = Instant::now();
        engine.step(still_pose, 1.0).map_err(|e| e.to_string())?;
        std::hint::black_box(engine.garment_positions());
        if k >= WARM_UP {
            still.push(start.elapsed().as_secs_f64());
        }
    }
    let ms = median_ms(&mut times);
    let still_ms = median_ms(&mut still);
    Ok(InferenceBench {
        dof: garment.vertex_count() * 3,
        body_vertices: engine.body_positions().len(),
        model,
        precision,
        threads,
        parallel,
        build_ms,
        ms_per_frame: ms,
        fps: 1e3 / ms,
        still_fps: 1e3 / still_ms,
        weight_bytes,
        stored_bytes: engine.weight_bytes(),
        basis_bytes: engine.basis_bytes(),
        basis_f32_bytes,
        basis_rows_read: rows_read / frames as f64,
        paired_floor_ms: (!floor_times.is_empty()).then(|| median_ms(&mut floor_times)),
        paired_stored_floor_ms: (!stored_floor_times.is_empty())
            .then(|| median_ms(&mut stored_floor_times)),
        engine_peak_bytes,
    })
}

/// How far the reduced-precision engine's garment is from the f32 engine's.
#[derive(Clone, Debug, Serialize)]
pub struct PrecisionError {
    /// Degrees of freedom.
    pub dof: usize,
    /// Storage precision of the basis / of the other layers.
    pub precision: String,
    /// Frames compared (the walk, GRU state carried over, `w = 1`).
    pub frames: usize,
    /// Largest distance between the rest-space offsets of a vertex in the two engines (the
    /// vertex error before skinning, which is nearly rigid), metres.
    pub max_offset_error_m: f64,
    /// Mean of that distance over all vertices and frames, metres.
    pub mean_offset_error_m: f64,
    /// Largest distance between posed garment vertices, metres. Besides the f16 error it holds
    /// the f32 rounding of world coordinates (an ulp is 4.8e-7 m for coordinates of 4 m to
    /// 8 m), so it cannot drop below a few 1e-7 m once the body walks away from the origin.
    pub max_posed_error_m: f64,
    /// Largest offset magnitude of the f32 engine (the scale of the error), metres.
    pub max_offset_m: f64,
}

impl PrecisionError {
    /// Largest offset error as a fraction of the largest offset (scale-free).
    pub fn relative(&self) -> f64 {
        self.max_offset_error_m / self.max_offset_m.max(1e-12)
    }
}

fn norm3(v: &[f32]) -> f64 {
    v.iter()
        .map(|c| f64::from(*c) * f64::from(*c))
        .sum::<f64>()
        .sqrt()
}

/// Runs an f32 engine and one with `options`' precisions side by side over `frames` frames
/// of the walk and measures the garment error.
pub fn measure_precision_error(
    avatar: &Avatar,
    garment: &Garment,
    weights: InferenceWeights,
    options: InferenceOptions,
    frames: usize,
) -> Result<PrecisionError, String> {
    let walk = bench_motion()?;
    let precision = format!(
        "{}/{}",
        options.basis_precision.name(),
        options.layer_precision.name()
    );
    let exact = InferenceOptions {
        skin_body: false,
        ..InferenceOptions::exact()
    };
    let reduced = InferenceOptions {
        skin_body: false,
        ..options
    };
    let build = |w, o| {
        ModelArtifact::new(w, DescriptorConfig::default(), FPS)
            .into_engine(avatar, garment, o)
            .map_err(|e| e.to_string())
    };
    let mut reference = build(weights.clone(), exact)?;
    let mut engine = build(weights, reduced)?;
    let (mut max, mut sum, mut count, mut max_offset, mut max_posed) =
        (0f64, 0f64, 0usize, 0f64, 0f64);
    for pose in walk.frames.iter().cycle().take(frames) {
        reference.step(pose, 1.0).map_err(|e| e.to_string())?;
        engine.step(pose, 1.0).map_err(|e| e.to_string())?;
        for (a, b) in reference
            .offsets()
            .chunks_exact(3)
            .zip(engine.offsets().chunks_exact(3))
        {
            let d = norm3(&[a[0] - b[0], a[1] - b[1], a[2] - b[2]]);
            max = max.max(d);
            sum += d;
            count += 1;
            max_offset = max_offset.max(norm3(a));
        }
        for (a, b) in reference
            .garment_positions()
            .iter()
            .zip(engine.garment_positions())
        {
            max_posed = max_posed.max(f64::from((a - b).norm()));
        }
    }
    Ok(PrecisionError {
        dof: garment.vertex_count() * 3,
        precision,
        frames,
        max_offset_error_m: max,
        mean_offset_error_m: sum / count.max(1) as f64,
        max_posed_error_m: max_posed,
        max_offset_m: max_offset,
    })
}

/// The mannequin used by every benchmark.
pub fn bench_avatar() -> Result<Avatar, String> {
    mannequin().map_err(|e| e.to_string())
}
