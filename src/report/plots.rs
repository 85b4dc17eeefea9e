//! The report's figures as SVG text, drawn with plotters (text stays SVG `<text>`).
//!
//! A figure is a grid of panels; a panel is either line/point series on linear or log10 axes
//! (log axes plot `log10` of the data and label the ticks with the original values) or
//! horizontal bars.

use plotters::prelude::*;

use super::accuracy::Method;
use super::{Report, ReportError};

/// One data series of a panel.
#[derive(Clone, Debug, Default)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// `(x, y)` points in data units.
    pub points: Vec<(f64, f64)>,
    /// Palette index.
    pub color: usize,
    /// Draw a line through the points.
    pub line: bool,
    /// Draw a marker at each point.
    pub markers: bool,
}

/// What a panel shows.
#[derive(Clone, Debug)]
pub enum PanelKind {
    /// Series on x/y axes; `true` makes an axis log10.
    Lines {
        /// The series.
        series: Vec<Series>,
        /// Log10 x axis.
        log_x: bool,
        /// Log10 y axis.
        log_y: bool,
    },
    /// One horizontal bar per `(label, value)`.
    Bars(Vec<(String, f64)>),
}

/// One panel of a figure.
#[derive(Clone, Debug)]
pub struct Panel {
    /// Caption.
    pub title: String,
    /// X axis description.
    pub x_desc: String,
    /// Y axis description.
    pub y_desc: String,
    /// Content.
    pub kind: PanelKind,
}

fn plot_err(name: &str, e: impl std::fmt::Display) -> ReportError {
    ReportError::Plot {
        name: name.to_string(),
        reason: e.to_string(),
    }
}

fn color(i: usize) -> RGBColor {
    const C: [RGBColor; 8] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
    ];
    C[i % C.len()]
}

/// Nicely formatted tick value.
fn tick(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        format!("{v:.0e}")
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 1.0 {
        format!("{v:.3}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    } else {
        format!("{v:.4}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    }
}

/// `(lo, hi)` of `values` with 5% padding (a unit range around a single value).
fn padded(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let span = hi - lo;
    let pad = if span > 1e-12 {
        0.05 * span
    } else {
        0.5 * lo.abs().max(1e-3)
    };
    (lo - pad, hi + pad)
}

/// Draws `panels` in a grid of `cols` columns into an SVG of `size` pixels.
pub fn figure(
    name: &str,
    panels: &[Panel],
    cols: usize,
    size: (u32, u32),
) -> Result<String, ReportError> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| plot_err(name, e))?;
        let cols = cols.max(1);
        let rows = panels.len().div_ceil(cols).max(1);
        let areas = root.split_evenly((rows, cols));
        for (panel, area) in panels.iter().zip(areas.iter()) {
            match &panel.kind {
                PanelKind::Lines {
                    series,
                    log_x,
                    log_y,
                } => lines(name, area, panel, series, *log_x, *log_y)?,
                PanelKind::Bars(bars) => bars_panel(name, area, panel, bars)?,
            }
        }
        root.present().map_err(|e| plot_err(name, e))?;
    }
    Ok(svg)
}

fn lines<DB: DrawingBackend>(
    name: &str,
    area: &DrawingArea<DB, plotters::coord::Shift>,
    panel: &Panel,
    series: &[Series],
    log_x: bool,
    log_y: bool,
) -> Result<(), ReportError> {
    let tx = |v: f64| {
        if log_x {
            (v > 0.0).then(|| v.log10())
        } else {
            Some(v)
        }
    };
    let ty = |v: f64| {
        if log_y {
            (v > 0.0).then(|| v.log10())
        } else {
            Some(v)
        }
    };
    let mapped: Vec<Vec<(f64, f64)>> = series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .filter_map(|&(x, y)| Some((tx(x)?, ty(y)?)))
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .collect()
        })
        .collect();
    let (x0, x1) = padded(mapped.iter().flatten().map(|p| p.0));
    let (y0, y1) = padded(mapped.iter().flatten().map(|p| p.1));
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, ("sans-serif", 16))
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(56)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| plot_err(name, e))?;
    let fx = move |v: &f64| tick(if log_x { 10f64.powf(*v) } else { *v });
    let fy = move |v: &f64| tick(if log_y { 10f64.powf(*v) } else { *v });
    chart
        .configure_mesh()
        .x_desc(panel.x_desc.as_str())
        .y_desc(panel.y_desc.as_str())
        .x_labels(6)
        .y_labels(6)
        .x_label_formatter(&fx)
        .y_label_formatter(&fy)
        .label_style(("sans-serif", 11))
        .draw()
        .map_err(|e| plot_err(name, e))?;
    let mut labelled = false;
    for (s, pts) in series.iter().zip(&mapped) {
        let c = color(s.color);
        if s.line && pts.len() > 1 {
            let drawn = chart
                .draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(2)))
                .map_err(|e| plot_err(name, e))?;
            if !s.label.is_empty() {
                drawn.label(s.label.clone()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 16, y)], c.stroke_width(2))
                });
                labelled = true;
            }
        }
        if s.markers || pts.len() == 1 || !s.line {
            let drawn = chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 3, c.filled())))
                .map_err(|e| plot_err(name, e))?;
            let line_has_legend = s.line && pts.len() > 1;
            if !(s.label.is_empty() || line_has_legend) {
                drawn
                    .label(s.label.clone())
                    .legend(move |(x, y)| Circle::new((x + 8, y), 3, c.filled()));
                labelled = true;
            }
        }
    }
    if labelled {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.4))
            .label_font(("sans-serif", 11))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|e| plot_err(name, e))?;
    }
    Ok(())
}

