//! Evaluation of a trained model on a data split: the fast inference engine plays each motion
//! of the split at the training rate, and the §4.2 metrics of every frame are averaged.

use serde::Serialize;

use neural_cloth_core::scene::config::Split;
use neural_cloth_physics::PhysicsTerms;
use neural_cloth_physics::metrics::sequence_metrics;

use super::metrics::MetricRecord;
use super::trained::TrainedModel;
use super::{BackendKind, TrainError, device_for};

/// Metrics of one motion.
#[derive(Clone, Debug, Serialize)]
pub struct MotionEval {
    /// Motion name.
    pub name: String,
    /// Frames evaluated (at the training rate).
    pub frames: usize,
    /// Mean metrics over the frames (inertia from the third frame on).
    pub metrics: MetricRecord,
}

/// Metrics of a split.
#[derive(Clone, Debug, Serialize)]
pub struct EvalReport {
    /// The split evaluated.
    pub split: Split,
    /// The dynamic weight used.
    pub w: f32,
    /// Per motion.
    pub motions: Vec<MotionEval>,
    /// Frame-weighted mean over all motions.
    pub mean: MetricRecord,
}

/// Evaluates `trained` on the motions of `split` at dynamic weight `w`.
pub fn evaluate(trained: &TrainedModel, split: Split, w: f32) -> Result<EvalReport, TrainError> {
    let scene = &trained.scene;
    let fps = trained.meta.training_fps;
    let device = device_for(BackendKind::Cpu, false);
    let terms = PhysicsTerms::new(&scene.garment, &scene.fabric, &scene.effects, &device)?;
    let mut motions = Vec::new();
    let mut all = Vec::new();
    for motion in scene.motions_in(split) {
        let motion = motion
            .resample(fps)
            .map_err(neural_cloth_model::ModelError::from)?;
        let mut engine = trained.garment_engine()?;
        let mut frames = Vec::with_capacity(motion.frames.len());
        for pose in &motion.frames {
            engine.step(pose, w)?;
            frames.push(engine.garment_positions().to_vec());
        }
        let bodies = trained.bodies_of(&motion)?;
        let per_frame = sequence_metrics(&terms, &frames, bodies.as_deref(), 1.0 / fps)?;
        let records: Vec<MetricRecord> = per_frame
            .iter()
            .map(|m| MetricRecord::from_metrics(scene.fabric.cloth_model, m, 0.0))
            .collect();
        let mut mean = MetricRecord::mean(&records);
        // Inertia exists from the third frame on: average it over those frames only.
        let with_inertia: Vec<f64> = per_frame.iter().filter_map(|m| m.inertia_j).collect();
        mean.inertia = with_inertia.iter().sum::<f64>() / with_inertia.len().max(1) as f64;
        mean.step = trained.step;
        all.extend(records.iter().copied().map(|mut r| {
            r.inertia = mean.inertia;
            r
        }));
        motions.push(MotionEval {
            name: motion.name.clone(),
            frames: frames.len(),
            metrics: mean,
        });
    }
    if motions.is_empty() {
        return Err(TrainError::Data(format!(
            "the scene has no motion in the {split:?} split"
        )));
    }
    let mut mean = MetricRecord::mean(&all);
    mean.step = trained.step;
    Ok(EvalReport {
        split,
        w,
        motions,
        mean,
    })
}
