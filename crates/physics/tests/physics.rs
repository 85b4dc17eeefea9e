//! Integration tests of the physics layer: gradients against finite differences, known
//! values, effect gating, metrics, hard cases and the reference simulator.

#[path = "physics/common.rs"]
mod common;
#[path = "physics/hard_cases.rs"]
mod hard_cases;
#[path = "physics/scenes.rs"]
mod scenes;
#[path = "physics/terms.rs"]
mod terms_and_metrics;

use std::sync::Arc;

use burn::tensor::{DType, Device};
use common::*;
use neural_cloth_core::geometry::{TriMesh, Vec3};
use neural_cloth_physics::collision::{self, BodyBatch, Contacts, PosedBody};
use neural_cloth_physics::friction::{self, FrictionContacts};
use neural_cloth_physics::shapes::{sheet, tube, uv_sphere};
use neural_cloth_physics::{ClothModel, Effects, FabricParams, Term, energies};

type Energy<'a> = dyn Fn(&burn::tensor::Tensor<3>) -> burn::tensor::Tensor<1> + 'a;

fn f64_device() -> Device {
    Device::flex().autodiff()
}

/// A randomly perturbed, randomly bent 4x3 sheet with a sphere body nearby.
fn random_case(seed: u64) -> (TriMesh, Vec<f64>) {
    let mesh = sheet(
        4,
        3,
        Vec3::new(-0.2, 1.0, -0.15),
        Vec3::new(0.4, 0.0, 0.0),
        Vec3::new(0.0, 0.05, 0.3),
    );
    let mut rng = Lcg(seed);
    let mut rest = mesh.clone();
    for p in &mut rest.positions {
        *p += Vec3::new(rng.next() as f32, rng.next() as f32, rng.next() as f32) * 0.03;
    }
    let x: Vec<f64> = flat(&rest.positions)
        .iter()
        .map(|v| v * (1.0 + 0.15 * rng.next()) + 0.02 * rng.next())
        .collect();
    (rest, x)
}

