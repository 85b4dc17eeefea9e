//! The full benchmark suite and its Markdown report.

use std::time::Instant;

use serde::Serialize;

use crate::model::{ClothNetConfig, DescriptorConfig, EncoderKind, InferenceOptions, Precision};
use crate::physics::cost::{CostReport, measure_term_costs};
use crate::scene::config::{Effects, SceneConfig};
use crate::scene::procedural::build_builtin;
use crate::train::handle::Session;
use crate::train::{RunLocation, TrainConfig, TrainSetup, prepare};

use super::report::write_markdown;
use super::{
    InferenceBench, MemoryBandwidth, PrecisionError, bench_avatar, bench_inference,
    measure_bandwidth, measure_precision_error, peak_rss_bytes, random_weights_of, reset_peak_rss,
    scene_with_dof,
};

/// Garments from this many degrees of freedom on (a basis of ≥ 200 MB in f32) get a floor
/// read after every timed frame; smaller ones would have their weights evicted from the cache
/// by it.
const PAIRED_FLOOR_MIN_DOF: usize = 100_000;

/// Training step time at one batch size and set of effects.
#[derive(Clone, Debug, Serialize)]
pub struct TrainBench {
    /// Windows per batch.
    pub batch: usize,
    /// Window length in seconds.
    pub window_secs: f32,
    /// Training frame rate.
    pub fps: f32,
    /// Effects of the scene (the default scene has all but pinning).
    pub effects: Effects,
    /// Physics as fused kernels (true, the default path) or as burn tensor code (the
    /// reference path the kernels are checked against).
    pub fused_physics: bool,
    /// Median milliseconds per optimiser step.
    pub ms_per_step: f64,
    /// Peak resident memory of the process during the steps, bytes.
    pub peak_bytes: usize,
}

/// Everything `neural-cloth bench` measures.
#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    /// Cores available.
    pub cores: usize,
    /// True when the AVX2 + FMA + F16C kernels ran (false: portable loops).
    pub simd: bool,
    /// Inference at each size, model, precision and thread count.
    pub inference: Vec<InferenceBench>,
    /// Garment error of the default (f16) engine against the f32 one.
    pub precision: Vec<PrecisionError>,
    /// Streaming reads of buffers the size of each basis (f32 and f16), 1 thread and all.
    pub bandwidth: Vec<MemoryBandwidth>,
    /// Training step times.
    pub training: Vec<TrainBench>,
    /// Per-term physics costs at 10K DoF.
    pub physics: Option<CostReport>,
    /// Seconds the suite took.
    pub total_secs: f64,
}

/// What to run.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Garment sizes in degrees of freedom.
    pub dofs: Vec<usize>,
    /// Frames timed per inference run (at least; small garments run a second of frames).
    pub frames: usize,
    /// Batch sizes of the training benchmark (empty: skip); the first one is also timed with
    /// each effect switched off.
    pub train_batches: Vec<usize>,
    /// Steps timed per batch size.
    pub train_steps: usize,
    /// Measure the physics terms.
    pub physics: bool,
}

impl Default for BenchOptions {
    fn default() -> Self {
        Self {
            dofs: vec![10_000, 250_000],
            frames: 60,
            train_batches: vec![16, 32],
            train_steps: 10,
            physics: true,
        }
    }
}

