//! Effect gating and metrics.

use burn::tensor::{DType, Device};
use neural_cloth_core::geometry::Vec3;
use neural_cloth_physics::metrics::History;
use neural_cloth_physics::shapes::sheet;
use neural_cloth_physics::{Effects, FabricParams, PhysicsError, Term};

use super::common::*;
use super::random_case;

#[test]
fn effects_decide_which_terms_exist() {
    let device = Device::flex();
    let (mesh, x) = random_case(9);
    let fabric = FabricParams::default();
    let rest = rest_of(&mesh, &[0], &[], &fabric);
    let xt = tensor(&x, &device, DType::F32);
    let t = terms(&rest, &fabric, &all_effects(), &device, DType::F32);
    assert!(matches!(
        t.static_losses(&xt, None),
        Err(PhysicsError::MissingBody)
    ));
    let bare = Effects {
        gravity: false,
        bending: false,
        collision: false,
        dynamics: false,
        pinning: false,
        friction: false,
    };
    let t = terms(&rest, &fabric, &bare, &device, DType::F32);
    assert!(
        t.tensors().hinge.is_none()
            && t.tensors().collide.is_none()
            && t.tensors().pinned.is_none()
    );
    let names: Vec<Term> = t
        .static_losses(&xt, None)
        .unwrap()
        .terms
        .iter()
        .map(|(t, _)| *t)
        .collect();
    assert_eq!(names, vec![Term::Stretch, Term::Shear]);
    assert!(t.pinning(&xt, &xt).is_none());
    let wrong = tensor(&x[..x.len() - 3], &device, DType::F32);
    assert!(matches!(
        t.static_losses(&wrong, None),
        Err(PhysicsError::ShapeMismatch { .. })
    ));
    let values = t.static_losses(&xt, None).unwrap().values().unwrap();
    assert!(values.iter().all(|(_, v)| v.is_finite() && *v >= 0.0));
}

#[test]
fn metrics_of_rest_stretched_and_moving_meshes() {
    let device = Device::flex();
    let mesh = sheet(4, 4, Vec3::zeros(), Vec3::x(), Vec3::z());
    let fabric = FabricParams::default();
    let rest = rest_of(&mesh, &[], &[], &fabric);
    let t = terms(&rest, &fabric, &all_effects(), &device, DType::F32);
    let x0 = flat(&mesh.positions);
    let m = t
        .metrics(&tensor(&x0, &device, DType::F32), None, None)
        .unwrap();
    assert!(
        m.edge_elongation_m < 1e-6 && m.stretch < 1e-6 && m.bending_rad < 1e-6 && m.shear < 1e-6
    );
    assert!(m.collision_pct.is_none() && m.inertia_j.is_none());
    // 10 % uniform stretch: every edge 10 % longer, stretch 0.1, Green strain ‖G‖ = √2·0.105.
    let x1: Vec<f64> = x0.iter().map(|v| v * 1.1).collect();
    let m = t
        .metrics(&tensor(&x1, &device, DType::F32), None, None)
        .unwrap();
    assert!(
        (m.edge_strain - 0.1).abs() < 1e-5 && (m.stretch - 0.1).abs() < 1e-5,
        "{m:?}"
    );
    assert!((m.green_strain - 2f64.sqrt() * 0.105).abs() < 1e-5, "{m:?}");
    // Constant velocity: zero inertia; a sudden 1 cm jump: m·1cm mass-weighted distance.
    let shift = |d: f64| -> Vec<f64> {
        x0.iter()
            .enumerate()
            .map(|(i, v)| if i % 3 == 1 { v + d } else { *v })
            .collect()
    };
    let hist = History {
        x_t1: tensor(&shift(0.01), &device, DType::F32),
        x_t2: tensor(&shift(0.0), &device, DType::F32),
        dt_secs: 0.1,
        friction: None,
    };
    let m = t
        .metrics(
            &tensor(&shift(0.02), &device, DType::F32),
            None,
            Some(&hist),
        )
        .unwrap();
    assert!(m.inertia_j.unwrap().abs() < 1e-8 && m.inertia_m.unwrap().abs() < 1e-6);
    let m = t
        .metrics(
            &tensor(&shift(0.03), &device, DType::F32),
            None,
            Some(&hist),
        )
        .unwrap();
    let expected = 0.5 / 0.01 * rest.total_mass_kg * 1e-4;
    assert!(
        (m.inertia_j.unwrap() - expected).abs() < 1e-3 * expected
            && (m.inertia_m.unwrap() - 0.01).abs() < 1e-6
    );
    // Sequence metrics: gravity potential falls as the sheet drops.
    let frames: Vec<Vec<Vec3>> = (0..4)
        .map(|k| {
            mesh.positions
                .iter()
                .map(|p| p - Vec3::y() * (0.01 * k as f32))
                .collect()
        })
        .collect();
    let seq =
        neural_cloth_physics::metrics::sequence_metrics(&t, &frames, None, 1.0 / 30.0).unwrap();
    assert_eq!(seq.len(), 4);
    assert!(seq.windows(2).all(|w| w[1].gravity_j < w[0].gravity_j));
    assert!(seq[2].inertia_j.unwrap().abs() < 1e-6);
}
