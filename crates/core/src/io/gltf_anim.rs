//! glTF animations to motions: keyframe tracks (LINEAR, STEP, CUBICSPLINE) sampled at a fixed
//! rate into local joint rotations and the root translation.
//!
//! Rotation channels drive local rotations. The translation of joint 0 is the root
//! translation; a translation on the single-child chain below joint 0 (e.g. a hip joint under
//! an unanimated root joint) is moved into the root translation exactly. Other translation and
//! scale channels, and channels on non-joint nodes, are ignored with a warning.

use std::collections::HashMap;

use super::IoError;
use super::gltf_doc::GltfDoc;
use crate::geometry::rotation::slerp_unit;
use crate::geometry::{Mat4, Quat, Vec3};
use crate::scene::{JointTransform, Motion, Pose, Skeleton};

/// Most frames one animation may resample to.
const MAX_FRAMES: f32 = 2.0e5;

#[derive(Clone, Copy, PartialEq)]
enum Interp {
    Linear,
    Step,
    Cubic,
}

/// One keyframe track: `dims` values per key (times 3 for cubic splines: in-tangent, value,
/// out-tangent).
struct Track {
    times: Vec<f32>,
    values: Vec<f32>,
    dims: usize,
    interp: Interp,
}

impl Track {
    fn value_at_key(&self, k: usize) -> &[f32] {
        let d = self.dims;
        let start = if self.interp == Interp::Cubic {
            (3 * k + 1) * d
        } else {
            k * d
        };
        self.values.get(start..start + d).unwrap_or(&[])
    }

    fn keys(&self) -> usize {
        self.times.len()
    }

