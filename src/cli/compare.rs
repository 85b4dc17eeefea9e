//! `neural-cloth compare RUN`: checks a trained run against the reference simulator on the
//! same motion (distances, dynamic amplitude, hem radius, the paper's metrics) with a progress
//! bar; prints a table, or JSON with `--json`.

use std::fmt::Write as _;
use std::path::PathBuf;

use indicatif::{ProgressBar, ProgressStyle};

use neural_cloth::train::compare::{
    CompareOptions, CompareReport, MotionComparison, TrainingCheck, append_checks, compare,
};
use neural_cloth::train::load_trained;

/// Arguments of `compare`.
#[derive(clap::Args, Debug)]
pub struct CompareArgs {
    /// Run folder (or checkpoint folder) of a trained model.
    pub checkpoint: PathBuf,
    /// Motion of the run's scene (or "NAME (mirrored)": its left/right mirror image);
    /// default: every motion of the validation split.
    #[arg(long)]
    pub motion: Option<String>,
    /// Dynamic weight w of the network in [0, 2] (1 = as trained).
    #[arg(long, default_value_t = 1.0)]
    pub w: f32,
    /// L-BFGS iterations per frame of the reference simulation.
    #[arg(long, default_value_t = 200)]
    pub iterations: usize,
    /// Seconds the simulator holds the first pose before the motion plays, to come to rest
    /// (0..=5).
    #[arg(long, default_value_t = 3.0)]
    pub settle: f32,
    /// Simulate again even when RUN/reference/ (or another run in RUN's folder) holds this
    /// reference.
    #[arg(long)]
    pub no_cache: bool,
    /// Skip the GRU state's drift (the network replayed one training window before each
    /// frame, which costs about one play of the motion per frame of a window).
    #[arg(long)]
    pub no_drift: bool,
    /// Also step the simulator once from each pair of the network's own frames and measure
    /// how far the network's next frame is from that step (does it obey the physics frame by
    /// frame, and which way does physics push it; at --w 1 only, on scenes with dynamics;
    /// costs about one simulation of the motion).
    #[arg(long)]
    pub one_step: bool,
    /// Also simulate each motion with twice the iterations and print how far the two
    /// simulations are apart: whether the reference is converged (a distance to an
    /// unconverged one means little; costs about two more references; cached).
    #[arg(long)]
    pub spread: bool,
    /// Also simulate each motion from the settled garment moved by a micrometre and print how
    /// far it is from the reference: whether the motion is predictable at all (a simulation
    /// that forks on such a change cannot be matched frame by frame; costs about one more
    /// reference; cached).
    #[arg(long)]
    pub sensitivity: bool,
    /// Print the report as JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Also append the check (with the run's seed, steps, minutes and dead units) to this
    /// JSON-lines file; `neural-cloth report` renders `docs/report/training_checks.jsonl`.
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// What the run is, in words, for the recorded check (e.g. its non-default settings).
    #[arg(long, requires = "record")]
    pub label: Option<String>,
}

/// Runs `compare`.
pub fn run(args: CompareArgs) -> anyhow::Result<()> {
    let trained = load_trained(&args.checkpoint)?;
    let options = CompareOptions {
        w: args.w,
        iterations: args.iterations,
        settle_secs: args.settle,
        use_cache: !args.no_cache,
        drift: !args.no_drift,
        one_step: args.one_step,
        spread: args.spread,
        sensitivity: args.sensitivity,
        ..Default::default()
    };
    options.validate()?;
    let bar = ProgressBar::new(1000);
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:30} {percent:>3}% {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let report = compare(&trained, args.motion.as_deref(), &options, &mut |p| {
        bar.set_position((1000.0 * p.fraction()).round() as u64);
        bar.set_message(format!(
            "{}: {} ({}/{})",
            p.motion,
            p.phase.label(),
            p.done,
            p.total
        ));
        true
    })?;
    bar.finish_and_clear();
    if let Some(path) = &args.record {
        append_checks(
            path,
            &TrainingCheck::from_report(&trained, &report, args.label.as_deref()),
        )?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", table(&report));
    }
    Ok(())
}

/// The report as a readable text table.
pub fn table(report: &CompareReport) -> String {
    let o = &report.options;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "run {} (step {}): garment '{}', {} vertices, {} fps, w = {}",
        report.run.display(),
        report.step,
        report.garment,
        report.vertices,
        report.fps,
        o.w
    );
    let _ = writeln!(
        s,
        "reference: {} L-BFGS iterations per frame after settling {} s on the first pose",
        o.iterations, o.settle_secs
    );
    let _ = writeln!(
        s,
        "still frame: every joint slower than {} m/s for the last {} s; swing: mean distance \
         from the quasi-static result (network at w = 0, simulator without dynamics); quasi-static \
         distance: the network at w = 0 against the simulator without dynamics; motion \
         distance: the network's motion (w against w = 0) against the simulator's (dynamic \
         against quasi-static); slip: \
         the part of a difference that is a rigid motion of the whole garment (a frictionless \
         garment slides over the body), shape: what is left after it; state drift: the \
         network with its GRU state carried over the motion against the same network \
         restarted one training window (and burn-in) before each frame; one-step: each \
         network frame against one simulator step from the network's two previous frames \
         (turn with body < 0: physics holds the garment further back); reference spread: the \
         reference against the same simulation at twice the iterations; reference \
         sensitivity: against the same simulation from a start moved by 1 µm",
        o.still_speed_m_per_s, o.still_window_secs
    );
    for m in &report.motions {
        motion_table(&mut s, m);
    }
    s
}

/// One motion's block of the table.
fn motion_table(s: &mut String, m: &MotionComparison) {
    let r = &m.measures;
    let source = match m.reference.cached {
        true => "cached".to_string(),
        false => format!("simulated in {:.1} s", m.reference.simulate_secs),
    };
    let _ = writeln!(
        s,
        "\nmotion '{}': {} frames ({} still); reference {source}: {}",
        m.name,
        r.frames,
        r.still_frames,
        m.reference.path.display()
    );
    let _ = writeln!(
        s,
        "  {:<28}{:>12}{:>12}{:>12}",
        "", "all frames", "still", "moving"
    );
    for row in r.rows() {
        let [all, still, moving] = row.cells();
        let _ = writeln!(s, "  {:<28}{all:>12}{still:>12}{moving:>12}", row.label);
    }
    let _ = writeln!(s, "  {:<28}{:>12}{:>12}", "metrics", "network", "simulator");
    for row in m.metric_rows() {
        let d = row.decimals;
        let _ = writeln!(
            s,
            "  {:<28}{:>12.d$}{:>12.d$}",
            row.label, row.network, row.simulator
        );
    }
}
