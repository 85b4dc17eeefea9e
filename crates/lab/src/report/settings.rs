//! Settings against cost: training frame rate (15/30/60 fps), temporal window (0.1/0.5/1 s,
//! paper Fig. 6), garment resolution and each declared scene effect switched off, each trained
//! for the same time from the same seed. Per setting: median training step time, inference
//! speed (pose to garment, one thread) and the validation metrics reached.

use serde::{Deserialize, Serialize};

use neural_cloth_core::scene::Scene;
use neural_cloth_core::scene::config::{GarmentSource, SceneConfig, Split};
use neural_cloth_train::{MetricRecord, TrainConfig};

use super::runs::{
    RunSpec, RunSummary, engine_for, interleaved_step_ms, median, poses_at, time_inference,
    train_run,
};
use super::{Progress, ProgressFn, ReportError, rebuild_at};

/// Settings of the sweep.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SettingsOptions {
    /// Wall-clock budget of the whole sweep, seconds; > 0.
    pub budget_secs: f64,
    /// Seed of every run.
    pub seed: u64,
}

/// One setting's cost and result.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SettingRow {
    /// "baseline", "frame rate", "window", "resolution" or "effects".
    pub group: String,
    /// What differs from the baseline, e.g. "60 fps" or "no collision".
    pub label: String,
    /// Garment vertices.
    pub vertices: usize,
    /// Training frame rate, fps.
    pub fps: f32,
    /// Temporal window, seconds.
    pub window_secs: f32,
    /// Frames per training window.
    pub window_frames: usize,
    /// Effects of the scene (gravity, bending, collision, dynamics).
    pub effects: [bool; 4],
    /// Median milliseconds per training step (measured round-robin over all settings).
    pub step_ms: f64,
    /// Median milliseconds per inferred frame (measured round-robin over all settings).
    pub inference_ms: f64,
    /// Metrics of the last validation pass.
    pub validation: MetricRecord,
    /// The run (with its validation curve).
    pub run: RunSummary,
}

impl SettingRow {
    /// Inferred frames per second.
    pub fn inference_fps(&self) -> f64 {
        if self.inference_ms > 0.0 {
            1e3 / self.inference_ms
        } else {
            0.0
        }
    }
}

/// Turns one effect off.
type SwitchOff = fn(&mut neural_cloth_core::scene::Effects);

struct Variant {
    group: &'static str,
    label: String,
    scene: Scene,
    /// Its description; the training rate is `scene.training_fps` (and the description's).
    config: Option<SceneConfig>,
    window_secs: f32,
}

/// The variants of `scene`: baseline, 15/60 fps, 0.1/1.0 s windows, ¼ and ½ resolution (built-in
/// garments only), and each declared effect off.
fn variants(scene: &Scene, config: &SceneConfig) -> Result<Vec<Variant>, ReportError> {
    let fps = scene.training_fps;
    let base = |group, label: String, mut scene: Scene, fps, window_secs| {
        let mut config = config.clone();
        scene.training_fps = fps;
        config.training_fps = fps;
        Variant {
            group,
            label,
            scene,
            config: Some(config),
            window_secs,
        }
    };
    let mut out = vec![base(
        "baseline",
        format!(
            "{fps} fps, 0.5 s, {} vertices",
            scene.garment.vertex_count()
        ),
        scene.clone(),
        fps,
        0.5,
    )];
    for f in [15.0f32, 60.0] {
        out.push(base(
            "frame rate",
            format!("{f} fps"),
            scene.clone(),
            f,
            0.5,
        ));
    }
    for w in [0.1f32, 1.0] {
        out.push(base(
            "window",
            format!("{w} s window"),
            scene.clone(),
            fps,
            w,
        ));
    }
    if let GarmentSource::Builtin { resolution, .. } = &config.garment {
        let mut sizes: Vec<usize> = [4usize, 2]
            .iter()
            .map(|d| {
                (resolution / d).max(neural_cloth_core::scene::procedural::garments::MIN_VERTICES)
            })
            .filter(|n| n < resolution)
            .collect();
        sizes.dedup();
        for n in sizes {
            let (s, c) = rebuild_at(config, Some(n))?;
            let label = format!("{} vertices", s.garment.vertex_count());
            out.push(Variant {
                group: "resolution",
                label,
                scene: s,
                config: Some(c),
                window_secs: 0.5,
            });
        }
    }
    let e = scene.effects;
    let switches: [(&str, bool, SwitchOff); 5] = [
        ("no gravity", e.gravity, |e| e.gravity = false),
        ("no bending", e.bending, |e| e.bending = false),
        ("no collision", e.collision, |e| e.collision = false),
        ("no dynamics", e.dynamics, |e| e.dynamics = false),
        ("no friction", e.friction, |e| e.friction = false),
    ];
    for (label, on, switch_off) in switches {
        if on {
            let mut s = scene.clone();
            switch_off(&mut s.effects);
            s.effects.drop_unmet_needs();
            let mut c = config.clone();
            switch_off(&mut c.effects);
            c.effects.drop_unmet_needs();
            out.push(Variant {
                group: "effects",
                label: label.into(),
                scene: s,
                config: Some(c),
                window_secs: 0.5,
            });
        }
    }
    Ok(out)
}

