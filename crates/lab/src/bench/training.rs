//! The training-step benchmark and its floor (issue 12).
//!
//! * [`bench_training`]: median step time of the default scene at one batch size, with the
//!   fused or the burn reference physics and the fused or burn's Adam, so that every path is
//!   timed in the same run as the others.
//! * [`step_flops`]: the floating-point work of a step, counted from the network's own layer
//!   shapes: the static encoder on the predicted frames, the dynamic encoder and the GRU unroll
//!   on every frame of the window, the decoder, the basis products and the skinning, each
//!   forward and (about twice that) backward. The physics is not counted: it is a few MFLOP.
//! * [`measure_matmul_rates`]: the machine's single-precision matrix-product rate with burn's
//!   own kernels (the flex backend on all threads) on the shapes of the step, measured in the
//!   same run; the floor of a step is its FLOPs over the best of these rates.

use std::time::Instant;

use burn::nn::Linear;
use burn::tensor::{Device, Distribution, Tensor};
use serde::Serialize;

use neural_cloth_core::scene::config::{Effects, SceneConfig};
use neural_cloth_core::scene::procedural::build_builtin;
use neural_cloth_model::{ClothNet, ClothNetConfig, DescriptorConfig};
use neural_cloth_train::handle::Session;
use neural_cloth_train::{RunLocation, TrainConfig, TrainSetup, prepare};

use super::{peak_rss_bytes, reset_peak_rss};

/// Frames of each window whose garment is predicted (`x_{t-2}, x_{t-1}, x_t`).
const PREDICTED_FRAMES: usize = 3;
/// Steps run before timing starts (the first ones allocate the optimiser state).
const WARM_UP_STEPS: usize = 2;
/// Training frame rate of the benchmarked scene, frames per second.
const BENCH_FPS: f32 = 30.0;
/// Window of the issue's reference scene, seconds (issue 12 states its goals at 0.5 s).
const ISSUE_WINDOW_SECS: f32 = 0.5;
/// Seconds each matrix-product shape is timed at least.
const MATMUL_SECS: f64 = 0.3;

/// What one training benchmark runs.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TrainCase {
    /// Windows per batch.
    pub batch: usize,
    /// Effects of the scene (the default scene has all but pinning).
    pub effects: Effects,
    /// Physics as fused kernels (the default) or as burn tensor code (the reference path).
    pub fused_physics: bool,
    /// The fused Adam (the default) or burn's.
    pub fused_adam: bool,
    /// Training window, seconds: 0.5 (the issue's reference scene, the default before round 12
    /// of issue 11) or 1 (today's default, [`TrainConfig::window_secs`]).
    pub window_secs: f32,
    /// Still windows skip the dynamic encoder ([`TrainConfig::skip_still_dynamics`], the
    /// default) or go through it (the path before).
    pub skip_still: bool,
    /// The batch in two halves on two threads ([`TrainConfig::split_batch`], the default) or
    /// whole (the path before).
    pub split_batch: bool,
}

impl TrainCase {
    /// The default path (fused physics and Adam) at `batch` with every effect of the default
    /// scene (all but pinning, friction included).
    pub fn default_at(batch: usize) -> Self {
        Self {
            batch,
            effects: SceneConfig::default_scene().effects,
            fused_physics: true,
            fused_adam: true,
            window_secs: ISSUE_WINDOW_SECS,
            skip_still: true,
            split_batch: true,
        }
    }

    /// The path before issue 12: burn's physics and burn's Adam.
    pub fn reference_at(batch: usize) -> Self {
        Self {
            fused_physics: false,
            fused_adam: false,
            split_batch: false,
            ..Self::default_at(batch)
        }
    }

