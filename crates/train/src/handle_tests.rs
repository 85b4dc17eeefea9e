//! Tests of the training loop with a session double.

use std::sync::{Arc, Mutex};

use super::*;

/// Records the schedule factor and run progress of every step; validates to `validation`; its checkpoints
/// succeed when `checkpoints` is set (writing nothing); everything else is inert.
struct Recording {
    factors: Arc<Mutex<Vec<f64>>>,
    factor: f64,
    progresses: Arc<Mutex<Vec<Option<f64>>>>,
    progress: Option<f64>,
    validation: MetricRecord,
    checkpoints: bool,
}

impl Session for Recording {
    fn step(&mut self) -> Result<MetricRecord, TrainError> {
        if let Ok(mut f) = self.factors.lock() {
            f.push(self.factor);
        }
        if let Ok(mut p) = self.progresses.lock() {
            p.push(self.progress);
        }
        Ok(MetricRecord {
            loss: 1.0,
            ..Default::default()
        })
    }
    fn validate(&mut self) -> Result<MetricRecord, TrainError> {
        Ok(self.validation)
    }
    fn weights_finite(&self) -> bool {
        true
    }
    fn snapshot(&self) -> Result<neural_cloth_model::ModelArtifact, TrainError> {
        Err(TrainError::Data("no weights".into()))
    }
    fn checkpoint(&mut self, _: u64, _: &MetricHistory) -> Result<PathBuf, TrainError> {
        if self.checkpoints {
            Ok(PathBuf::from("unused/checkpoint"))
        } else {
            Err(TrainError::NoCheckpointYet)
        }
    }
    fn restore_last_checkpoint(&mut self) -> Result<u64, TrainError> {
        Err(TrainError::NoCheckpointYet)
    }
    fn learning_rate(&self) -> f64 {
        1e-3
    }
    fn set_learning_rate(&mut self, _: f64) {}
    fn set_schedule_factor(&mut self, factor: f64) {
        self.factor = factor;
    }
    fn set_run_progress(&mut self, progress: Option<f64>) {
        self.progress = progress;
    }
    fn set_fabric(&mut self, _: FabricParams) -> Result<(), TrainError> {
        Ok(())
    }
    fn set_window(&mut self, _: f32) -> Result<(), TrainError> {
        Ok(())
    }
}

fn recording(factors: &Arc<Mutex<Vec<f64>>>) -> Recording {
    Recording {
        factors: factors.clone(),
        factor: 1.0,
        progresses: Arc::default(),
        progress: None,
        validation: MetricRecord {
            loss: 1.0,
            ..Default::default()
        },
        checkpoints: false,
    }
}

fn loop_config(max_steps: Option<u64>, lr_decay: (f64, f64), warmup_steps: u64) -> LoopConfig {
    LoopConfig {
        run_dir: PathBuf::from("unused"),
        start_step: 0,
        history: MetricHistory::default(),
        max_steps,
        max_secs: None,
        validate_every: 1000,
        snapshot_every: 1000,
        checkpoint_every: 1000,
        max_rollbacks: 1,
        warnings: Vec::new(),
        dead_limit_pct: 100.0,
        lr_decay,
        warmup_steps,
    }
}

