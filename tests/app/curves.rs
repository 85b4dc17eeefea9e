//! Curves people can read (issue 15): smoothed lines over faint raw values, validation as
//! solid dots in a colour of its own, log axes for metrics spanning decades, a y range the
//! first steps cannot set, labelled markers where a setting changed during training, and the
//! "improving / flat / diverging" indicator of the validation loss, and the last check
//! against simulation.

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use neural_cloth::app::NeuralClothApp;
use neural_cloth::app::metrics::MetricRecord;
use neural_cloth::train::handle::{LiveSetting, TrainEvent};

use super::{options, snapshot_options};

/// Size of the curve panel snapshot, in points (pixels at 1 pixel per point).
const PANEL: egui::Vec2 = egui::vec2(900.0, 260.0);

/// A run of 400 noisy steps with a spike at step 10, a validation pass every 25 steps whose
/// loss keeps falling, and a fabric change applied at step 150, fed to the training panel
/// through the trainer's events as a live run would.
fn feed_run(app: &mut NeuralClothApp) {
    let training = &mut app.state.training;
    for step in 1..=400u64 {
        let s = step as f64;
        let wobble = ((step * 7919 + 13) % 101) as f64 / 50.0 - 1.0;
        let record = MetricRecord {
            step,
            wall_secs: s * 0.1,
            loss: 2.0 / (1.0 + s / 40.0),
            strain: if step == 10 {
                0.6
            } else {
                0.02 + 0.08 * (-s / 80.0).exp() + 0.008 * wobble
            },
            bending: 0.05 + 0.2 * (-s / 90.0).exp() + 0.01 * wobble,
            collision_pct: 25.0 * (-s / 40.0).exp() + 0.2 + 0.05 * wobble.abs(),
            ..Default::default()
        };
        training.apply(TrainEvent::Step(record));
        if step == 150 {
            training.apply(TrainEvent::Applied(LiveSetting::Fabric));
        }
        if step % 25 == 0 {
            training.apply(TrainEvent::Validation(MetricRecord {
                strain: record.strain * 1.3,
                dead_units_pct: 4.0,
                ..record
            }));
        }
    }
}

#[test]
fn curves_show_the_trend_and_where_a_setting_changed() {
    let mut app = NeuralClothApp::new(&egui::Context::default(), None, options(None))
        .expect("the default scene builds");
    feed_run(&mut app);
    assert_eq!(app.state.training.markers.len(), 1);
    let mut h = Harness::builder()
        .with_size(PANEL)
        .with_pixels_per_point(1.0)
        .wgpu()
        .build_ui_state(|ui, app: &mut NeuralClothApp| app.plot_ui(ui), app);
    h.run();
    // The indicator says where the validation loss is heading, in words.
    h.get_by_label_contains("validation loss: improving");
    // The fabric change is listed with its step (and drawn as a labelled line on each plot).
    h.get_by_label("fabric at step 150");
    // Collision falls from 25 % to 0.2 %: a log axis, said in its title.
    h.get_by_label("collision (%) · log");
    h.snapshot_options("metric_curves_readable", &snapshot_options());

    // A rejected change leaves no marker; a rollback marks the new learning rate.
    h.state_mut().state.training.apply(TrainEvent::Rejected {
        setting: LiveSetting::Window { secs: 9.0 },
        error: std::sync::Arc::new(neural_cloth::train::TrainError::Data("too long".into())),
    });
    h.state_mut().state.training.apply(TrainEvent::RolledBack {
        diverged_at: 390,
        restored_step: 300,
        learning_rate: 5e-4,
    });
    h.run();
    let markers = &h.state().state.training.markers;
    assert_eq!(markers.len(), 2, "{markers:?}");
    h.get_by_label("learning rate 5.0e-4 at step 300");
}

#[test]
fn curves_show_the_last_check_against_simulation() {
    use neural_cloth::train::compare::{
        Amplitude, AmplitudeStats, CompareOptions, CompareReport, DistanceStats, MetricPair,
        MotionComparison, MotionMeasures, ReferenceInfo, StateDrift,
    };
    let mut app = NeuralClothApp::new(&egui::Context::default(), None, options(None))
        .expect("the default scene builds");
    feed_run(&mut app);
    let swing = |moving_mm| AmplitudeStats {
        all_mm: moving_mm,
        still_mm: None,
        moving_mm: Some(moving_mm),
    };
    let measures = MotionMeasures {
        frames: 181,
        all: DistanceStats {
            frames: 181,
            mean_mm: 22.2,
            p95_mm: 41.1,
        },
        amplitude: Amplitude {
            network: swing(19.2),
            simulator: swing(32.2),
        },
        drift: Some(StateDrift {
            window_frames: 18,
            mean_mm: 0.3,
            max_frame_mm: 0.6,
            height_mm: 0.0,
        }),
        ..Default::default()
    };
    app.cost.check.job.result = Some(Ok(CompareReport {
        run: "run".into(),
        step: 400,
        garment: "tshirt".into(),
        vertices: 3400,
        fps: 30.0,
        below_hips: false,
        options: CompareOptions::default(),
        motions: vec![MotionComparison {
            name: "spin".into(),
            measures,
            metrics: MetricPair::default(),
            objective: Default::default(),
            reference: ReferenceInfo::default(),
        }],
    }));
    let mut h = Harness::builder()
        .with_size(PANEL)
        .with_pixels_per_point(1.0)
        .build_ui_state(|ui, app: &mut NeuralClothApp| app.plot_ui(ui), app);
    h.run();
    h.get_by_label(
        "checked against simulation at step 400: spin 22.2 mm (swing 19.2 / 32.2 mm, drift 0.3 mm)",
    );
}
