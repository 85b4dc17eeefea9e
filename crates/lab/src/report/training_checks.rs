//! The report's table of training targets (issue 11): recorded `compare --record` checks of
//! trained runs against the reference simulator, one row per run, seed and motion, with each
//! target judged from the numbers (met, not met, or not measured).

use std::collections::BTreeMap;
use std::fmt::Write as _;

use neural_cloth_train::compare::TrainingCheck;

/// Skirt: the still hem radius within this fraction of the simulator's.
pub const STILL_HEM_TOLERANCE: f64 = 0.10;
/// Skirt: the hem opening while moving, as a fraction of the simulator's.
pub const OPENING_FRACTION: f64 = 0.70;
/// T-shirt: mean distance on still poses, mm.
pub const STILL_DISTANCE_MM: f64 = 2.0;
/// T-shirt: mean distance on the held-out spin, mm.
pub const SPIN_DISTANCE_MM: f64 = 12.0;
/// T-shirt: the network's swing as a fraction of the simulator's.
pub const SWING_FRACTION: f64 = 0.5;

/// A verdict word.
fn verdict(met: Option<bool>) -> &'static str {
    match met {
        Some(true) => "met",
        Some(false) => "**not met**",
        None => "—",
    }
}

/// Still hem within tolerance, and the opening fraction, of one check (garments below the hips).
fn hem_targets(c: &TrainingCheck) -> (Option<bool>, Option<f64>) {
    let Some(hem) = c.motion.measures.hem else {
        return (None, None);
    };
    let still_ok = hem
        .still
        .map(|s| (s.network_m - s.simulator_m).abs() <= STILL_HEM_TOLERANCE * s.simulator_m.abs());
    let opening = match (hem.still, hem.moving) {
        (Some(s), Some(m)) if (m.simulator_m - s.simulator_m).abs() > 1e-9 => {
            Some((m.network_m - s.network_m) / (m.simulator_m - s.simulator_m))
        }
        _ => None,
    };
    (still_ok, opening)
}

/// True when the moving hem radius grows with `w` over every recorded `w` of one run and
/// motion (`None` with fewer than two).
fn monotone_in_w(checks: &[&TrainingCheck]) -> Option<bool> {
    let mut by_w: Vec<(f32, f64)> = checks
        .iter()
        .filter_map(|c| Some((c.w, c.motion.measures.hem?.moving?.network_m)))
        .collect();
    by_w.sort_by(|a, b| a.0.total_cmp(&b.0));
    by_w.dedup_by(|a, b| a.0 == b.0);
    (by_w.len() >= 2).then(|| by_w.windows(2).all(|p| p[1].1 > p[0].1))
}

fn mm(v: Option<f64>) -> String {
    v.map_or_else(|| "—".into(), |v| format!("{v:.1}"))
}

fn metres(v: Option<f64>) -> String {
    v.map_or_else(|| "—".into(), |v| format!("{v:.3}"))
}

