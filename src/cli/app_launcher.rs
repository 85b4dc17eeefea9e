//! Connects the app's training panel to the real trainer (`train::Trainer`).

use std::sync::Arc;

use neural_cloth::app::{TrainerLauncher, TrainingRequest};
use neural_cloth::model::{ClothNetConfig, DescriptorConfig};
use neural_cloth::scene::config::SceneConfig;
use neural_cloth::train::{RunLocation, TrainSetup, Trainer, TrainerHandle};

/// The scene description of an app request: the built-in scene with the loaded files in
/// place of its avatar, garment and motions (absolute paths).
fn scene_config_of(request: &TrainingRequest) -> SceneConfig {
    use neural_cloth::scene::config::{AvatarSource, GarmentSource, MotionSource, Split};
    let abs = |p: &std::path::Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let mut config = SceneConfig::default_scene();
    let sources = &request.sources;
    config.effects = request.scene.effects;
    config.training_fps = request.scene.training_fps;
    if let Some(a) = &sources.avatar {
        config.avatar = AvatarSource::File {
            path: abs(a),
            units: None,
        };
    }
    if let Some(g) = &sources.garment {
        config.garment = GarmentSource::File {
            path: abs(g),
            units: None,
            smoothing_passes: None,
        };
    }
    // A loaded avatar brings its own animations; loaded BVH motions come on top.
    let mut motion_files: Vec<&std::path::PathBuf> = sources.avatar.iter().collect();
    motion_files.extend(&sources.motions);
    if !motion_files.is_empty() {
        config.motions = motion_files
            .into_iter()
            .map(|m| MotionSource::File {
                path: abs(m),
                units: None,
                split: Split::Train,
                name: None,
                joint_map: None,
            })
            .collect();
    }
    config
}

/// Starts real training runs for the app.
pub struct RealLauncher;

impl TrainerLauncher for RealLauncher {
    fn launch(
        &mut self,
        request: TrainingRequest,
        notify: Arc<dyn Fn() + Send + Sync>,
    ) -> Result<TrainerHandle, String> {
        let scene = (*request.scene).clone();
        // The run stores its scene description so it can be evaluated and baked later; a
        // scene that no longer matches it is refused at load time (garment fingerprint).
        let scene_config = scene_config_of(&request);
        let setup = TrainSetup {
            scene,
            scene_config,
            train: request.config,
            model: ClothNetConfig::default(),
            descriptors: DescriptorConfig::default(),
            fabric: Some(request.fabric),
            location: RunLocation::NewUnder(request.run_dir),
        };
        Trainer::spawn(setup, Some(notify)).map_err(|e| e.to_string())
    }
}

/// Bakes and writes exports for the app's export dialog through the `bake` layer.
pub struct RealExporter;

impl neural_cloth::app::export::Exporter for RealExporter {
    fn export(
        &self,
        request: neural_cloth::app::export::ExportRequest,
        progress: &mut dyn FnMut(usize, usize) -> bool,
    ) -> Result<String, String> {
        use neural_cloth::bake::{BakeOptions, ModelSource, bake};
        use neural_cloth::model::{InferenceEngine, InferenceOptions};
        let weights = request
            .weights
            .ok_or("train a model first: there are no weights to bake with")?;
        let motion = request
            .avatar
            .motions
            .get(request.motion)
            .ok_or("no such motion")?
            .clone();
        let format = request.format.bake_format();
        // The model runs at the rate it was trained at; the bake resamples to `request.fps`.
        let train_fps = neural_cloth::train::TrainConfig::default().fps;
        let engine = InferenceEngine::from_scene(
            (*weights).clone(),
            &request.avatar,
            &request.garment,
            &DescriptorConfig::default(),
            train_fps,
            InferenceOptions {
                skin_body: false,
                ..Default::default()
            },
        )
        .map_err(|e| e.to_string())?;
        let mut source = ModelSource::new(engine, train_fps);
        let options = BakeOptions {
            format,
            out: request.path,
            fps: request.fps,
            w: request.w,
            include_body: request.include_body,
            preset: request.preset,
            ..Default::default()
        };
        let report = bake(
            &request.avatar,
            &request.garment,
            &motion,
            &mut source,
            &options,
            progress,
        )
        .map_err(|e| e.to_string())?;
        let mut outputs = report.outputs.clone();
        if request.rest_obj && request.format.is_point_cache() {
            let path = neural_cloth::app::export::rest_obj_path(&options.out);
            outputs.push(neural_cloth::app::export::write_rest_obj(
                &request.garment,
                request.preset,
                &path,
            )?);
        }
        let mut line = format!(
            "wrote {} frames to {}",
            report.frames,
            outputs
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        );
        if let (Some(t), Some(e)) = (report.morph_targets, report.max_error_m) {
            line.push_str(&format!(
                " ({t} morph targets, max error {:.2} mm)",
                e * 1e3
            ));
        }
        Ok(line)
    }
}
