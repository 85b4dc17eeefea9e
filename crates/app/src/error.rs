//! Errors of the app layer: what a user action or one of the app's background jobs can fail
//! with. The errors of the layers below pass through unchanged (their messages name the
//! file); the app's own say what to do. The UI shows them as text.

use std::path::PathBuf;

/// An app action or background job that failed.
#[derive(Debug, thiserror::Error)]
pub enum AppError {
    /// Reading a scene part, a garment or a mesh failed.
    #[error(transparent)]
    Io(#[from] neural_cloth_core::io::IoError),
    /// Writing an export file failed.
    #[error(transparent)]
    Export(#[from] neural_cloth_core::io::export::ExportError),
    /// A scene could not be assembled.
    #[error(transparent)]
    Scene(#[from] neural_cloth_core::scene::SceneError),
    /// The scene description does not describe a trainable scene.
    #[error(transparent)]
    Config(#[from] neural_cloth_core::scene::config::ConfigError),
    /// Training, a run folder or a comparison with the simulator failed.
    #[error(transparent)]
    Train(#[from] neural_cloth_train::TrainError),
    /// An inference engine could not be built.
    #[error(transparent)]
    Model(#[from] neural_cloth_model::ModelError),
    /// A bake failed.
    #[error(transparent)]
    Bake(#[from] neural_cloth_bake::BakeError),
    /// Fitting a garment failed.
    #[error(transparent)]
    Fit(#[from] neural_cloth_fit::FitError),
    /// The cost experiment failed.
    #[error(transparent)]
    Report(#[from] neural_cloth_lab::report::ReportError),
    /// A trainer snapshot's weights do not fit the scene shown.
    #[error("snapshot of step {step} does not fit the scene: {source}")]
    Snapshot {
        /// The snapshot's training step.
        step: u64,
        /// Why the engine refused it.
        #[source]
        source: neural_cloth_model::ModelError,
    },
    /// The viewport's collision points could not be queried on the posed body.
    #[error("collision query: {0}")]
    CollisionQuery(#[source] neural_cloth_physics::PhysicsError),
    /// A folder of the in-app file browser could not be listed.
    #[error("{source}: {}", path.display())]
    ReadFolder {
        /// The I/O error.
        #[source]
        source: std::io::Error,
        /// The folder.
        path: PathBuf,
    },
    /// A background thread could not be started.
    #[error("cannot start the thread {name}: {source}")]
    Thread {
        /// The thread's name.
        name: String,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// A background thread panicked.
    #[error("the {name} thread panicked")]
    Panicked {
        /// The thread's name.
        name: String,
    },
    /// A job of this kind runs already.
    #[error("{0} is already running")]
    AlreadyRunning(&'static str),
    /// The action needs something the app does not have (a garment, a training motion,
    /// trained weights, an exporter); says what to do.
    #[error("{0}")]
    Missing(&'static str),
}
