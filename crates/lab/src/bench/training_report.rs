//! The training part of the benchmark report: step times of each path, the floor measured in
//! the same run, and the training goals of issue 12 as ratios.

use std::fmt::Write as _;

use neural_cloth_core::scene::config::Effects;
use neural_cloth_train::TrainConfig;

use super::report::effects_label;
use super::suite::BenchReport;
use super::training::{TrainBench, TrainCase, floor_secs};

/// Goal of issue 12 for the default scene at batch 16, ms per step.
const GOAL_16_MS: f64 = 100.0;
/// Goal at batch 32, ms per step.
const GOAL_32_MS: f64 = 180.0;
/// The step should be within this factor of the floor.
const GOAL_FLOOR_RATIO: f64 = 2.0;

fn mb(bytes: usize) -> f64 {
    bytes as f64 / 1e6
}

/// The floor of `t` in milliseconds ([`floor_secs`] with the rates measured at its batch
/// size).
pub fn floor_ms(r: &BenchReport, t: &TrainBench) -> Option<f64> {
    let rates = &r.matmul.iter().find(|f| f.batch == t.case.batch)?.rates;
    Some(floor_secs(&t.flops, rates)? * 1e3)
}

fn find(r: &BenchReport, case: TrainCase) -> Option<&TrainBench> {
    r.training.iter().find(|t| {
        let c = &t.case;
        c.batch == case.batch
            && c.effects == case.effects
            && c.fused_physics == case.fused_physics
            && c.fused_adam == case.fused_adam
            && c.window_secs == case.window_secs
            && c.skip_still == case.skip_still
            && c.split_batch == case.split_batch
    })
}

/// The step-time table and the matrix-product rates.
pub fn training_tables(r: &BenchReport) -> String {
    let mut s = String::new();
    if r.training.is_empty() {
        return s;
    }
    let _ = writeln!(s, "\n### Training step (default scene, flex CPU backend)\n");
    let _ = writeln!(
        s,
        "Step times: median over the timed steps; the paths of one batch size are stepped round \
         robin (one step of each in turn, all sessions alive) so that the machine's changing load \
         affects them alike. Peak MB: each path's process peak over a few steps alone.\n"
    );
    let _ = writeln!(
        s,
        "Floor: the step's matrix and skinning FLOPs (forward and backward, counted from the \
         network's layers; the physics is a few MFLOP and not counted), each part over the rate \
         of burn's own matrix product measured in this run on that part's shapes (table below: \
         the basis products, the layers, the GRU step).\n"
    );
    let _ = writeln!(
        s,
        "| batch | effects | path | window s | fps | ms / step | steps / s | peak MB | GFLOP / step | floor ms | step / floor |"
    );
    let _ = writeln!(s, "|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    for t in &r.training {
        let floor = floor_ms(r, t);
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {:.1} | {:.2} | {:.0} | {:.2} | {} | {} |",
            t.case.batch,
            effects_label(&t.case.effects),
            t.case.path_label(),
            t.window_secs,
            t.fps,
            t.ms_per_step,
            1e3 / t.ms_per_step,
            mb(t.peak_bytes),
            t.flops.total() / 1e9,
            floor.map_or("-".into(), |f| format!("{f:.1}")),
            floor.map_or("-".into(), |f| format!("{:.2}×", t.ms_per_step / f)),
        );
    }
    if let Some(t) = r.training.first() {
        let f = &t.flops;
        let _ = writeln!(
            s,
            "\nWork of a batch-{} step, GFLOP: encoders {:.2}, GRU unroll {:.2}, decoder {:.2}, \
             basis products {:.2}, skinning {:.3}.",
            t.case.batch,
            f.encoders / 1e9,
            f.gru / 1e9,
            f.decoder / 1e9,
            f.basis / 1e9,
            f.skinning / 1e9
        );
    }
    if !r.matmul.is_empty() {
        let _ = writeln!(
            s,
            "\n#### burn's matrix product on the step's shapes (flex, all threads)\n"
        );
        let _ = writeln!(s, "| batch | shape | [m, k] × [k, n] | ms | GFLOP/s |");
        let _ = writeln!(s, "|---:|---|---|---:|---:|");
        for f in &r.matmul {
            for m in &f.rates {
                let _ = writeln!(
                    s,
                    "| {} | {} | [{}, {}] × [{}, {}] | {:.3} | {:.1} |",
                    f.batch, m.what, m.m, m.k, m.k, m.n, m.ms, m.gflops
                );
            }
        }
    }
    s
}

