//! `neural-cloth soak --minutes N`: what the app does, headless, for a long time. Training
//! runs on its background thread as `train` starts it; the main thread meanwhile plays the
//! scene's motions through an inference engine at 30 fps, swapping in each snapshot of the
//! weights as the app's preview does, and bakes a short PC2 with the current weights every
//! minute. Resident memory, open file descriptors and threads are sampled at the start and
//! every minute into a CSV; the summary judges growth after a warm-up of 10 minutes.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Context;

use neural_cloth::bake::{BakeFormat, BakeOptions, ModelSource, bake};
use neural_cloth::model::{
    ClothNetConfig, DescriptorConfig, InferenceEngine, InferenceOptions, ModelArtifact,
};
use neural_cloth::scene::Scene;
use neural_cloth::train::{RunLocation, TrainConfig, TrainEvent, TrainSetup, Trainer};

/// Minutes of warm-up before which memory is allowed to grow.
const WARMUP_MINUTES: f64 = 10.0;
/// Goal: resident memory grows by less than this after the warm-up, percent.
const RSS_GOAL_PCT: f64 = 5.0;
/// Preview frame period (the app's playback at 30 fps).
const FRAME: Duration = Duration::from_millis(33);
/// Sample and bake period.
const PERIOD: Duration = Duration::from_secs(60);
/// Output frames of each periodic bake.
const BAKE_FRAMES: usize = 60;

/// Arguments of `soak`.
#[derive(clap::Args, Debug)]
pub struct SoakArgs {
    /// Train (and soak) for this many minutes.
    #[arg(long)]
    pub minutes: f64,
    /// Scene file (TOML); default: the built-in scene.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Folder of the run folder (under `runs/`) and of the periodic bake.
    #[arg(long, default_value = "soak")]
    pub out: PathBuf,
    /// CSV file the samples are appended to (default: DIR/soak.csv).
    #[arg(long)]
    pub csv: Option<PathBuf>,
}

/// One sample of the process's resources.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Minutes since the start.
    pub elapsed_min: f64,
    /// Resident memory, MiB.
    pub rss_mb: f64,
    /// Open file descriptors.
    pub fds: usize,
    /// Threads of the process.
    pub threads: usize,
    /// Latest training step seen.
    pub train_step: u64,
    /// Bakes written so far.
    pub bakes: u64,
    /// Preview frames stepped so far.
    pub preview_frames: u64,
}

impl Sample {
    const HEADER: &'static str = "elapsed_min,rss_mb,fds,threads,train_step,bakes,preview_frames";

    fn csv_line(&self) -> String {
        format!(
            "{:.2},{:.1},{},{},{},{},{}",
            self.elapsed_min,
            self.rss_mb,
            self.fds,
            self.threads,
            self.train_step,
            self.bakes,
            self.preview_frames
        )
    }
}

/// What a soak's samples say.
#[derive(Clone, Debug, PartialEq)]
pub struct Verdict {
    /// Resident memory at the end of the warm-up (the first sample at or after it; the first
    /// sample when the run was shorter), MiB.
    pub rss_warm_mb: f64,
    /// Minute of that sample.
    pub warm_min: f64,
    /// Resident memory of the last sample, MiB.
    pub rss_end_mb: f64,
    /// Growth from `rss_warm_mb` to `rss_end_mb`, percent.
    pub growth_pct: f64,
    /// File descriptors, smallest and largest after the warm-up sample.
    pub fds: (usize, usize),
    /// Threads, smallest and largest after the warm-up sample.
    pub threads: (usize, usize),
    /// Resources that grew after the warm-up (a leak): empty when none did.
    pub leaks: Vec<String>,
}

impl Verdict {
    /// Whether resident memory stayed under the goal.
    pub fn rss_ok(&self) -> bool {
        self.growth_pct < RSS_GOAL_PCT
    }
}

