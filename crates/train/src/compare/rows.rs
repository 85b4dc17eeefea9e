//! The rows of a motion's comparison table, in display order: one home for what `compare`
//! prints and what the app's "Check against simulation" shows.

use super::MotionComparison;
use super::measure::{HemPair, MotionMeasures};
use super::spread::ReferenceSpread;

/// One row of the geometric table: a label with its unit and the values over all frames,
/// the still frames and the moving frames (`None`: not measured there).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeasureRow {
    /// What the row measures, with its unit ("distance mean, mm").
    pub label: &'static str,
    /// All frames, still frames, moving frames.
    pub values: [Option<f64>; 3],
    /// Decimals to show.
    pub decimals: usize,
}

/// One row of the metric table: the network's value beside the simulator's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MetricRow {
    /// What the row measures.
    pub label: &'static str,
    /// The network's value.
    pub network: f64,
    /// The simulator's value.
    pub simulator: f64,
    /// Decimals to show.
    pub decimals: usize,
}

impl MeasureRow {
    /// The three values with the row's decimals, a dash where not measured.
    pub fn cells(&self) -> [String; 3] {
        let d = self.decimals;
        self.values
            .map(|v| v.map_or_else(|| "—".into(), |v| format!("{v:.d$}")))
    }
}

fn row(label: &'static str, values: [Option<f64>; 3], decimals: usize) -> MeasureRow {
    MeasureRow {
        label,
        values,
        decimals,
    }
}

