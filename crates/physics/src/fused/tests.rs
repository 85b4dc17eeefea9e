//! The fused kernels against the burn reference (values and autodiff gradients, `f64`), against
//! central differences, and the surrogate's value and gradient in `f32` and through an upstream
//! operation.

use std::sync::{Arc, OnceLock};

use burn::tensor::{DType, Device, Tensor, TensorData};

use super::*;
use crate::collision::{BodyBatch, Contacts, PosedBody};
use crate::shapes::{sheet, uv_sphere};
use crate::tensors::read_f64;
use crate::{ClothModel, Effects, FabricParams, PhysicsTerms, Term};
use neural_cloth_core::geometry::{Topology, TriMesh, Vec3};
use neural_cloth_core::scene::procedural::{GarmentKind, builtin_garment, mannequin};
use neural_cloth_core::scene::{Avatar, Garment};

/// Deterministic pseudo-random numbers in [-0.5, 0.5).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64) / ((1u64 << 53) as f64) - 0.5
    }
}

fn all_effects() -> Effects {
    Effects {
        gravity: true,
        bending: true,
        collision: true,
        dynamics: true,
        pinning: true,
        friction: true,
    }
}

fn f64_device() -> Device {
    Device::flex().autodiff()
}

fn tensor(x: &[f64], batch: usize, device: &Device, dtype: DType) -> Tensor<3> {
    Tensor::from_data(
        TensorData::new(x.to_vec(), [batch, x.len() / batch / 3, 3]),
        (device, dtype),
    )
}

fn flat(positions: &[Vec3]) -> Vec<f64> {
    positions
        .iter()
        .flat_map(|p| [p.x, p.y, p.z].map(f64::from))
        .collect()
}

/// A test scene: rest state, `batch` posed samples and the bodies they collide with.
struct Case {
    name: String,
    rest: Arc<GarmentRest>,
    x: Vec<f64>,
    batch: usize,
    bodies: BodyBatch,
}

/// A randomly perturbed 5x4 sheet (rest and pose), three samples, a sphere cutting through it;
/// one vertex does not collide and one is pinned.
fn random_case(seed: u64) -> Case {
    let mesh = sheet(
        5,
        4,
        Vec3::new(-0.2, 1.0, -0.15),
        Vec3::new(0.4, 0.0, 0.0),
        Vec3::new(0.0, 0.05, 0.3),
    );
    let mut rng = Lcg(seed);
    let mut rest_mesh = mesh.clone();
    for p in &mut rest_mesh.positions {
        *p += Vec3::new(rng.next() as f32, rng.next() as f32, rng.next() as f32) * 0.03;
    }
    let rest = GarmentRest::new(&rest_mesh, &Topology::new(&rest_mesh), &[0], &[3], 0.15).unwrap();
    let batch = 3;
    let x: Vec<f64> = (0..batch)
        .flat_map(|_| flat(&rest_mesh.positions))
        .map(|v| v * (1.0 + 0.15 * rng.next()) + 0.02 * rng.next())
        .collect();
    let body_mesh = uv_sphere(Vec3::new(0.0, 0.75, 0.0), 0.3, 10, 14);
    let body = Arc::new(PosedBody::new(body_mesh.positions, &body_mesh.faces).unwrap());
    Case {
        name: format!("random sheet (seed {seed})"),
        rest: Arc::new(rest),
        x,
        batch,
        bodies: BodyBatch::new(vec![body; batch]),
    }
}

fn scene() -> &'static (Avatar, Garment, Garment) {
    static SCENE: OnceLock<(Avatar, Garment, Garment)> = OnceLock::new();
    SCENE.get_or_init(|| {
        let avatar = mannequin().unwrap();
        let shirt = builtin_garment(&avatar, GarmentKind::TShirt, 3400, None).unwrap();
        let skirt = builtin_garment(&avatar, GarmentKind::Skirt, 1200, None).unwrap();
        (avatar, shirt, skirt)
    })
}