/// Runs every variant for an equal share of `options.budget_secs`. Step and inference times
/// are measured round-robin over all variants (so that a change of machine load during the
/// sweep affects them alike); the training runs give the metrics reached and their own step
/// counts. `progress` sees 0..1; returning false cancels.
pub fn run_settings(
    scene: &Scene,
    config: &SceneConfig,
    options: &SettingsOptions,
    progress: &mut ProgressFn<'_>,
) -> Result<Vec<SettingRow>, ReportError> {
    let started = std::time::Instant::now();
    let all = variants(scene, config)?;
    let n = all.len().max(1);
    let specs: Vec<RunSpec> = all
        .iter()
        .map(|v| RunSpec {
            label: v.label.clone(),
            scene: v.scene.clone(),
            config: v.config.clone(),
            train: TrainConfig {
                window_secs: v.window_secs,
                seed: options.seed,
                ..TrainConfig::default()
            },
            model: Default::default(),
            budget_secs: 0.0,
            min_steps: 2,
            validations: 6,
            snapshot_fractions: Vec::new(),
        })
        .collect();
    let mut say = |fraction: f64, detail: String| {
        progress(&Progress {
            phase: "settings".into(),
            fraction,
            detail,
        })
    };
    let step_ms = interleaved_step_ms(&specs, 3, 2, &mut |f| {
        say(0.1 * f, "timing training steps round-robin".into())
    })?;
    // Each run keeps ~8% of its share for preparing data and validation.
    let left = (options.budget_secs - started.elapsed().as_secs_f64()).max(0.0);
    let per_run = 0.92 * left / n as f64;
    let mut runs = Vec::with_capacity(n);
    for (k, mut spec) in specs.into_iter().enumerate() {
        spec.budget_secs = per_run;
        let label = spec.label.clone();
        let run = train_run(spec, &mut |f| {
            say(
                0.1 + 0.88 * (k as f64 + f) / n as f64,
                format!("training '{label}'"),
            )
        })?;
        runs.push(run);
    }
    if !say(0.98, "timing inference round-robin".into()) {
        return Err(ReportError::Cancelled);
    }
    let mut engines = Vec::with_capacity(n);
    for (v, run) in all.iter().zip(&runs) {
        let motion = [Split::Validation, Split::Train, Split::Test]
            .into_iter()
            .find_map(|s| v.scene.motions_in(s).next());
        let poses = motion
            .map(|m| {
                let fps = v.scene.training_fps;
                poses_at(m, fps, (fps as usize).max(10))
            })
            .unwrap_or_default();
        engines.push((engine_for(&run.weights, &v.scene)?, poses));
    }
    let mut inference: Vec<Vec<f64>> = vec![Vec::new(); n];
    for _ in 0..5 {
        for ((engine, poses), times) in engines.iter_mut().zip(inference.iter_mut()) {
            if !poses.is_empty() {
                times.push(time_inference(engine, poses, 40)?);
            }
        }
    }
    let mut rows = Vec::with_capacity(n);
    for (((v, run), step), times) in all.into_iter().zip(runs).zip(step_ms).zip(inference) {
        let effects = [
            v.scene.effects.gravity,
            v.scene.effects.bending,
            v.scene.effects.collision,
            v.scene.effects.dynamics,
        ];
        let fps = v.scene.training_fps;
        let window_frames = TrainConfig {
            window_secs: v.window_secs,
            ..TrainConfig::default()
        }
        .window_frames(fps);
        rows.push(SettingRow {
            group: v.group.into(),
            label: v.label,
            vertices: v.scene.garment.vertex_count(),
            fps,
            window_secs: v.window_secs,
            window_frames,
            effects,
            step_ms: step,
            inference_ms: median(&times),
            validation: run.validation,
            run: run.summary(),
        });
    }
    Ok(rows)
}