impl MotionMeasures {
    /// The geometric rows: distances, swings, the rigid split (all frames only: a frame's
    /// best rigid motion is fitted per frame), the GRU state's drift, the one-step check and
    /// the reference's spread (all frames only) and the hem radii (still and moving only).
    pub fn rows(&self) -> Vec<MeasureRow> {
        let mut rows = vec![
            row(
                "distance mean, mm",
                [
                    Some(self.all.mean_mm),
                    self.still.map(|d| d.mean_mm),
                    self.moving.map(|d| d.mean_mm),
                ],
                1,
            ),
            row(
                "distance p95, mm",
                [
                    Some(self.all.p95_mm),
                    self.still.map(|d| d.p95_mm),
                    self.moving.map(|d| d.p95_mm),
                ],
                1,
            ),
        ];
        for (label, a) in [
            ("swing network, mm", self.amplitude.network),
            ("swing simulator, mm", self.amplitude.simulator),
        ] {
            rows.push(row(label, [Some(a.all_mm), a.still_mm, a.moving_mm], 1));
        }
        if let Some(split) = &self.split {
            for (label, d) in [
                ("quasi-static distance, mm", split.quasi_static),
                ("motion distance, mm", split.motion),
            ] {
                rows.push(row(label, [Some(d.all_mm), d.still_mm, d.moving_mm], 1));
            }
        }
        if let Some(rigid) = &self.rigid {
            for (label, value) in [
                ("distance after rigid fit, mm", rigid.shape_distance_mm),
                ("slip network, mm", rigid.network_slip_mm),
                ("slip simulator, mm", rigid.simulator_slip_mm),
                ("shape swing network, mm", rigid.network_shape_swing_mm),
                ("shape swing simulator, mm", rigid.simulator_shape_swing_mm),
            ] {
                rows.push(row(label, [Some(value), None, None], 1));
            }
        }
        if let Some(drift) = &self.drift {
            for (label, value) in [
                ("state drift, mm", drift.mean_mm),
                ("state drift worst frame, mm", drift.max_frame_mm),
                ("state drift height, mm", drift.height_mm),
            ] {
                rows.push(row(label, [Some(value), None, None], 1));
            }
        }
        if let Some(step) = &self.one_step {
            rows.push(row(
                "one-step distance, mm",
                [Some(step.mean_mm), None, None],
                1,
            ));
            rows.push(row(
                "one-step shape, mm",
                [Some(step.shape_mm), None, None],
                1,
            ));
            rows.push(row(
                "one-step height, mm",
                [Some(step.height_mm), None, None],
                1,
            ));
            if let Some(turn) = step.turn_deg {
                rows.push(row(
                    "one-step turn with body, deg",
                    [Some(turn), None, None],
                    2,
                ));
            }
        }
        type Labels = [&'static str; 3];
        let others: [(Option<&ReferenceSpread>, Labels); 2] = [
            (
                self.spread.as_ref(),
                [
                    "reference spread, mm",
                    "reference spread p95, mm",
                    "reference spread after rigid fit, mm",
                ],
            ),
            (
                self.sensitivity.as_ref(),
                [
                    "reference sensitivity, mm",
                    "reference sensitivity p95, mm",
                    "reference sensitivity after rigid fit, mm",
                ],
            ),
        ];
        for (other, labels) in others {
            let Some(other) = other else { continue };
            let values = [Some(other.mean_mm), Some(other.p95_mm), other.shape_mm];
            for (label, value) in labels.into_iter().zip(values) {
                if let Some(value) = value {
                    rows.push(row(label, [Some(value), None, None], 1));
                }
            }
        }
        if let Some(hem) = &self.hem {
            type Radius = (&'static str, fn(&HemPair) -> f64);
            let radii: [Radius; 4] = [
                ("hem radius network, m", |h| h.network_m),
                ("hem radius simulator, m", |h| h.simulator_m),
                ("hem radius network w=0, m", |h| h.network_static_m),
                ("hem radius sim static, m", |h| h.simulator_static_m),
            ];
            for (label, pick) in radii {
                let values = [
                    None,
                    hem.still.as_ref().map(pick),
                    hem.moving.as_ref().map(pick),
                ];
                rows.push(row(label, values, 3));
            }
        }
        rows
    }
}

impl MotionComparison {
    /// The metric rows: the paper's metrics of both sides, the slip over the body, the
    /// training objective (pinning left out; inertia from each side's own history, so on
    /// still poses only a lower simulator value says the network's frames are not a minimum
    /// of the loss it was trained on) and, when either side has any, friction.
    pub fn metric_rows(&self) -> Vec<MetricRow> {
        let (net, sim) = (&self.metrics.network, &self.metrics.simulator);
        let mut rows: Vec<MetricRow> = net
            .named()
            .iter()
            .zip(sim.named())
            .map(|((label, network), (_, simulator))| MetricRow {
                label,
                network: *network,
                simulator,
                decimals: 4,
            })
            .collect();
        let mut push = |label, network, simulator, decimals| {
            rows.push(MetricRow {
                label,
                network,
                simulator,
                decimals,
            })
        };
        push("slip over the body, mm/frame", net.slip_mm, sim.slip_mm, 3);
        push("training objective, J", net.loss, sim.loss, 5);
        if net.friction != 0.0 || sim.friction != 0.0 {
            push("friction", net.friction, sim.friction, 6);
        }
        let (net, sim) = (&self.objective.network, &self.objective.simulator);
        if net.total() != 0.0 || sim.total() != 0.0 {
            for ((label, network), (_, simulator)) in net.named().into_iter().zip(sim.named()) {
                push(label, network, simulator, 6);
            }
        }
        rows
    }
}

#[cfg(test)]
mod tests {
    use super::super::measure::{Amplitude, AmplitudeStats, DistanceStats};
    use super::*;

    #[test]
    fn objective_rows_only_when_the_objective_was_split() {
        let mut c = MotionComparison {
            name: "spin".into(),
            measures: MotionMeasures::default(),
            metrics: Default::default(),
            objective: Default::default(),
            reference: Default::default(),
        };
        let plain = c.metric_rows().len();
        c.objective.simulator.fixed.collision_j = 0.0166;
        c.objective.network.inertia_j = 0.0245;
        let rows = c.metric_rows();
        assert_eq!(rows.len(), plain + 6, "one row per term");
        let collision = rows
            .iter()
            .find(|r| r.label == "objective: collision, J")
            .unwrap();
        assert_eq!((collision.network, collision.simulator), (0.0, 0.0166));
        let inertia = rows
            .iter()
            .find(|r| r.label == "objective: inertia, J")
            .unwrap();
        assert_eq!((inertia.network, inertia.simulator), (0.0245, 0.0));
    }

    #[test]
    fn rows_follow_what_was_measured() {
        let stats = DistanceStats {
            frames: 10,
            mean_mm: 2.0,
            p95_mm: 5.0,
        };
        let swing = AmplitudeStats {
            all_mm: 1.0,
            still_mm: None,
            moving_mm: Some(1.5),
        };
        let m = MotionMeasures {
            frames: 10,
            still_frames: 0,
            all: stats,
            still: None,
            moving: Some(stats),
            amplitude: Amplitude {
                network: swing,
                simulator: swing,
            },
            hem: None,
            rigid: None,
            split: None,
            drift: None,
            one_step: None,
            spread: None,
            sensitivity: None,
        };
        let rows = m.rows();
        assert_eq!(
            rows.len(),
            4,
            "no rigid split and no hem: distances and swings"
        );
        assert_eq!(rows[0].values, [Some(2.0), None, Some(2.0)]);
        assert_eq!(rows[1].label, "distance p95, mm");
        assert_eq!(rows[3].values, [Some(1.0), None, Some(1.5)]);
        assert_eq!(rows[3].cells(), ["1.0", "—", "1.5"]);
        let split = MotionMeasures {
            split: Some(super::super::StaticMotionSplit {
                quasi_static: swing,
                motion: AmplitudeStats {
                    all_mm: 3.0,
                    still_mm: None,
                    moving_mm: Some(3.5),
                },
            }),
            ..m
        };
        let rows = split.rows();
        assert_eq!(rows.len(), 6, "the split adds two rows after the swings");
        assert_eq!(rows[4].label, "quasi-static distance, mm");
        assert_eq!(rows[5].cells(), ["3.0", "—", "3.5"]);
        let drifting = MotionMeasures {
            drift: Some(super::super::StateDrift {
                window_frames: 18,
                mean_mm: 7.6,
                max_frame_mm: 9.0,
                height_mm: 7.2,
            }),
            ..m
        };
        let rows = drifting.rows();
        assert_eq!(rows.len(), 7, "the drift adds three rows");
        assert_eq!(rows[4].label, "state drift, mm");
        assert_eq!(rows[6].cells(), ["7.2", "—", "—"]);
        let stepped = MotionMeasures {
            one_step: Some(super::super::OneStep {
                frames: 8,
                mean_mm: 7.8,
                shape_mm: 7.1,
                height_mm: 1.2,
                turn_deg: Some(-0.46),
            }),
            ..m
        };
        let rows = stepped.rows();
        assert_eq!(rows.len(), 8, "the one-step check adds four rows");
        assert_eq!(rows[4].label, "one-step distance, mm");
        assert_eq!(rows[7].cells(), ["-0.46", "—", "—"]);
        let spread = MotionMeasures {
            spread: Some(super::super::ReferenceSpread {
                iterations: 200,
                start_jitter_m: 0.0,
                mean_mm: 17.1,
                p95_mm: 67.9,
                shape_mm: Some(7.6),
            }),
            ..m
        };
        let rows = spread.rows();
        assert_eq!(rows.len(), 7, "the spread adds three rows");
        assert_eq!(rows[4].label, "reference spread, mm");
        assert_eq!(rows[6].cells(), ["7.6", "—", "—"]);
        let both = MotionMeasures {
            sensitivity: spread.spread.map(|s| super::super::ReferenceSpread {
                start_jitter_m: 1e-6,
                mean_mm: 30.2,
                ..s
            }),
            ..spread
        };
        let rows = both.rows();
        assert_eq!(
            rows.len(),
            10,
            "the sensitivity adds three rows after the spread"
        );
        assert_eq!(rows[7].label, "reference sensitivity, mm");
        assert_eq!(rows[7].cells(), ["30.2", "—", "—"]);
        let still_body = MotionMeasures {
            one_step: stepped.one_step.map(|s| super::super::OneStep {
                turn_deg: None,
                ..s
            }),
            ..m
        };
        assert_eq!(
            still_body.rows().len(),
            7,
            "no turn row when the body does not turn"
        );
    }
}
