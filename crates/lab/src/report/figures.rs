//! The report's figures: which data goes into which panel of which SVG.

use super::accuracy::Method;
use super::plots::{Panel, PanelKind, Series, figure, lines_panel, series};
use super::{Report, ReportError};

/// Running mean of the y values over `window` points (centred), for noisy per-step curves.
fn smooth(points: &[(f64, f64)], window: usize) -> Vec<(f64, f64)> {
    let half = window / 2;
    (0..points.len())
        .map(|i| {
            let lo = i.saturating_sub(half);
            let hi = (i + half + 1).min(points.len());
            let ys: Vec<f64> = points
                .get(lo..hi)
                .unwrap_or_default()
                .iter()
                .map(|p| p.1)
                .filter(|y| y.is_finite())
                .collect();
            let x = points.get(i).map_or(0.0, |p| p.0);
            (x, ys.iter().sum::<f64>() / ys.len().max(1) as f64)
        })
        .collect()
}

/// Every figure of the report as `(file name, SVG text)`.
pub fn all_figures(r: &Report) -> Result<Vec<(String, String)>, ReportError> {
    let mut out = Vec::new();
    let a = &r.accuracy;
    // Accuracy against time.
    let sims: Vec<_> = a
        .points
        .iter()
        .filter(|p| p.method == Method::Simulator)
        .collect();
    let nets: Vec<_> = a
        .points
        .iter()
        .filter(|p| p.method == Method::Neural)
        .collect();
    let pick = |pts: &[&super::CostPoint], f: fn(&super::CostPoint) -> f64| {
        pts.iter()
            .map(|p| (p.ms_per_frame, f(p)))
            .collect::<Vec<_>>()
    };
    let accuracy = [
        lines_panel(
            "Error to the reference vs cost per frame",
            "ms per frame (log)",
            "vertex error, mm (log)",
            vec![
                series("simulator, mean", pick(&sims, |p| p.mean_mm), 0, true, true),
                series("simulator, p95", pick(&sims, |p| p.p95_mm), 5, true, true),
                series("network, mean", pick(&nets, |p| p.mean_mm), 1, false, true),
                series("network, p95", pick(&nets, |p| p.p95_mm), 3, false, true),
            ],
            true,
            true,
        ),
        lines_panel(
            "Eq. 8 residual vs cost per frame",
            "ms per frame (log)",
            "RMS residual / mean vertex weight (log)",
            vec![
                series("simulator", pick(&sims, |p| p.residual_rms), 0, true, true),
                series("network", pick(&nets, |p| p.residual_rms), 1, false, true),
                series(
                    "reference",
                    vec![(a.reference.ms_per_frame, a.reference.residual_rms)],
                    2,
                    false,
                    true,
                ),
            ],
            true,
            true,
        ),
    ];
    out.push((
        "accuracy_vs_time.svg".to_string(),
        figure("accuracy_vs_time", &accuracy, 2, (1200, 480))?,
    ));
    // Training curves of the default run.
    let metric = |k: usize, rec: &neural_cloth_train::MetricRecord| {
        rec.named().get(k).map(|n| n.1).unwrap_or(f64::NAN)
    };
    let names = [
        "strain",
        "bending (rad)",
        "collision (%)",
        "gravity (J)",
        "inertia (J)",
    ];
    let curves: Vec<Panel> = names
        .iter()
        .enumerate()
        .map(|(k, n)| {
            let train: Vec<(f64, f64)> = a
                .training
                .train
                .iter()
                .map(|rec| (rec.wall_secs, metric(k, rec)))
                .collect();
            let val: Vec<(f64, f64)> = a
                .training
                .validation
                .iter()
                .map(|rec| (rec.wall_secs, metric(k, rec)))
                .collect();
            let smoothed = smooth(&train, (train.len() / 40).max(1));
            lines_panel(
                n,
                "seconds of training",
                n,
                vec![
                    series("train (running mean)", smoothed, 7, true, false),
                    series("validation", val, 1, true, true),
                ],
                false,
                false,
            )
        })
        .collect();
    out.push((
        "training_curves.svg".to_string(),
        figure("training_curves", &curves, 3, (1350, 700))?,
    ));
    // Settings against cost.
    let bars = |f: fn(&super::SettingRow) -> f64| {
        r.settings
            .iter()
            .map(|s| (s.label.clone(), f(s)))
            .collect::<Vec<_>>()
    };
    let settings = [
        Panel {
            title: "Training step".into(),
            x_desc: "ms per step (median)".into(),
            y_desc: String::new(),
            kind: PanelKind::Bars(bars(|s| s.step_ms)),
        },
        Panel {
            title: "Inference".into(),
            x_desc: "frames per second (1 thread)".into(),
            y_desc: String::new(),
            kind: PanelKind::Bars(bars(|s| s.inference_fps())),
        },
    ];
    out.push((
        "settings_cost.svg".to_string(),
        figure("settings_cost", &settings, 2, (1300, 520))?,
    ));
    // Fig. 6: window and frame rate against the validation metrics over time.
    let curve = |group: &str, k: usize| -> Vec<Series> {
        r.settings
            .iter()
            .filter(|s| s.group == group || s.group == "baseline")
            .enumerate()
            .map(|(i, s)| {
                series(
                    s.label.clone(),
                    s.run
                        .validation
                        .iter()
                        .map(|v| (v.wall_secs, metric(k, v)))
                        .collect(),
                    i,
                    true,
                    true,
                )
            })
            .collect()
    };
    let fig6 = [
        lines_panel(
            "Window: validation inertia",
            "seconds of training",
            "inertia (J)",
            curve("window", 4),
            false,
            false,
        ),
        lines_panel(
            "Window: validation gravity",
            "seconds of training",
            "gravity (J)",
            curve("window", 3),
            false,
            false,
        ),
        lines_panel(
            "Frame rate: validation inertia",
            "seconds of training",
            "inertia (J)",
            curve("frame rate", 4),
            false,
            false,
        ),
        lines_panel(
            "Frame rate: validation gravity",
            "seconds of training",
            "gravity (J)",
            curve("frame rate", 3),
            false,
            false,
        ),
    ];
    out.push((
        "window_fps_curves.svg".to_string(),
        figure("window_fps_curves", &fig6, 2, (1200, 800))?,
    ));
    // Disentanglement.
    let d = &r.fidelity.disentanglement;
    let dis = [
        lines_panel(
            &format!("w sweep on the spin at {:.2} s", d.sweep_time_secs),
            "w",
            "mean displacement from w = 0, mm",
            vec![series(
                "ours",
                d.w.iter()
                    .zip(&d.displacement_mm)
                    .map(|(w, m)| (f64::from(*w), *m))
                    .collect(),
                1,
                true,
                true,
            )],
            false,
            false,
        ),
        lines_panel(
            "|z_D| after the body stops mid-spin",
            "seconds since the stop",
            "|z_D| (L2)",
            vec![series(
                "ours",
                d.decay
                    .iter()
                    .map(|(t, z)| (f64::from(*t), f64::from(*z)))
                    .collect(),
                0,
                true,
                true,
            )],
            false,
            false,
        ),
    ];
    out.push((
        "disentanglement.svg".to_string(),
        figure("disentanglement", &dis, 2, (1200, 460))?,
    ));
    // Skirt radius under the spin.
    let s = &r.fidelity.skirt;
    let radius = |v: &[f32]| {
        s.times
            .iter()
            .zip(v)
            .map(|(t, r)| (f64::from(*t), 1e3 * f64::from(*r)))
            .collect::<Vec<_>>()
    };
    let skirt = [lines_panel(
        "Hem radius about the body axis under the spin",
        "seconds",
        "mean hem radius, mm",
        vec![
            series("ours (w = 1)", radius(&s.ours_m), 1, true, false),
            series("SNUG-style", radius(&s.snug_m), 0, true, false),
            series("ours, static (w = 0)", radius(&s.static_m), 3, true, false),
            series(
                "SNUG-style, static (w = 0)",
                radius(&s.snug_static_m),
                4,
                true,
                false,
            ),
            series("skinned template", radius(&s.skinned_m), 7, true, false),
            series(
                format!("simulator {} it", s.reference_iterations),
                radius(&s.reference_m),
                2,
                true,
                false,
            ),
        ],
        false,
        false,
    )];
    out.push((
        "skirt_spin.svg".to_string(),
        figure("skirt_spin", &skirt, 1, (900, 480))?,
    ));
    // Fig. 7: ablation curves.
    let abl = |k: usize| -> Vec<Series> {
        r.fidelity
            .ablation
            .iter()
            .enumerate()
            .map(|(i, row)| {
                series(
                    row.label.clone(),
                    row.run
                        .validation
                        .iter()
                        .map(|v| (v.wall_secs, metric(k, v)))
                        .collect(),
                    i,
                    true,
                    true,
                )
            })
            .collect()
    };
    let ablation = [
        lines_panel(
            "Validation collisions",
            "seconds of training",
            "collision (%)",
            abl(2),
            false,
            false,
        ),
        lines_panel(
            "Validation inertia",
            "seconds of training",
            "inertia (J)",
            abl(4),
            false,
            false,
        ),
    ];
    out.push((
        "ablation_curves.svg".to_string(),
        figure("ablation_curves", &ablation, 2, (1200, 460))?,
    ));
    Ok(out)
}
