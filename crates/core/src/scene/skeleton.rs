//! Joint hierarchies, poses and forward kinematics.

use crate::geometry::{Mat4, Quat, Vec3};

use super::SceneError;

/// Translation, rotation and scale of a joint relative to its parent.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointTransform {
    /// Offset from the parent joint, in the parent's units.
    pub translation: Vec3,
    /// Local rotation.
    pub rotation: Quat,
    /// Local scale (1 for most rigs).
    pub scale: Vec3,
}

impl Default for JointTransform {
    fn default() -> Self {
        Self {
            translation: Vec3::zeros(),
            rotation: Quat::identity(),
            scale: Vec3::repeat(1.0),
        }
    }
}

impl JointTransform {
    /// `parent_from_joint` as a 4x4 matrix (T * R * S, as glTF).
    pub fn to_matrix(&self) -> Mat4 {
        Mat4::new_translation(&self.translation)
            * self.rotation.to_homogeneous()
            * Mat4::new_nonuniform_scaling(&self.scale)
    }
}

/// A body pose: one local rotation per joint plus the translation of the first root joint.
#[derive(Clone, Debug, PartialEq)]
pub struct Pose {
    /// Local joint rotations (`parent_from_joint` rotation), one per skeleton joint.
    pub rotations: Vec<Quat>,
    /// Translation of joint 0 relative to its parent space, replacing its rest translation.
    pub root_translation: Vec3,
}

/// A joint hierarchy. Joints are ordered so that a parent always precedes its children.
#[derive(Clone, Debug, PartialEq)]
pub struct Skeleton {
    /// Joint names (unique).
    pub names: Vec<String>,
    /// Parent of each joint; `None` for roots.
    pub parents: Vec<Option<usize>>,
    /// Rest (bind-time node) transform of each joint relative to its parent.
    pub rest_local: Vec<JointTransform>,
    /// Inverse bind matrices: `joint_from_bind` maps bind-space mesh vertices into joint space.
    pub joint_from_bind: Vec<Mat4>,
    /// For root joints, the fixed transform of the space they hang from (non-joint ancestors and
    /// unit conversion). Identity for non-roots (unused).
    pub world_from_root_parent: Vec<Mat4>,
}

impl Skeleton {
    /// Builds and validates a skeleton whose joints are already topologically ordered.
    pub fn new(
        names: Vec<String>,
        parents: Vec<Option<usize>>,
        rest_local: Vec<JointTransform>,
        joint_from_bind: Vec<Mat4>,
        world_from_root_parent: Vec<Mat4>,
    ) -> Result<Self, SceneError> {
        let n = names.len();
        if n == 0 {
            return Err(SceneError::InvalidSkeleton("no joints".into()));
        }
        if [
            parents.len(),
            rest_local.len(),
            joint_from_bind.len(),
            world_from_root_parent.len(),
        ]
        .iter()
        .any(|&len| len != n)
        {
            return Err(SceneError::InvalidSkeleton(format!(
                "{n} names but {} parents, {} rest transforms, {} inverse bind matrices, {} root spaces",
                parents.len(),
                rest_local.len(),
                joint_from_bind.len(),
                world_from_root_parent.len()
            )));
        }
        for (j, p) in parents.iter().enumerate() {
            if let Some(p) = *p
                && p >= j
            {
                return Err(SceneError::InvalidSkeleton(format!(
                    "joint {j} '{}' has parent {p}, which does not precede it",
                    names[j]
                )));
            }
        }
        let mut seen = std::collections::HashSet::new();
        for name in &names {
            if !seen.insert(name.as_str()) {
                return Err(SceneError::InvalidSkeleton(format!(
                    "duplicate joint name '{name}'"
                )));
            }
        }
        let finite = |m: &Mat4| m.iter().all(|v| v.is_finite());
        if !joint_from_bind
            .iter()
            .chain(&world_from_root_parent)
            .all(finite)
            || !rest_local.iter().all(|t| finite(&t.to_matrix()))
        {
            return Err(SceneError::InvalidSkeleton("non-finite transform".into()));
        }
        Ok(Self {
            names,
            parents,
            rest_local,
            joint_from_bind,
            world_from_root_parent,
        })
    }

