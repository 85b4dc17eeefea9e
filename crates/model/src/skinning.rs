//! Linear blend skinning of the network's output, on burn tensors (training) and on plain
//! slices (inference), with the joint matrices both share.
//!
//! The garment template lives in the avatar's world rest space, so its skinning matrices are
//! `world_from_joint(pose) * inverse(world_from_joint(rest))` (as
//! [`neural_cloth_core::scene::Garment::pose_with_offsets`]). Matrices are passed as the top three rows of
//! the 4x4 affine matrix, row-major: 12 floats per joint.

use burn::tensor::{Device, Int, Tensor, TensorData};

use neural_cloth_core::geometry::skinning::MAX_INFLUENCES;
use neural_cloth_core::geometry::{Mat4, SkinWeights, Vec3};
use neural_cloth_core::scene::{Garment, Pose, Skeleton};

use super::ModelError;
use super::descriptors::world_from_joint_into;

/// Floats per joint matrix (3x4, row-major).
pub const MATRIX_FLOATS: usize = 12;

/// Writes `left[j] * right[j]` for every joint as 3x4 row-major blocks into `out`.
pub fn write_matrices_3x4(left: &[Mat4], right: &[Mat4], out: &mut [f32]) {
    for ((l, r), o) in left
        .iter()
        .zip(right)
        .zip(out.chunks_exact_mut(MATRIX_FLOATS))
    {
        let m = l * r;
        for row in 0..3 {
            for col in 0..4 {
                o[row * 4 + col] = m[(row, col)];
            }
        }
    }
}

/// Builds garment skinning matrices from poses without allocating per call.
#[derive(Clone, Debug)]
pub struct SkinMatrixBuilder {
    skeleton: Skeleton,
    rest_from_world: Vec<Mat4>,
    world: Vec<Mat4>,
}

impl SkinMatrixBuilder {
    /// A builder for `skeleton` (the rest pose defines the garment's space).
    pub fn new(skeleton: &Skeleton) -> Self {
        let rest_from_world = skeleton
            .world_from_joint(&skeleton.rest_pose())
            .iter()
            .map(|m| m.try_inverse().unwrap_or_else(Mat4::identity))
            .collect();
        Self {
            skeleton: skeleton.clone(),
            rest_from_world,
            world: vec![Mat4::identity(); skeleton.len()],
        }
    }

    /// Number of skeleton joints (matrices per pose).
    pub fn joint_count(&self) -> usize {
        self.skeleton.len()
    }

    /// `inverse(world_from_joint(rest))` per joint.
    pub fn rest_from_world(&self) -> &[Mat4] {
        &self.rest_from_world
    }

    /// Writes the `J_all * 12` garment matrices of `pose` into `out`.
    pub fn write(&mut self, pose: &Pose, out: &mut [f32]) -> Result<(), ModelError> {
        let n = self.skeleton.len();
        if pose.rotations.len() != n {
            return Err(ModelError::ShapeMismatch {
                what: "pose rotations".into(),
                expected: n,
                found: pose.rotations.len(),
            });
        }
        if out.len() != n * MATRIX_FLOATS {
            return Err(ModelError::ShapeMismatch {
                what: "matrix output floats".into(),
                expected: n * MATRIX_FLOATS,
                found: out.len(),
            });
        }
        world_from_joint_into(&self.skeleton, pose, &mut self.world);
        write_matrices_3x4(&self.world, &self.rest_from_world, out);
        Ok(())
    }

    /// Appends the garment matrices of `pose` to `out` (for assembling `[B, T, J_all, 12]`).
    pub fn append(&mut self, pose: &Pose, out: &mut Vec<f32>) -> Result<(), ModelError> {
        let start = out.len();
        out.resize(start + self.skeleton.len() * MATRIX_FLOATS, 0.0);
        let res = self.write(pose, &mut out[start..]);
        if res.is_err() {
            out.truncate(start);
        }
        res
    }
}

