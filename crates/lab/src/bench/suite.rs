//! The full benchmark suite and its Markdown report.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use crate::bench::cost::{CostReport, measure_term_costs};
use neural_cloth_core::scene::config::Effects;
use neural_cloth_model::{DescriptorConfig, EncoderKind, InferenceOptions, Precision};
use neural_cloth_train::TrainConfig;

use super::report::write_markdown;
use super::training::{MatmulRate, TrainBench, TrainCase, bench_cases, measure_matmul_rates};
use super::{
    InferenceBench, MemoryBandwidth, PrecisionError, bench_avatar, bench_inference,
    measure_bandwidth, measure_precision_error, random_weights_of, scene_with_dof,
};

/// Garments from this many degrees of freedom on (a basis of ≥ 200 MB in f32) get a floor
/// read after every timed frame; smaller ones would have their weights evicted from the cache
/// by it.
const PAIRED_FLOOR_MIN_DOF: usize = 100_000;

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
    /// burn's matrix-product rates on the shapes of the step, per batch size (the floor).
    pub matmul: Vec<TrainFloor>,
    /// Inference on trained weights (`bench --weights RUN`): the run and its step, and the
    /// engine on the run's garment, f32 and f16, one thread.
    pub trained: Option<(String, Vec<InferenceBench>)>,
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
    /// Time the burn reference path and the effect variants beside the default configuration
    /// and burn's Adam (false: those two only, e.g. to profile them).
    pub train_variants: bool,
    /// Seconds of the warm start's drape before the timed steps (`None`: the training
    /// default; `Some(0.0)` skips the simulator, whose drape does not change a step's work).
    pub predrape_secs: Option<f32>,
    /// A trained run whose newest checkpoint is timed too (the share of basis rows read
    /// depends on the weights: random ones read about half).
    pub trained: Option<PathBuf>,
}

/// burn's matrix-product rates at one batch size.
#[derive(Clone, Debug, Serialize)]
pub struct TrainFloor {
    /// Windows per batch.
    pub batch: usize,
    /// The rate on each of the step's largest shapes.
    pub rates: Vec<MatmulRate>,
}

impl BenchOptions {
    /// The same training batches and steps, nothing else measured, only the default
    /// configuration and burn's Adam (`bench --train-only`, for profiling a step).
    pub fn train_only(self) -> Self {
        Self {
            dofs: Vec::new(),
            frames: 0,
            physics: false,
            train_variants: false,
            predrape_secs: Some(0.0),
            trained: None,
            ..self
        }
    }
}

