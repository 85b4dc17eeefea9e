//! Helpers shared by the physics integration tests.

use std::sync::Arc;

use burn::tensor::{DType, Device, Tensor, TensorData};
use neural_cloth_core::geometry::{Topology, TriMesh, Vec3};
use neural_cloth_physics::rest::GarmentRest;
use neural_cloth_physics::tensors::read_f64;
use neural_cloth_physics::{Effects, FabricParams, PhysicsTerms};

/// Deterministic pseudo-random numbers in [-0.5, 0.5).
pub struct Lcg(pub u64);

impl Lcg {
    pub fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64) / ((1u64 << 53) as f64) - 0.5
    }
}

pub fn all_effects() -> Effects {
    Effects {
        gravity: true,
        bending: true,
        collision: true,
        dynamics: true,
        pinning: true,
        friction: true,
    }
}

pub fn rest_of(
    mesh: &TriMesh,
    pinned: &[u32],
    no_collide: &[u32],
    fabric: &FabricParams,
) -> Arc<GarmentRest> {
    Arc::new(
        GarmentRest::new(
            mesh,
            &Topology::new(mesh),
            pinned,
            no_collide,
            fabric.density_kg_per_m2,
        )
        .unwrap(),
    )
}

pub fn terms(
    rest: &Arc<GarmentRest>,
    fabric: &FabricParams,
    effects: &Effects,
    device: &Device,
    dtype: DType,
) -> PhysicsTerms {
    PhysicsTerms::from_rest(rest.clone(), fabric, effects, device, dtype).unwrap()
}

/// `[1, V, 3]` tensor from f64 coordinates.
pub fn tensor(x: &[f64], device: &Device, dtype: DType) -> Tensor<3> {
    Tensor::from_data(
        TensorData::new(x.to_vec(), [1, x.len() / 3, 3]),
        (device, dtype),
    )
}

pub fn flat(positions: &[Vec3]) -> Vec<f64> {
    positions
        .iter()
        .flat_map(|p| [p.x as f64, p.y as f64, p.z as f64])
        .collect()
}

pub fn scalar(t: Tensor<1>) -> f64 {
    read_f64(t.sum()).unwrap()[0]
}

pub fn all_finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// Autodiff gradient of `f` at `x`.
pub fn gradient(
    f: &dyn Fn(&Tensor<3>) -> Tensor<1>,
    x: &[f64],
    device: &Device,
    dtype: DType,
) -> (f64, Vec<f64>) {
    let xt = tensor(x, device, dtype).require_grad();
    let e = f(&xt).sum();
    let value = read_f64(e.clone().detach()).unwrap()[0];
    let grads = e.backward();
    let g = xt
        .grad(&grads)
        .map(|g| read_f64(g).unwrap())
        .unwrap_or_else(|| vec![0.0; x.len()]);
    (value, g)
}

/// Asserts the autodiff gradient of `f` matches central differences (step 1e-6, tolerance 1e-5
/// of the largest gradient component) on `coords` coordinates.
pub fn check_gradient(
    name: &str,
    f: &dyn Fn(&Tensor<3>) -> Tensor<1>,
    x: &[f64],
    coords: &[usize],
    device: &Device,
    dtype: DType,
) {
    let (h, rel_tol) = (1e-6, 1e-5);
    let (_, g) = gradient(f, x, device, dtype);
    assert!(all_finite(&g), "{name}: non-finite gradient");
    let scale = g.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-12);
    assert!(
        scale > 1e-10,
        "{name}: gradient is identically zero, the check would be vacuous"
    );
    for &i in coords {
        let mut xp = x.to_vec();
        let mut xm = x.to_vec();
        xp[i] += h;
        xm[i] -= h;
        let fp = scalar(f(&tensor(&xp, device, dtype)));
        let fm = scalar(f(&tensor(&xm, device, dtype)));
        let fd = (fp - fm) / (2.0 * h);
        assert!(
            (fd - g[i]).abs() <= rel_tol * scale,
            "{name}: coordinate {i}: autodiff {} vs central difference {fd} (scale {scale})",
            g[i]
        );
    }
}