/// Judges `samples` (in time order) after `warmup_min` minutes: memory growth from the first
/// sample at or after the warm-up to the last, and whether file descriptors or threads grew.
/// A count grew when the smallest value of the last third of the samples after the warm-up
/// is above the largest of the first third: a steady leak raises the floor, a file briefly
/// open during a checkpoint does not. None without samples.
pub fn judge(samples: &[Sample], warmup_min: f64) -> Option<Verdict> {
    let last = samples.last()?;
    let from = samples
        .iter()
        .position(|s| s.elapsed_min >= warmup_min)
        .unwrap_or(0);
    let after = &samples[from..];
    let warm = after.first()?;
    let growth_pct = if warm.rss_mb > 0.0 {
        (last.rss_mb - warm.rss_mb) / warm.rss_mb * 100.0
    } else {
        0.0
    };
    let range = |f: fn(&Sample) -> usize| {
        let min = after.iter().map(f).min().unwrap_or(0);
        let max = after.iter().map(f).max().unwrap_or(0);
        (min, max)
    };
    let third = after.len() / 3;
    let mut leaks = Vec::new();
    if third > 0 {
        let head = &after[..third];
        let tail = &after[after.len() - third..];
        let grew = |f: fn(&Sample) -> usize| {
            let head_max = head.iter().map(f).max().unwrap_or(0);
            let tail_min = tail.iter().map(f).min().unwrap_or(0);
            (tail_min > head_max).then_some((head_max, tail_min))
        };
        if let Some((a, b)) = grew(|s| s.fds) {
            leaks.push(format!("file descriptors grew from {a} to {b}"));
        }
        if let Some((a, b)) = grew(|s| s.threads) {
            leaks.push(format!("threads grew from {a} to {b}"));
        }
    }
    Some(Verdict {
        rss_warm_mb: warm.rss_mb,
        warm_min: warm.elapsed_min,
        rss_end_mb: last.rss_mb,
        growth_pct,
        fds: range(|s| s.fds),
        threads: range(|s| s.threads),
        leaks,
    })
}

/// Resident memory (MiB), open file descriptors and threads of this process, from /proc.
fn resources() -> anyhow::Result<(f64, usize, usize)> {
    let field = |name: &str| {
        neural_cloth::bench::status_field(name)
            .with_context(|| format!("no {name} in /proc/self/status"))
    };
    let rss_kb = field("VmRSS:")?;
    let threads = field("Threads:")?;
    // Counts the descriptor read_dir itself holds, the same in every sample.
    let fds = std::fs::read_dir("/proc/self/fd")
        .context("listing /proc/self/fd")?
        .count();
    Ok((rss_kb as f64 / 1024.0, fds, threads))
}

/// The main thread's side of the soak: the preview engine, its playback and the bakes.
struct Preview {
    scene: Scene,
    fps: f32,
    engine: Option<InferenceEngine>,
    weights: Option<Arc<ModelArtifact>>,
    motion: usize,
    frame: usize,
    frames: u64,
    bakes: u64,
    bake_out: PathBuf,
}

impl Preview {
    fn options() -> InferenceOptions {
        InferenceOptions {
            skin_body: false,
            ..Default::default()
        }
    }

    /// Swaps in a snapshot (building the engine on the first).
    fn set_weights(&mut self, model: Arc<ModelArtifact>) -> anyhow::Result<()> {
        match &mut self.engine {
            Some(engine) => model.swap_into(engine, &self.scene.avatar, &self.scene.garment)?,
            None => {
                self.engine =
                    Some(model.engine(&self.scene.avatar, &self.scene.garment, Self::options())?)
            }
        }
        self.weights = Some(model);
        Ok(())
    }

    /// Plays one frame of the current motion, going on to the next motion at its end.
    fn step(&mut self) -> anyhow::Result<()> {
        let Some(engine) = &mut self.engine else {
            return Ok(());
        };
        let Some((motion, _)) = self.scene.motions.get(self.motion) else {
            return Ok(());
        };
        let count = (motion.duration_secs() * self.fps).floor().max(0.0) as usize + 1;
        if self.frame >= count {
            self.frame = 0;
            self.motion = (self.motion + 1) % self.scene.motions.len().max(1);
            engine.reset();
            return Ok(());
        }
        engine.step(&motion.sample(self.frame as f32 / self.fps), 1.0)?;
        // The app hands a copy of the positions to the renderer each frame.
        std::hint::black_box(engine.garment_positions().to_vec());
        self.frame += 1;
        self.frames += 1;
        Ok(())
    }

    /// Bakes the first frames of the first motion with the current weights, over the same
    /// file each time, through a fresh engine as the app's export does.
    fn bake(&mut self) -> anyhow::Result<()> {
        let Some(weights) = &self.weights else {
            return Ok(());
        };
        let Some((motion, _)) = self.scene.motions.first() else {
            return Ok(());
        };
        let engine = weights.engine(&self.scene.avatar, &self.scene.garment, Self::options())?;
        let mut source = ModelSource::new(engine);
        let frames = (motion.duration_secs() * 30.0).floor() as usize + 1;
        let options = BakeOptions {
            format: BakeFormat::Pc2,
            out: self.bake_out.clone(),
            fps: 30.0,
            end_frame: Some(frames.min(BAKE_FRAMES)),
            ..Default::default()
        };
        bake(
            &self.scene.avatar,
            &self.scene.garment,
            motion,
            &mut source,
            &options,
            &mut |_, _| true,
        )?;
        self.bakes += 1;
        Ok(())
    }
}

