//! Whether a finished run's garment looks broken: its last validation metrics against limits
//! far above what healthy runs show, so that a run whose garment tore, crumpled or sank into
//! the body says so in its summary instead of finishing quietly.
//!
//! Healthy runs of the built-in garments (docs/TRAINING.md, rounds 1-13: t-shirt, skirt and
//! dress, every seed) end with a mean strain of 0.01-0.035, a mean bending error of
//! 0.05-0.25 rad and 0-0.02 % of the vertices inside the body. The limits sit about ten times
//! above the first two and well above the third.

use std::fmt;

use super::metrics::MetricRecord;

/// Limits of the health check; a metric above its limit (or not finite) marks the run broken.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HealthLimits {
    /// Mean edge strain, unitless, > 0; default 0.3 (healthy runs: 0.01-0.035).
    pub strain: f64,
    /// Mean dihedral-angle error against rest, radians, > 0; default 0.8 (healthy: 0.05-0.25).
    pub bending_rad: f64,
    /// Share of garment vertices inside the body, percent in (0, 100]; default 5 (healthy:
    /// below 0.02).
    pub collision_pct: f64,
}

impl Default for HealthLimits {
    fn default() -> Self {
        Self {
            strain: 0.3,
            bending_rad: 0.8,
            collision_pct: 5.0,
        }
    }
}

/// A metric of a finished run beyond its health limit.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Unhealthy {
    /// What is measured, in words ("mean strain").
    pub metric: &'static str,
    /// The run's value.
    pub value: f64,
    /// The limit it passed.
    pub limit: f64,
    /// What healthy runs show, in words.
    pub healthy: &'static str,
}

impl fmt::Display for Unhealthy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} {:.3} (limit {}; healthy runs {})",
            self.metric, self.value, self.limit, self.healthy
        )
    }
}

/// The metrics of `record` beyond `limits`, in the order strain, bending, collision; empty when
/// the garment looks healthy.
pub fn assess(record: &MetricRecord, limits: &HealthLimits) -> Vec<Unhealthy> {
    [
        ("mean strain", record.strain, limits.strain, "0.01-0.035"),
        (
            "mean bending error, rad",
            record.bending,
            limits.bending_rad,
            "0.05-0.25",
        ),
        (
            "vertices inside the body, %",
            record.collision_pct,
            limits.collision_pct,
            "below 0.02",
        ),
    ]
    .into_iter()
    // A value that is not finite is broken too.
    .filter(|(_, value, limit, _)| !value.is_finite() || value > limit)
    .map(|(metric, value, limit, healthy)| Unhealthy {
        metric,
        value,
        limit,
        healthy,
    })
    .collect()
}

/// One line for a summary: what looks broken and what to check, or `None` when nothing does.
pub fn verdict_line(problems: &[Unhealthy]) -> Option<String> {
    if problems.is_empty() {
        return None;
    }
    let list: Vec<String> = problems.iter().map(ToString::to_string).collect();
    Some(format!(
        "the trained garment looks broken: {}; check that the garment fits the avatar \
         (`neural-cloth fit`), that the scene pins what must hang (pinning), and the fabric's \
         stiffness",
        list.join(", ")
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn healthy() -> MetricRecord {
        MetricRecord {
            strain: 0.02,
            bending: 0.12,
            collision_pct: 0.01,
            gravity: 1.08,
            ..MetricRecord::default()
        }
    }

    #[test]
    fn a_healthy_run_passes_and_each_broken_metric_is_named() {
        let limits = HealthLimits::default();
        assert!(assess(&healthy(), &limits).is_empty());
        assert_eq!(verdict_line(&assess(&healthy(), &limits)), None);
        // The skirt that fell off the body in the issue-13 audit: strain 9.85 after 20 steps.
        let fallen = MetricRecord {
            strain: 9.8481,
            ..healthy()
        };
        let problems = assess(&fallen, &limits);
        assert_eq!(problems.len(), 1);
        assert_eq!(problems[0].metric, "mean strain");
        let line = verdict_line(&problems).unwrap();
        assert!(line.contains("mean strain 9.848 (limit 0.3"), "{line}");
        let crumpled = MetricRecord {
            bending: 1.2,
            collision_pct: 12.0,
            ..healthy()
        };
        let names: Vec<_> = assess(&crumpled, &limits)
            .iter()
            .map(|p| p.metric)
            .collect();
        assert_eq!(
            names,
            ["mean bending error, rad", "vertices inside the body, %"]
        );
    }

    #[test]
    fn a_metric_that_is_not_finite_is_broken() {
        let record = MetricRecord {
            bending: f64::NAN,
            ..healthy()
        };
        assert_eq!(assess(&record, &HealthLimits::default()).len(), 1);
    }
}