    /// Number of joints.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// True when the skeleton has no joints (never, once constructed).
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Index of the joint called `name`.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n == name)
    }

    /// The rest pose: rest rotations and the rest translation of joint 0.
    pub fn rest_pose(&self) -> Pose {
        Pose {
            rotations: self.rest_local.iter().map(|t| t.rotation).collect(),
            root_translation: self.rest_local[0].translation,
        }
    }

    /// `world_from_joint` for every joint under `pose` (forward kinematics).
    pub fn world_from_joint(&self, pose: &Pose) -> Vec<Mat4> {
        let mut out = vec![Mat4::identity(); self.len()];
        self.world_from_joint_into(pose, &mut out);
        out
    }

    /// Forward kinematics into `out` (one `world_from_joint` per joint), without allocating.
    /// Joint 0 takes the pose's root translation; missing rotations fall back to the rest
    /// rotation.
    pub fn world_from_joint_into(&self, pose: &Pose, out: &mut [Mat4]) {
        for j in 0..self.len().min(out.len()) {
            let rest = &self.rest_local[j];
            let local = JointTransform {
                translation: if j == 0 {
                    pose.root_translation
                } else {
                    rest.translation
                },
                rotation: pose.rotations.get(j).copied().unwrap_or(rest.rotation),
                scale: rest.scale,
            }
            .to_matrix();
            let parent = match self.parents[j] {
                Some(p) => out[p],
                None => self.world_from_root_parent[j],
            };
            out[j] = parent * local;
        }
    }

    /// Skinning matrices `world_from_joint * joint_from_bind` for `pose`.
    pub fn skin_from_bind(&self, pose: &Pose) -> Vec<Mat4> {
        self.world_from_joint(pose)
            .iter()
            .zip(&self.joint_from_bind)
            .map(|(w, b)| w * b)
            .collect()
    }

    /// World positions of all joints under `pose`.
    pub fn joint_positions(&self, pose: &Pose) -> Vec<Vec3> {
        self.world_from_joint(pose)
            .iter()
            .map(|m| m.fixed_view::<3, 1>(0, 3).into_owned())
            .collect()
    }

    /// Children of each joint.
    pub fn children(&self) -> Vec<Vec<usize>> {
        let mut c = vec![Vec::new(); self.len()];
        for (j, p) in self.parents.iter().enumerate() {
            if let Some(p) = p {
                c[*p].push(j);
            }
        }
        c
    }
}

/// World-space rotation part of an affine matrix, with scale removed; identity when degenerate.
pub fn rotation_of(m: &Mat4) -> Quat {
    let r = m.fixed_view::<3, 3>(0, 0).into_owned();
    let cols: Vec<Vec3> = (0..3).map(|k| r.column(k).into_owned()).collect();
    let Some(c0) = crate::geometry::safe_normalize(cols[0]) else {
        return Quat::identity();
    };
    let Some(c1) = crate::geometry::safe_normalize(cols[1] - c0 * c0.dot(&cols[1])) else {
        return Quat::identity();
    };
    let c2 = c0.cross(&c1);
    let rot = nalgebra::Rotation3::from_matrix_unchecked(crate::geometry::Mat3::from_columns(&[
        c0, c1, c2,
    ]));
    Quat::from_rotation_matrix(&rot)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A 3-joint chain along +Y with unit bones and bind = rest.
    pub fn chain() -> Skeleton {
        let rest = vec![
            JointTransform::default(),
            JointTransform {
                translation: Vec3::y(),
                ..Default::default()
            },
            JointTransform {
                translation: Vec3::y(),
                ..Default::default()
            },
        ];
        let parents = vec![None, Some(0), Some(1)];
        let mut sk = Skeleton::new(
            vec!["root".into(), "mid".into(), "tip".into()],
            parents,
            rest,
            vec![Mat4::identity(); 3],
            vec![Mat4::identity(); 3],
        )
        .unwrap();
        let rest_pose = sk.rest_pose();
        sk.joint_from_bind = sk
            .world_from_joint(&rest_pose)
            .iter()
            .map(|m| m.try_inverse().unwrap())
            .collect();
        sk
    }

    #[test]
    fn forward_kinematics_bends_the_chain() {
        let sk = chain();
        let mut pose = sk.rest_pose();
        pose.rotations[1] = Quat::from_axis_angle(&Vec3::z_axis(), std::f32::consts::FRAC_PI_2);
        let p = sk.joint_positions(&pose);
        assert!((p[2] - Vec3::new(-1.0, 1.0, 0.0)).norm() < 1e-6);
        for m in sk.skin_from_bind(&sk.rest_pose()) {
            assert!((m - Mat4::identity()).norm() < 1e-6);
        }
    }

    #[test]
    fn rejects_bad_order_and_duplicates() {
        let t = vec![JointTransform::default(); 2];
        let i = vec![Mat4::identity(); 2];
        assert!(
            Skeleton::new(
                vec!["a".into(), "b".into()],
                vec![Some(1), None],
                t.clone(),
                i.clone(),
                i.clone()
            )
            .is_err()
        );
        assert!(
            Skeleton::new(
                vec!["a".into(), "a".into()],
                vec![None, Some(0)],
                t,
                i.clone(),
                i
            )
            .is_err()
        );
    }

    #[test]
    fn rotation_of_strips_scale() {
        let q = Quat::from_euler_angles(0.2, 0.4, -0.3);
        let m = q.to_homogeneous() * Mat4::new_scaling(3.0);
        assert!(rotation_of(&m).angle_to(&q) < 1e-5);
    }
}
