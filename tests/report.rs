//! Smoke run of `neural-cloth report` (a tiny budget on small garments): the experiments run,
//! their numbers obey the facts they must obey, and the files are written and parse.

use neural_cloth::report::{
    CostOptions, Method, Report, ReportError, ReportOptions, default_scene_at, run_cost_experiment,
    run_report, write_report,
};

#[test]
fn smoke_report_measures_and_writes_everything() {
    let options = ReportOptions {
        budget_secs: 12.0,
        scene: None,
        seed: 0,
        command: "neural-cloth report --budget-minutes 0.2".into(),
    };
    let mut last_fraction = 0.0f64;
    let mut monotone = true;
    let report = run_report(&options, &mut |p| {
        monotone &= p.fraction + 1e-9 >= last_fraction || p.phase != "accuracy";
        last_fraction = p.fraction;
        (0.0..=1.0).contains(&p.fraction)
    })
    .expect("report runs");
    assert!(monotone, "accuracy progress went backwards");

    // Accuracy against time: more iterations, less error and a smaller residual.
    let a = &report.accuracy;
    assert!(a.clip_frames >= 3 && a.vertices > 0);
    let sims: Vec<_> = a.simulator_points().collect();
    let one = sims
        .iter()
        .find(|p| p.iterations == Some(1))
        .expect("1-iteration simulator");
    let most = sims
        .iter()
        .max_by_key(|p| p.iterations)
        .expect("simulator points");
    assert!(most.iterations > one.iterations);
    assert!(
        one.mean_mm > most.mean_mm,
        "1 it: {} mm, {:?} it: {} mm",
        one.mean_mm,
        most.iterations,
        most.mean_mm
    );
    assert!(one.p95_mm >= one.mean_mm * 0.5 && one.p95_mm > 0.0);
    assert!(
        one.residual_rms > a.reference.residual_rms,
        "1 it residual {} vs reference {}",
        one.residual_rms,
        a.reference.residual_rms
    );
    assert!(
        sims.iter()
            .all(|p| p.ms_per_frame > 0.0 && p.mean_mm.is_finite())
    );
    let nets: Vec<_> = a.neural_points().collect();
    assert_eq!(nets.len(), 4);
    for n in &nets {
        assert!(
            n.ms_per_frame > 0.0 && n.mean_mm > 0.0 && n.residual_rms.is_finite(),
            "{n:?}"
        );
        assert!(n.speedup.is_some_and(|s| s.factor > 0.0));
        assert_eq!(n.method, Method::Neural);
    }
    assert!(
        nets.windows(2)
            .all(|w| w[0].train_steps <= w[1].train_steps)
    );
    assert!(!a.training.train.is_empty() && !a.training.validation.is_empty());

    // Disentanglement: exact zeros for a still body, w = 0 is the static prediction.
    let d = &report.fidelity.disentanglement;
    assert_eq!(d.zd_max_network, Some(0.0));
    assert_eq!(d.zd_max_engine, 0.0);
    assert_eq!(d.still_change_mm, 0.0);
    assert_eq!(d.w.len(), 11);
    assert_eq!(d.displacement_mm.first().copied(), Some(0.0));
    assert!(d.displacement_mm.iter().all(|v| v.is_finite()));

    // The skirt: radii of a real hem, and a reference simulation that reached the window.
    let k = &report.fidelity.skirt;
    for r in [
        k.mean_ours_m,
        k.mean_snug_m,
        k.mean_static_m,
        k.mean_snug_static_m,
        k.mean_skinned_m,
    ] {
        assert!((0.05..1.0).contains(&r), "hem radius {r} m");
    }
    assert!(k.hem_vertices > 0 && k.ours_m.len() == k.times.len());

    // Ablation rows in Tab. 2 order.
    let labels: Vec<&str> = report
        .fidelity
        .ablation
        .iter()
        .map(|r| r.label.as_str())
        .collect();
    assert_eq!(
        labels,
        ["Entangled", "Disentangled", "+Mirror", "+Aug. motions"]
    );
    assert!(
        report
            .fidelity
            .ablation
            .iter()
            .all(|r| r.validation.is_finite() && r.validation.strain > 0.0 && r.run.steps >= 2)
    );

    // Settings: every axis is there and costs were measured.
    let find = |label: &str| {
        report
            .settings
            .iter()
            .find(|s| s.label == label)
            .unwrap_or_else(|| panic!("missing setting {label}"))
    };
    let base = report
        .settings
        .iter()
        .find(|s| s.group == "baseline")
        .expect("baseline");
    assert!(
        find("60 fps").window_frames > base.window_frames
            && find("15 fps").window_frames < base.window_frames
    );
    assert!(find("1 s window").window_frames > find("0.1 s window").window_frames);
    for label in ["no gravity", "no bending", "no collision", "no dynamics"] {
        assert!(!find(label).effects.iter().all(|e| *e));
    }
    assert!(
        report
            .settings
            .iter()
            .any(|s| s.group == "resolution" && s.vertices < base.vertices)
    );
    assert!(
        report
            .settings
            .iter()
            .all(|s| s.step_ms > 0.0 && s.inference_ms > 0.0 && s.run.steps >= 2)
    );

    // Files: Markdown naming every figure, SVGs, and JSON that reads back.
    let dir = tempfile::tempdir().expect("temp dir");
    let written = write_report(&report, dir.path()).expect("report written");
    let md = std::fs::read_to_string(dir.path().join("REPORT.md")).expect("REPORT.md");
    assert!(
        md.contains("## 1. Accuracy against time")
            && md.contains("neural-cloth report --budget-minutes 0.2")
    );
    let svgs: Vec<_> = written
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "svg"))
        .collect();
    assert_eq!(svgs.len(), 7);
    for svg in svgs {
        let text = std::fs::read_to_string(svg).expect("svg");
        assert!(
            text.starts_with("<svg") && text.trim_end().ends_with("</svg>"),
            "{}",
            svg.display()
        );
        let name = svg.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        assert!(
            md.contains(&format!("report/{name}")),
            "REPORT.md does not show {name}"
        );
    }
    let json =
        std::fs::read_to_string(dir.path().join("report").join("report.json")).expect("json");
    let back: Report = serde_json::from_str(&json).expect("report.json parses");
    assert_eq!(back.accuracy.clip_frames, a.clip_frames);
    assert_eq!(back.settings.len(), report.settings.len());
}

#[test]
fn the_cost_experiment_can_be_cancelled() {
    let (scene, _) = default_scene_at(Some(300)).expect("scene");
    let options = CostOptions {
        budget_secs: 5.0,
        ..CostOptions::default()
    };
    let mut calls = 0;
    let result = run_cost_experiment(&scene, &options, &mut |_| {
        calls += 1;
        false
    });
    assert!(
        matches!(result, Err(ReportError::Cancelled)),
        "{:?}",
        result.map(|r| r.points.len())
    );
    assert_eq!(calls, 1);
}

#[test]
#[ignore = "benchmark: run with --ignored --nocapture and copy the table into docs/PHYSICS.md"]
fn measure_term_costs_at_10k_dof() {
    let report =
        neural_cloth::bench::cost::measure_term_costs(&burn::tensor::Device::flex(), 10_000, 8, 10)
            .unwrap();
    println!("{}", report.to_markdown());
    assert!(report.terms.iter().all(|t| t.ms.is_finite() && t.ms > 0.0));
}