/// A built-in garment on the mannequin in its bind pose, two samples with a few millimetres of
/// noise, the second squeezed so that part of it sits inside the body.
fn garment_case(garment: &Garment, avatar: &Avatar, seed: u64) -> Case {
    let rest = GarmentRest::from_garment(garment, &FabricParams::default()).unwrap();
    let mut rng = Lcg(seed);
    let batch = 2;
    // Sample 0 as built, sample 1 pulled in horizontally by 8 % (into the body).
    let x: Vec<f64> = (0..batch)
        .flat_map(|b| {
            let squeeze = 1.0 - 0.08 * b as f64;
            flat(&garment.mesh.positions)
                .into_iter()
                .enumerate()
                .map(move |(i, v)| if i % 3 == 1 { v } else { v * squeeze })
        })
        .map(|v| v + 0.006 * rng.next())
        .collect();
    let body = Arc::new(
        PosedBody::new(avatar.bind_mesh.positions.clone(), &avatar.bind_mesh.faces).unwrap(),
    );
    Case {
        name: garment.name.clone(),
        rest: Arc::new(rest),
        x,
        batch,
        bodies: BodyBatch::new(vec![body; batch]),
    }
}

/// Per-sample energies and the gradient of their sum, for every static term of `terms`.
fn evaluate_terms(
    terms: &PhysicsTerms,
    case: &Case,
    contacts: &Contacts,
) -> Vec<(Term, Vec<f64>, Vec<f64>)> {
    let (device, dtype) = (terms.device().clone(), terms.dtype());
    let count = terms
        .static_energies(&tensor(&case.x, case.batch, &device, dtype), Some(contacts))
        .unwrap()
        .len();
    (0..count)
        .map(|i| {
            let x = tensor(&case.x, case.batch, &device, dtype).require_grad();
            let (term, e) = terms
                .static_energies(&x, Some(contacts))
                .unwrap()
                .swap_remove(i);
            let values = read_f64(e.clone().detach()).unwrap();
            let grads = e.sum().backward();
            let g = x
                .grad(&grads)
                .map(|g| read_f64(g).unwrap())
                .unwrap_or_else(|| vec![0.0; case.x.len()]);
            (term, values, g)
        })
        .collect()
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

/// Asserts the fused and reference terms of `case` agree for every cloth model: same terms in
/// the same order, per-sample values and gradients within `1e-5` relative.
fn assert_fused_matches_reference(case: &Case) {
    let device = f64_device();
    let n = case.rest.vertex_count();
    let xf: Vec<f32> = case.x.iter().map(|v| *v as f32).collect();
    let contacts = Contacts::query(&case.bodies, &xf, n, &device, DType::F64).unwrap();
    let colliding = contacts.distances_m.iter().filter(|d| **d < 0.004).count();
    assert!(colliding > 0, "{}: no vertex touches the body", case.name);
    for model in [
        ClothModel::MassSpring,
        ClothModel::BaraffWitkin,
        ClothModel::Stvk,
    ] {
        let fabric = FabricParams {
            cloth_model: model,
            ..FabricParams::default()
        };
        let terms = PhysicsTerms::from_rest(
            case.rest.clone(),
            &fabric,
            &all_effects(),
            &device,
            DType::F64,
        )
        .unwrap();
        assert!(terms.fused(), "fused kernels are the default");
        let fused = evaluate_terms(&terms, case, &contacts);
        let reference = evaluate_terms(&terms.clone().with_fused(false), case, &contacts);
        let names = |t: &[(Term, Vec<f64>, Vec<f64>)]| t.iter().map(|r| r.0).collect::<Vec<_>>();
        assert_eq!(names(&fused), names(&reference), "{}: {model:?}", case.name);
        for ((term, fv, fg), (_, rv, rg)) in fused.iter().zip(&reference) {
            let what = format!("{} {model:?} {}", case.name, term.name());
            for (a, b) in fv.iter().zip(rv) {
                assert!(
                    (a - b).abs() <= 1e-5 * b.abs().max(1e-12),
                    "{what}: energy {a} vs reference {b}"
                );
            }
            let scale = max_abs(rg);
            assert!(
                scale > 0.0,
                "{what}: zero reference gradient, vacuous check"
            );
            for (i, (a, b)) in fg.iter().zip(rg).enumerate() {
                assert!(
                    (a - b).abs() <= 1e-5 * scale,
                    "{what}: gradient {i}: {a} vs reference {b} (scale {scale})"
                );
            }
        }
    }
}

#[test]
fn fused_terms_match_the_burn_reference_on_random_sheets() {
    for seed in [1, 7, 42] {
        assert_fused_matches_reference(&random_case(seed));
    }
}

#[test]
fn fused_terms_match_the_burn_reference_on_builtin_garments() {
    let (avatar, shirt, skirt) = scene();
    assert_fused_matches_reference(&garment_case(shirt, avatar, 3));
    assert_fused_matches_reference(&garment_case(skirt, avatar, 4));
}

/// Every kernel with the stiffnesses of the default fabric (Baraff-Witkin split in two),
/// widened from `f32` exactly as [`PhysicsTerms`] does.
fn every_kernel() -> Vec<Kernel> {
    let f = FabricParams::default();
    let k = |v: f32| f64::from(v);
    vec![
        Kernel::MassSpring {
            k: k(f.stretch_stiffness),
        },
        Kernel::BaraffWitkinStretch {
            k: k(f.stretch_stiffness),
        },
        Kernel::BaraffWitkinShear {
            k: k(f.shear_stiffness),
        },
        Kernel::Stvk {
            lambda: k(f.lame_lambda),
            mu: k(f.lame_mu),
        },
        Kernel::Bending {
            k: k(f.bending_stiffness),
        },
        Kernel::Collision {
            k: k(f.collision_stiffness),
            eps_m: k(f.collision_threshold_m),
        },
        Kernel::Gravity {
            g: f.gravity_m_per_s2.map(f64::from),
        },
    ]
}

fn host_contacts(case: &Case) -> HostContacts {
    let n = case.rest.vertex_count();
    let mut contacts = HostContacts::default();
    for (k, q) in case.x.chunks_exact(3).enumerate() {
        let body = &case.bodies.bodies[k / n];
        let q = Vec3::new(q[0] as f32, q[1] as f32, q[2] as f32);
        let i = body.nearest(&q);
        let (p, nb) = (body.positions()[i], body.normals()[i]);
        contacts.points.extend([p.x, p.y, p.z]);
        contacts.normals.extend([nb.x, nb.y, nb.z]);
    }
    contacts
}

#[test]
fn fused_gradients_match_central_differences() {
    let (avatar, shirt, _) = scene();
    for case in [
        random_case(5),
        random_case(11),
        garment_case(shirt, avatar, 8),
    ] {
        let pool = ScratchPool::default();
        let contacts = host_contacts(&case);
        let mut rng = Lcg(99);
        let h = 1e-6;
        for kernel in every_kernel() {
            let run = |x: &[f64]| -> Evaluation<f64> {
                let mut out =
                    evaluate(&case.rest, &[kernel], x, case.batch, Some(&contacts), &pool).unwrap();
                out.swap_remove(0)
            };
            let total = |x: &[f64]| -> f64 { run(x).energies.iter().sum() };
            let analytic = run(&case.x).gradient;
            let scale = max_abs(&analytic);
            assert!(scale > 0.0, "{} {kernel:?}: zero gradient", case.name);
            // Coordinates with a non-zero gradient (collision touches few vertices).
            let active: Vec<usize> = (0..case.x.len()).filter(|&i| analytic[i] != 0.0).collect();
            for _ in 0..12 {
                let pick = ((rng.next() + 0.5) * active.len() as f64) as usize;
                let i = active[pick % active.len()];
                let (mut xp, mut xm) = (case.x.clone(), case.x.clone());
                xp[i] += h;
                xm[i] -= h;
                let fd = (total(&xp) - total(&xm)) / (2.0 * h);
                assert!(
                    (fd - analytic[i]).abs() <= 1e-5 * scale,
                    "{} {kernel:?}: coordinate {i}: analytic {} vs central difference {fd} \
                     (scale {scale})",
                    case.name,
                    analytic[i]
                );
            }
        }
    }
}

#[test]
fn fused_kernels_handle_collapsed_and_folded_elements() {
    // Coincident vertices, a face collapsed to a point and a hinge folded flat onto itself:
    // finite values and gradients, equal to the reference.
    let mut case = random_case(21);
    let n = case.rest.vertex_count();
    let (a, b) = (6, 7);
    for k in 0..3 {
        case.x[3 * b + k] = case.x[3 * a + k];
    }
    // Sample 1: fold the sheet along its middle row onto itself.
    for v in 0..n {
        let y = case.x[3 * (n + v) + 2];
        if y > 0.0 {
            case.x[3 * (n + v) + 2] = -y;
        }
    }
    assert_fused_matches_reference(&case);
    let pool = ScratchPool::default();
    let contacts = host_contacts(&case);
    for e in evaluate(
        &case.rest,
        &every_kernel(),
        &case.x,
        case.batch,
        Some(&contacts),
        &pool,
    )
    .unwrap()
    {
        assert!(e.energies.iter().chain(&e.gradient).all(|v| v.is_finite()));
    }
}

#[test]
fn surrogate_has_the_energy_as_value_and_the_kernel_gradient_upstream_in_f32() {
    // x = 2 w: the gradient reaching w must be 2 G, the value e, in the training dtype.
    let device = Device::flex().autodiff();
    let case = random_case(13);
    let fabric = FabricParams::default();
    let effects = Effects {
        collision: false,
        ..all_effects()
    };
    let terms =
        PhysicsTerms::from_rest(case.rest.clone(), &fabric, &effects, &device, DType::F32).unwrap();
    let w = tensor(&case.x, case.batch, &device, DType::F32)
        .div_scalar(2.0)
        .detach();
    let xf: Vec<f32> = read_f64(w.clone().mul_scalar(2.0))
        .unwrap()
        .iter()
        .map(|v| *v as f32)
        .collect();
    let kernels: Vec<Kernel> = every_kernel()
        .into_iter()
        .filter(|k| {
            !matches!(
                k,
                Kernel::Collision { .. } | Kernel::MassSpring { .. } | Kernel::Stvk { .. }
            )
        })
        .collect();
    let expected = evaluate(
        &case.rest,
        &kernels,
        &xf,
        case.batch,
        None,
        &ScratchPool::default(),
    )
    .unwrap();
    assert_eq!(
        terms
            .static_energies(&w.clone().mul_scalar(2.0), None)
            .unwrap()
            .len(),
        expected.len()
    );
    for (i, want) in expected.iter().enumerate() {
        // A fresh graph per term: burn consumes the tape on backward.
        let w = w.clone().require_grad();
        let (term, e) = terms
            .static_energies(&w.clone().mul_scalar(2.0), None)
            .unwrap()
            .swap_remove(i);
        let value = read_f64(e.clone().detach()).unwrap();
        for (v, w) in value.iter().zip(&want.energies) {
            assert_eq!(*v as f32, *w as f32, "{}: value", term.name());
        }
        let grads = e.sum().backward();
        let g = read_f64(w.grad(&grads).unwrap()).unwrap();
        let scale = want.gradient.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        assert!(scale > 0.0, "{}: zero gradient", term.name());
        for (a, b) in g.iter().zip(&want.gradient) {
            assert!(
                (*a as f32 - 2.0 * b).abs() <= 1e-6 * scale,
                "{}: upstream gradient {a} vs 2 x {b}",
                term.name()
            );
        }
    }
}

#[test]
fn shape_errors_are_typed() {
    let case = random_case(2);
    let pool = ScratchPool::default();
    let short = &case.x[..case.x.len() - 3];
    assert!(matches!(
        evaluate(
            &case.rest,
            &every_kernel()[..1],
            short,
            case.batch,
            None,
            &pool
        ),
        Err(PhysicsError::ShapeMismatch { .. })
    ));
    assert!(matches!(
        evaluate(
            &case.rest,
            &every_kernel(),
            &case.x,
            case.batch,
            None,
            &pool
        ),
        Err(PhysicsError::ShapeMismatch { .. })
    ));
    let single = TriMesh::new(vec![Vec3::zeros(), Vec3::x(), Vec3::y()], vec![[0, 1, 2]]).unwrap();
    let rest = GarmentRest::new(&single, &Topology::new(&single), &[], &[], 0.15).unwrap();
    assert!(evaluate(&rest, &every_kernel()[..1], &[0.0f64; 9], 0, None, &pool).is_err());
}

#[test]
#[ignore = "timing: run with --ignored --nocapture"]
fn kernel_cost_per_sample() {
    // This thread's CPU time (the machine may be shared), best of 5 runs of 40.
    let cpu_ns = || -> f64 {
        std::fs::read_to_string("/proc/thread-self/schedstat")
            .ok()
            .and_then(|s| s.split_whitespace().next()?.parse().ok())
            .unwrap_or(0.0)
    };
    let mesh = crate::shapes::tube(Vec3::new(0.0, 1.0, 0.0), 0.31, 0.45, 0.25, -0.35, 81, 39);
    let rest = GarmentRest::new(&mesh, &Topology::new(&mesh), &[], &[], 0.15).unwrap();
    let x: Vec<f32> = mesh
        .positions
        .iter()
        .enumerate()
        .flat_map(|(i, p)| {
            let w = 0.01 * ((i * 7) as f32).sin();
            [p.x * (1.0 + w), p.y + w, p.z * (1.0 - w)]
        })
        .collect();
    let contacts = HostContacts {
        points: x.iter().map(|v| v * 0.99).collect(),
        normals: x.iter().map(|_| 0.577).collect(),
    };
    let mut g = vec![0.0; x.len()];
    let pool = ScratchPool::default();
    println!(
        "{} vertices, {} faces, {} hinges",
        rest.vertex_count(),
        rest.faces.len(),
        rest.hinges.len()
    );
    for kernel in every_kernel() {
        let s = Sample {
            x: &x,
            contacts: Some((&contacts.points, &contacts.normals)),
        };
        let best = (0..5)
            .map(|_| {
                let start = cpu_ns();
                for _ in 0..40 {
                    g.iter_mut().for_each(|v| *v = 0.0);
                    std::hint::black_box(run(&kernel, &rest, &s, &mut g, &pool));
                }
                (cpu_ns() - start) / 40.0
            })
            .fold(f64::INFINITY, f64::min);
        println!("{kernel:?}: {:.3} ms per sample", best * 1e-6);
    }
}

#[test]
fn fused_terms_match_the_reference_on_wgpu() {
    use burn::tensor::DeviceKind;
    let device = Device::wgpu(DeviceKind::DefaultDevice).autodiff();
    let case = random_case(31);
    let fabric = FabricParams::default();
    let effects = Effects {
        collision: false,
        ..all_effects()
    };
    let terms =
        PhysicsTerms::from_rest(case.rest.clone(), &fabric, &effects, &device, DType::F32).unwrap();
    let total = |t: &PhysicsTerms| {
        let x = tensor(&case.x, case.batch, &device, DType::F32).require_grad();
        let e = t
            .static_energies(&x, None)
            .unwrap()
            .into_iter()
            .map(|(_, e)| e.sum())
            .reduce(|a, b| a + b)
            .unwrap();
        let value = read_f64(e.clone().detach()).unwrap()[0];
        let g = read_f64(x.grad(&e.backward()).unwrap()).unwrap();
        (value, g)
    };
    let (fv, fg) = total(&terms);
    let (rv, rg) = total(&terms.clone().with_fused(false));
    eprintln!("wgpu: fused {fv} reference {rv}");
    assert!((fv - rv).abs() <= 1e-4 * rv.abs());
    let scale = max_abs(&rg);
    for (a, b) in fg.iter().zip(&rg) {
        assert!((a - b).abs() <= 1e-3 * scale, "{a} vs {b}");
    }
}