/// Median optimiser-step time of the default scene with `effects` at `batch`, with the fused
/// physics kernels or (`fused_physics = false`) the burn reference path.
pub fn bench_training(
    batch: usize,
    steps: usize,
    effects: Effects,
    fused_physics: bool,
) -> Result<TrainBench, String> {
    let mut config = SceneConfig::default_scene();
    config.effects = effects;
    let scene = build_builtin(&config).map_err(|e| e.to_string())?;
    let dir =
        std::env::temp_dir().join(format!("neural-cloth-bench-{}-{batch}", std::process::id()));
    let train = TrainConfig {
        batch_size: batch,
        window_secs: 0.5,
        fps: 30.0,
        fused_physics,
        ..Default::default()
    };
    let setup = TrainSetup {
        scene,
        scene_config: config,
        train: train.clone(),
        model: ClothNetConfig::default(),
        descriptors: DescriptorConfig::default(),
        fabric: None,
        location: RunLocation::At(dir.clone()),
    };
    let (mut session, _) = prepare(setup).map_err(|e| e.to_string())?;
    reset_peak_rss();
    let mut times = Vec::new();
    for k in 0..steps + 2 {
        let start = Instant::now();
        session.step().map_err(|e| e.to_string())?;
        if k >= 2 {
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    let peak_bytes = peak_rss_bytes();
    let _ = std::fs::remove_dir_all(&dir);
    times.sort_by(f64::total_cmp);
    Ok(TrainBench {
        batch,
        window_secs: train.window_secs,
        fps: train.fps,
        effects,
        fused_physics,
        ms_per_step: times.get(times.len() / 2).copied().unwrap_or(f64::NAN),
        peak_bytes,
    })
}

/// The name of a physics path in logs and tables.
pub fn physics_label(fused: bool) -> &'static str {
    if fused { "fused" } else { "burn (reference)" }
}

/// One inference configuration of the suite.
struct Run {
    kind: EncoderKind,
    basis: Precision,
    layers: Precision,
    all_threads: bool,
    /// Use the pool whatever the garment size (`parallel_min_values = 0`).
    force_parallel: bool,
}

impl Run {
    fn new(kind: EncoderKind, basis: Precision, layers: Precision, all_threads: bool) -> Self {
        Self {
            kind,
            basis,
            layers,
            all_threads,
            force_parallel: false,
        }
    }
}

/// The configurations timed at garment size number `index`: f32 (exact) and the default f16
/// engine on 1 thread and all threads; at the first size also the f16 engine forced onto all
/// threads, f16 basis with f32 layers, and the static-only model (a scene without dynamics).
fn runs(index: usize, cores: usize) -> Vec<Run> {
    let (f32_, f16_) = (Precision::F32, Precision::F16);
    let full = EncoderKind::Disentangled;
    let mut out = Vec::new();
    let threads: &[bool] = if cores > 1 { &[false, true] } else { &[false] };
    for &(basis, layers) in &[(f32_, f32_), (f16_, f16_)] {
        for &all_threads in threads {
            out.push(Run::new(full, basis, layers, all_threads));
        }
    }
    if index == 0 {
        if cores > 1 {
            out.push(Run {
                force_parallel: true,
                ..Run::new(full, f16_, f16_, true)
            });
        }
        out.push(Run::new(full, f16_, f32_, false));
        out.push(Run::new(EncoderKind::StaticOnly, f16_, f16_, false));
    }
    out
}

/// Streaming reads of buffers the size of a basis of `values` weights in f32 and in f16, on 1
/// thread and on `cores` threads. The suite measures them before and after the inference
/// runs of a garment and keeps the faster: the floor is the best this machine did.
fn floors(values: usize, cores: usize) -> Vec<MemoryBandwidth> {
    let thread_counts: &[usize] = if cores > 1 { &[1, cores] } else { &[1] };
    [values * 4, values * 2]
        .iter()
        .flat_map(|&bytes| {
            thread_counts
                .iter()
                .map(move |&threads| measure_bandwidth(bytes, threads, 5))
        })
        .collect()
}

/// Runs the suite; `log` receives a line per finished measurement.
pub fn run_suite(options: &BenchOptions, log: &mut dyn FnMut(&str)) -> Result<BenchReport, String> {
    let started = Instant::now();
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let avatar = bench_avatar()?;
    let input_joints = crate::model::descriptors::select_input_joints(
        &avatar.skeleton.names,
        &DescriptorConfig::default().exclude_patterns,
    )
    .len();
    let mut inference = Vec::new();
    let mut precision = Vec::new();
    let mut bandwidth = Vec::new();
    for (index, &dof) in options.dofs.iter().enumerate() {
        let garment = scene_with_dof(&avatar, dof)?;
        let weights = random_weights_of(
            EncoderKind::Disentangled,
            input_joints,
            garment.vertex_count(),
        )?;
        let basis_values = weights.basis.weight.len();
        let before = floors(basis_values, cores);
        for run in runs(index, cores) {
            let w = match run.kind {
                EncoderKind::Disentangled => weights.clone(),
                kind => random_weights_of(kind, input_joints, garment.vertex_count())?,
            };
            let engine_options = InferenceOptions {
                threads: if run.all_threads { cores } else { 1 },
                // The engine's own policy: small garments stay on one thread (see the report).
                parallel_min_values: if run.force_parallel {
                    0
                } else {
                    InferenceOptions::default().parallel_min_values
                },
                skin_body: true,
                basis_precision: run.basis,
                layer_precision: run.layers,
            };
            // Floor reads between frames only where the basis cannot stay in the cache anyway.
            let paired = options.dofs.iter().max() == Some(&dof) && dof >= PAIRED_FLOOR_MIN_DOF;
            let b = bench_inference(&avatar, &garment, w, engine_options, options.frames, paired)?;
            log(&format!(
                "inference {} DoF, {:?}, {}, {} thread(s): {:.3} ms/frame ({:.0} fps)",
                b.dof, b.model, b.precision, b.threads, b.ms_per_frame, b.fps
            ));
            inference.push(b);
        }
        let error_frames = (2 * options.frames).max(30);
        for layers in [Precision::F32, Precision::F16] {
            let reduced = InferenceOptions {
                basis_precision: Precision::F16,
                layer_precision: layers,
                ..InferenceOptions::default()
            };
            let e =
                measure_precision_error(&avatar, &garment, weights.clone(), reduced, error_frames)?;
            log(&format!(
                "{} error at {} DoF over {} frames: max {:.2e} m, mean {:.2e} m (offsets up to {:.2e} m)",
                e.precision,
                e.dof,
                e.frames,
                e.max_offset_error_m,
                e.mean_offset_error_m,
                e.max_offset_m
            ));
            precision.push(e);
        }
        drop(weights);
        let after = floors(basis_values, cores);
        for (b, a) in before.into_iter().zip(after) {
            let m = if a.ms_per_pass < b.ms_per_pass { a } else { b };
            log(&format!(
                "streaming read of {:.1} MB, {} thread(s): {:.3} ms ({:.1} GB/s)",
                m.bytes as f64 / 1e6,
                m.threads,
                m.ms_per_pass,
                m.gb_per_sec
            ));
            bandwidth.push(m);
        }
    }
    let mut training = Vec::new();
    for (k, &batch) in options.train_batches.iter().enumerate() {
        let all = Effects::default();
        let mut variants = vec![(all, true)];
        if k == 0 {
            // The reference path first, so the ratio fused / burn is measured in this run.
            variants.insert(0, (all, false));
            for off in [
                Effects {
                    collision: false,
                    ..all
                },
                Effects {
                    bending: false,
                    ..all
                },
                Effects {
                    dynamics: false,
                    ..all
                },
            ] {
                variants.push((off, true));
            }
        }
        for (effects, fused) in variants {
            let t = bench_training(batch, options.train_steps, effects, fused)?;
            log(&format!(
                "training step, batch {batch}, {}, {} physics: {:.1} ms, peak {:.0} MB",
                super::report::effects_label(&t.effects),
                physics_label(fused),
                t.ms_per_step,
                t.peak_bytes as f64 / 1e6
            ));
            training.push(t);
        }
    }
    let physics = if options.physics {
        let device = crate::train::device_for(crate::train::BackendKind::Cpu, false);
        let report = measure_term_costs(&device, 10_000, 16, 5).map_err(|e| e.to_string())?;
        log("physics terms measured");
        Some(report)
    } else {
        None
    };
    Ok(BenchReport {
        cores,
        simd: crate::model::kernels::simd_available(),
        inference,
        precision,
        bandwidth,
        training,
        physics,
        total_secs: started.elapsed().as_secs_f64(),
    })
}

impl BenchReport {
    /// The report as Markdown tables, with ratios against the baselines of the same run and
    /// the gap to each goal of the issue.
    pub fn to_markdown(&self) -> String {
        write_markdown(self)
    }
}
