//! App layer: the eframe authoring app (wgpu backend). `neural-cloth` without a subcommand
//! opens it on the built-in default scene.
//!
//! - [`state::AppState`]: everything the app shows and edits, testable without a window.
//! - [`NeuralClothApp`]: the eframe `App`; its panels are `*_ui(&mut self, ui)` functions, one
//!   panel per `*_panel.rs` file, that only call into the state (no simulation or training
//!   logic here).
//! - [`viewport::Viewport`]: the 3D view, drawn by [`neural_cloth_render`] through an `egui_wgpu`
//!   paint callback into its own texture.
//! - Training runs on the trainer's thread ([`training::TrainingControl`]); the UI drains its
//!   events once per frame and never waits for it.

pub mod background;
pub mod confirm_panel;
pub mod cost;
pub mod cost_panel;
pub mod curve_math;
pub mod effects_panel;
pub mod error;
pub mod export;
pub mod export_dialog;
pub mod export_service;
pub mod fabric_panel;
pub mod file_browser;
pub mod file_picker;
pub mod file_picker_panel;
pub mod fit;
pub mod fit_panel;
pub mod frame_builder;
pub mod menu_panel;
pub mod metrics;
pub mod motions_panel;
pub mod playback;
pub mod plot_panel;
pub mod preview;
pub mod project;
pub mod project_io;
pub mod project_v1;
pub mod runs;
pub mod runs_panel;
pub mod scene_edit;
pub mod scene_panel;
pub mod sim_check;
pub mod sim_check_panel;
pub mod state;
pub mod status_panel;
pub mod timeline_panel;
pub mod training;
pub mod training_panel;
pub mod viewport;

use std::path::PathBuf;
use std::sync::Arc;

pub use error::AppError;
pub use scene_edit::LoadKind;
pub use state::{AppState, SceneParts};
pub use training::{TrainerLauncher, TrainingControl, TrainingRequest, TrainingState};
pub use viewport::Viewport;

/// Start-up options of the app.
#[derive(Default)]
pub struct AppOptions {
    /// Project file to open at start.
    pub project: Option<PathBuf>,
    /// Starts training runs (None: the Train button reports that no trainer is available).
    pub launcher: Option<Box<dyn TrainerLauncher>>,
    /// Bakes and writes exports (None: the export dialog reports that export is unavailable).
    pub exporter: Option<Box<dyn export::Exporter>>,
    /// Where the recent-files list is kept (None: [`project::RecentFiles::default_store`]);
    /// the recent runs are kept beside it.
    pub recent_store: Option<PathBuf>,
    /// Which file dialog to use (default: the desktop's where there is one).
    pub file_dialog: file_picker::DialogMode,
}

/// The built-in default scene: the procedural mannequin, its t-shirt and motions
/// ([`neural_cloth_core::scene::SceneConfig::default_scene`], loaded by the io scene loader).
pub fn default_scene() -> anyhow::Result<SceneParts> {
    let config = neural_cloth_core::scene::SceneConfig::default_scene();
    let here = std::path::Path::new(".");
    let loaded = neural_cloth_core::io::scene_loader::load_scene(&config, here, here)
        .map_err(|e| anyhow::anyhow!("default scene: {e}"))?;
    Ok(SceneParts::from_scene(loaded.scene, config))
}

/// The eframe application.
pub struct NeuralClothApp {
    /// All editable state.
    pub state: AppState,
    /// The 3D viewport.
    pub viewport: Viewport,
    /// Show the metric curves panel.
    pub show_curves: bool,
    /// The accuracy/time experiment of the Cost panel.
    pub cost: cost::CostState,
    /// "Fit garment" running on its own thread.
    pub fit: fit::FitState,
    /// The export dialog's service: the exporter, the running export, the last outcome.
    pub export: export_service::ExportService,
    /// Scene revision the camera was framed for.
    framed_revision: u64,
    /// Repaint request handed to the trainer thread.
    notify: Arc<dyn Fn() + Send + Sync>,
    /// The file dialogs (desktop or in-app).
    pub picker: file_picker::FilePicker,
    /// The question being asked before quitting or resetting.
    pub confirm: Option<confirm_panel::Confirm>,
    /// Quitting was confirmed (or needed no question): the next close goes through.
    pub quit_confirmed: bool,
}

