//! The metric curves panel (egui_plot), live while training runs: each metric's raw per-step
//! values faint behind their smoothed line, validation passes as solid markers in a colour of
//! their own, a log axis for a metric spanning decades, a y range the first steps cannot set,
//! labelled vertical markers where a setting changed, an "improving / flat / diverging"
//! verdict on the validation loss, and the last check against simulation.

use egui_plot::{Line, LineStyle, MarkerShape, Plot, PlotPoint, Points, Text, VLine};

use super::NeuralClothApp;
use super::curve_math::{Trend, TrendReport};
use super::metrics::{Metric, PreparedCurve, SettingMarker, XAxis, loss_trend, prepare_curve};

/// Colour of each metric's curve, in [`Metric::ALL`] order.
pub const METRIC_COLORS: [egui::Color32; 6] = [
    egui::Color32::from_rgb(90, 170, 255),
    egui::Color32::from_rgb(250, 170, 60),
    egui::Color32::from_rgb(240, 90, 90),
    egui::Color32::from_rgb(120, 210, 120),
    egui::Color32::from_rgb(200, 130, 230),
    egui::Color32::from_rgb(160, 160, 160),
];

impl NeuralClothApp {
    /// Metric curves of the current run: the trend of the validation loss and the setting
    /// changes on top, then one small plot per shown metric (each with its own scale).
    pub fn plot_ui(&mut self, ui: &mut egui::Ui) {
        let curves = &mut self.state.curves;
        ui.horizontal_wrapped(|ui| {
            ui.strong("Metrics");
            for (k, metric) in Metric::ALL.iter().enumerate() {
                if let Some(shown) = curves.shown.get_mut(k) {
                    ui.checkbox(shown, metric.label());
                }
            }
        });
        ui.horizontal(|ui| {
            ui.checkbox(&mut curves.validation, "validation (dots)");
            ui.checkbox(&mut curves.log_scale, "log scale")
                .on_hover_text("plot a metric whose values span more than a decade on a log axis");
            ui.separator();
            ui.label("x axis:");
            ui.selectable_value(&mut curves.x_axis, XAxis::Step, "step");
            ui.selectable_value(&mut curves.x_axis, XAxis::WallClock, "wall-clock (s)");
        });
        let history = &self.state.training.history;
        if history.train.is_empty() && history.validation.is_empty() {
            ui.centered_and_justified(|ui| {
                ui.weak("No metrics yet: press Train.");
            });
            return;
        }
        let markers = &self.state.training.markers;
        ui.horizontal_wrapped(|ui| {
            trend_ui(ui, loss_trend(history));
            markers_ui(ui, markers);
        });
        if let Some(Ok(report)) = &self.cost.check.job.result {
            ui.weak(super::sim_check::check_summary(report))
                .on_hover_text("the last Check against simulation (Cost panel)");
        }
        let x_axis = curves.x_axis;
        let shown: Vec<(usize, Metric)> = Metric::ALL
            .iter()
            .copied()
            .enumerate()
            .filter(|(_, m)| curves.is_shown(*m))
            .collect();
        if shown.is_empty() {
            return;
        }
        let validation = curves.validation;
        let log_scale = curves.log_scale;
        ui.columns(shown.len(), |columns| {
            for (column, (k, metric)) in columns.iter_mut().zip(&shown) {
                let color = METRIC_COLORS
                    .get(*k)
                    .copied()
                    .unwrap_or(egui::Color32::GRAY);
                let curve = prepare_curve(history, *metric, x_axis, log_scale);
                let title = if curve.log {
                    format!("{} · log", metric.label())
                } else {
                    metric.label().to_string()
                };
                column.vertical_centered(|ui| ui.small(title));
                let style = CurveStyle {
                    color,
                    validation: validation.then(|| column.visuals().strong_text_color()),
                    marker: column.visuals().warn_fg_color,
                };
                metric_plot_ui(column, *metric, &curve, markers, x_axis, &style);
            }
        });
    }
}

/// Colours of one metric's plot.
struct CurveStyle {
    /// Training curves (raw faint, smoothed strong).
    color: egui::Color32,
    /// Validation markers; None hides validation.
    validation: Option<egui::Color32>,
    /// Setting-change markers.
    marker: egui::Color32,
}

/// Colour of a trend verdict.
fn trend_color(trend: Trend) -> egui::Color32 {
    match trend {
        Trend::Improving => egui::Color32::from_rgb(110, 200, 110),
        Trend::Flat => egui::Color32::from_rgb(170, 170, 170),
        Trend::Diverging => egui::Color32::from_rgb(240, 90, 90),
    }
}

