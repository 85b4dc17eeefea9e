//! Curve data for the metric panel: which metric, which split, which x axis, taken from the
//! trainer's [`MetricHistory`] (filled from `TrainEvent::Step` / `TrainEvent::Validation`).

pub use neural_cloth_train::metrics::{MetricHistory, MetricRecord};

use super::curve_math;

/// Largest number of points drawn per curve; longer histories are thinned evenly.
pub const MAX_PLOT_POINTS: usize = 2000;

/// Which data split a curve shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Split {
    /// Training batches.
    Train,
    /// Held-out validation sequences.
    Validation,
}

/// The metrics shown in the curve panel (paper §4.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Metric {
    /// Mean edge elongation / strain, dimensionless.
    Strain,
    /// Mean dihedral-angle error, radians.
    Bending,
    /// Share of garment vertices inside the body, percent.
    Collision,
    /// Gravitational potential energy, joules.
    Gravity,
    /// Inertia term, joules.
    Inertia,
    /// Dead ReLU units of the worst layer, percent (validation passes only).
    DeadUnits,
}

impl Metric {
    /// All metrics in display order.
    pub const ALL: [Metric; 6] = [
        Metric::Strain,
        Metric::Bending,
        Metric::Collision,
        Metric::Gravity,
        Metric::Inertia,
        Metric::DeadUnits,
    ];

    /// Label with unit, for legends and titles.
    pub fn label(self) -> &'static str {
        match self {
            Metric::Strain => "strain",
            Metric::Bending => "bending (rad)",
            Metric::Collision => "collision (%)",
            Metric::Gravity => "gravity (J)",
            Metric::Inertia => "inertia (J)",
            Metric::DeadUnits => "dead units (%)",
        }
    }

    /// The value of this metric in `record`.
    pub fn value(self, record: &MetricRecord) -> f64 {
        match self {
            Metric::Strain => record.strain,
            Metric::Bending => record.bending,
            Metric::Collision => record.collision_pct,
            Metric::Gravity => record.gravity,
            Metric::Inertia => record.inertia,
            Metric::DeadUnits => record.dead_units_pct,
        }
    }
}

/// The x axis of the curves.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum XAxis {
    /// Optimiser step.
    #[default]
    Step,
    /// Wall-clock seconds of training.
    WallClock,
}

/// Records of `split`.
pub fn records(history: &MetricHistory, split: Split) -> &[MetricRecord] {
    match split {
        Split::Train => &history.train,
        Split::Validation => &history.validation,
    }
}

/// `[x, y]` points of `metric` on `split` against `x_axis`, thinned to at most
/// [`MAX_PLOT_POINTS`] (always keeping the latest); non-finite values are skipped.
pub fn series(
    history: &MetricHistory,
    split: Split,
    metric: Metric,
    x_axis: XAxis,
) -> Vec<[f64; 2]> {
    let all = records(history, split);
    let stride = all.len().div_ceil(MAX_PLOT_POINTS).max(1);
    let last = all.len().saturating_sub(1);
    all.iter()
        .enumerate()
        .filter(|(k, _)| k % stride == 0 || *k == last)
        .filter_map(|(_, r)| {
            let x = match x_axis {
                XAxis::Step => r.step as f64,
                XAxis::WallClock => r.wall_secs,
            };
            let y = metric.value(r);
            (x.is_finite() && y.is_finite()).then_some([x, y])
        })
        .collect()
}

/// A setting changed during training (fabric, window, learning rate), drawn as a labelled
/// vertical line on the curves.
#[derive(Clone, Debug, PartialEq)]
pub struct SettingMarker {
    /// Optimiser step at which the trainer applied the change.
    pub step: u64,
    /// Wall-clock seconds of training at that step.
    pub wall_secs: f64,
    /// What changed, e.g. `fabric`, `window 0.8 s`, `learning rate 5.0e-4`.
    pub name: String,
}

impl SettingMarker {
    /// Position of the marker on `x_axis`.
    pub fn x(&self, x_axis: XAxis) -> f64 {
        match x_axis {
            XAxis::Step => self.step as f64,
            XAxis::WallClock => self.wall_secs,
        }
    }
}

/// Changes of the same setting closer than this many steps share one marker (dragging the
/// window slider sends a change every frame).
pub const MARKER_MERGE_STEPS: u64 = 50;