/// Skins flat rest positions `[V * 3]` with 3x4 joint matrices into `out`, given per-vertex
/// joint indices and weights (a [`SkinWeights`]' two arrays, or a chunk of them). Joints
/// outside `matrices` contribute nothing.
pub fn skin_positions_into(
    rest: &[f32],
    joint_index: &[[u16; MAX_INFLUENCES]],
    weights: &[[f32; MAX_INFLUENCES]],
    matrices: &[f32],
    out: &mut [Vec3],
) {
    let joints = matrices.len() / MATRIX_FLOATS;
    for (((p, js), ws), o) in rest
        .chunks_exact(3)
        .zip(joint_index)
        .zip(weights)
        .zip(out.iter_mut())
    {
        let mut m = [0.0f32; MATRIX_FLOATS];
        for (&j, &w) in js.iter().zip(ws) {
            let j = j as usize;
            if w != 0.0 && j < joints {
                let jm = &matrices[j * MATRIX_FLOATS..(j + 1) * MATRIX_FLOATS];
                for (a, b) in m.iter_mut().zip(jm) {
                    *a += w * b;
                }
            }
        }
        *o = Vec3::new(
            m[0] * p[0] + m[1] * p[1] + m[2] * p[2] + m[3],
            m[4] * p[0] + m[5] * p[1] + m[6] * p[2] + m[7],
            m[8] * p[0] + m[9] * p[1] + m[10] * p[2] + m[11],
        );
    }
}

/// Garment template and skin weights as tensors: adds offsets to the template and skins the
/// result with per-frame joint matrices, differentiably.
#[derive(Clone, Debug)]
pub struct GarmentLbs {
    template: Tensor<2>,
    joint_index: Tensor<1, Int>,
    weights: Tensor<2>,
    vertices: usize,
    joints: usize,
}

impl GarmentLbs {
    /// From a template (rest space) and its skin weights over `joint_count` skeleton joints.
    pub fn new(
        template: &[Vec3],
        skin: &SkinWeights,
        joint_count: usize,
        device: &Device,
    ) -> Result<Self, ModelError> {
        let v = template.len();
        if skin.len() != v {
            return Err(ModelError::ShapeMismatch {
                what: "garment skin weights (one per vertex)".into(),
                expected: v,
                found: skin.len(),
            });
        }
        if v == 0 || joint_count == 0 {
            return Err(ModelError::InvalidInput(
                "garment skinning needs vertices and joints".into(),
            ));
        }
        if let Some(j) = skin.max_joint().filter(|&j| j as usize >= joint_count) {
            return Err(ModelError::ShapeMismatch {
                what: format!("garment skin weights refer to joint {j}; joints in skeleton"),
                expected: joint_count,
                found: j as usize + 1,
            });
        }
        if !template.iter().all(|p| p.iter().all(|c| c.is_finite())) {
            return Err(ModelError::InvalidInput(
                "garment template has a non-finite vertex".into(),
            ));
        }
        let flat: Vec<f32> = template.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
        // Unused slots (weight 0) may hold any index: clamp them into range.
        let idx: Vec<i64> = skin
            .joints
            .iter()
            .zip(&skin.weights)
            .flat_map(|(js, ws)| {
                (0..MAX_INFLUENCES).map(move |k| if ws[k] != 0.0 { js[k] as i64 } else { 0 })
            })
            .collect();
        let w: Vec<f32> = skin.weights.iter().flatten().copied().collect();
        Ok(Self {
            template: Tensor::from_data(TensorData::new(flat, [v, 3]), device),
            joint_index: Tensor::from_data(TensorData::new(idx, [v * MAX_INFLUENCES]), device),
            weights: Tensor::from_data(TensorData::new(w, [v, MAX_INFLUENCES]), device),
            vertices: v,
            joints: joint_count,
        })
    }

    /// From a garment whose weights refer to a skeleton of `joint_count` joints.
    pub fn from_garment(
        garment: &Garment,
        joint_count: usize,
        device: &Device,
    ) -> Result<Self, ModelError> {
        Self::new(&garment.mesh.positions, &garment.skin, joint_count, device)
    }

    /// Number of vertices `V`.
    pub fn vertices(&self) -> usize {
        self.vertices
    }

    /// Number of skeleton joints the matrices must cover.
    pub fn joints(&self) -> usize {
        self.joints
    }

    /// Template `[V, 3]`.
    pub fn template(&self) -> Tensor<2> {
        self.template.clone()
    }

    /// Template plus offsets `[B, T, V, 3]`.
    pub fn rest(&self, offsets: Tensor<4>) -> Tensor<4> {
        offsets + self.template.clone().unsqueeze::<4>()
    }

