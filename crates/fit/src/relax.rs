//! Relaxing an aligned garment onto the avatar's rest pose with the reference simulator: the
//! same settle on a held rest pose that the training's warm start runs
//! (`physics::simulator::settle_on_rest_pose`), with bending, collision and inertia but without
//! gravity, so vertices left inside the body are pushed out and the garment keeps its shape
//! and place. Gravity is left to the training's warm start: without a pinned waistband a
//! skirt slides off a frictionless body, and the fit would write it at the feet.

use burn::tensor::Device;

use neural_cloth_core::geometry::{TriMesh, Vec3};
use neural_cloth_core::scene::{Avatar, Garment, GarmentOptions};
use neural_cloth_physics::simulator::settle_on_rest_pose;
use neural_cloth_physics::{Effects, FabricParams};

use super::FitError;

/// How long and how finely the garment is relaxed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RelaxSettings {
    /// Seconds of simulated settling on the held rest pose; (0, 60], default 1.
    pub settle_secs: f32,
    /// Simulation steps per second; [1, 1000], default 30.
    pub fps: f32,
    /// L-BFGS iterations per step; 1..=10000, default 60.
    pub iterations: usize,
}

impl Default for RelaxSettings {
    fn default() -> Self {
        Self {
            settle_secs: 1.0,
            fps: 30.0,
            iterations: 60,
        }
    }
}

/// Largest garment-to-body distance accepted while relaxing, metres (a long dress's hem may
/// hang far from the nearest body vertex; its skin weights do not matter at the rest pose).
const RELAX_MAX_DISTANCE_M: f32 = 5.0;

/// The garment `mesh` (already aligned, metres) after settling on `avatar`'s rest pose with
/// the default fabric. `name` names the garment in errors.
pub fn relax(
    avatar: &Avatar,
    name: &str,
    mesh: &TriMesh,
    settings: &RelaxSettings,
) -> Result<Vec<Vec3>, FitError> {
    let options = GarmentOptions {
        max_distance_m: RELAX_MAX_DISTANCE_M,
        ..GarmentOptions::default()
    };
    let garment = Garment::new(name, mesh.clone(), avatar, &options)?;
    Ok(settle_on_rest_pose(
        avatar,
        &garment,
        &FabricParams::default(),
        &Effects {
            gravity: false,
            pinning: false,
            ..Effects::default()
        },
        settings.settle_secs,
        settings.fps,
        settings.iterations,
        &Device::flex(),
    )?)
}
