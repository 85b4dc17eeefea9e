//! The report's figures as SVG text, drawn with plotters (text stays SVG `<text>`).
//!
//! A figure is a grid of panels; a panel is either line/point series on linear or log10 axes
//! (log axes plot `log10` of the data and label the ticks with the original values) or
//! horizontal bars. [`super::figures`] assembles the report's figures from these.

use plotters::prelude::*;

use super::ReportError;

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

/// Tick value on a linear axis spanning `span`: enough digits to tell ticks about a fifth of
/// the span apart.
fn tick_in(v: f64, span: f64) -> String {
    if !(span.is_finite() && span > 0.0) {
        return tick(v);
    }
    let step_exp = (span / 5.0).log10().floor() as i32;
    let a = v.abs();
    if a < 0.5 * 10f64.powi(step_exp) {
        return "0".into();
    }
    if (1e-3..1e5).contains(&a) || step_exp >= 0 {
        let decimals = (-step_exp).max(0) as usize;
        format!("{v:.decimals$}")
    } else {
        let digits = (a.log10().floor() as i32 - step_exp).clamp(0, 6) as usize;
        format!("{v:.digits$e}")
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
    let (span_x, span_y) = (x1 - x0, y1 - y0);
    let fx = move |v: &f64| {
        if log_x {
            tick(10f64.powf(*v))
        } else {
            tick_in(*v, span_x)
        }
    };
    let fy = move |v: &f64| {
        if log_y {
            tick(10f64.powf(*v))
        } else {
            tick_in(*v, span_y)
        }
    };
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

/// A panel of line/point series.
pub fn lines_panel(
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

/// A series of `(x, y)` points with palette colour `color`.
pub fn series(
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
        assert_eq!(tick_in(1.1031, 0.001), "1.1031");
        assert_eq!(tick_in(8.2e-5, 4e-6), "8.20e-5");
        assert_eq!(tick_in(20.0, 50.0), "20");
    }
}