/// Appends the section to `s`; nothing when there are no checks.
pub fn render_training_checks(s: &mut String, checks: &[TrainingCheck]) {
    if checks.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "## 0. Training against the simulator (targets of issue 11)\n\n\
         Recorded with `neural-cloth compare RUN --motion M --record docs/report/training_checks.jsonl` \
         (reference simulator on the same garment, fabric, effects and body; see [`TRAINING.md`](TRAINING.md) \
         for the scenes and the history). Minutes are training wall-clock minutes on this 2-core machine \
         with the threads shown; still = frames where every joint is slower than 0.1 m/s; swing = mean \
         distance of each moving frame from its quasi-static counterpart (network at w = 0, simulator \
         without dynamics). Caution on the t-shirt's swing since round 7: the network's w = 0 drape \
         hangs 4-7 mm above the simulator's still drape and its dynamic branch adds that sag back \
         for any motion (docs/TRAINING.md, round 8), so its swing (and the \"swing ≥ half\" verdicts \
         below) include that offset; its distances to the simulator at w = 1 do not. \
         Caution on every distance to the simulator on fast turns (round 20): the reference at \
         100 iterations per frame, which these checks used unless said, is not converged there: \
         32-36 mm from the same simulation at 200 on the t-shirt's twirl and spin (the spinning \
         shirt whirls off-centre and the two put it on opposite sides), where 200 and 400 agree \
         to 4.9 mm on the spin; differences between runs hold, absolute distances are against \
         that reference. Caution on the twirl (round 21): its simulation forks, the whole shirt \
         slipping about the body at one frame or another, so that the same simulation from a \
         start moved by 1 µm is 48.1 mm from it (on the spin: 4.7 mm); no distance to it \
         frame by frame says much there. The diagnostic rows \"the simulator against itself\" \
         show the spread and the sensitivity where they were measured (`compare --spread`, \
         `--sensitivity`).\n"
    );
    let _ = writeln!(
        s,
        "| garment | run | seed | minutes (threads) | steps | motion | w | mean mm all / still | swing mm net / sim | still hem m net / sim | moving hem m net / sim | opening | dead % | finite |"
    );
    let _ = writeln!(
        s,
        "|---|---:|---:|---:|---|---:|---|---|---|---|---:|---:|---|"
    );
    for c in checks {
        let m = &c.motion.measures;
        let hem = m.hem;
        let still = hem.and_then(|h| h.still);
        let moving = hem.and_then(|h| h.moving);
        let (_, opening) = hem_targets(c);
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.1} ({}) | {} | {} | {} | {:.1} / {} | {} / {} | {} / {} | {} / {} | {} | {} | {} |",
            c.garment,
            c.label.as_deref().unwrap_or(&c.run),
            c.seed,
            c.train_minutes,
            c.threads,
            c.steps,
            c.motion.name,
            c.w,
            m.all.mean_mm,
            mm(m.still.map(|d| d.mean_mm)),
            mm(m.amplitude.network.moving_mm),
            mm(m.amplitude.simulator.moving_mm),
            metres(still.map(|h| h.network_m)),
            metres(still.map(|h| h.simulator_m)),
            metres(moving.map(|h| h.network_m)),
            metres(moving.map(|h| h.simulator_m)),
            opening.map_or_else(|| "—".into(), |o| format!("{:.0} %", 100.0 * o)),
            c.dead_units_pct
                .map_or_else(|| "—".into(), |d| format!("{d:.0}")),
            if c.finite { "yes" } else { "**no**" },
        );
    }
    let _ = writeln!(s);
    render_verdicts(s, checks);
}

