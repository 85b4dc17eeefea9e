//! The full benchmark suite and its Markdown table.

use std::time::Instant;

use serde::Serialize;

use crate::model::{ClothNetConfig, DescriptorConfig};
use crate::physics::cost::{CostReport, measure_term_costs};
use crate::scene::config::SceneConfig;
use crate::scene::procedural::build_builtin;
use crate::train::handle::Session;
use crate::train::{RunLocation, TrainConfig, TrainSetup, prepare};

use super::{InferenceBench, MemoryBandwidth, bench_avatar, bench_inference, measure_bandwidth, peak_rss_bytes, random_weights, reset_peak_rss, scene_with_dof};

/// Training step time at one batch size.
#[derive(Clone, Debug, Serialize)]
pub struct TrainBench {
    /// Windows per batch.
    pub batch: usize,
    /// Window length in seconds.
    pub window_secs: f32,
    /// Training frame rate.
    pub fps: f32,
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
    /// Inference at each size and thread count.
    pub inference: Vec<InferenceBench>,
    /// Streaming read of a buffer the size of the 250K basis, 1 thread and all threads.
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
    /// Frames timed per inference run.
    pub frames: usize,
    /// Batch sizes of the training benchmark (empty: skip).
    pub train_batches: Vec<usize>,
    /// Steps timed per batch size.
    pub train_steps: usize,
    /// Measure the physics terms.
    pub physics: bool,
}

impl Default for BenchOptions {
    fn default() -> Self {
        Self { dofs: vec![10_000, 250_000], frames: 60, train_batches: vec![16, 32], train_steps: 10, physics: true }
    }
}

/// Median optimiser-step time of the default scene at `batch`.
pub fn bench_training(batch: usize, steps: usize) -> Result<TrainBench, String> {
    let config = SceneConfig::default_scene();
    let scene = build_builtin(&config).map_err(|e| e.to_string())?;
    let dir = std::env::temp_dir().join(format!("neural-cloth-bench-{}-{batch}", std::process::id()));
    let train = TrainConfig { batch_size: batch, window_secs: 0.5, fps: 30.0, ..Default::default() };
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
        session.step()?;
        if k >= 2 {
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    let peak_bytes = peak_rss_bytes();
    let _ = std::fs::remove_dir_all(&dir);
    times.sort_by(f64::total_cmp);
    Ok(TrainBench { batch, window_secs: train.window_secs, fps: train.fps, ms_per_step: times[times.len() / 2], peak_bytes })
}

/// Runs the suite; `log` receives a line per finished measurement.
pub fn run_suite(options: &BenchOptions, log: &mut dyn FnMut(&str)) -> Result<BenchReport, String> {
    let started = Instant::now();
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    let avatar = bench_avatar()?;
    let input_joints = crate::model::descriptors::select_input_joints(&avatar.skeleton.names, &DescriptorConfig::default().exclude_patterns).len();
    let mut inference = Vec::new();
    let mut bandwidth = Vec::new();
    for &dof in &options.dofs {
        let garment = scene_with_dof(&avatar, dof)?;
        let weights = random_weights(input_joints, garment.vertex_count())?;
        let mut thread_counts = vec![1];
        if cores > 1 {
            thread_counts.push(cores);
        }
        for &threads in &thread_counts {
            let b = bench_inference(&avatar, &garment, &weights, threads, options.frames)?;
            log(&format!("inference {} DoF, {threads} thread(s): {:.3} ms/frame ({:.0} fps)", b.dof, b.ms_per_frame, b.fps));
            inference.push(b);
        }
        if dof == *options.dofs.iter().max().unwrap_or(&dof) {
            for &threads in &thread_counts {
                let m = measure_bandwidth(weights.basis.weight.len() * 4, threads, 5);
                log(&format!("streaming read of {} MB, {threads} thread(s): {:.2} ms ({:.1} GB/s)", m.bytes / (1 << 20), m.ms_per_pass, m.gb_per_sec));
                bandwidth.push(m);
            }
        }
    }
    let mut training = Vec::new();
    for &batch in &options.train_batches {
        let t = bench_training(batch, options.train_steps)?;
        log(&format!("training step, batch {batch}: {:.1} ms, peak {:.0} MB", t.ms_per_step, t.peak_bytes as f64 / 1e6));
        training.push(t);
    }
    let physics = if options.physics {
        let device = crate::train::device_for(crate::train::BackendKind::Cpu, false);
        let report = measure_term_costs(&device, 10_000, 16, 5).map_err(|e| e.to_string())?;
        log("physics terms measured");
        Some(report)
    } else {
        None
    };
    Ok(BenchReport { cores, inference, bandwidth, training, physics, total_secs: started.elapsed().as_secs_f64() })
}

impl BenchReport {
    /// The report as Markdown tables, with ratios against the baselines of the same run.
    pub fn to_markdown(&self) -> String {
        use std::fmt::Write as _;
        let mut s = String::new();
        let _ = writeln!(s, "### Inference: raw pose → garment and body meshes\n");
        let _ = writeln!(s, "| DoF | threads | ms / frame | fps | fps, still body | weights MB | engine peak MB | frame / bandwidth floor |");
        let _ = writeln!(s, "|---:|---:|---:|---:|---:|---:|---:|---:|");
        for b in &self.inference {
            let floor = self.bandwidth.iter().find(|m| m.threads == b.threads && m.bytes <= b.weight_bytes + (1 << 20) && b.weight_bytes <= m.bytes + (64 << 20));
            let ratio = floor.map(|m| format!("{:.2}×", b.ms_per_frame / m.ms_per_pass)).unwrap_or_else(|| "—".into());
            let _ = writeln!(
                s,
                "| {} | {} | {:.3} | {:.0} | {:.0} | {:.1} | {:.1} | {} |",
                b.dof,
                b.threads,
                b.ms_per_frame,
                b.fps,
                b.still_fps,
                b.weight_bytes as f64 / 1e6,
                b.engine_peak_bytes as f64 / 1e6,
                ratio
            );
        }
        if !self.bandwidth.is_empty() {
            let _ = writeln!(s, "\n### Memory-bandwidth floor (streaming read of a buffer the size of the largest basis)\n");
            let _ = writeln!(s, "| MB | threads | ms / pass | GB/s |");
            let _ = writeln!(s, "|---:|---:|---:|---:|");
            for m in &self.bandwidth {
                let _ = writeln!(s, "| {:.0} | {} | {:.2} | {:.1} |", m.bytes as f64 / 1e6, m.threads, m.ms_per_pass, m.gb_per_sec);
            }
        }
        if !self.training.is_empty() {
            let _ = writeln!(s, "\n### Training step (default scene, flex CPU backend)\n");
            let _ = writeln!(s, "| batch | window s | fps | ms / step | steps / s | peak MB |");
            let _ = writeln!(s, "|---:|---:|---:|---:|---:|---:|");
            for t in &self.training {
                let _ = writeln!(s, "| {} | {} | {} | {:.1} | {:.2} | {:.0} |", t.batch, t.window_secs, t.fps, t.ms_per_step, 1e3 / t.ms_per_step, t.peak_bytes as f64 / 1e6);
            }
        }
        if let Some(p) = &self.physics {
            let _ = writeln!(s, "\n### Physics terms at 10K DoF (forward + backward)\n");
            s.push_str(&p.to_markdown());
        }
        let _ = writeln!(s, "\n{} cores; the suite took {:.0} s.", self.cores, self.total_secs);
        s
    }
}