#[test]
fn gradients_of_every_energy_match_central_differences_in_f64() {
    let device = f64_device();
    let dtype = DType::F64;
    for seed in [1u64, 7, 42] {
        let (mesh, x) = random_case(seed);
        let n = mesh.positions.len();
        let fabric = FabricParams::default();
        let rest = rest_of(&mesh, &[0, 5], &[3], &fabric);
        let t = terms(&rest, &fabric, &all_effects(), &device, dtype);
        let rt = t.tensors();
        // A body whose surface cuts through the sheet, so some vertices collide.
        let body_mesh = uv_sphere(Vec3::new(0.0, 0.75, 0.0), 0.3, 10, 14);
        let body = Arc::new(PosedBody::new(body_mesh.positions.clone(), &body_mesh.faces).unwrap());
        let xf: Vec<f32> = x.iter().map(|v| *v as f32).collect();
        let bodies = BodyBatch::new(vec![body]);
        let contacts = Contacts::query(&bodies, &xf, n, &device, dtype).unwrap();
        // The body 1 cm to the side a frame earlier: friction's body motion.
        let shifted = body_mesh
            .positions
            .iter()
            .map(|p| p - Vec3::new(0.01, 0.0, 0.005));
        let before = BodyBatch::new(vec![Arc::new(
            PosedBody::new(shifted.collect(), &body_mesh.faces).unwrap(),
        )]);
        let fc = FrictionContacts::new(&contacts, &bodies, &before, &[], &rest, &fabric).unwrap();
        assert!(
            fc.touching().unwrap() > 0,
            "seed {seed}: no vertex in the friction band"
        );
        let depth: Vec<f64> = {
            let d = collision::signed_distances(&tensor(&x, &device, dtype), &contacts);
            neural_cloth_physics::tensors::read_f64(d).unwrap()
        };
        assert!(
            depth.iter().any(|d| *d < 0.004),
            "seed {seed}: no vertex touches the body"
        );
        let prev1: Vec<f64> = x.iter().map(|v| v * 0.98).collect();
        let prev2: Vec<f64> = x.iter().map(|v| v * 0.97 + 0.01).collect();
        let (p1, p2) = (
            tensor(&prev1, &device, dtype),
            tensor(&prev2, &device, dtype),
        );
        let target = tensor(&flat(&mesh.positions), &device, dtype);
        let mut rng = Lcg(seed + 100);
        let coords: Vec<usize> = (0..14)
            .map(|_| ((rng.next() + 0.5) * (3 * n) as f64) as usize % (3 * n))
            .collect();
        let stvk = terms(
            &rest,
            &FabricParams {
                cloth_model: ClothModel::Stvk,
                ..fabric.clone()
            },
            &all_effects(),
            &device,
            dtype,
        );
        let cases: Vec<(&str, Box<Energy>)> = vec![
            (
                "mass-spring",
                Box::new(|x| energies::mass_spring(x, rt, 10.0)),
            ),
            (
                "baraff-witkin stretch",
                Box::new(|x| energies::baraff_witkin(x, rt, 10.0, 0.0).0),
            ),
            (
                "baraff-witkin shear",
                Box::new(|x| energies::baraff_witkin(x, rt, 0.0, 1.0).1),
            ),
            (
                "stvk",
                Box::new(|x| energies::stvk(x, stvk.tensors(), 20.9, 11.1)),
            ),
            ("bending", Box::new(|x| energies::bending(x, rt, 2e-5))),
            (
                "collision",
                Box::new(|x| collision::collision(x, &contacts, rt, 10.0, 0.004)),
            ),
            ("gravity", Box::new(|x| energies::gravity(x, rt))),
            (
                "inertia",
                Box::new(|x| energies::inertia(x, &p1, &p2, rt, 1.0 / 30.0)),
            ),
            ("pinning", Box::new(|x| t.pinning(x, &target).unwrap())),
            ("friction", Box::new(|x| friction::friction(x, &p1, &fc))),
        ];
        for (name, f) in &cases {
            check_gradient(
                &format!("{name} (seed {seed})"),
                f.as_ref(),
                &x,
                &coords,
                &device,
                dtype,
            );
        }
    }
}

#[test]
fn f32_gradients_agree_with_f64_ones() {
    let (mesh, x) = random_case(3);
    let fabric = FabricParams::default();
    let rest = rest_of(&mesh, &[], &[], &fabric);
    let effects = Effects {
        collision: false,
        ..all_effects()
    };
    let (d64, d32) = (f64_device(), Device::flex().autodiff());
    let t64 = terms(&rest, &fabric, &effects, &d64, DType::F64);
    let t32 = terms(&rest, &fabric, &effects, &d32, DType::F32);
    let total = |t: &neural_cloth_physics::PhysicsTerms| {
        let t = t.clone();
        move |x: &burn::tensor::Tensor<3>| t.static_losses_with(x, None).unwrap().total().unwrap()
    };
    let (v64, g64) = gradient(&total(&t64), &x, &d64, DType::F64);
    let (v32, g32) = gradient(&total(&t32), &x, &d32, DType::F32);
    assert!(
        (v64 - v32).abs() <= 1e-4 * v64.abs().max(1e-6),
        "{v64} vs {v32}"
    );
    let scale = g64.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (a, b) in g64.iter().zip(&g32) {
        assert!((a - b).abs() <= 1e-3 * scale, "{a} vs {b}");
    }
}

