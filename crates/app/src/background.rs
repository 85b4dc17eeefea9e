//! A cancellable job on a named background thread with shared progress, for the panels that
//! run long computations (the Cost experiment, "Check against simulation").

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use super::error::AppError;

/// Reports progress `P` to the UI; returns false once the user cancelled.
pub struct Reporter<P> {
    progress: Arc<Mutex<P>>,
    cancel: Arc<AtomicBool>,
    notify: Arc<dyn Fn() + Send + Sync>,
}

impl<P> Reporter<P> {
    /// Stores `now`, asks for a repaint, and says whether to go on.
    pub fn report(&self, now: P) -> bool {
        if let Ok(mut slot) = self.progress.lock() {
            *slot = now;
        }
        (self.notify)();
        !self.cancel.load(Ordering::Relaxed)
    }
}

/// A job running `work` on its own thread.
pub struct BackgroundJob<P, R> {
    progress: Arc<Mutex<P>>,
    cancel: Arc<AtomicBool>,
    thread: JoinHandle<Result<R, AppError>>,
    name: String,
}

impl<P: Clone + Send + 'static, R: Send + 'static> BackgroundJob<P, R> {
    /// Starts `work` on the thread `name` with progress starting at `initial`; `notify`
    /// requests a repaint whenever progress moves.
    pub fn spawn(
        name: &str,
        initial: P,
        notify: Arc<dyn Fn() + Send + Sync>,
        work: impl FnOnce(&Reporter<P>) -> Result<R, AppError> + Send + 'static,
    ) -> Result<Self, AppError> {
        let progress = Arc::new(Mutex::new(initial));
        let cancel = Arc::new(AtomicBool::new(false));
        let reporter = Reporter {
            progress: progress.clone(),
            cancel: cancel.clone(),
            notify,
        };
        let thread = std::thread::Builder::new()
            .name(name.into())
            .spawn(move || work(&reporter))
            .map_err(|source| AppError::Thread {
                name: name.into(),
                source,
            })?;
        Ok(Self {
            progress,
            cancel,
            thread,
            name: name.into(),
        })
    }

    /// Asks the job to stop at its next progress report.
    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed);
    }

    /// True once the thread has ended.
    pub fn is_finished(&self) -> bool {
        self.thread.is_finished()
    }

    /// The job's result (blocks until the thread ends; call after [`Self::is_finished`]).
    pub fn join(self) -> Result<R, AppError> {
        let name = self.name;
        self.thread
            .join()
            .unwrap_or_else(|_| Err(AppError::Panicked { name }))
    }

    /// The latest progress.
    pub fn progress(&self) -> Option<P> {
        self.progress.lock().ok().map(|p| p.clone())
    }
}

/// Takes the result of `job` once it has finished (never blocks on a running one).
pub fn poll_job<P: Clone + Send + 'static, R: Send + 'static>(
    job: &mut Option<BackgroundJob<P, R>>,
) -> Option<Result<R, AppError>> {
    if job.as_ref().is_some_and(BackgroundJob::is_finished) {
        job.take().map(BackgroundJob::join)
    } else {
        None
    }
}