impl NeuralClothApp {
    /// Builds the app on the default scene. `render_state` is eframe's (or kittest's) wgpu
    /// state; without it the viewport shows a notice.
    pub fn new(
        ctx: &egui::Context,
        render_state: Option<&egui_wgpu::RenderState>,
        options: AppOptions,
    ) -> anyhow::Result<Self> {
        let parts = default_scene()?;
        let recent = project::RecentFiles::load(
            options
                .recent_store
                .or_else(project::RecentFiles::default_store),
        );
        let state = AppState::new(parts, TrainingControl::new(options.launcher), recent);
        let repaint_ctx = ctx.clone();
        let notify: Arc<dyn Fn() + Send + Sync> = Arc::new(move || repaint_ctx.request_repaint());
        let mut app = Self {
            state,
            viewport: Viewport::new(render_state),
            show_curves: true,
            cost: cost::CostState::default(),
            fit: fit::FitState::default(),
            export: export_service::ExportService::new(options.exporter.map(Arc::from)),
            framed_revision: 0,
            notify: notify.clone(),
            picker: file_picker::FilePicker::new(options.file_dialog),
            confirm: None,
            quit_confirmed: false,
        };
        app.state.preview.set_notify(notify.clone());
        app.state.runs.notify = Some(notify);
        app.state.mark_saved();
        if let Some(p) = options.project {
            app.state.open_project(&p);
        }
        Ok(app)
    }

    /// The repaint request the trainer calls after each event.
    pub fn notifier(&self) -> Arc<dyn Fn() + Send + Sync> {
        self.notify.clone()
    }

    /// Per-frame work that is not drawing: trainer events, finished background jobs,
    /// playback time.
    fn tick(&mut self, ui: &egui::Ui) {
        self.handle_close_request(ui);
        self.state.poll_training();
        self.state.poll_run_load();
        self.state.sync_retention();
        self.poll_jobs();
        let dt = ui.input(|i| i.stable_dt);
        self.state.advance(dt);
        if self.state.playback.playing || self.state.training.state().is_active() {
            ui.ctx().request_repaint();
        }
    }

    /// Collects the app's finished background jobs (fit, cost, simulation check, export),
    /// whether or not their panels are open.
    fn poll_jobs(&mut self) {
        if let Some(outcome) = self.fit.poll() {
            self.state.apply_fit(outcome);
        }
        self.cost.job.poll();
        self.cost.check.job.poll();
        self.export.poll(&mut self.state);
    }

    /// Lays out every panel and the viewport.
    pub fn root_ui(&mut self, ui: &mut egui::Ui) {
        self.tick(ui);
        egui::Panel::top("menu").show(ui, |ui| self.menu_ui(ui));
        egui::Panel::bottom("status").show(ui, |ui| self.status_ui(ui));
        egui::Panel::bottom("timeline").show(ui, |ui| self.timeline_ui(ui));
        egui::Panel::left("controls")
            .default_size(300.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| {
                    self.scene_ui(ui);
                    self.motions_ui(ui);
                    self.training_ui(ui);
                    self.runs_ui(ui);
                    self.fabric_ui(ui);
                    self.effects_ui(ui);
                    self.cost_ui(ui);
                });
            });
        if self.show_curves {
            egui::Panel::bottom("curves")
                .resizable(true)
                .default_size(170.0)
                .show(ui, |ui| self.plot_ui(ui));
        }
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE)
            .show(ui, |ui| self.viewport_ui(ui));
        self.export_ui(ui);
        self.file_picker_ui(ui);
        self.confirm_ui(ui);
    }

    /// The 3D viewport, framed on the scene whenever the scene changes.
    pub fn viewport_ui(&mut self, ui: &mut egui::Ui) {
        let (frame, revision) = self.state.scene_frame();
        if self.framed_revision != self.state.scene.revision {
            let rest = neural_cloth_render::SceneFrame {
                body: frame.body.clone(),
                garment: frame.garment.clone(),
                ..Default::default()
            };
            self.viewport.frame_scene(&rest);
            self.framed_revision = self.state.scene.revision;
        }
        self.viewport.ui(ui, &frame, revision, &self.state.draw);
    }
}

impl eframe::App for NeuralClothApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.root_ui(ui);
    }
}

/// Opens the app window (wgpu renderer) and runs until it closes.
pub fn run_app(options: AppOptions) -> anyhow::Result<()> {
    let native = eframe::NativeOptions {
        renderer: eframe::Renderer::Wgpu,
        viewport: egui::ViewportBuilder::default()
            .with_title("neural-cloth")
            .with_inner_size([1280.0, 800.0]),
        ..Default::default()
    };
    let mut options = Some(options);
    eframe::run_native(
        "neural-cloth",
        native,
        Box::new(move |cc| {
            let options = options.take().unwrap_or_default();
            let app = NeuralClothApp::new(&cc.egui_ctx, cc.wgpu_render_state.as_ref(), options)?;
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| anyhow::anyhow!("cannot open the window: {e}"))
}
