//! Metric records and their history over a run (train and validation), shared by the CLI
//! progress bar, the checkpoint files and the app's curves.

use serde::{Deserialize, Serialize};

use neural_cloth_physics::{ClothMetrics, ClothModel};

/// The paper's §4.2 metrics plus the total loss, at one moment of training.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MetricRecord {
    /// Optimiser step.
    pub step: u64,
    /// Seconds of training wall-clock time since the run started (pauses excluded).
    pub wall_secs: f64,
    /// Total loss (sum of the weighted terms).
    pub loss: f64,
    /// Cloth in-plane term: mean edge elongation or strain (unitless).
    pub strain: f64,
    /// Mean absolute dihedral error against rest, radians.
    pub bending: f64,
    /// Percentage of garment vertices inside the body, 0..=100.
    pub collision_pct: f64,
    /// Gravity potential energy per garment, joules.
    pub gravity: f64,
    /// Inertia term per garment, joules.
    pub inertia: f64,
    /// Bending as the official code defines it: plain mean over every pair of adjacent faces
    /// of the change of the unsigned angle between their normals, radians.
    #[serde(default)]
    pub paper_bending: f64,
    /// Baraff-Witkin stretch as the official code defines it: area-weighted mean of
    /// `| |w_u| - 1 | + | |w_v| - 1 |` on rest frames rotated onto `+Z`, unitless.
    #[serde(default)]
    pub paper_stretch: f64,
    /// Dead ReLU units, percent 0..=100, of the worst layer the stall remedy can revive (the
    /// decoder and the static encoder's hidden layers): units whose output is zero for every
    /// probe window. Measured on validation passes only (0 on training steps).
    #[serde(default)]
    pub dead_units_pct: f64,
    /// Friction dissipation per garment, joules (0 when the scene has no friction).
    #[serde(default)]
    pub friction: f64,
    /// Mean slip of the garment over the body where it touches, millimetres per frame (0 when
    /// not measured).
    #[serde(default)]
    pub slip_mm: f64,
}

impl MetricRecord {
    /// True when every value is finite.
    pub fn is_finite(&self) -> bool {
        [
            self.wall_secs,
            self.loss,
            self.strain,
            self.bending,
            self.collision_pct,
            self.gravity,
            self.inertia,
        ]
        .iter()
        .all(|v| v.is_finite())
    }

    /// `(name, value)` pairs of the §4.2 metrics, in display order.
    pub fn named(&self) -> [(&'static str, f64); 5] {
        [
            ("strain", self.strain),
            ("bending", self.bending),
            ("collision %", self.collision_pct),
            ("gravity", self.gravity),
            ("inertia", self.inertia),
        ]
    }
}

/// All metric records of a run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MetricHistory {
    /// One record per training step (or per logged step).
    pub train: Vec<MetricRecord>,
    /// One record per validation pass.
    pub validation: Vec<MetricRecord>,
}

impl MetricHistory {
    /// The step of the last training record, or 0.
    pub fn last_step(&self) -> u64 {
        self.train.last().map(|r| r.step).unwrap_or(0)
    }

    /// Drops every record after `step` (used when rolling back to a checkpoint).
    pub fn truncate_after(&mut self, step: u64) {
        self.train.retain(|r| r.step <= step);
        self.validation.retain(|r| r.step <= step);
    }
}

impl MetricRecord {
    /// The record of physics metrics `m` for a garment of cloth model `model` (the strain is
    /// the model's own in-plane measure: edge strain, Baraff-Witkin stretch or Green strain),
    /// with total loss `loss`. Step and time are left at zero for the caller.
    pub fn from_metrics(model: ClothModel, m: &ClothMetrics, loss: f64) -> Self {
        let strain = match model {
            ClothModel::MassSpring => m.edge_strain.abs(),
            ClothModel::BaraffWitkin => m.stretch,
            ClothModel::Stvk => m.green_strain,
        };
        Self {
            loss,
            strain,
            bending: m.bending_rad,
            collision_pct: m.collision_pct.unwrap_or(0.0),
            gravity: m.gravity_j,
            inertia: m.inertia_j.unwrap_or(0.0),
            paper_bending: m.paper_bending_rad,
            paper_stretch: m.paper_stretch,
            friction: m.friction_j.unwrap_or(0.0),
            slip_mm: m.slip_m.map_or(0.0, |s| 1e3 * s),
            ..Default::default()
        }
    }

    /// Field-wise mean of `records` (zero when empty).
    pub fn mean(records: &[MetricRecord]) -> Self {
        let n = records.len().max(1) as f64;
        let sum = |f: fn(&MetricRecord) -> f64| records.iter().map(f).sum::<f64>() / n;
        Self {
            step: records.last().map(|r| r.step).unwrap_or(0),
            wall_secs: records.last().map(|r| r.wall_secs).unwrap_or(0.0),
            loss: sum(|r| r.loss),
            strain: sum(|r| r.strain),
            bending: sum(|r| r.bending),
            collision_pct: sum(|r| r.collision_pct),
            gravity: sum(|r| r.gravity),
            inertia: sum(|r| r.inertia),
            paper_bending: sum(|r| r.paper_bending),
            paper_stretch: sum(|r| r.paper_stretch),
            dead_units_pct: sum(|r| r.dead_units_pct),
            friction: sum(|r| r.friction),
            slip_mm: sum(|r| r.slip_mm),
        }
    }
}