/// Records `marker`: replaces the last marker when it is of the same setting (same first word,
/// e.g. `window`) and fewer than [`MARKER_MERGE_STEPS`] steps earlier, appends it otherwise.
pub fn push_marker(markers: &mut Vec<SettingMarker>, marker: SettingMarker) {
    let setting = |m: &SettingMarker| m.name.split_whitespace().next().map(str::to_owned);
    if let Some(last) = markers.last_mut()
        && setting(last) == setting(&marker)
        && marker.step.saturating_sub(last.step) < MARKER_MERGE_STEPS
    {
        *last = marker;
        return;
    }
    markers.push(marker);
}

/// One metric's curves ready to draw: raw per-step values, their smoothed line, validation
/// points, all in plot coordinates (`log10` of the value when [`PreparedCurve::log`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PreparedCurve {
    /// Raw training values, thinned to [`MAX_PLOT_POINTS`].
    pub raw: Vec<[f64; 2]>,
    /// Centred exponential average of the training values (time constant in steps).
    pub smooth: Vec<[f64; 2]>,
    /// Validation values (one per pass).
    pub validation: Vec<[f64; 2]>,
    /// The y values are `log10` of the metric.
    pub log: bool,
    /// The y range to show (warm-up left out, robust to spikes), in plot coordinates.
    pub y_range: Option<(f64, f64)>,
}

/// Records of `split` with a finite `metric` value: `(step, x, value)`.
fn finite_points(
    history: &MetricHistory,
    split: Split,
    metric: Metric,
    x_axis: XAxis,
) -> Vec<(f64, f64, f64)> {
    records(history, split)
        .iter()
        .filter_map(|r| {
            let x = match x_axis {
                XAxis::Step => r.step as f64,
                XAxis::WallClock => r.wall_secs,
            };
            let y = metric.value(r);
            (x.is_finite() && y.is_finite()).then_some((r.step as f64, x, y))
        })
        .collect()
}

/// Evenly thins `points` to at most [`MAX_PLOT_POINTS`], keeping the last one.
fn thin(points: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    let stride = points.len().div_ceil(MAX_PLOT_POINTS).max(1);
    let last = points.len().saturating_sub(1);
    points
        .into_iter()
        .enumerate()
        .filter(|(k, _)| k % stride == 0 || *k == last)
        .map(|(_, p)| p)
        .collect()
}

/// Prepares `metric`'s curves: the training values smoothed with [`curve_math::centred_ema`] (a time
/// constant of [`curve_math::smoothing_steps`]), validation as is, on a log axis when
/// `allow_log` and the values after the warm-up span more than a decade, and a y range that
/// ignores the first [`curve_math::warmup_records`] training records and their validation
/// passes. Dead units are measured on validation passes only, so they have no training curve.
pub fn prepare_curve(
    history: &MetricHistory,
    metric: Metric,
    x_axis: XAxis,
    allow_log: bool,
) -> PreparedCurve {
    let train = if metric == Metric::DeadUnits {
        Vec::new()
    } else {
        finite_points(history, Split::Train, metric, x_axis)
    };
    let validation = finite_points(history, Split::Validation, metric, x_axis);
    let steps: Vec<f64> = train.iter().map(|p| p.0).collect();
    let values: Vec<f64> = train.iter().map(|p| p.2).collect();
    let total = steps.last().copied().unwrap_or(0.0) - steps.first().copied().unwrap_or(0.0);
    let smooth = curve_math::centred_ema(&steps, &values, curve_math::smoothing_steps(total));
    let skip = curve_math::warmup_records(train.len());
    let cutoff = train.get(skip).map_or(f64::NEG_INFINITY, |p| p.0);
    let late_val: Vec<f64> = validation
        .iter()
        .filter(|p| p.0 >= cutoff)
        .map(|p| p.2)
        .collect();
    let late_raw = values.get(skip..).unwrap_or(&[]);
    // The smoothed line is an average of the raw values, so their percentiles cover it, bar
    // the decaying tail of a spike, which must not set the scale either.
    let log = allow_log && {
        let mut all = late_raw.to_vec();
        all.extend(&late_val);
        curve_math::spans_decades(&all)
    };
    let to_y = |v: f64| if log { v.log10() } else { v };
    let map = |v: &[f64]| v.iter().map(|&y| to_y(y)).collect::<Vec<_>>();
    let y_range = curve_math::robust_range(&map(late_raw), &map(&late_val));
    let finite = |mut v: Vec<[f64; 2]>| {
        v.retain(|p| p[1].is_finite());
        v
    };
    PreparedCurve {
        raw: thin(finite(train.iter().map(|p| [p.1, to_y(p.2)]).collect())),
        smooth: thin(finite(
            train
                .iter()
                .zip(&smooth)
                .filter(|(_, s)| s.is_finite())
                .map(|(p, s)| [p.1, to_y(*s)])
                .collect(),
        )),
        validation: finite(validation.iter().map(|p| [p.1, to_y(p.2)]).collect()),
        log,
        y_range,
    }
}

