//! Curve data for the metric panel: which metric, which split, which x axis, taken from the
//! trainer's [`MetricHistory`] (filled from `TrainEvent::Step` / `TrainEvent::Validation`).

pub use crate::train::metrics::{MetricHistory, MetricRecord};

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
}
