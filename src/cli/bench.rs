//! `neural-cloth bench`: inference fps at 10K and 250K DoF (1 thread and all threads), the
//! memory-bandwidth floor, training step time and per-term physics cost.

use std::path::PathBuf;

use neural_cloth::bench::{BenchOptions, run_suite};

/// Arguments of `bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Print the results as JSON instead of tables.
    #[arg(long)]
    pub json: bool,
    /// A quick run (10K DoF only, fewer frames and steps) for smoke tests.
    #[arg(long)]
    pub quick: bool,
    /// Only the physics term costs (burn against fused kernels), nothing else.
    #[arg(long, conflicts_with = "quick")]
    pub physics_only: bool,
    /// Also write the tables to this Markdown file (e.g. docs/BENCHMARKS.md).
    #[arg(long)]
    pub markdown: Option<PathBuf>,
    /// Only the training steps (the default path and burn's Adam, and their floor, without the
    /// warm start's drape) at these batch sizes (e.g. `16,32`), nothing else: for profiling.
    #[arg(long, value_delimiter = ',', conflicts_with_all = ["quick", "physics_only"])]
    pub train_only: Option<Vec<usize>>,
    /// Steps timed per training configuration (default 10).
    #[arg(long)]
    pub steps: Option<usize>,
    /// Also time the inference engine on the newest checkpoint of this trained run (on the
    /// run's own garment and motion): trained weights skip another share of basis rows than
    /// random ones.
    #[arg(long, value_name = "RUN")]
    pub weights: Option<PathBuf>,
}

/// Runs `bench`.
pub fn run(args: BenchArgs) -> anyhow::Result<()> {
    let mut options = if let Some(batches) = &args.train_only {
        BenchOptions {
            train_batches: batches.clone(),
            ..BenchOptions::default()
        }
        .train_only()
    } else if args.physics_only {
        BenchOptions {
            dofs: Vec::new(),
            frames: 0,
            train_batches: Vec::new(),
            train_steps: 0,
            physics: true,
            train_variants: false,
            predrape_secs: None,
            trained: None,
        }
    } else if args.quick {
        BenchOptions {
            dofs: vec![10_000],
            frames: 10,
            train_batches: vec![4],
            train_steps: 2,
            physics: false,
            train_variants: true,
            predrape_secs: None,
            trained: None,
        }
    } else {
        BenchOptions::default()
    };
    if let Some(steps) = args.steps {
        options.train_steps = steps.max(1);
    }
    options.trained = args.weights.clone();
    let report =
        run_suite(&options, &mut |line| eprintln!("{line}")).map_err(anyhow::Error::msg)?;
    let markdown = report.to_markdown();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!("{markdown}");
    }
    if let Some(path) = args.markdown {
        let machine = machine_description();
        let weights = args
            .weights
            .as_ref()
            .map_or(String::new(), |w| format!(" --weights {}", w.display()));
        let text = format!(
            "# Benchmarks\n\nMeasured with `neural-cloth bench{weights} --markdown {}` (release build).\n\nMachine: {machine}.\n\n{markdown}",
            path.display()
        );
        neural_cloth::io::export::atomic::write_atomic(&path, text.as_bytes())?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

/// CPU model and core count from /proc/cpuinfo (Linux), else the core count.
pub fn machine_description() -> String {
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines().find_map(|l| {
                l.strip_prefix("model name")
                    .map(|v| v.trim_start_matches([' ', '\t', ':']).to_string())
            })
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let mem = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find_map(|l| l.strip_prefix("MemTotal:").map(|v| v.trim().to_string()))
        })
        .unwrap_or_default();
    format!("{model}, {cores} cores available, {mem} memory")
}