/// The validation loss trend of `history` (see [`curve_math::validation_trend`]).
pub fn loss_trend(history: &MetricHistory) -> Option<curve_math::TrendReport> {
    let losses: Vec<f64> = history.validation.iter().map(|r| r.loss).collect();
    curve_math::validation_trend(&losses)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(step: u64) -> MetricRecord {
        MetricRecord {
            step,
            wall_secs: step as f64 * 0.5,
            strain: 1.0 / (step as f64 + 1.0),
            collision_pct: f64::NAN,
            ..Default::default()
        }
    }

    #[test]
    fn series_follow_the_chosen_axis_and_skip_nan() {
        let mut h = MetricHistory::default();
        h.train.extend((0..4).map(record));
        h.validation.push(record(10));
        assert_eq!(
            series(&h, Split::Train, Metric::Strain, XAxis::Step)[1],
            [1.0, 0.5]
        );
        assert_eq!(
            series(&h, Split::Train, Metric::Strain, XAxis::WallClock)[2],
            [1.0, 1.0 / 3.0]
        );
        assert!(series(&h, Split::Train, Metric::Collision, XAxis::Step).is_empty());
        assert_eq!(
            series(&h, Split::Validation, Metric::Strain, XAxis::Step).len(),
            1
        );
    }

    #[test]
    fn long_histories_are_thinned_but_keep_the_ends() {
        let mut h = MetricHistory::default();
        h.train.extend((0..10_001).map(record));
        let s = series(&h, Split::Train, Metric::Strain, XAxis::Step);
        assert!(s.len() <= MAX_PLOT_POINTS + 1, "{}", s.len());
        assert_eq!(s.first().map(|p| p[0]), Some(0.0));
        assert_eq!(s.last().map(|p| p[0]), Some(10_000.0));
    }
    #[test]
    fn an_early_spike_does_not_set_the_range_and_decades_go_log() {
        let mut h = MetricHistory::default();
        for step in 1..=400u64 {
            let s = step as f64;
            h.train.push(MetricRecord {
                step,
                wall_secs: s * 0.1,
                strain: if step == 10 {
                    3.0
                } else {
                    0.02 + 0.005 * (s * 0.7).sin()
                },
                collision_pct: 25.0 * (-s / 40.0).exp() + 0.05,
                ..Default::default()
            });
            if step % 50 == 0 {
                h.validation.push(MetricRecord {
                    step,
                    strain: 0.025,
                    loss: 1.0 / s,
                    dead_units_pct: 10.0,
                    ..Default::default()
                });
            }
        }
        let strain = prepare_curve(&h, Metric::Strain, XAxis::Step, true);
        assert!(!strain.log);
        let (lo, hi) = strain.y_range.unwrap();
        assert!(hi < 0.05 && lo > 0.0, "{lo}..{hi}");
        assert_eq!(strain.raw.len(), 400);
        assert_eq!(strain.smooth.len(), 400);
        assert_eq!(strain.validation.len(), 8);
        let collision = prepare_curve(&h, Metric::Collision, XAxis::Step, true);
        assert!(collision.log);
        let (lo, hi) = collision.y_range.unwrap();
        assert!(lo < -1.0 && hi > 0.5, "{lo}..{hi}");
        assert!(!prepare_curve(&h, Metric::Collision, XAxis::Step, false).log);
        let dead = prepare_curve(&h, Metric::DeadUnits, XAxis::Step, true);
        assert!(dead.raw.is_empty() && dead.validation.len() == 8);
        assert_eq!(
            loss_trend(&h).map(|r| r.trend),
            Some(curve_math::Trend::Improving)
        );
    }

    #[test]
    fn a_dragged_slider_leaves_one_marker() {
        let marker = |step, name: &str| SettingMarker {
            step,
            wall_secs: 0.0,
            name: name.into(),
        };
        let mut markers = Vec::new();
        for (step, name) in [
            (100, "window 0.5 s"),
            (103, "window 0.6 s"),
            (110, "window 0.8 s"),
            (112, "fabric"),
            (300, "fabric"),
        ] {
            push_marker(&mut markers, marker(step, name));
        }
        let names: Vec<(u64, &str)> = markers.iter().map(|m| (m.step, m.name.as_str())).collect();
        assert_eq!(
            names,
            vec![(110, "window 0.8 s"), (112, "fabric"), (300, "fabric")]
        );
    }
}
