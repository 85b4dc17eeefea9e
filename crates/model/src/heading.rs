//! The heading-free rotation frame of the motion descriptors: a rotation without its twist
//! about gravity, and the choice between the paper's frame and this one
//! ([`RotationFrame`], explained in [`crate::descriptors`]).

use nalgebra::{Quaternion, Rotation3};
use serde::{Deserialize, Serialize};

use neural_cloth_core::geometry::{Mat3, Quat, Vec3};

/// How joint rotations enter the descriptors (see [`crate::descriptors`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RotationFrame {
    /// The paper's: the root's global rotation with its heading; 6D derivatives in the
    /// parent's frame. Runs and models saved before the field existed use it.
    Paper,
    /// The root's rotation without its heading about gravity; rotation derivatives in the
    /// joint's own frame (heading-invariant, the turning rate with its sign). Default.
    #[default]
    HeadingFree,
}

impl RotationFrame {
    /// The frame of configurations saved before [`DescriptorConfig::rotation_frame`] existed.
    pub(crate) fn saved_before_round_24() -> Self {
        Self::Paper
    }
}

/// `global` without its twist about the unit vector `up` (swing-twist decomposition
/// `q = twist · swing`, the swing returned): invariant to any rotation about `up` applied
/// before it. A rotation that turns `up` upside down has no defined heading and is returned
/// as it is.
pub fn without_heading(global: &Mat3, up: &Vec3) -> Mat3 {
    let q = Quat::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*global));
    let along_up = up * q.imag().dot(up);
    let twist = Quaternion::new(q.w, along_up.x, along_up.y, along_up.z);
    let norm = twist.norm();
    if norm.is_nan() || norm <= 1e-6 {
        return *global;
    }
    let twist = Quat::new_unchecked(twist / norm);
    twist.inverse().to_rotation_matrix().into_inner() * global
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::descriptors::{DYNAMIC_DIM, DescriptorConfig, DescriptorExtractor, STATIC_DIM};
    use neural_cloth_core::geometry::Mat4;
    use neural_cloth_core::scene::{JointTransform, Pose, Skeleton};

    fn close(a: &Mat3, b: &Mat3) -> f32 {
        (a - b).abs().max()
    }

    fn yaw(angle: f32) -> Quat {
        Quat::from_axis_angle(&Vec3::y_axis(), angle)
    }

    #[test]
    fn without_heading_ignores_turns_about_up_and_keeps_tilts() {
        let up = Vec3::y();
        let tilt = Quat::from_euler_angles(0.3, -0.2, 0.5);
        let reference = without_heading(&tilt.to_rotation_matrix().into_inner(), &up);
        for angle in [-3.0f32, -1.0, 0.4, 2.5] {
            let turned = (yaw(angle) * tilt).to_rotation_matrix().into_inner();
            assert!(close(&without_heading(&turned, &up), &reference) < 1e-5);
        }
        let pure_yaw = yaw(1.2).to_rotation_matrix().into_inner();
        assert!(close(&without_heading(&pure_yaw, &up), &Mat3::identity()) < 1e-6);
        let lean = Quat::from_axis_angle(&Vec3::x_axis(), 0.4)
            .to_rotation_matrix()
            .into_inner();
        assert!(
            close(&without_heading(&lean, &up), &lean) < 1e-6,
            "no twist in a lean"
        );
        let upside_down = Quat::from_axis_angle(&Vec3::x_axis(), std::f32::consts::PI)
            .to_rotation_matrix()
            .into_inner();
        assert!(close(&without_heading(&upside_down, &up), &upside_down) < 1e-6);
    }

    /// A root and two joints above it, 0.3 m apart.
    fn chain() -> Skeleton {
        let rest = (0..3)
            .map(|j| JointTransform {
                translation: Vec3::y() * if j == 0 { 0.0 } else { 0.3 },
                ..Default::default()
            })
            .collect();
        Skeleton::new(
            vec!["Hips".into(), "Spine".into(), "Neck".into()],
            vec![None, Some(0), Some(1)],
            rest,
            vec![Mat4::identity(); 3],
            vec![Mat4::identity(); 3],
        )
        .unwrap()
    }

    /// 20 frames of a body that walks, leans, bends and turns at `turn_rate` rad/s, all
    /// turned by `heading` about the vertical.
    fn motion(heading: f32, turn_rate: f32) -> Vec<Pose> {
        let sk = chain();
        (0..20)
            .map(|t| {
                let s = t as f32 / 30.0;
                let mut pose = sk.rest_pose();
                let lean = Quat::from_euler_angles(0.2 * (3.0 * s).sin(), 0.0, 0.1 * s);
                pose.rotations[0] = yaw(heading) * yaw(turn_rate * s) * lean;
                pose.rotations[1] = Quat::from_euler_angles(0.5 * s, 0.2, -0.3 * s);
                pose.rotations[2] = Quat::from_euler_angles(0.1, 0.4 * s * s, 0.0);
                pose.root_translation = yaw(heading) * Vec3::new(0.8 * s, 0.9, 0.3 * s * s);
                pose
            })
            .collect()
    }

    fn descriptors(frame: RotationFrame, poses: &[Pose]) -> (Vec<f32>, Vec<f32>) {
        let config = DescriptorConfig {
            rotation_frame: frame,
            ..Default::default()
        };
        let mut ex = DescriptorExtractor::new(&chain(), &config, 30.0).unwrap();
        let d = ex.poses(poses).unwrap();
        (d.static_desc, d.dynamic_desc)
    }

    fn max_diff(a: &[f32], b: &[f32]) -> f32 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f32::max)
    }

    #[test]
    fn heading_free_descriptors_do_not_depend_on_the_heading() {
        let (s0, d0) = descriptors(RotationFrame::HeadingFree, &motion(0.0, 2.0));
        let (s1, d1) = descriptors(RotationFrame::HeadingFree, &motion(2.2, 2.0));
        assert!(max_diff(&s0, &s1) < 1e-5, "{}", max_diff(&s0, &s1));
        assert!(max_diff(&d0, &d1) < 2e-3, "{}", max_diff(&d0, &d1));
        let (p0, q0) = descriptors(RotationFrame::Paper, &motion(0.0, 2.0));
        let (p1, q1) = descriptors(RotationFrame::Paper, &motion(2.2, 2.0));
        assert!(
            max_diff(&p0, &p1) > 0.5,
            "the paper's root 6D carries the heading"
        );
        assert!(max_diff(&q0, &q1) > 0.5, "and so does its derivative");
        let joint_rows = |v: &[f32], dim: usize| v.chunks(dim).skip(1).step_by(3).count();
        assert_eq!(joint_rows(&s0, STATIC_DIM), joint_rows(&p0, STATIC_DIM));
    }

    #[test]
    fn heading_free_rotation_rate_is_the_turn_with_its_sign() {
        for rate in [-6.0f32, 6.0] {
            let poses: Vec<Pose> = (0..10)
                .map(|t| {
                    let mut pose = chain().rest_pose();
                    pose.rotations[0] = yaw(rate * t as f32 / 30.0);
                    pose
                })
                .collect();
            let (_, d) = descriptors(RotationFrame::HeadingFree, &poses);
            let expected = -(rate / 30.0).sin() * 30.0;
            for t in 1..10 {
                let root = &d[t * 3 * DYNAMIC_DIM..][..DYNAMIC_DIM];
                assert!((root[2] - expected).abs() < 1e-3, "frame {t}: {root:?}");
                let shrink = ((rate / 30.0).cos() - 1.0) * 30.0;
                assert!((root[0] - shrink).abs() < 1e-3, "frame {t}: {root:?}");
                assert!(root[1..2].iter().chain(&root[3..6]).all(|v| v.abs() < 1e-3));
            }
            let (_, paper) = descriptors(RotationFrame::Paper, &poses);
            let root_at = |t: usize| paper[t * 3 * DYNAMIC_DIM + 2];
            assert!(
                (root_at(2) - root_at(6)).abs() > 1.0,
                "in the paper's frame the same turn reads differently as the heading changes"
            );
        }
    }

    #[test]
    fn still_body_has_zero_heading_free_dynamics() {
        let pose = motion(1.0, 0.0)[7].clone();
        let (_, d) = descriptors(RotationFrame::HeadingFree, &vec![pose; 6]);
        assert!(d.iter().all(|v| *v == 0.0));
    }

    #[test]
    fn configurations_saved_without_the_field_keep_the_papers_frame() {
        assert_eq!(
            DescriptorConfig::default().rotation_frame,
            RotationFrame::HeadingFree
        );
        let old: DescriptorConfig = toml::from_str("gravity_dir = [0.0, -1.0, 0.0]").unwrap();
        assert_eq!(old.rotation_frame, RotationFrame::Paper);
        let text = toml::to_string(&DescriptorConfig::default()).unwrap();
        let back: DescriptorConfig = toml::from_str(&text).unwrap();
        assert_eq!(back, DescriptorConfig::default());
    }
}