    /// Samples the raw value at `t` (clamped); rotations are slerped for LINEAR.
    fn sample(&self, t: f32, rotation: bool) -> Vec<f32> {
        let n = self.keys();
        let i = self.times.partition_point(|&x| x <= t);
        if i == 0 || n == 1 {
            return self.value_at_key(0).to_vec();
        }
        if i >= n {
            return self.value_at_key(n - 1).to_vec();
        }
        let k = i - 1;
        if self.interp == Interp::Step {
            return self.value_at_key(k).to_vec();
        }
        let (t0, t1) = (self.times[k], self.times[k + 1]);
        let dt = t1 - t0;
        let u = if dt > 0.0 {
            ((t - t0) / dt).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (a, b) = (self.value_at_key(k), self.value_at_key(k + 1));
        match self.interp {
            Interp::Linear if rotation => {
                let (qa, qb) = (quat_of(a), quat_of(b));
                let q = slerp_unit(&qa, &qb, u);
                vec![q.i, q.j, q.k, q.w]
            }
            Interp::Cubic => {
                let d = self.dims;
                let out_a = self
                    .values
                    .get((3 * k + 2) * d..(3 * k + 3) * d)
                    .unwrap_or(&[]);
                let in_b = self
                    .values
                    .get((3 * k + 3) * d..(3 * k + 4) * d)
                    .unwrap_or(&[]);
                let (u2, u3) = (u * u, u * u * u);
                let (h00, h10, h01, h11) = (
                    2.0 * u3 - 3.0 * u2 + 1.0,
                    u3 - 2.0 * u2 + u,
                    -2.0 * u3 + 3.0 * u2,
                    u3 - u2,
                );
                (0..d)
                    .map(|c| {
                        let g = |s: &[f32]| s.get(c).copied().unwrap_or(0.0);
                        h00 * g(a) + h10 * dt * g(out_a) + h01 * g(b) + h11 * dt * g(in_b)
                    })
                    .collect()
            }
            _ => a.iter().zip(b).map(|(x, y)| x + (y - x) * u).collect(),
        }
    }
}

/// A quaternion from `[x, y, z, w]`, normalised; identity when degenerate.
fn quat_of(v: &[f32]) -> Quat {
    let g = |c: usize| v.get(c).copied().unwrap_or(0.0);
    let q = nalgebra::Quaternion::new(g(3), g(0), g(1), g(2));
    let n = q.norm();
    if n.is_finite() && n > 1e-8 {
        Quat::new_unchecked(q / n)
    } else {
        Quat::identity()
    }
}

fn vec3_of(v: &[f32]) -> Vec3 {
    let g = |c: usize| v.get(c).copied().unwrap_or(0.0);
    Vec3::new(g(0), g(1), g(2))
}

/// Tracks of one joint.
#[derive(Default)]
struct JointTracks {
    rotation: Option<Track>,
    translation: Option<Track>,
    scale: Option<Track>,
}

/// Reads every animation of `doc` as a motion for `skeleton` sampled at `fps`.
/// `length_tolerance` (file units) decides when an ignored translation "differs from rest".
pub(crate) fn load_motions(
    doc: &GltfDoc,
    skeleton: &Skeleton,
    joint_of_node: &HashMap<usize, usize>,
    fps: f32,
    length_tolerance: f32,
    warnings: &mut Vec<String>,
) -> Result<Vec<Motion>, IoError> {
    let mut motions = Vec::new();
    for anim in doc.doc.animations() {
        let name = anim
            .name()
            .filter(|n| !n.trim().is_empty())
            .map(str::to_string)
            .unwrap_or_else(|| format!("animation {}", anim.index()));
        let mut tracks: Vec<JointTracks> = (0..skeleton.len())
            .map(|_| JointTracks::default())
            .collect();
        let (mut off_joint, mut morph) = (0usize, 0usize);
        let mut t_max = 0.0f32;
        // Channel targets are not checked by the crate's validation: read them from the JSON.
        let json_channels = doc
            .doc
            .as_json()
            .animations
            .get(anim.index())
            .map(|a| a.channels.as_slice())
            .unwrap_or(&[]);
        for (channel, raw) in anim.channels().zip(json_channels) {
            let what = format!("animation '{name}' channel {}", channel.index());
            let gltf::json::validation::Checked::Valid(property) = raw.target.path else {
                return Err(doc.invalid(format!("{what}: unknown target path")));
            };
            let node = raw.target.node.value();
            if node >= doc.parents.len() {
                return Err(doc.invalid(format!("{what}: target node {node} does not exist")));
            }
            if property == gltf::animation::Property::MorphTargetWeights {
                morph += 1;
                continue;
            }
            let Some(&j) = joint_of_node.get(&node) else {
                off_joint += 1;
                continue;
            };
            let track = read_track(doc, &channel, property, &what)?;
            t_max = t_max.max(track.times.last().copied().unwrap_or(0.0));
            let slot = &mut tracks[j];
            match property {
                gltf::animation::Property::Rotation => slot.rotation = Some(track),
                gltf::animation::Property::Translation => slot.translation = Some(track),
                _ => slot.scale = Some(track),
            }
        }
        if off_joint > 0 {
            warnings.push(format!(
                "animation '{name}': {off_joint} channels on non-joint nodes ignored"
            ));
        }
        if morph > 0 {
            warnings.push(format!(
                "animation '{name}': {morph} morph-weight channels ignored"
            ));
        }
        if t_max * fps > MAX_FRAMES {
            return Err(IoError::Unsupported {
                what: format!("animation '{name}' lasts {t_max} s (too long to resample)"),
                path: doc.path.clone(),
            });
        }
        let trunk = trunk_of(skeleton);
        let folded: Vec<usize> = trunk
            .iter()
            .copied()
            .filter(|&j| j != 0 && tracks[j].translation.is_some())
            .collect();
        for (j, jt) in tracks.iter().enumerate() {
            let rest = &skeleton.rest_local[j];
            if let Some(t) = &jt.translation
                && j != 0
                && !folded.contains(&j)
            {
                let dev = max_deviation(t, &rest.translation);
                if dev > length_tolerance {
                    warnings.push(format!("animation '{name}': translation of joint '{}' ignored (differs from rest by up to {dev:.4} file units)", skeleton.names[j]));
                }
            }
            if let Some(s) = &jt.scale {
                let dev = max_deviation(s, &rest.scale);
                if dev > 1e-3 {
                    warnings.push(format!("animation '{name}': scale of joint '{}' ignored (differs from rest by up to {dev:.4})", skeleton.names[j]));
                }
            }
        }
        if let Some(&deepest) = folded.last() {
            warnings.push(format!(
                "animation '{name}': translation of joint '{}' applied through the root translation",
                skeleton.names[deepest]
            ));
        }
        let count = (t_max * fps + 1e-3).floor() as usize + 1;
        let mut frames = Vec::with_capacity(count);
        for k in 0..count {
            let t = (k as f32 / fps).min(t_max);
            frames.push(sample_pose(
                skeleton,
                &tracks,
                &trunk,
                folded.last().copied(),
                t,
            ));
        }
        let motion =
            Motion::new(name, fps, frames, skeleton.len()).map_err(|source| IoError::Scene {
                source,
                path: doc.path.clone(),
            })?;
        motions.push(motion);
    }
    Ok(motions)
}

/// Joint 0 and the chain of only children below it, down to the first joint with several
/// (or no) children.
fn trunk_of(skeleton: &Skeleton) -> Vec<usize> {
    let children = skeleton.children();
    let mut trunk = vec![0];
    let mut cur = 0;
    while let [only] = children[cur].as_slice() {
        trunk.push(*only);
        cur = *only;
    }
    trunk
}

fn max_deviation(track: &Track, rest: &Vec3) -> f32 {
    (0..track.keys())
        .map(|k| (vec3_of(track.value_at_key(k)) - rest).abs().max())
        .fold(0.0, f32::max)
}

/// The pose at time `t`. When `fold_to` is a trunk joint, the trunk's animated translations
/// are replaced by an equivalent translation of joint 0.
fn sample_pose(
    skeleton: &Skeleton,
    tracks: &[JointTracks],
    trunk: &[usize],
    fold_to: Option<usize>,
    t: f32,
) -> Pose {
    let rotations: Vec<Quat> = tracks
        .iter()
        .zip(&skeleton.rest_local)
        .map(|(jt, rest)| {
            jt.rotation
                .as_ref()
                .map(|r| quat_of(&r.sample(t, true)))
                .unwrap_or(rest.rotation)
        })
        .collect();
    let translation_at = |j: usize| -> Vec3 {
        match tracks.get(j).and_then(|jt| jt.translation.as_ref()) {
            Some(tr) => vec3_of(&tr.sample(t, false)),
            None => skeleton.rest_local[j].translation,
        }
    };
    let mut root_translation = translation_at(0);
    if let Some(end) = fold_to {
        // World position of `end` with the animated trunk translations, versus with rest ones.
        let chain_world = |animated: bool| -> Mat4 {
            let mut m = skeleton.world_from_root_parent[0];
            for &j in trunk {
                let rest = &skeleton.rest_local[j];
                let translation = if j == 0 || animated {
                    translation_at(j)
                } else {
                    rest.translation
                };
                m *= JointTransform {
                    translation,
                    rotation: rotations[j],
                    scale: rest.scale,
                }
                .to_matrix();
                if j == end {
                    break;
                }
            }
            m
        };
        let delta = chain_world(true).fixed_view::<3, 1>(0, 3)
            - chain_world(false).fixed_view::<3, 1>(0, 3);
        let linear = skeleton.world_from_root_parent[0]
            .fixed_view::<3, 3>(0, 0)
            .into_owned();
        if let Some(inv) = linear.try_inverse() {
            let shift = inv * delta;
            if shift.iter().all(|v| v.is_finite()) {
                root_translation += shift;
            }
        }
    }
    Pose {
        rotations,
        root_translation,
    }
}

/// Reads and validates the sampler of `channel`.
fn read_track(
    doc: &GltfDoc,
    channel: &gltf::animation::Channel,
    property: gltf::animation::Property,
    what: &str,
) -> Result<Track, IoError> {
    let sampler = channel.sampler();
    let interp = match sampler.interpolation() {
        gltf::animation::Interpolation::Linear => Interp::Linear,
        gltf::animation::Interpolation::Step => Interp::Step,
        gltf::animation::Interpolation::CubicSpline => Interp::Cubic,
    };
    let times = doc.read_f32(&sampler.input(), 1, &format!("{what} input"))?;
    if times.is_empty() {
        return Err(doc.invalid(format!("{what}: sampler has no keyframes")));
    }
    if let Some(k) = times.windows(2).position(|w| w[1] < w[0]) {
        return Err(doc.invalid(format!("{what}: keyframe times decrease at key {}", k + 1)));
    }
    if times[0] < 0.0 {
        return Err(doc.invalid(format!("{what}: negative keyframe time {}", times[0])));
    }
    let rotation = property == gltf::animation::Property::Rotation;
    let dims = if rotation { 4 } else { 3 };
    let values = doc.read_f32(&sampler.output(), dims, &format!("{what} output"))?;
    let per_key = if interp == Interp::Cubic { 3 } else { 1 };
    let expected = times.len() * per_key;
    if values.len() / dims != expected {
        return Err(IoError::JointCountMismatch {
            what: format!("{what}: output values (per keyframe {per_key})"),
            expected,
            found: values.len() / dims,
            path: doc.path.clone(),
        });
    }
    let mut track = Track {
        times,
        values,
        dims,
        interp,
    };
    if rotation {
        for k in 0..track.keys() {
            let v = track.value_at_key(k);
            let g = |c: usize| v.get(c).copied().unwrap_or(f32::NAN);
            let q = doc.quat([g(0), g(1), g(2), g(3)], &format!("{what} keyframe {k}"))?;
            let start = if interp == Interp::Cubic {
                (3 * k + 1) * 4
            } else {
                k * 4
            };
            if let Some(slot) = track.values.get_mut(start..start + 4) {
                slot.copy_from_slice(&[q.i, q.j, q.k, q.w]);
            }
        }
    }
    Ok(track)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn track(interp: Interp, values: Vec<f32>) -> Track {
        Track {
            times: vec![0.0, 1.0],
            values,
            dims: 3,
            interp,
        }
    }

    #[test]
    fn linear_step_and_clamping() {
        let t = track(Interp::Linear, vec![0.0, 0.0, 0.0, 2.0, 4.0, 6.0]);
        assert_eq!(t.sample(0.5, false), vec![1.0, 2.0, 3.0]);
        assert_eq!(t.sample(-1.0, false), vec![0.0, 0.0, 0.0]);
        assert_eq!(t.sample(5.0, false), vec![2.0, 4.0, 6.0]);
        let s = track(Interp::Step, vec![0.0, 0.0, 0.0, 2.0, 4.0, 6.0]);
        assert_eq!(s.sample(0.99, false), vec![0.0, 0.0, 0.0]);
        assert_eq!(s.sample(1.0, false), vec![2.0, 4.0, 6.0]);
    }

    #[test]
    fn cubic_hermite_hits_keys_and_follows_tangents() {
        // Keys 0 -> 1 with zero tangents: smoothstep; value 0.5 at u = 0.5.
        // Layout per key: in-tangent (3), value (3), out-tangent (3).
        let mut v = vec![0.0; 18];
        v[12] = 1.0; // second key's value, x
        let t = track(Interp::Cubic, v);
        assert!((t.sample(0.5, false)[0] - 0.5).abs() < 1e-6);
        assert!((t.sample(0.25, false)[0] - 0.15625).abs() < 1e-6);
        assert_eq!(t.sample(1.0, false)[0], 1.0);
    }

    #[test]
    fn rotation_slerp_is_unit() {
        let a = Quat::identity();
        let b = Quat::from_axis_angle(&Vec3::y_axis(), 1.0);
        let t = Track {
            times: vec![0.0, 1.0],
            values: vec![a.i, a.j, a.k, a.w, b.i, b.j, b.k, b.w],
            dims: 4,
            interp: Interp::Linear,
        };
        let q = quat_of(&t.sample(0.5, true));
        assert!((q.angle() - 0.5).abs() < 1e-5);
    }
}