impl Default for BenchOptions {
    fn default() -> Self {
        Self {
            dofs: vec![10_000, 250_000],
            frames: 60,
            train_batches: vec![16, 32],
            train_steps: 10,
            physics: true,
            train_variants: true,
            predrape_secs: None,
            trained: None,
        }
    }
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
    let input_joints = neural_cloth_model::descriptors::select_input_joints(
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
    let trained = match &options.trained {
        Some(run) => Some(bench_trained(run, options.frames, log)?),
        None => None,
    };
    let (training, matmul) = run_training(options, log)?;
    let physics = if options.physics {
        let device = neural_cloth_train::device_for(neural_cloth_train::BackendKind::Cpu, false);
        let report = measure_term_costs(&device, 10_000, 16, 5).map_err(|e| e.to_string())?;
        log("physics terms measured");
        Some(report)
    } else {
        None
    };
    Ok(BenchReport {
        cores,
        simd: neural_cloth_model::kernels::simd_available(),
        inference,
        precision,
        bandwidth,
        training,
        matmul,
        trained,
        physics,
        total_secs: started.elapsed().as_secs_f64(),
    })
}

/// The inference engine on the newest checkpoint of `run` (its own garment, avatar and first
/// motion), exact f32 and the default f16, one thread.
fn bench_trained(
    run: &Path,
    frames: usize,
    log: &mut dyn FnMut(&str),
) -> Result<(String, Vec<InferenceBench>), String> {
    let trained = neural_cloth_train::load_trained(run).map_err(|e| e.to_string())?;
    let Some((motion, _)) = trained.scene.motions.first() else {
        return Err(format!("{}: the run's scene has no motion", run.display()));
    };
    let mut out = Vec::new();
    for precision in [Precision::F32, Precision::F16] {
        let engine_options = InferenceOptions {
            threads: 1,
            basis_precision: precision,
            layer_precision: precision,
            ..InferenceOptions::default()
        };
        let b = super::bench_artifact(
            &trained.scene.avatar,
            &trained.scene.garment,
            motion,
            trained.artifact.clone(),
            engine_options,
            frames,
            false,
        )?;
        log(&format!(
            "inference on trained weights, {} DoF, {}: {:.3} ms/frame, {:.0}% of the basis rows read",
            b.dof,
            b.precision,
            b.ms_per_frame,
            100.0 * b.basis_rows_read
        ));
        out.push(b);
    }
    Ok((format!("{} (step {})", run.display(), trained.step), out))
}

/// The cases timed at the `k`-th batch size: burn's Adam with the fused physics (the step
/// before the fused Adam) and the default path; with variants, at the first size also the
/// reference path (burn physics and Adam) and each effect off.
fn training_cases(k: usize, batch: usize, variants: bool) -> Vec<TrainCase> {
    let default = TrainCase::default_at(batch);
    let burn_adam = TrainCase {
        fused_adam: false,
        split_batch: false,
        ..default
    };
    // Today's 1 s window (issue 11, round 12), beside the 0.5 s reference.
    let default_window = TrainCase {
        window_secs: TrainConfig::default().window_secs,
        ..default
    };
    // The same with the still windows through the recurrent encoder (the path before).
    let still_through = TrainCase {
        skip_still: false,
        split_batch: false,
        ..default_window
    };
    // The same with the batch whole, on one thread (the path before).
    let whole = TrainCase {
        split_batch: false,
        ..default_window
    };
    if !variants || k > 0 {
        return vec![burn_adam, default, default_window, whole, still_through];
    }
    let all = default.effects;
    let mut cases = vec![
        TrainCase::reference_at(batch),
        burn_adam,
        default,
        default_window,
        whole,
        still_through,
    ];
    // Friction acts at contacts between frames: off with collision or dynamics.
    for effects in [
        Effects {
            collision: false,
            friction: false,
            ..all
        },
        Effects {
            bending: false,
            ..all
        },
        Effects {
            dynamics: false,
            friction: false,
            ..all
        },
        Effects {
            friction: false,
            ..all
        },
    ] {
        cases.push(TrainCase { effects, ..default });
    }
    cases
}

/// The training benchmarks of `options` and the matrix-product rates of each batch size.
fn run_training(
    options: &BenchOptions,
    log: &mut dyn FnMut(&str),
) -> Result<(Vec<TrainBench>, Vec<TrainFloor>), String> {
    let mut training = Vec::new();
    let mut matmul = Vec::new();
    for (k, &batch) in options.train_batches.iter().enumerate() {
        let cases = training_cases(k, batch, options.train_variants);
        for t in bench_cases(&cases, options.train_steps, options.predrape_secs)? {
            log(&format!(
                "training step, batch {batch}, {}, {}: {:.1} ms, peak {:.0} MB",
                super::report::effects_label(&t.case.effects),
                t.case.path_label(),
                t.ms_per_step,
                t.peak_bytes as f64 / 1e6
            ));
            training.push(t);
        }
        if let Some(t) = training.last() {
            let rates = measure_matmul_rates(batch, t.vertices, t.input_joints);
            for r in &rates {
                log(&format!(
                    "matmul {} [{}, {}] × [{}, {}]: {:.2} ms, {:.1} GFLOP/s",
                    r.what, r.m, r.k, r.k, r.n, r.ms, r.gflops
                ));
            }
            matmul.push(TrainFloor { batch, rates });
        }
    }
    Ok((training, matmul))
}

impl BenchReport {
    /// The report as Markdown tables, with ratios against the baselines of the same run and
    /// the gap to each goal of the issue.
    pub fn to_markdown(&self) -> String {
        write_markdown(self)
    }
}