/// Appends samples to the CSV and prints them.
struct Log {
    file: std::fs::File,
    samples: Vec<Sample>,
}

impl Log {
    fn open(path: &Path) -> anyhow::Result<Self> {
        let fresh = !path.exists();
        let mut file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .with_context(|| format!("opening {}", path.display()))?;
        if fresh {
            writeln!(file, "{}", Sample::HEADER)
                .with_context(|| format!("writing {}", path.display()))?;
        }
        println!("{}", Sample::HEADER);
        Ok(Self {
            file,
            samples: Vec::new(),
        })
    }

    fn record(&mut self, sample: Sample) -> anyhow::Result<()> {
        let line = sample.csv_line();
        writeln!(self.file, "{line}").context("appending to the soak CSV")?;
        self.file.flush().context("appending to the soak CSV")?;
        println!("{line}");
        self.samples.push(sample);
        Ok(())
    }
}

/// Runs `soak`.
pub fn run(args: SoakArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.minutes.is_finite() && args.minutes > 0.0,
        "--minutes must be positive, not {}",
        args.minutes
    );
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let (scene, scene_config) = super::scene_args::scene_from_args(
        &super::scene_args::SceneArgs::file(args.scene.as_deref()),
    )?;
    anyhow::ensure!(!scene.motions.is_empty(), "the scene has no motion");
    let train = TrainConfig {
        max_minutes: Some(args.minutes),
        ..Default::default()
    };
    let fps = scene.training_fps;
    let setup = TrainSetup {
        scene: scene.clone(),
        scene_config,
        train,
        model: ClothNetConfig::default(),
        descriptors: DescriptorConfig::default(),
        location: RunLocation::NewUnder(args.out.join("runs")),
    };
    let csv = args
        .csv
        .clone()
        .unwrap_or_else(|| args.out.join("soak.csv"));
    let mut log = Log::open(&csv)?;
    let mut preview = Preview {
        scene,
        fps,
        engine: None,
        weights: None,
        motion: 0,
        frame: 0,
        frames: 0,
        bakes: 0,
        bake_out: args.out.join("soak_bake.pc2"),
    };
    let start = Instant::now();
    let handle = Trainer::spawn(setup, None)?;
    let mut step = 0u64;
    let sample = |step: u64, preview: &Preview| -> anyhow::Result<Sample> {
        let (rss_mb, fds, threads) = resources()?;
        Ok(Sample {
            elapsed_min: start.elapsed().as_secs_f64() / 60.0,
            rss_mb,
            fds,
            threads,
            train_step: step,
            bakes: preview.bakes,
            preview_frames: preview.frames,
        })
    };
    log.record(sample(step, &preview)?)?;
    // The trainer stops itself after --minutes; this bound only guards against a hang.
    let deadline = start + Duration::from_secs_f64(args.minutes * 60.0 + 600.0);
    let mut next_frame = start + FRAME;
    let mut next_period = start + PERIOD;
    let mut outcome: anyhow::Result<()> = Ok(());
    loop {
        let now = Instant::now();
        if now >= deadline {
            outcome = Err(anyhow::anyhow!(
                "training did not finish 10 minutes after its limit"
            ));
            break;
        }
        if now >= next_frame {
            preview.step()?;
            next_frame += FRAME;
            if next_frame < now {
                // Fell behind (a bake, a busy machine): drop frames as playback does.
                next_frame = now + FRAME;
            }
        }
        if now >= next_period {
            if let Err(e) = preview.bake() {
                eprintln!("warning: bake failed: {e}");
            }
            log.record(sample(step, &preview)?)?;
            next_period += PERIOD;
        }
        let wait = next_frame.saturating_duration_since(Instant::now());
        let Some(event) = handle.recv_timeout(wait) else {
            continue;
        };
        match event {
            TrainEvent::Started { run_dir, step: s } => {
                eprintln!("run folder: {} (from step {s})", run_dir.display());
            }
            TrainEvent::Step(r) => step = r.step,
            TrainEvent::Snapshot { step: s, weights } => {
                step = step.max(s);
                preview.set_weights(weights)?;
            }
            TrainEvent::Warning(w) => eprintln!("warning: {w}"),
            TrainEvent::Note(n) => eprintln!("note: {n}"),
            TrainEvent::RolledBack {
                diverged_at,
                restored_step,
                ..
            } => eprintln!("diverged at step {diverged_at}: rolled back to step {restored_step}"),
            TrainEvent::Finished(result) => {
                if let Err(e) = result {
                    outcome = Err(anyhow::anyhow!("training failed: {e}"));
                }
                break;
            }
            TrainEvent::Validation(_)
            | TrainEvent::Preparing(_)
            | TrainEvent::Checkpoint { .. }
            | TrainEvent::Stalled { .. }
            | TrainEvent::Paused
            | TrainEvent::Resumed
            | TrainEvent::Applied(_)
            | TrainEvent::Rejected { .. } => {}
        }
    }
    // The last sample, before the trainer's thread is joined.
    log.record(sample(step, &preview)?)?;
    handle.join();
    outcome?;
    let verdict = judge(&log.samples, WARMUP_MINUTES).context("no samples")?;
    print_summary(&verdict, &log.samples);
    if !verdict.leaks.is_empty() {
        anyhow::bail!("leak: {}", verdict.leaks.join("; "));
    }
    Ok(())
}