fn bars_panel<DB: DrawingBackend>(
    name: &str,
    area: &DrawingArea<DB, plotters::coord::Shift>,
    panel: &Panel,
    bars: &[(String, f64)],
) -> Result<(), ReportError> {
    let top = bars
        .iter()
        .map(|b| b.1)
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max)
        .max(1e-9)
        * 1.1;
    let n = bars.len().max(1) as f64;
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, ("sans-serif", 16))
        .margin(8)
        .x_label_area_size(36)
        .y_label_area_size(170)
        .build_cartesian_2d(0.0..top, -0.5..n - 0.5)
        .map_err(|e| plot_err(name, e))?;
    let labels: Vec<String> = bars.iter().map(|b| b.0.clone()).collect();
    let fy = move |v: &f64| {
        let i = v.round();
        if (v - i).abs() < 1e-6 && i >= 0.0 {
            labels.get(i as usize).cloned().unwrap_or_default()
        } else {
            String::new()
        }
    };
    let fx = |v: &f64| tick(*v);
    chart
        .configure_mesh()
        .x_desc(panel.x_desc.as_str())
        .y_desc(panel.y_desc.as_str())
        .y_labels(bars.len().max(1) * 2 + 1)
        .x_labels(6)
        .y_label_formatter(&fy)
        .x_label_formatter(&fx)
        .disable_y_mesh()
        .label_style(("sans-serif", 11))
        .draw()
        .map_err(|e| plot_err(name, e))?;
    chart
        .draw_series(bars.iter().enumerate().map(|(i, (_, v))| {
            let y = i as f64;
            Rectangle::new([(0.0, y - 0.35), (v.max(0.0), y + 0.35)], color(0).filled())
        }))
        .map_err(|e| plot_err(name, e))?;
    Ok(())
}

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

fn lines_panel(
    title: &str,
    x: &str,
    y: &str,
    series: Vec<Series>,
    log_x: bool,
    log_y: bool,
) -> Panel {
    Panel {
        title: title.into(),
        x_desc: x.into(),
        y_desc: y.into(),
        kind: PanelKind::Lines {
            series,
            log_x,
            log_y,
        },
    }
}

fn series(
    label: impl Into<String>,
    points: Vec<(f64, f64)>,
    color: usize,
    line: bool,
    markers: bool,
) -> Series {
    Series {
        label: label.into(),
        points,
        color,
        line,
        markers,
    }
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
    let metric = |k: usize, rec: &crate::train::MetricRecord| {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_figure_is_svg_with_its_text() {
        let panels = [
            lines_panel(
                "a title",
                "x",
                "y",
                vec![series("s", vec![(1.0, 10.0), (10.0, 1.0)], 0, true, true)],
                true,
                true,
            ),
            Panel {
                title: "bars".into(),
                x_desc: "ms".into(),
                y_desc: String::new(),
                kind: PanelKind::Bars(vec![("one".into(), 2.0), ("two".into(), 3.0)]),
            },
        ];
        let svg = figure("test", &panels, 2, (600, 300)).unwrap();
        assert!(
            svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"),
            "{}",
            &svg[..60.min(svg.len())]
        );
        for text in ["a title", "bars", "one", "two"] {
            assert!(svg.contains(text), "missing {text}");
        }
        assert_eq!(tick(0.0), "0");
        assert_eq!(tick(2.5), "2.5");
        assert_eq!(tick(150.0), "150");
    }
}