    /// Name of the path in logs and tables.
    pub fn path_label(&self) -> &'static str {
        match (self.fused_physics, self.fused_adam, self.skip_still) {
            (true, true, true) if self.split_batch => "fused physics, fused Adam, batch in halves",
            (true, true, true) => "fused physics, fused Adam",
            (true, true, false) => "fused physics, fused Adam, still windows through the GRU",
            (true, false, _) => "fused physics, burn Adam",
            (false, true, _) => "burn physics, fused Adam",
            (false, false, _) => "burn (reference)",
        }
    }
}

/// Step time of one [`TrainCase`].
#[derive(Clone, Debug, Serialize)]
pub struct TrainBench {
    /// What ran.
    pub case: TrainCase,
    /// Window length in seconds.
    pub window_secs: f32,
    /// Training frame rate.
    pub fps: f32,
    /// Median milliseconds per optimiser step.
    pub ms_per_step: f64,
    /// Peak resident memory of the process during the steps, bytes.
    pub peak_bytes: usize,
    /// Floating-point work of one step.
    pub flops: StepFlops,
    /// Garment vertices of the scene.
    pub vertices: usize,
    /// Input joints of the network.
    pub input_joints: usize,
}

/// Floating-point operations of one training step, by part (forward and backward together;
/// backward counted as twice the forward: the gradients of the inputs and of the weights).
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct StepFlops {
    /// Static encoder and the dynamic encoder's layers before the GRU.
    pub encoders: f64,
    /// The GRU unroll over the window.
    pub gru: f64,
    /// The decoder's hidden layers.
    pub decoder: f64,
    /// The basis and dynamic-basis products.
    pub basis: f64,
    /// Adding the template and skinning the predicted frames.
    pub skinning: f64,
}

impl StepFlops {
    /// All parts.
    pub fn total(&self) -> f64 {
        self.encoders + self.gru + self.decoder + self.basis + self.skinning
    }
}

/// The rate of burn's matrix product on one shape.
#[derive(Clone, Debug, Serialize)]
pub struct MatmulRate {
    /// What the shape is in the step.
    pub what: String,
    /// The part of the step whose floor this rate sets.
    pub part: Part,
    /// `[m, k] × [k, n]`.
    pub m: usize,
    /// Inner dimension.
    pub k: usize,
    /// Columns of the result.
    pub n: usize,
    /// Median milliseconds per product.
    pub ms: f64,
    /// Billions of floating-point operations per second (`2mkn / time`).
    pub gflops: f64,
}

/// The parts of a step whose matrix products share a shape class.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Part {
    /// The basis products (`B·K` rows against `V·3` columns).
    Basis,
    /// The layers on every frame or the predicted frames (encoders, decoder; skinning too).
    Layers,
    /// The GRU's per-frame products (`B` rows).
    Gru,
}

/// Forward + backward FLOPs of a linear layer applied to `rows` rows.
fn linear_flops(layer: &Linear, rows: usize) -> f64 {
    let [d_in, d_out] = layer.weight.dims();
    3.0 * 2.0 * (rows * d_in * d_out) as f64
}

fn layers_flops(layers: &[Linear], rows: usize) -> f64 {
    layers.iter().map(|l| linear_flops(l, rows)).sum()
}