fn print_summary(v: &Verdict, samples: &[Sample]) {
    let first = samples.first();
    let last = samples.last();
    println!(
        "soak: {:.1} minutes, {} training steps, {} preview frames, {} bakes",
        last.map_or(0.0, |s| s.elapsed_min),
        last.map_or(0, |s| s.train_step),
        last.map_or(0, |s| s.preview_frames),
        last.map_or(0, |s| s.bakes)
    );
    println!(
        "RSS: start {:.1} MiB, at {:.1} min {:.1} MiB, end {:.1} MiB: {:+.2} % after the \
         warm-up (goal under {RSS_GOAL_PCT} %: {})",
        first.map_or(0.0, |s| s.rss_mb),
        v.warm_min,
        v.rss_warm_mb,
        v.rss_end_mb,
        v.growth_pct,
        if v.rss_ok() { "met" } else { "missed" }
    );
    println!(
        "file descriptors {}..{}, threads {}..{} after the warm-up: {}",
        v.fds.0,
        v.fds.1,
        v.threads.0,
        v.threads.1,
        if v.leaks.is_empty() {
            "no growth".to_string()
        } else {
            v.leaks.join("; ")
        }
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn s(elapsed_min: f64, rss_mb: f64, fds: usize, threads: usize) -> Sample {
        Sample {
            elapsed_min,
            rss_mb,
            fds,
            threads,
            train_step: 0,
            bakes: 0,
            preview_frames: 0,
        }
    }

    #[test]
    fn growth_is_measured_from_the_end_of_the_warm_up() {
        let samples: Vec<Sample> = (0..=20)
            .map(|m| s(m as f64, if m < 10 { 50.0 + m as f64 } else { 100.0 }, 9, 4))
            .chain([s(21.0, 102.0, 9, 4)])
            .collect();
        let v = judge(&samples, 10.0).unwrap();
        assert_eq!(v.rss_warm_mb, 100.0);
        assert_eq!(v.warm_min, 10.0);
        assert_eq!(v.rss_end_mb, 102.0);
        assert!((v.growth_pct - 2.0).abs() < 1e-9);
        assert!(v.rss_ok());
        assert!(v.leaks.is_empty());
        assert_eq!((v.fds, v.threads), ((9, 9), (4, 4)));
    }

    #[test]
    fn a_steady_rise_of_descriptors_or_threads_is_a_leak_and_a_blip_is_not() {
        // Threads come up during the warm-up (the trainer's pool): not judged.
        let blip: Vec<Sample> = (0..=30)
            .map(|m| {
                s(
                    m as f64,
                    100.0,
                    if m == 20 { 11 } else { 9 },
                    (m.min(3)) + 1,
                )
            })
            .collect();
        let v = judge(&blip, 10.0).unwrap();
        assert!(v.leaks.is_empty(), "{:?}", v.leaks);
        assert_eq!(v.fds, (9, 11));
        let leaking: Vec<Sample> = (0..=30)
            .map(|m| s(m as f64, 100.0, 9 + m / 5, 4 + m / 10))
            .collect();
        let v = judge(&leaking, 10.0).unwrap();
        assert_eq!(v.leaks.len(), 2, "{:?}", v.leaks);
        assert!(v.leaks[0].starts_with("file descriptors grew"));
        assert!(v.leaks[1].starts_with("threads grew"));
    }

    #[test]
    fn memory_past_the_goal_misses_it_and_a_short_run_judges_from_its_start() {
        let samples = [s(0.0, 100.0, 9, 4), s(1.0, 110.0, 9, 4)];
        let v = judge(&samples, 10.0).unwrap();
        assert_eq!(v.warm_min, 0.0);
        assert!((v.growth_pct - 10.0).abs() < 1e-9);
        assert!(!v.rss_ok());
        assert!(judge(&[], 10.0).is_none());
    }
}