fn factors_of(max_steps: Option<u64>, lr_decay: (f64, f64), warmup_steps: u64) -> Vec<f64> {
    let factors = Arc::new(Mutex::new(Vec::new()));
    let config = loop_config(max_steps, lr_decay, warmup_steps);
    let handle = TrainerHandle::spawn_session(recording(&factors), config, None).unwrap();
    // Drain the events until the thread ends, so it never blocks on a full channel; an
    // open-ended run is stopped after 20 steps.
    while !handle.is_finished() {
        handle.drain();
        if max_steps.is_none() && factors.lock().unwrap().len() >= 20 {
            handle.stop();
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    handle.join();
    factors.lock().unwrap().clone()
}

#[test]
fn a_bounded_run_decays_its_learning_rate_over_its_last_steps_only() {
    let f = factors_of(Some(10), (0.3, 0.1), 0);
    assert_eq!(f.len(), 10);
    // Progress before step k+1 is k / 10: flat up to 0.7, then the half cosine.
    assert!(f[..8].iter().all(|&x| x == 1.0), "{f:?}");
    assert!((f[8] - crate::config::lr_schedule_factor(0.8, 0.3, 0.1)).abs() < 1e-12);
    assert!(f[9] < f[8] && f[9] > 0.1, "{f:?}");
    // Without decay, or open-ended, the rate stays.
    assert!(
        factors_of(Some(10), (0.0, 0.1), 0)
            .iter()
            .all(|&x| x == 1.0)
    );
    assert!(factors_of(None, (0.3, 0.1), 0).iter().all(|&x| x == 1.0));
}

#[test]
fn the_learning_rate_warms_up_over_the_first_steps_of_open_and_bounded_runs() {
    for max_steps in [Some(10), None] {
        let f = factors_of(max_steps, (0.0, 0.1), 4);
        assert_eq!(f[..5], [0.25, 0.5, 0.75, 1.0, 1.0], "{max_steps:?}: {f:?}");
    }
    // With a decay too, the two factors multiply.
    let f = factors_of(Some(10), (0.3, 0.1), 4);
    assert_eq!(f[0], 0.25);
    assert!(f[9] < 1.0 && f[9] > 0.1, "{f:?}");
}

#[test]
fn a_live_setting_is_applied_or_rejected_with_its_error() {
    let window = LiveSetting::Window { secs: 0.8 };
    assert!(matches!(
        live_outcome(window, Ok(())),
        TrainEvent::Applied(LiveSetting::Window { secs }) if secs == 0.8
    ));
    match live_outcome(
        LiveSetting::Fabric,
        Err(TrainError::Data("too stiff".into())),
    ) {
        TrainEvent::Rejected { setting, error } => {
            assert_eq!(setting, LiveSetting::Fabric);
            assert!(error.to_string().contains("too stiff"), "{error}");
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(window.to_string(), "window 0.8 s");
}

/// The summary of a run names the metrics beyond the health limits (the skirt of the issue-13
/// audit fell off the body, strain 9.85, and the summary said nothing).
#[test]
fn a_broken_garment_is_named_in_the_summary_issue_13() {
    let summary_of = |validation: MetricRecord| {
        let factors = Arc::new(Mutex::new(Vec::new()));
        let session = Recording {
            validation,
            checkpoints: true,
            ..recording(&factors)
        };
        let handle =
            TrainerHandle::spawn_session(session, loop_config(Some(3), (0.0, 1.0), 0), None)
                .unwrap();
        let summary = loop {
            match handle.recv_timeout(Duration::from_secs(10)) {
                Some(TrainEvent::Finished(result)) => break result.unwrap(),
                Some(_) => {}
                None => panic!("no summary"),
            }
        };
        handle.join();
        summary
    };
    let healthy = MetricRecord {
        strain: 0.02,
        bending: 0.1,
        ..Default::default()
    };
    let summary = summary_of(healthy);
    assert!(summary.health.is_empty() && summary.health_warning().is_none());
    let summary = summary_of(MetricRecord {
        strain: 9.8481,
        ..healthy
    });
    assert_eq!(summary.health.len(), 1);
    let warning = summary.health_warning().unwrap();
    assert!(warning.contains("mean strain 9.848"), "{warning}");
}

#[test]
fn the_loop_tells_the_session_how_far_a_bounded_run_is() {
    let factors = Arc::new(Mutex::new(Vec::new()));
    let session = recording(&factors);
    let progresses = session.progresses.clone();
    let handle =
        TrainerHandle::spawn_session(session, loop_config(Some(4), (0.0, 0.1), 0), None).unwrap();
    while !handle.is_finished() {
        handle.drain();
        std::thread::sleep(Duration::from_millis(1));
    }
    handle.join();
    // Before step k + 1 the run is k / 4 through its steps.
    let seen = progresses.lock().unwrap().clone();
    assert_eq!(seen, [Some(0.0), Some(0.25), Some(0.5), Some(0.75)]);
}

/// Counts how often the loop reads the weights back: as a snapshot, or to check them.
struct ReadBacks {
    artifact: neural_cloth_model::ModelArtifact,
    snapshots: Arc<Mutex<usize>>,
    checks: Arc<Mutex<usize>>,
}

impl Session for ReadBacks {
    fn step(&mut self) -> Result<MetricRecord, TrainError> {
        Ok(MetricRecord {
            loss: 1.0,
            ..Default::default()
        })
    }
    fn validate(&mut self) -> Result<MetricRecord, TrainError> {
        Ok(MetricRecord {
            loss: 1.0,
            ..Default::default()
        })
    }
    fn weights_finite(&self) -> bool {
        *self.checks.lock().unwrap() += 1;
        self.artifact.weights.validate().is_ok()
    }
    fn snapshot(&self) -> Result<neural_cloth_model::ModelArtifact, TrainError> {
        *self.snapshots.lock().unwrap() += 1;
        Ok(self.artifact.clone())
    }
    fn checkpoint(&mut self, _: u64, _: &MetricHistory) -> Result<PathBuf, TrainError> {
        Ok(PathBuf::from("unused/checkpoint"))
    }
    fn restore_last_checkpoint(&mut self) -> Result<u64, TrainError> {
        Err(TrainError::NoCheckpointYet)
    }
    fn learning_rate(&self) -> f64 {
        1e-3
    }
    fn set_learning_rate(&mut self, _: f64) {}
    fn set_fabric(&mut self, _: FabricParams) -> Result<(), TrainError> {
        Ok(())
    }
    fn set_window(&mut self, _: f32) -> Result<(), TrainError> {
        Ok(())
    }
}

/// A small network's weights as the loop's snapshots carry them.
fn small_artifact() -> neural_cloth_model::ModelArtifact {
    let config = neural_cloth_model::ClothNetConfig {
        static_hidden: vec![8],
        joint_hidden: vec![4, 4],
        dynamic_hidden: vec![16],
        latent: 12,
        decoder_hidden: vec![10],
        ..Default::default()
    };
    let model = config.init(3, 5, &burn::tensor::Device::flex()).unwrap();
    let weights = neural_cloth_model::InferenceWeights::from_module(&model).unwrap();
    neural_cloth_model::ModelArtifact::new(weights, Default::default(), 30.0)
}

/// Runs `steps` steps of `session` (snapshots every 4, checkpoints every 6); returns the
/// snapshot events and how the run ended.
fn run_read_backs(session: ReadBacks, steps: u64) -> (usize, Result<RunSummary, Arc<TrainError>>) {
    let config = LoopConfig {
        snapshot_every: 4,
        checkpoint_every: 6,
        ..loop_config(Some(steps), (0.0, 1.0), 0)
    };
    let handle = TrainerHandle::spawn_session(session, config, None).unwrap();
    let mut snapshot_events = 0;
    let end = loop {
        match handle.recv_timeout(Duration::from_secs(10)) {
            Some(TrainEvent::Snapshot { .. }) => snapshot_events += 1,
            Some(TrainEvent::Finished(result)) => break result,
            Some(_) => {}
            None => panic!("the run did not finish"),
        }
    };
    handle.join();
    (snapshot_events, end)
}

/// A snapshot step reads the weights back once: the snapshot's copy is checked for
/// non-finite weights and then sent, and sent again as the final snapshot when the run ends
/// on it (issue 12: the loop read them twice, three times on the last step).
#[test]
fn a_snapshot_step_reads_the_weights_back_once() {
    let snapshots = Arc::new(Mutex::new(0));
    let checks = Arc::new(Mutex::new(0));
    let session = ReadBacks {
        artifact: small_artifact(),
        snapshots: snapshots.clone(),
        checks: checks.clone(),
    };
    let (events, end) = run_read_backs(session, 12);
    assert!(end.is_ok(), "{end:?}");
    // Snapshots at steps 4, 8 and 12, the last sent again at the end without a read-back;
    // the checkpoint of step 6 alone checks the weights.
    assert_eq!(*snapshots.lock().unwrap(), 3);
    assert_eq!(events, 4);
    assert_eq!(*checks.lock().unwrap(), 1);
    // A run that does not end on a snapshot step reads the final weights once more.
    let snapshots = Arc::new(Mutex::new(0));
    let session = ReadBacks {
        artifact: small_artifact(),
        snapshots: snapshots.clone(),
        checks: Arc::default(),
    };
    let (events, end) = run_read_backs(session, 10);
    assert!(end.is_ok(), "{end:?}");
    assert_eq!((*snapshots.lock().unwrap(), events), (3, 3));
    // A snapshot with a non-finite weight is a divergence, not a picture to send.
    let mut artifact = small_artifact();
    artifact.weights.basis.weight[0] = f32::NAN;
    let session = ReadBacks {
        artifact,
        snapshots: Arc::default(),
        checks: Arc::default(),
    };
    let (events, end) = run_read_backs(session, 12);
    assert_eq!(events, 0);
    assert!(
        matches!(
            end.as_ref().map_err(|e| &**e),
            Err(TrainError::RollbackFailed { .. })
        ),
        "{end:?}"
    );
}
