//! A cancellable job on a named background thread with shared progress, for the panels that
//! run long computations (the Cost experiment, "Check against simulation", export, fit), and
//! [`JobSlot`]: one such job at a time plus the result of the last one.

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

/// One background job at a time and the result of the last one: the state behind a panel's
/// long action (start, progress, cancel, result).
pub struct JobSlot<P, R> {
    job: Option<BackgroundJob<P, R>>,
    /// The last result, or the error that ended (or refused) the last job.
    pub result: Option<Result<R, AppError>>,
}

impl<P, R> Default for JobSlot<P, R> {
    fn default() -> Self {
        Self {
            job: None,
            result: None,
        }
    }
}

impl<P: Clone + Send + 'static, R: Send + 'static> JobSlot<P, R> {
    /// True while a job runs.
    pub fn is_running(&self) -> bool {
        self.job.is_some()
    }

    /// Starts `work` as [`BackgroundJob::spawn`] does; refused with
    /// [`AppError::AlreadyRunning`] (naming `what`) while a job runs.
    pub fn start(
        &mut self,
        what: &'static str,
        name: &str,
        initial: P,
        notify: Arc<dyn Fn() + Send + Sync>,
        work: impl FnOnce(&Reporter<P>) -> Result<R, AppError> + Send + 'static,
    ) -> Result<(), AppError> {
        if self.job.is_some() {
            return Err(AppError::AlreadyRunning(what));
        }
        self.job = Some(BackgroundJob::spawn(name, initial, notify, work)?);
        Ok(())
    }

    /// Asks the running job to stop at its next progress report.
    pub fn cancel(&self) {
        if let Some(job) = &self.job {
            job.cancel();
        }
    }

    /// Moves a finished job's result into [`Self::result`] (never blocks on a running one).
    pub fn poll(&mut self) {
        if let Some(result) = poll_job(&mut self.job) {
            self.result = Some(result);
        }
    }

    /// Progress of the running job.
    pub fn progress(&self) -> Option<P> {
        self.job.as_ref().and_then(BackgroundJob::progress)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wait(slot: &mut JobSlot<u32, u32>) {
        let started = std::time::Instant::now();
        while slot.is_running() {
            slot.poll();
            std::thread::sleep(std::time::Duration::from_millis(5));
            assert!(started.elapsed().as_secs() < 60, "the job must end");
        }
    }

    #[test]
    fn a_slot_runs_one_job_keeps_its_result_and_cancels() {
        let mut slot = JobSlot::<u32, u32>::default();
        let (go_tx, go_rx) = std::sync::mpsc::channel::<()>();
        slot.start("a job", "test-slot", 0, Arc::new(|| {}), move |r| {
            r.report(7);
            go_rx.recv().ok();
            Ok(41 + u32::from(r.report(8)))
        })
        .unwrap();
        assert!(slot.is_running());
        let refused = slot.start("a job", "test-slot", 0, Arc::new(|| {}), |_| Ok(0));
        assert!(matches!(refused, Err(AppError::AlreadyRunning("a job"))));
        go_tx.send(()).unwrap();
        wait(&mut slot);
        assert!(
            matches!(slot.result, Some(Ok(42))),
            "not cancelled: report says go on"
        );
        assert_eq!(slot.progress(), None, "no progress once the job has ended");

        let (go_tx, go_rx) = std::sync::mpsc::channel::<()>();
        slot.start("a job", "test-slot", 0, Arc::new(|| {}), move |r| {
            go_rx.recv().ok();
            Ok(u32::from(r.report(1)))
        })
        .unwrap();
        slot.cancel();
        go_tx.send(()).unwrap();
        wait(&mut slot);
        assert!(
            matches!(slot.result, Some(Ok(0))),
            "cancelled: report says stop"
        );
    }
}