    /// Skins rest positions `[B, T, V, 3]` with joint matrices `[B, T, J_all, 12]`.
    pub fn skin(&self, rest: Tensor<4>, matrices: Tensor<4>) -> Tensor<4> {
        let [b, t, v, _] = rest.dims();
        let blended = matrices
            .select(2, self.joint_index.clone())
            .reshape([b, t, v, MAX_INFLUENCES, MATRIX_FLOATS])
            .mul(self.weights.clone().reshape([1, 1, v, MAX_INFLUENCES, 1]))
            .sum_dim(3)
            .reshape([b, t, v, 3, 4]);
        let linear = blended
            .clone()
            .narrow(4, 0, 3)
            .mul(rest.reshape([b, t, v, 1, 3]))
            .sum_dim(4);
        (linear + blended.narrow(4, 3, 1)).reshape([b, t, v, 3])
    }

    /// Posed garment `[B, T, V, 3]` from offsets `[B, T, V, 3]` and matrices `[B, T, J_all, 12]`.
    pub fn pose(&self, offsets: Tensor<4>, matrices: Tensor<4>) -> Tensor<4> {
        self.skin(self.rest(offsets), matrices)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use neural_cloth_core::geometry::Quat;
    use neural_cloth_core::scene::JointTransform;

    fn two_joints() -> Skeleton {
        let rest = vec![
            JointTransform::default(),
            JointTransform {
                translation: Vec3::new(0.0, 0.5, 0.0),
                ..Default::default()
            },
        ];
        Skeleton::new(
            vec!["a".into(), "b".into()],
            vec![None, Some(0)],
            rest,
            vec![Mat4::identity(); 2],
            vec![Mat4::identity(); 2],
        )
        .unwrap()
    }

    #[test]
    fn tensor_and_slice_skinning_agree_with_scene_convention() {
        let sk = two_joints();
        let (skin, _) = SkinWeights::from_influences(
            vec![vec![(0, 1.0)], vec![(0, 0.3), (1, 0.7)], vec![(1, 1.0)]],
            0,
        );
        let template = vec![
            Vec3::new(0.1, 0.0, 0.0),
            Vec3::new(0.0, 0.5, 0.1),
            Vec3::new(0.2, 0.9, -0.1),
        ];
        let mut pose = sk.rest_pose();
        pose.rotations[1] = Quat::from_euler_angles(0.4, 0.1, -0.7);
        pose.root_translation = Vec3::new(0.0, 1.0, 0.5);
        let mut builder = SkinMatrixBuilder::new(&sk);
        let mut mats = vec![0.0; 2 * MATRIX_FLOATS];
        builder.write(&pose, &mut mats).unwrap();
        // Reference: the generic LBS of the geometry layer with the same matrices.
        let world = sk.world_from_joint(&pose);
        let full: Vec<Mat4> = world
            .iter()
            .zip(builder.rest_from_world())
            .map(|(w, r)| w * r)
            .collect();
        let expected = neural_cloth_core::geometry::linear_blend_skin(&template, &skin, &full);
        let flat: Vec<f32> = template.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
        let mut out = vec![Vec3::zeros(); 3];
        skin_positions_into(&flat, &skin.joints, &skin.weights, &mats, &mut out);
        let device = Device::flex();
        let lbs = GarmentLbs::new(&template, &skin, 2, &device).unwrap();
        let offsets = Tensor::<4>::zeros([1, 1, 3, 3], &device);
        let m = Tensor::<4>::from_data(
            TensorData::new(mats.clone(), [1, 1, 2, MATRIX_FLOATS]),
            &device,
        );
        let posed: Vec<f32> = lbs.pose(offsets, m).try_into_vec_as::<f32>().unwrap();
        for (v, e) in expected.iter().enumerate() {
            assert!((out[v] - e).norm() < 1e-5);
            assert!(
                (Vec3::new(posed[3 * v], posed[3 * v + 1], posed[3 * v + 2]) - e).norm() < 1e-5
            );
        }
        assert!(
            (expected[2] - template[2]).norm() > 0.1,
            "the pose moves the garment"
        );
        assert!(GarmentLbs::new(&template, &skin, 1, &device).is_err());
    }
}
