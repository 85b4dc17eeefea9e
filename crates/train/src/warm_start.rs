//! Warm start of a run from a simulated drape (issue 11): the reference simulator lets the
//! garment settle on the avatar's rest pose, and the network's basis bias starts at the
//! offset from the template to that drape. Still unsupervised: the only data is our own
//! simulator's answer for one still pose.
//!
//! Why: a flared template (the built-in skirt's hem stands 276 mm from the body axis, where it
//! hangs at about 133 mm) must fold to drape. Folds are a buckling instability: from the
//! smooth template the loss gradient points nowhere near them, and a network that starts
//! there learns a smooth compromise slowly (measured in docs/TRAINING.md). The simulator,
//! stepping through the fall, finds the folds; the network then learns the deviations from
//! them. At the rest pose the garment's skinning matrices are the identity, so the simulated
//! world positions are rest-space positions.

use burn::tensor::{Device, Tensor, TensorData};

use neural_cloth_core::geometry::Vec3;
use neural_cloth_core::scene::{Avatar, Garment};
use neural_cloth_model::ClothNet;
use neural_cloth_physics::simulator::settle_on_rest_pose;
use neural_cloth_physics::{Effects, FabricParams};

use super::{BackendKind, TrainError, device_for};

/// The garment after `settle_secs` of simulation on the avatar's rest pose, at `fps` with
/// `iterations` L-BFGS iterations per step, on the CPU.
pub fn simulated_drape(
    avatar: &Avatar,
    garment: &Garment,
    fabric: &FabricParams,
    effects: &Effects,
    settle_secs: f32,
    fps: f32,
    iterations: usize,
) -> Result<Vec<Vec3>, TrainError> {
    let device = device_for(BackendKind::Cpu, false);
    Ok(settle_on_rest_pose(
        avatar,
        garment,
        fabric,
        effects,
        settle_secs,
        fps,
        iterations,
        &device,
    )?)
}

/// Mean distance between the drape and the template, metres (how far the warm start moves).
pub fn mean_offset_m(garment: &Garment, drape: &[Vec3]) -> f64 {
    let n = drape.len().min(garment.vertex_count()).max(1);
    garment
        .mesh
        .positions
        .iter()
        .zip(drape)
        .map(|(t, d)| f64::from((d - t).norm()))
        .sum::<f64>()
        / n as f64
}

/// Sets the basis bias of `net` to `drape - template` (rest space). Fails when the network
/// has no basis bias or the vertex counts differ.
pub fn set_basis_bias_to_drape(
    net: &mut ClothNet,
    garment: &Garment,
    drape: &[Vec3],
    device: &Device,
) -> Result<(), TrainError> {
    if drape.len() != garment.vertex_count() || net.vertices != drape.len() {
        return Err(TrainError::Data(format!(
            "drape of {} vertices for a garment of {} and a network of {}",
            drape.len(),
            garment.vertex_count(),
            net.vertices
        )));
    }
    // Stored as b̂ = b / bias_scale (see `ClothNetConfig::basis_bias_lr_scale`).
    let inv_scale = (1.0 / net.decoder.bias_scale) as f32;
    let offsets: Vec<f32> = garment
        .mesh
        .positions
        .iter()
        .zip(drape)
        .flat_map(|(t, d)| {
            let o = (d - t) * inv_scale;
            [o.x, o.y, o.z]
        })
        .collect();
    let n = offsets.len();
    let Some(bias) = net.decoder.basis.bias.take() else {
        return Err(TrainError::Data(
            "the network has no basis bias to warm-start (model.basis_bias = false)".into(),
        ));
    };
    net.decoder.basis.bias = Some(bias.map(|_| {
        let t = Tensor::<1>::from_data(TensorData::new(offsets, [n]), device);
        if device.is_autodiff() {
            t.require_grad()
        } else {
            t
        }
    }));
    Ok(())
}