#[test]
fn rest_garment_has_zero_stretch_and_bending_energy() {
    let device = Device::flex();
    let mesh = tube(Vec3::new(0.0, 1.0, 0.0), 0.2, 0.35, 0.2, -0.3, 24, 8);
    for model in [
        ClothModel::MassSpring,
        ClothModel::BaraffWitkin,
        ClothModel::Stvk,
    ] {
        let fabric = FabricParams {
            cloth_model: model,
            ..FabricParams::default()
        };
        let rest = rest_of(&mesh, &[], &[], &fabric);
        let t = terms(
            &rest,
            &fabric,
            &Effects {
                collision: false,
                ..all_effects()
            },
            &device,
            DType::F32,
        );
        let x = tensor(&flat(&mesh.positions), &device, DType::F32);
        let losses = t.static_losses(&x, None).unwrap();
        // Reference scale: the same garment stretched by 1 %.
        let stretched = tensor(
            &flat(&mesh.positions)
                .iter()
                .map(|v| v * 1.01)
                .collect::<Vec<_>>(),
            &device,
            DType::F32,
        );
        let ref_stretch = scalar(
            t.static_losses(&stretched, None)
                .unwrap()
                .get(Term::Stretch)
                .unwrap()
                .clone(),
        );
        assert!(ref_stretch > 0.0);
        for term in [Term::Stretch, Term::Shear, Term::Bending] {
            if let Some(v) = losses.get(term) {
                let v = scalar(v.clone());
                assert!(
                    v.abs() <= 1e-6 * ref_stretch,
                    "{model:?} {term:?} at rest = {v} (1 % stretch gives {ref_stretch})"
                );
            }
        }
        let bent = tensor(
            &flat(&mesh.positions)
                .iter()
                .enumerate()
                .map(|(i, v)| {
                    if i % 3 == 0 {
                        v * (1.0 + 0.1 * ((i / 3) % 2) as f64)
                    } else {
                        *v
                    }
                })
                .collect::<Vec<_>>(),
            &device,
            DType::F32,
        );
        assert!(
            scalar(
                t.static_losses(&bent, None)
                    .unwrap()
                    .get(Term::Bending)
                    .unwrap()
                    .clone()
            ) > 0.0
        );
    }
}

#[test]
fn uniformly_stretched_squares_have_the_analytic_energy() {
    let device = f64_device();
    let (s, q) = (0.1f64, 0.05f64);
    // A horizontal square (normal ±Y, frame u = Z) and a vertical one (normal exactly +Z).
    let horizontal = sheet(3, 3, Vec3::zeros(), Vec3::x(), Vec3::z());
    let vertical = sheet(3, 3, Vec3::zeros(), Vec3::x(), Vec3::y());
    for (mesh, warp_axis) in [(horizontal, 2usize), (vertical, 1usize)] {
        // Stretch by (1+s) along X (weft) and (1+q) along the warp axis.
        let x: Vec<f64> = flat(&mesh.positions)
            .iter()
            .enumerate()
            .map(|(i, v)| match i % 3 {
                0 => v * (1.0 + s),
                k if k == warp_axis => v * (1.0 + q),
                _ => *v,
            })
            .collect();
        let xt = tensor(&x, &device, DType::F64);
        let fabric = FabricParams::default();
        let rest = rest_of(&mesh, &[], &[], &fabric);
        let t = terms(&rest, &fabric, &all_effects(), &device, DType::F64);
        // Baraff-Witkin: k Σ 2A (s² + q²) with Σ 2A = 2 m², no shear.
        let (stretch, shear) = energies::baraff_witkin(&xt, t.tensors(), 10.0, 1.0);
        let expected = 10.0 * 2.0 * (s * s + q * q);
        let got = scalar(stretch);
        assert!(
            (got - expected).abs() < 1e-7 * expected,
            "{got} vs {expected}"
        );
        assert!(scalar(shear).abs() < 1e-12);
        // StVK: Σ 2A (μ (G00² + G11²) + λ/2 (G00 + G11)²).
        let (g0, g1) = (
            ((1.0 + s).powi(2) - 1.0) / 2.0,
            ((1.0 + q).powi(2) - 1.0) / 2.0,
        );
        let psi = 11.1 * (g0 * g0 + g1 * g1) + 0.5 * 20.9 * (g0 + g1).powi(2);
        let got = scalar(energies::stvk(&xt, t.tensors(), 20.9, 11.1));
        assert!(
            (got - 2.0 * psi).abs() < 1e-7 * psi,
            "{got} vs {}",
            2.0 * psi
        );
        // Mass-spring: k Σ_e (|A e| - |e|)² edge by edge.
        let springs: f64 = rest
            .edges
            .iter()
            .map(|&[a, b]| {
                let d = mesh.positions[a as usize] - mesh.positions[b as usize];
                let d = [d.x as f64, d.y as f64, d.z as f64];
                let scale = |k: usize| {
                    if k == 0 {
                        1.0 + s
                    } else if k == warp_axis {
                        1.0 + q
                    } else {
                        1.0
                    }
                };
                let l0 = d.iter().map(|v| v * v).sum::<f64>().sqrt();
                let l1 = (0..3)
                    .map(|k| (d[k] * scale(k)).powi(2))
                    .sum::<f64>()
                    .sqrt();
                (l1 - l0).powi(2)
            })
            .sum();
        let got = scalar(energies::mass_spring(&xt, t.tensors(), 10.0));
        assert!(
            (got - 10.0 * springs).abs() < 1e-7 * springs,
            "{got} vs {}",
            10.0 * springs
        );
    }
}