/// One line per run and motion at `w = 1`: each target of the issue, met or not.
fn render_verdicts(s: &mut String, checks: &[TrainingCheck]) {
    let mut groups: BTreeMap<(String, String, u64, String), Vec<&TrainingCheck>> = BTreeMap::new();
    for c in checks {
        groups
            .entry((
                c.garment.clone(),
                c.run.clone(),
                c.steps,
                c.motion.name.clone(),
            ))
            .or_default()
            .push(c);
    }
    let _ = writeln!(
        s,
        "| garment | run | seed | minutes | steps | motion | target | value | verdict |\n|---|---|---:|---:|---:|---|---|---|---|"
    );
    for ((garment, _, _, motion), group) in &groups {
        let Some(c) = group.iter().find(|c| (c.w - 1.0).abs() < 1e-6) else {
            continue;
        };
        let mut row = |target: &str, value: String, met: Option<bool>| {
            // A run fitted to the simulator's frames measures the network, not the method.
            // A warm-started run's minutes leave out the simulation of its training motions.
            let judged = match (c.fitted_to_simulator, c.warm_start_steps) {
                (true, _) => "— (fitted to the simulator: a diagnostic)".to_string(),
                (false, 0) => verdict(met).to_string(),
                (false, steps) => format!(
                    "{} (warm start of {steps} steps from our simulator: its simulation is \
                     not in the minutes)",
                    verdict(met)
                ),
            };
            let _ = writeln!(
                s,
                "| {garment} | {} | {} | {:.1} | {} | {motion} | {target} | {value} | {judged} |",
                c.label.as_deref().unwrap_or(&c.run),
                c.seed,
                c.train_minutes,
                c.steps,
            );
        };
        let m = &c.motion.measures;
        if let Some(hem) = m.hem {
            let (still_ok, opening) = hem_targets(c);
            if let Some(st) = hem.still {
                row(
                    "still hem radius within 10 % of the simulator's",
                    format!("{:.3} / {:.3} m", st.network_m, st.simulator_m),
                    still_ok,
                );
            }
            if let Some(o) = opening {
                row(
                    "hem opening ≥ 70 % of the simulator's",
                    format!("{:.0} %", 100.0 * o),
                    Some(o >= OPENING_FRACTION),
                );
            }
            let mono = monotone_in_w(group);
            if mono.is_some() {
                let ws: Vec<String> = {
                    let mut w: Vec<f32> = group.iter().map(|c| c.w).collect();
                    w.sort_by(|a, b| a.total_cmp(b));
                    w.dedup();
                    w.iter().map(|w| format!("{w}")).collect()
                };
                row(
                    "moving hem radius monotone in w",
                    format!("w = {}", ws.join(", ")),
                    mono,
                );
            }
        } else if let Some(still) = m.still
            && m.still_frames * 10 >= m.frames * 9
        {
            row(
                "mean distance on still poses ≤ 2 mm",
                mm_against(still.mean_mm, STILL_DISTANCE_MM),
                Some(still.mean_mm <= STILL_DISTANCE_MM),
            );
        }
        if m.hem.is_none() && m.still_frames < m.frames {
            row(
                "mean distance on a moving motion ≤ 12 mm",
                mm_against(m.all.mean_mm, SPIN_DISTANCE_MM),
                Some(m.all.mean_mm <= SPIN_DISTANCE_MM),
            );
            if let (Some(net), Some(sim)) = (
                m.amplitude.network.moving_mm,
                m.amplitude.simulator.moving_mm,
            ) {
                row(
                    "swing ≥ half the simulator's",
                    format!("{net:.1} / {sim:.1} mm"),
                    Some(net >= SWING_FRACTION * sim),
                );
            }
            // Not the wording: the same two measures with each frame's rigid motion of
            // the whole garment (a frictionless garment's slip over the body) taken out.
            if let Some(rigid) = m.rigid {
                row(
                    "(diagnostic) distance after each frame's rigid fit",
                    format!("{:.1} mm", rigid.shape_distance_mm),
                    None,
                );
                row(
                    "(diagnostic) shape swing ≥ half the simulator's",
                    format!(
                        "{:.1} / {:.1} mm (slip {:.1} / {:.1})",
                        rigid.network_shape_swing_mm,
                        rigid.simulator_shape_swing_mm,
                        rigid.network_slip_mm,
                        rigid.simulator_slip_mm
                    ),
                    Some(
                        rigid.network_shape_swing_mm
                            >= SWING_FRACTION * rigid.simulator_shape_swing_mm,
                    ),
                );
            }
        }
        // Not a target either: how far the GRU state carried over the whole motion takes the
        // frames from those of the same network restarted one training window before each.
        if let Some(drift) = m.drift {
            row(
                "(diagnostic) GRU state drift, carried against windowed",
                format!(
                    "{:.1} mm (worst frame {:.1}, height {:+.1}; window {} frames)",
                    drift.mean_mm, drift.max_frame_mm, drift.height_mm, drift.window_frames
                ),
                None,
            );
        }
        // Nor this: each frame against one simulator step from the network's own history.
        if let Some(step) = m.one_step {
            let turn = step
                .turn_deg
                .map_or_else(String::new, |t| format!(", turn with the body {t:+.2}°"));
            row(
                "(diagnostic) one simulator step from the network's own frames",
                format!(
                    "{:.1} mm (shape {:.1}, height {:+.1}{turn})",
                    step.mean_mm, step.shape_mm, step.height_mm
                ),
                None,
            );
        }
        // Nor this: how far the reference is from itself at twice the iterations, below
        // which a distance to it means little.
        // And from a start moved by a micrometre: whether the motion is predictable at all.
        let others = [
            (
                m.spread,
                "(diagnostic) the simulator against itself at twice the iterations",
            ),
            (
                m.sensitivity,
                "(diagnostic) the simulator against itself from a start moved by 1 µm",
            ),
        ];
        for (other, label) in others {
            let Some(other) = other else { continue };
            let shape = other
                .shape_mm
                .map_or_else(String::new, |d| format!(", after rigid fit {d:.1}"));
            row(
                label,
                format!(
                    "{:.1} mm (p95 {:.1}{shape}; {} iterations)",
                    other.mean_mm, other.p95_mm, other.iterations
                ),
                None,
            );
        }
        row(
            "no dead network, no NaN",
            format!(
                "dead {} %, finite {}",
                c.dead_units_pct
                    .map_or_else(|| "—".into(), |d| format!("{d:.0}")),
                c.finite
            ),
            Some(c.finite && c.dead_units_pct.is_none_or(|d| d < 100.0)),
        );
    }
    let _ = writeln!(s);
}