/// The work of one step of `model` on `batch` windows of `frames` frames, the last
/// `predicted` of which are decoded and skinned.
///
/// `skipped` windows of the batch skip the recurrent encoder (still windows,
/// [`TrainConfig::skip_still_dynamics`]).
pub fn step_flops(
    model: &ClothNet,
    batch: usize,
    skipped: usize,
    frames: usize,
    predicted: usize,
) -> StepFlops {
    let predicted_rows = batch * predicted;
    // Rows of the recurrent encoder: every window but those that skip it (still windows).
    let window_rows = batch.saturating_sub(skipped) * frames;
    let mut f = StepFlops::default();
    if let Some(s) = &model.static_encoder {
        f.encoders += layers_flops(&s.layers, predicted_rows);
    }
    for enc in [&model.dynamic_encoder, &model.entangled_encoder]
        .into_iter()
        .flatten()
    {
        f.encoders += layers_flops(&enc.joint_mlp.layers, window_rows * model.input_joints);
        f.encoders += layers_flops(&enc.mlp.layers, window_rows);
        for gate in [&enc.gru.update_gate, &enc.gru.reset_gate, &enc.gru.new_gate] {
            f.gru += linear_flops(&gate.input_transform, window_rows);
            f.gru += linear_flops(&gate.hidden_transform, window_rows);
        }
    }
    f.decoder = layers_flops(&model.decoder.mlp.layers, predicted_rows);
    f.basis = linear_flops(&model.decoder.basis, predicted_rows);
    if let Some(b) = &model.decoder.dynamic_basis {
        f.basis += linear_flops(b, predicted_rows);
    }
    // Template add (3), rotation (9 products, 6 sums) and translation (3) per vertex.
    f.skinning = 3.0 * 21.0 * (predicted_rows * model.vertices) as f64;
    f
}

/// A training session of one [`TrainCase`], ready to step.
struct Prepared {
    case: TrainCase,
    session: neural_cloth_train::session::NeuralSession,
    train: TrainConfig,
    /// Training frame rate of the scene, frames per second.
    fps: f32,
    dir: std::path::PathBuf,
}

impl Prepared {
    /// The default scene (30 fps) with `case`'s effects, batch, window and paths; a run folder
    /// of its own (`tag`) in the temporary directory.
    fn new(case: TrainCase, predrape_secs: Option<f32>, tag: usize) -> Result<Self, String> {
        let mut config = SceneConfig::default_scene();
        config.effects = case.effects;
        config.training_fps = BENCH_FPS;
        let scene = build_builtin(&config).map_err(|e| e.to_string())?;
        let dir = std::env::temp_dir().join(format!(
            "neural-cloth-bench-{}-{}-{tag}",
            std::process::id(),
            case.batch
        ));
        let defaults = TrainConfig::default();
        let train = TrainConfig {
            batch_size: case.batch,
            window_secs: case.window_secs,
            fused_physics: case.fused_physics,
            fused_adam: case.fused_adam,
            skip_still_dynamics: case.skip_still,
            split_batch: case.split_batch,
            predrape_secs: predrape_secs.unwrap_or(defaults.predrape_secs),
            ..defaults
        };
        let setup = TrainSetup {
            scene,
            scene_config: config,
            train: train.clone(),
            model: ClothNetConfig::default(),
            descriptors: DescriptorConfig::default(),
            location: RunLocation::At(dir.clone()),
        };
        let (session, _) = prepare(setup).map_err(|e| e.to_string())?;
        Ok(Self {
            case,
            session,
            train,
            fps: BENCH_FPS,
            dir,
        })
    }

    fn step(&mut self) -> Result<f64, String> {
        let start = Instant::now();
        self.session.step().map_err(|e| e.to_string())?;
        Ok(start.elapsed().as_secs_f64())
    }
}