#[test]
fn a_vertex_one_centimetre_inside_a_sphere_gives_the_analytic_collision_loss() {
    let device = f64_device();
    let (radius, eps, k_c) = (0.5f32, 0.004f64, 10.0f64);
    let body_mesh = uv_sphere(Vec3::zeros(), radius, 24, 32);
    let body = Arc::new(PosedBody::new(body_mesh.positions.clone(), &body_mesh.faces).unwrap());
    // Vertex 0 sits 1 cm below the north pole (a body vertex whose normal is +Y by symmetry);
    // the other two are well outside.
    let garment = TriMesh::new(
        vec![
            Vec3::new(0.0, radius - 0.01, 0.0),
            Vec3::new(0.3, 0.9, 0.0),
            Vec3::new(0.0, 0.9, 0.3),
        ],
        vec![[0, 1, 2]],
    )
    .unwrap();
    let fabric = FabricParams::default();
    let rest = rest_of(&garment, &[], &[], &fabric);
    let t = terms(&rest, &fabric, &all_effects(), &device, DType::F64);
    let x = tensor(&flat(&garment.positions), &device, DType::F64);
    let losses = t
        .static_losses(&x, Some(&BodyBatch::new(vec![body.clone()])))
        .unwrap();
    let got = scalar(losses.get(Term::Collision).unwrap().clone());
    let expected = k_c * (-0.01f64 - eps).powi(2);
    assert!(
        (got - expected).abs() < 1e-5 * expected,
        "{got} vs {expected}"
    );
    assert!((body.signed_distance(&garment.positions[0]) + 0.01).abs() < 1e-5);
    // Exactly on the surface: d = 0 still costs k ε² and pushes outwards.
    let on = TriMesh::new(
        vec![
            Vec3::new(0.0, radius, 0.0),
            Vec3::new(0.3, 0.9, 0.0),
            Vec3::new(0.0, 0.9, 0.3),
        ],
        vec![[0, 1, 2]],
    )
    .unwrap();
    let xs = flat(&on.positions);
    let contacts = Contacts::query(
        &BodyBatch::new(vec![body]),
        &xs.iter().map(|v| *v as f32).collect::<Vec<_>>(),
        3,
        &device,
        DType::F64,
    )
    .unwrap();
    let (v, g) = gradient(
        &|x| collision::collision(x, &contacts, t.tensors(), 10.0, 0.004),
        &xs,
        &device,
        DType::F64,
    );
    assert!(
        (v - k_c * eps * eps).abs() < 1e-6 * v && g[1] < 0.0 && all_finite(&g),
        "{v} {g:?}"
    );
}