/// `value_mm` to a tenth of a millimetre, or to a hundredth where the tenth would read as
/// `limit_mm` while the value is over it (2.02 against a 2 mm target reads "2.02 mm", not "2.0").
fn mm_against(value_mm: f64, limit_mm: f64) -> String {
    let tenths = format!("{value_mm:.1}");
    if value_mm > limit_mm && tenths == format!("{limit_mm:.1}") {
        format!("{value_mm:.2} mm")
    } else {
        format!("{tenths} mm")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use neural_cloth_train::compare::{
        DistanceStats, HemComparison, HemPair, MetricPair, MotionComparison, MotionMeasures,
        ReferenceInfo,
    };

    fn check(w: f32, still_net: f64, moving_net: f64) -> TrainingCheck {
        let pair = |net, sim| HemPair {
            network_m: net,
            simulator_m: sim,
            network_static_m: net,
            simulator_static_m: sim,
        };
        TrainingCheck {
            run: "runs/skirt".into(),
            label: None,
            scene: "skirt".into(),
            garment: "skirt".into(),
            seed: 0,
            steps: 2000,
            train_minutes: 10.0,
            threads: 1,
            dead_units_pct: Some(50.0),
            finite: true,
            w,
            iterations: 100,
            motion: MotionComparison {
                name: "spin".into(),
                measures: MotionMeasures {
                    frames: 10,
                    still_frames: 1,
                    all: DistanceStats {
                        frames: 10,
                        mean_mm: 20.0,
                        p95_mm: 40.0,
                    },
                    hem: Some(HemComparison {
                        vertices: 40,
                        still: Some(pair(still_net, 0.136)),
                        moving: Some(pair(moving_net, 0.266)),
                    }),
                    ..Default::default()
                },
                metrics: MetricPair::default(),
                objective: Default::default(),
                reference: ReferenceInfo::default(),
            },
            fitted_to_simulator: false,
            warm_start_steps: 0,
        }
    }

    #[test]
    fn a_warm_started_run_says_its_minutes_leave_out_the_simulation() {
        let mut c = check(1.0, 0.145, 0.245);
        c.warm_start_steps = 150;
        let mut s = String::new();
        render_training_checks(&mut s, &[c]);
        assert!(s.contains(
            "| 0.145 / 0.136 m | met (warm start of 150 steps from our simulator: its simulation is not in the minutes) |"
        ), "{s}");
    }

    #[test]
    fn a_run_fitted_to_the_simulator_meets_no_target() {
        let mut c = check(1.0, 0.145, 0.245);
        c.fitted_to_simulator = true;
        let mut s = String::new();
        render_training_checks(&mut s, &[c]);
        assert!(s.contains(
            "| still hem radius within 10 % of the simulator's | 0.145 / 0.136 m | — (fitted to the simulator: a diagnostic) |"
        ), "{s}");
        assert!(!s.contains("| met |"), "{s}");
    }

    #[test]
    fn skirt_targets_are_judged_from_the_numbers() {
        // Within 10 % and opening 0.1 / 0.13 = 77 %: met; 0.199 still: not met.
        let good = vec![check(1.0, 0.145, 0.245), check(0.0, 0.145, 0.150)];
        let mut s = String::new();
        render_training_checks(&mut s, &good);
        assert!(s.contains(
            "| still hem radius within 10 % of the simulator's | 0.145 / 0.136 m | met |"
        ));
        assert!(s.contains("| hem opening ≥ 70 % of the simulator's | 77 % | met |"));
        assert!(s.contains("| moving hem radius monotone in w | w = 0, 1 | met |"));
        let bad = vec![check(1.0, 0.199, 0.269), check(0.0, 0.199, 0.300)];
        let mut s = String::new();
        render_training_checks(&mut s, &bad);
        assert!(s.contains("0.199 / 0.136 m | **not met** |"), "{s}");
        assert!(s.contains("| hem opening ≥ 70 % of the simulator's | 54 % | **not met** |"));
        assert!(s.contains("| moving hem radius monotone in w | w = 0, 1 | **not met** |"));
    }

    #[test]
    fn the_rigid_split_of_a_shirt_is_shown_as_a_diagnostic() {
        let mut c = check(1.0, 0.0, 0.0);
        c.motion.measures.hem = None;
        c.motion.measures.amplitude.network.moving_mm = Some(14.0);
        c.motion.measures.amplitude.simulator.moving_mm = Some(33.0);
        c.motion.measures.rigid = Some(neural_cloth_train::compare::RigidSplit {
            shape_distance_mm: 22.5,
            network_slip_mm: 3.8,
            network_shape_swing_mm: 12.8,
            simulator_slip_mm: 28.5,
            simulator_shape_swing_mm: 18.6,
        });
        let mut s = String::new();
        render_training_checks(&mut s, &[c]);
        assert!(s.contains("| swing ≥ half the simulator's | 14.0 / 33.0 mm | **not met** |"));
        assert!(s.contains("| (diagnostic) distance after each frame's rigid fit | 22.5 mm | — |"));
        assert!(
            s.contains("12.8 / 18.6 mm (slip 3.8 / 28.5) | met |"),
            "{s}"
        );
        assert!(!s.contains("GRU state drift"), "not measured, not shown");
    }

    /// The section rendered from `checks` alone.
    fn render(checks: &[TrainingCheck]) -> String {
        let mut s = String::new();
        render_training_checks(&mut s, checks);
        s
    }

    #[test]
    fn the_one_step_check_is_shown_as_a_diagnostic() {
        let mut c = check(1.0, 0.17, 0.27);
        assert!(!render(&[c.clone()]).contains("one simulator step"));
        c.motion.measures.one_step = Some(neural_cloth_train::compare::OneStep {
            frames: 179,
            mean_mm: 7.8,
            shape_mm: 7.1,
            height_mm: 1.18,
            turn_deg: Some(-0.459),
        });
        let s = render(&[c]);
        assert!(
            s.contains("| (diagnostic) one simulator step from the network's own frames | 7.8 mm (shape 7.1, height +1.2, turn with the body -0.46°) | — |"),
            "{s}"
        );
    }

    #[test]
    fn the_reference_spread_is_shown_as_a_diagnostic() {
        let mut c = check(1.0, 0.0, 0.0);
        assert!(!render(&[c.clone()]).contains("| (diagnostic) the simulator against itself"));
        let spread = neural_cloth_train::compare::ReferenceSpread {
            iterations: 200,
            start_jitter_m: 0.0,
            mean_mm: 35.64,
            p95_mm: 56.5,
            shape_mm: Some(6.8),
        };
        c.motion.measures.spread = Some(spread);
        let s = render(&[c.clone()]);
        assert!(
            s.contains("| (diagnostic) the simulator against itself at twice the iterations | 35.6 mm (p95 56.5, after rigid fit 6.8; 200 iterations) | — |"),
            "{s}"
        );
        assert!(
            !s.contains("| (diagnostic) the simulator against itself from a start"),
            "{s}"
        );
        c.motion.measures.sensitivity = Some(neural_cloth_train::compare::ReferenceSpread {
            iterations: 100,
            start_jitter_m: 1e-6,
            mean_mm: 30.04,
            shape_mm: None,
            ..spread
        });
        let s = render(&[c]);
        assert!(
            s.contains("| (diagnostic) the simulator against itself from a start moved by 1 µm | 30.0 mm (p95 56.5; 100 iterations) | — |"),
            "{s}"
        );
    }

    #[test]
    fn the_state_drift_is_shown_as_a_diagnostic() {
        let mut c = check(1.0, 0.0, 0.0);
        c.motion.measures.drift = Some(neural_cloth_train::compare::StateDrift {
            window_frames: 63,
            mean_mm: 7.6,
            max_frame_mm: 9.0,
            height_mm: 7.2,
        });
        let mut s = String::new();
        render_training_checks(&mut s, &[c]);
        assert!(
            s.contains("| (diagnostic) GRU state drift, carried against windowed | 7.6 mm (worst frame 9.0, height +7.2; window 63 frames) | — |"),
            "{s}"
        );
    }

    #[test]
    fn no_checks_render_nothing() {
        let mut s = String::new();
        render_training_checks(&mut s, &[]);
        assert!(s.is_empty());
    }

    #[test]
    fn a_distance_just_over_its_target_does_not_read_as_the_target() {
        assert_eq!(mm_against(2.0206, STILL_DISTANCE_MM), "2.02 mm");
        assert_eq!(mm_against(1.97, STILL_DISTANCE_MM), "2.0 mm");
        assert_eq!(mm_against(2.3, STILL_DISTANCE_MM), "2.3 mm");
        assert_eq!(mm_against(18.75, SPIN_DISTANCE_MM), "18.8 mm");
    }
}