impl Drop for Prepared {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Peak resident memory of a few steps of `case` alone in the process (its own session, the
/// buffers of earlier runs returned first; no drape: it does not change a step's memory).
fn peak_of(case: TrainCase) -> Result<usize, String> {
    let mut run = Prepared::new(case, Some(0.0), usize::MAX)?;
    neural_cloth_train::alloc::release_freed_buffers();
    reset_peak_rss();
    for _ in 0..WARM_UP_STEPS {
        run.step()?;
    }
    Ok(peak_rss_bytes())
}

/// Median step times of `cases` on the default scene over `steps` steps each, stepped round
/// robin (one step of each case in turn) so that changes of machine load affect them alike.
/// `predrape_secs` is the warm start's drape (the default 1.5 s in the full suite; 0 skips the
/// simulator when only the step matters, e.g. to profile it: the drape sets the basis bias,
/// not the work of a step). The peak memory of each case is measured afterwards, alone.
pub fn bench_cases(
    cases: &[TrainCase],
    steps: usize,
    predrape_secs: Option<f32>,
) -> Result<Vec<TrainBench>, String> {
    let mut runs = cases
        .iter()
        .enumerate()
        .map(|(k, &case)| Prepared::new(case, predrape_secs, k))
        .collect::<Result<Vec<_>, _>>()?;
    for run in &mut runs {
        for _ in 0..WARM_UP_STEPS {
            run.step()?;
        }
    }
    let mut times = vec![Vec::new(); runs.len()];
    for _ in 0..steps.max(1) {
        for (run, t) in runs.iter_mut().zip(&mut times) {
            t.push(run.step()?);
        }
    }
    let mut out = Vec::with_capacity(runs.len());
    for (run, mut t) in runs.into_iter().zip(times) {
        let model = run.session.model();
        let (vertices, input_joints) = (model.vertices, model.input_joints);
        let still = if run.case.skip_still {
            run.train
                .still_windows(run.case.batch, run.case.effects.dynamics)
        } else {
            0
        };
        let flops = step_flops(
            model,
            run.case.batch,
            still,
            run.train.window_frames(run.fps),
            PREDICTED_FRAMES,
        );
        out.push(TrainBench {
            case: run.case,
            window_secs: run.train.window_secs,
            fps: run.fps,
            ms_per_step: super::median_ms(&mut t),
            peak_bytes: 0,
            flops,
            vertices,
            input_joints,
        });
    }
    for b in &mut out {
        b.peak_bytes = peak_of(b.case)?;
    }
    Ok(out)
}

/// [`bench_cases`] of one case.
pub fn bench_training(
    case: TrainCase,
    steps: usize,
    predrape_secs: Option<f32>,
) -> Result<TrainBench, String> {
    bench_cases(&[case], steps, predrape_secs)?
        .pop()
        .ok_or_else(|| "no training benchmark ran".to_string())
}

/// Median milliseconds of burn's `[m, k] × [k, n]` product on `device` ([`super::median_ms`]
/// takes seconds).
fn time_matmul(device: &Device, m: usize, k: usize, n: usize) -> f64 {
    let a = Tensor::<2>::random([m, k], Distribution::Default, device);
    let b = Tensor::<2>::random([k, n], Distribution::Default, device);
    let mut times = Vec::new();
    let started = Instant::now();
    while times.len() < 3 || (started.elapsed().as_secs_f64() < MATMUL_SECS && times.len() < 500) {
        let t = Instant::now();
        let c = a.clone().matmul(b.clone());
        // Reading one value waits for the product (and keeps it from being optimised away).
        let _ = c.slice([0..1, 0..1]).into_scalar::<f32>();
        times.push(t.elapsed().as_secs_f64());
    }
    super::median_ms(&mut times)
}

/// burn's matrix-product rate on the CPU backend (all threads) for the largest shapes of a
/// default step at `batch`: the basis product and its weight gradient, the layers on every
/// frame, the GRU's step; `vertices` garment vertices, `joints` input joints.
pub fn measure_matmul_rates(batch: usize, vertices: usize, joints: usize) -> Vec<MatmulRate> {
    let device = neural_cloth_train::device_for(neural_cloth_train::BackendKind::Cpu, false);
    let frames = TrainConfig::default().window_frames(BENCH_FPS);
    let (rows, window_rows) = (batch * PREDICTED_FRAMES, batch * frames);
    let latent = ClothNetConfig::default().latent;
    let dof = 3 * vertices;
    let shapes = [
        ("basis product", Part::Basis, rows, latent, dof),
        ("basis weight gradient", Part::Basis, latent, rows, dof),
        (
            "joint features → 512, every frame",
            Part::Layers,
            window_rows,
            32 * joints,
            512,
        ),
        (
            "512 → 512, every frame",
            Part::Layers,
            window_rows,
            latent,
            latent,
        ),
        (
            "GRU step, three gates",
            Part::Gru,
            batch,
            latent,
            3 * latent,
        ),
    ];
    shapes
        .iter()
        .map(|&(what, part, m, k, n)| {
            let ms = time_matmul(&device, m, k, n);
            MatmulRate {
                what: what.to_string(),
                part,
                m,
                k,
                n,
                ms,
                gflops: 2.0 * (m * k * n) as f64 / (ms * 1e6),
            }
        })
        .collect()
}

/// The mean rate of the shapes of `part` in `rates`, FLOP per second.
fn part_rate(rates: &[MatmulRate], part: Part) -> Option<f64> {
    let of: Vec<f64> = rates
        .iter()
        .filter(|r| r.part == part && r.gflops.is_finite() && r.gflops > 0.0)
        .map(|r| r.gflops * 1e9)
        .collect();
    (!of.is_empty()).then(|| of.iter().sum::<f64>() / of.len() as f64)
}

/// The floor of a step doing `flops` in seconds: each part's FLOPs over the rate of burn's
/// matrix product on that part's shapes (`rates`, measured in the same run).
pub fn floor_secs(flops: &StepFlops, rates: &[MatmulRate]) -> Option<f64> {
    let basis = part_rate(rates, Part::Basis)?;
    let layers = part_rate(rates, Part::Layers)?;
    let gru = part_rate(rates, Part::Gru)?;
    Some(
        flops.basis / basis
            + flops.gru / gru
            + (flops.encoders + flops.decoder + flops.skinning) / layers,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_step_work_follows_the_layer_shapes() {
        let device = Device::flex();
        let config = ClothNetConfig::default();
        let model = config.init(4, 10, &device).unwrap();
        let (b, t, k) = (2, 5, 3);
        let f = step_flops(&model, b, 0, t, k);
        // Skipped (still) windows leave the recurrent encoder only.
        let g = step_flops(&model, b, 1, t, k);
        assert_eq!(2.0 * g.gru, f.gru);
        assert_eq!(g.basis, f.basis);
        // Basis and dynamic basis: 3 × 2 × (B·K) × 512 × 30 each.
        assert_eq!(f.basis, 2.0 * 3.0 * 2.0 * (b * k * 512 * 30) as f64);
        // Three gates, input and hidden transforms 512 → 512, on every frame.
        assert_eq!(f.gru, 6.0 * 3.0 * 2.0 * (b * t * 512 * 512) as f64);
        assert_eq!(f.skinning, 3.0 * 21.0 * (b * k * 10) as f64);
        assert!(f.encoders > 0.0 && f.decoder > 0.0);
        assert_eq!(
            f.total(),
            f.encoders + f.gru + f.decoder + f.basis + f.skinning
        );
    }

    #[test]
    fn the_floor_divides_each_part_by_its_own_rate() {
        let rate = |part, gflops| MatmulRate {
            what: String::new(),
            part,
            m: 1,
            k: 1,
            n: 1,
            ms: 1.0,
            gflops,
        };
        let flops = StepFlops {
            encoders: 1e9,
            gru: 2e9,
            decoder: 1e9,
            basis: 4e9,
            skinning: 0.0,
        };
        let rates = [
            rate(Part::Basis, 30.0),
            rate(Part::Basis, 50.0),
            rate(Part::Layers, 100.0),
            rate(Part::Gru, 50.0),
        ];
        let floor = floor_secs(&flops, &rates).unwrap();
        assert!((floor - (4.0 / 40.0 + 2.0 / 50.0 + 2.0 / 100.0)).abs() < 1e-12);
        assert!(floor_secs(&flops, &rates[..2]).is_none());
    }

    #[test]
    fn the_reference_case_is_the_old_path() {
        let r = TrainCase::reference_at(16);
        assert!(!r.fused_physics && !r.fused_adam);
        assert_eq!(r.path_label(), "burn (reference)");
        assert!(TrainCase::default_at(32).fused_adam);
    }
}