#[test]
fn gravity_energy_is_sum_of_m_g_h_and_the_no_collide_list_is_skipped() {
    let device = Device::flex();
    let (mesh, x) = random_case(11);
    let fabric = FabricParams {
        gravity_m_per_s2: [0.0, -9.81, 0.0],
        density_kg_per_m2: 0.3,
        ..FabricParams::default()
    };
    let rest = rest_of(&mesh, &[], &[0, 1, 2], &fabric);
    let t = terms(&rest, &fabric, &all_effects(), &device, DType::F32);
    let expected: f64 = rest
        .mass_kg
        .iter()
        .zip(x.chunks(3))
        .map(|(m, p)| *m * 9.81 * p[1])
        .sum();
    let got = scalar(energies::gravity(
        &tensor(&x, &device, DType::F32),
        t.tensors(),
    ));
    assert!(
        (got - expected).abs() < 1e-5 * expected.abs(),
        "{got} vs {expected}"
    );
    assert!((rest.total_mass_kg - 0.3 * rest.total_area_m2).abs() < 1e-6 * rest.total_mass_kg);
    // Every vertex deep inside a big sphere, but the first three are exempt.
    let body_mesh = uv_sphere(Vec3::new(0.0, 1.0, 0.0), 2.0, 8, 12);
    let body = Arc::new(PosedBody::new(body_mesh.positions, &body_mesh.faces).unwrap());
    let xf: Vec<f32> = x.iter().map(|v| *v as f32).collect();
    let contacts = Contacts::query(
        &BodyBatch::new(vec![body]),
        &xf,
        mesh.positions.len(),
        &device,
        DType::F32,
    )
    .unwrap();
    let xt = tensor(&x, &device, DType::F32);
    let d = neural_cloth_physics::tensors::read_f64(collision::signed_distances(&xt, &contacts))
        .unwrap();
    let expected: f64 = d
        .iter()
        .enumerate()
        .filter(|(i, _)| *i >= 3)
        .map(|(_, d)| 10.0 * (d - 0.004).min(0.0).powi(2))
        .sum();
    let got = scalar(collision::collision(
        &xt,
        &contacts,
        t.tensors(),
        10.0,
        0.004,
    ));
    assert!(
        expected > 0.0 && (got - expected).abs() < 1e-4 * expected,
        "{got} vs {expected}"
    );
    let m = t.metrics(&xt, Some(&contacts), None).unwrap();
    assert_eq!(m.collision_pct, Some(100.0));
}

#[test]
fn inertia_gradient_reaches_only_the_current_frame() {
    let device = Device::flex().autodiff();
    let (mesh, x) = random_case(5);
    let fabric = FabricParams::default();
    let rest = rest_of(&mesh, &[], &[], &fabric);
    let t = terms(&rest, &fabric, &all_effects(), &device, DType::F32);
    let xt = tensor(&x, &device, DType::F32).require_grad();
    let x1 = tensor(
        &x.iter().map(|v| v - 0.01).collect::<Vec<_>>(),
        &device,
        DType::F32,
    )
    .require_grad();
    let x2 = tensor(
        &x.iter().map(|v| v + 0.02).collect::<Vec<_>>(),
        &device,
        DType::F32,
    )
    .require_grad();
    let loss = t.inertia(&xt, &x1, &x2, 1.0 / 30.0).unwrap();
    let grads = loss.backward();
    let g_t = neural_cloth_physics::tensors::read_f64(xt.grad(&grads).unwrap()).unwrap();
    assert!(g_t.iter().any(|v| v.abs() > 0.0));
    for prev in [&x1, &x2] {
        if let Some(g) = prev.grad(&grads) {
            assert!(
                neural_cloth_physics::tensors::read_f64(g)
                    .unwrap()
                    .iter()
                    .all(|v| *v == 0.0)
            );
        }
    }
    let off = terms(
        &rest,
        &fabric,
        &Effects {
            dynamics: false,
            ..all_effects()
        },
        &device,
        DType::F32,
    );
    assert!(off.inertia(&xt, &x1, &x2, 1.0 / 30.0).is_none());
}