/// The indicator line for a validation trend, e.g. "validation loss: improving (-12 % over
/// the last 8 passes)".
pub fn trend_text(report: Option<TrendReport>) -> String {
    match report {
        Some(r) => format!(
            "validation loss: {} ({:+.0} % over the last {} passes)",
            r.trend.label(),
            100.0 * r.relative_change,
            r.passes
        ),
        None => "validation loss: too few passes for a trend".to_string(),
    }
}

/// The "improving / flat / diverging" indicator.
fn trend_ui(ui: &mut egui::Ui, report: Option<TrendReport>) {
    let text = trend_text(report);
    let hover = "robust line fit through the latest validation passes, compared with their noise";
    match report {
        Some(r) => ui.colored_label(trend_color(r.trend), text),
        None => ui.weak(text),
    }
    .on_hover_text(hover);
}

/// Most setting changes listed above the plots (the plots mark them all).
const LISTED_MARKERS: usize = 6;

/// The list of the latest setting changes, e.g. "changed: fabric at step 120".
fn markers_ui(ui: &mut egui::Ui, markers: &[SettingMarker]) {
    if markers.is_empty() {
        return;
    }
    ui.separator();
    ui.weak("changed:");
    let skipped = markers.len().saturating_sub(LISTED_MARKERS);
    if skipped > 0 {
        ui.weak(format!("{skipped} earlier,"));
    }
    for m in markers.iter().skip(skipped) {
        ui.small(format!("{} at step {}", m.name, m.step));
    }
}

/// A value of a log axis (`log10` of the metric) as the metric's value.
fn log_tick(log10: f64) -> String {
    let v = 10f64.powf(log10);
    if (0.01..10_000.0).contains(&v) {
        format!("{}", (v * 1000.0).round() / 1000.0)
    } else {
        format!("{v:.0e}")
    }
}

/// One metric's plot: raw faint, smoothed strong, validation as solid dots, setting changes as
/// labelled vertical lines; the y range is the curve's robust one.
fn metric_plot_ui(
    ui: &mut egui::Ui,
    metric: Metric,
    curve: &PreparedCurve,
    markers: &[SettingMarker],
    x_axis: XAxis,
    style: &CurveStyle,
) {
    let height = ui.available_height().max(40.0);
    let mut plot = Plot::new(metric.label())
        .height(height)
        .y_axis_min_width(28.0)
        .allow_scroll(false)
        .allow_drag([true, false])
        .allow_zoom([true, false]);
    if curve.log {
        plot = plot.y_axis_formatter(|mark, _| log_tick(mark.value));
    }
    let y_range = curve.y_range;
    plot.show(ui, |plot| {
        if let Some((lo, hi)) = y_range {
            plot.set_plot_bounds_y(lo..=hi);
        }
        plot.line(
            Line::new("train (raw)", curve.raw.clone())
                .color(style.color.gamma_multiply(0.3))
                .width(1.0),
        );
        plot.line(
            Line::new("train (smoothed)", curve.smooth.clone())
                .color(style.color)
                .width(2.0),
        );
        if let Some(color) = style.validation
            && !curve.validation.is_empty()
        {
            // Solid, not dashed: egui_plot cuts a dashed line into dashes before clipping it to
            // the plot, so a validation value far outside a flat curve's narrow y range (a
            // tiny run whose logged inertia is all zero) became millions of dashes and
            // gigabytes of shapes (the app's tests were killed for memory).
            plot.line(
                Line::new("validation", curve.validation.clone())
                    .color(color.gamma_multiply(0.6))
                    .width(1.0),
            );
            plot.points(
                Points::new("validation", curve.validation.clone())
                    .color(color)
                    .shape(MarkerShape::Circle)
                    .filled(true)
                    .radius(3.0),
            );
        }
        let top = y_range.map_or(0.0, |(_, hi)| hi);
        for m in markers {
            let x = m.x(x_axis);
            plot.vline(
                VLine::new(m.name.clone(), x)
                    .color(style.marker)
                    .style(LineStyle::dashed_loose())
                    .width(1.0),
            );
            plot.text(
                Text::new(
                    m.name.clone(),
                    PlotPoint::new(x, top),
                    egui::RichText::new(format!(" {}", m.name)).small(),
                )
                .color(style.marker)
                .anchor(egui::Align2::LEFT_TOP),
            );
        }
    });
}