/// The engine on trained weights beside random weights of the same size and precision.
pub fn trained_table(r: &BenchReport) -> String {
    let mut s = String::new();
    let Some((run, benches)) = &r.trained else {
        return s;
    };
    let _ = writeln!(s, "\n### Inference on trained weights\n");
    let _ = writeln!(
        s,
        "Weights of {run}, on the run's own garment and first motion, 1 thread, beside the random \
         weights of the first table at about the same size (when measured). The share of \
         basis rows read (rows of nonzero decoder outputs and dynamic codes) depends on the \
         weights.\n"
    );
    let _ = writeln!(
        s,
        "| DoF | weights | ms / frame | fps | basis rows read | random weights: ms / frame | random: rows read |"
    );
    let _ = writeln!(s, "|---:|---|---:|---:|---:|---:|---:|");
    for b in benches {
        // The random-weight garment closest in size (the suite's 10K garment has 9996 DoF).
        let random = r.inference.iter().find(|x| {
            x.dof.abs_diff(b.dof) * 20 <= b.dof
                && x.precision == b.precision
                && x.threads == 1
                && x.model == b.model
        });
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} | {:.0} | {:.0}% | {} | {} |",
            b.dof,
            b.precision,
            b.ms_per_frame,
            b.fps,
            100.0 * b.basis_rows_read,
            random.map_or("-".into(), |x| format!("{:.3}", x.ms_per_frame)),
            random.map_or("-".into(), |x| format!("{:.0}%", 100.0 * x.basis_rows_read)),
        );
    }
    s
}

/// One goal line: the default path at `batch` against the other paths of the same run.
fn goal_line(r: &BenchReport, batch: usize, goal_ms: f64) -> Option<String> {
    let new = find(r, TrainCase::default_at(batch))?;
    let verdict = if new.ms_per_step <= goal_ms {
        "**met**".to_string()
    } else {
        format!("**not met** ({:.2}× the goal)", new.ms_per_step / goal_ms)
    };
    let mut line = format!(
        "- **Training step, batch {batch}, all effects, goal ≤ {goal_ms:.0} ms:** {:.1} ms with \
         the fused physics and the fused Adam, {verdict}",
        new.ms_per_step
    );
    let burn_adam = TrainCase {
        fused_adam: false,
        ..TrainCase::default_at(batch)
    };
    for (other, what) in [
        (
            TrainCase::reference_at(batch),
            "the burn reference path (physics and Adam)",
        ),
        (burn_adam, "the fused physics with burn's Adam"),
    ] {
        if let Some(o) = find(r, other) {
            let _ = write!(
                line,
                "; {:.2}× faster than {what} ({:.1} ms, peak {:.0} against {:.0} MB)",
                o.ms_per_step / new.ms_per_step,
                o.ms_per_step,
                mb(new.peak_bytes),
                mb(o.peak_bytes)
            );
        }
    }
    if let Some(floor) = floor_ms(r, new) {
        let ratio = new.ms_per_step / floor;
        let _ = write!(
            line,
            "; floor {floor:.1} ms ({:.2} GFLOP), step / floor **{ratio:.2}×** (goal ≤ {GOAL_FLOOR_RATIO:.0}×)",
            new.flops.total() / 1e9
        );
    }
    line.push('.');
    Some(line)
}

/// The training-step goals of issue 12, as ratios measured in this run.
pub fn training_gap(r: &BenchReport) -> String {
    let mut s = String::new();
    for (batch, goal) in [(16, GOAL_16_MS), (32, GOAL_32_MS)] {
        if let Some(line) = goal_line(r, batch, goal) {
            let _ = writeln!(s, "{line}");
        }
    }
    for batch in [16, 32] {
        let case = TrainCase {
            window_secs: TrainConfig::default().window_secs,
            ..TrainCase::default_at(batch)
        };
        if let (Some(t), Some(half)) = (find(r, case), find(r, TrainCase::default_at(batch))) {
            let floor = floor_ms(r, t).map_or(String::new(), |f| {
                format!(", floor {f:.1} ms, step / floor {:.2}×", t.ms_per_step / f)
            });
            let whole_case = TrainCase {
                split_batch: false,
                ..case
            };
            let whole = find(r, whole_case);
            let halves = whole.map_or(String::new(), |o| {
                format!(
                    "; {:.2}× faster than with the batch whole on one thread ({:.1} ms)",
                    o.ms_per_step / t.ms_per_step,
                    o.ms_per_step
                )
            });
            // The still windows' skip, both with the batch whole.
            let through = TrainCase {
                skip_still: false,
                ..whole_case
            };
            let skip = match (find(r, through), whole) {
                (Some(o), Some(w)) => format!(
                    "; with the batch whole, {:.2}× faster than with the still windows through \
                     the recurrent encoder ({:.1} ms)",
                    o.ms_per_step / w.ms_per_step,
                    o.ms_per_step
                ),
                _ => String::new(),
            };
            let _ = writeln!(
                s,
                "- **Today's default window ({} s), batch {batch}:** {:.1} ms per step, {:.2}× the \
                 issue's {} s window{floor}{halves}{skip}.",
                case.window_secs,
                t.ms_per_step,
                t.ms_per_step / half.ms_per_step,
                half.window_secs
            );
        }
    }
    let all = Effects::default();
    let time = |batch: usize| {
        r.training
            .iter()
            .find(|t| t.case == TrainCase::default_at(batch) && t.case.effects == all)
            .map(|t| t.ms_per_step)
    };
    if let (Some(t16), Some(t32)) = (time(16), time(32)) {
        let _ = writeln!(
            s,
            "- **Batch 32 against 16:** {:.2}× the step time for twice the windows \
             ({:.1} against {:.1} ms per window).",
            t32 / t16,
            t32 / 32.0,
            t16 / 16.0
        );
    }
    s
}
