//! Avatars for the fit layer's tests.

use neural_cloth_core::geometry::Vec3;
use neural_cloth_core::scene::Avatar;
use neural_cloth_core::scene::procedural::mannequin;

use super::probe::{self, BodyProbe};
use super::repose;

/// The mannequin with its hips and legs drawn in to no wider or deeper than its waist:
/// like a stylised game character (a short, straight torso on which nothing is wider
/// below the waist than at it), where a skirt cannot rest on the hips.
pub fn flat_hipped_mannequin() -> Avatar {
    let m = mannequin().unwrap();
    let arms = repose::Limbs::arms(&m).unwrap().moved_joints(&m.skeleton);
    let on_arm: Vec<bool> = (0..m.skin.len())
        .map(|v| {
            let w: f32 = m.skin.joints[v]
                .iter()
                .zip(m.skin.weights[v])
                .filter(|(j, _)| arms[usize::from(**j)])
                .map(|(_, w)| w)
                .sum();
            w > 0.01
        })
        .collect();
    let probe = BodyProbe::rest(&m).unwrap();
    let (crotch, neck) = probe.trunk_m().unwrap();
    let trunk: Vec<Vec3> = m
        .rest_mesh
        .positions
        .iter()
        .zip(&on_arm)
        .filter(|(_, a)| !**a)
        .map(|(p, _)| *p)
        .collect();
    // Half width and half depth (about the band's middle) of the trunk and legs at `y`.
    let extent = |y: f32| {
        let band: Vec<Vec3> = trunk
            .iter()
            .copied()
            .filter(|p| (p.y - y).abs() < 0.02)
            .collect();
        let (lo, hi) = probe::bounds_of(&band).unwrap();
        (hi.x.max(-lo.x), 0.5 * (hi.z - lo.z), 0.5 * (hi.z + lo.z))
    };
    // The waist: the narrowest band between the crotch and the chest.
    let waist = (0..20)
        .map(|k| crotch + 0.1 + k as f32 * 0.4 * (neck - crotch) / 20.0)
        .min_by(|a, b| extent(*a).0.total_cmp(&extent(*b).0))
        .unwrap();
    let (half_width, half_depth, _) = extent(waist);
    let mut bind = m.bind_mesh.clone();
    for (p, arm) in bind.positions.iter_mut().zip(&on_arm) {
        if *arm || p.y >= waist {
            continue;
        }
        let (w, d, mid) = extent(p.y);
        p.x *= (half_width / w).min(1.0);
        p.z = mid + (p.z - mid) * (half_depth / d).min(1.0);
    }
    Avatar::new("flat-hipped", m.skeleton, bind, m.skin, Vec::new()).unwrap()
}
