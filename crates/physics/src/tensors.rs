//! Device copies of a [`GarmentRest`] (index and coefficient tensors, built once per garment) and
//! small tensor helpers shared by the energies. Only the pieces an enabled effect needs are
//! uploaded.
//!
//! Shapes: positions are `[B, V, 3]`; per-element constants are `[1, N, 1]` so they broadcast
//! over the batch and the coordinate axis. Everything is created with an explicit dtype so the
//! same code runs in `f32` (training, any device) and `f64` (reference checks on `flex`).

use burn::tensor::{DType, Device, Int, Tensor, TensorData};

use neural_cloth_core::geometry::Vec3;

use super::rest::GarmentRest;
use super::{Effects, PhysicsError};

/// Rest quantities of one garment as device tensors.
#[derive(Clone, Debug)]
pub struct RestTensors {
    /// Device the tensors live on.
    pub device: Device,
    /// Float dtype of every float tensor.
    pub dtype: DType,
    /// Vertices.
    pub vertex_count: usize,
    /// Vertex masses `[1, V, 1]` in kg.
    pub mass: Tensor<3>,
    /// Edge endpoints.
    pub edge: Option<[Tensor<1, Int>; 2]>,
    /// Rest edge lengths `[1, E, 1]`.
    pub edge_rest: Option<Tensor<3>>,
    /// Squared regulariser under edge-length square roots, m².
    pub edge_eps2_m2: f64,
    /// Face corners.
    pub face: Option<[Tensor<1, Int>; 3]>,
    /// Inverse rest matrix entries `c00, c01, c10, c11`, each `[1, F, 1]`.
    pub face_inv: Option<[Tensor<3>; 4]>,
    /// `|cross|` at rest `[1, F, 1]` in m².
    pub face_area2: Option<Tensor<3>>,
    /// Hinge edge vertices `e0, e1` and faces `f0, f1`.
    pub hinge: Option<[Tensor<1, Int>; 4]>,
    /// Hinge constants: weight, rest cos, rest sin, each `[1, H, 1]`.
    pub hinge_consts: Option<[Tensor<3>; 3]>,
    /// `1/|c̄_f|` per face `[1, F, 1]` (uploaded with the hinges).
    pub face_normal_scale: Option<Tensor<3>>,
    /// Pinned vertex indices (None when there are none or pinning is off).
    pub pinned: Option<Tensor<1, Int>>,
    /// 1 for colliding vertices, 0 for no-collide ones, `[1, V, 1]`.
    pub collide: Option<Tensor<3>>,
    /// Gravity `[1, 1, 3]` in m/s².
    pub gravity: Tensor<3>,
}

impl RestTensors {
    /// Uploads what `effects` need (membrane terms and masses always).
    pub fn new(
        rest: &GarmentRest,
        gravity: Vec3,
        effects: &Effects,
        device: &Device,
        dtype: DType,
    ) -> Self {
        let col = |v: &[f64]| column(v, device, dtype);
        let ne = rest.edges.len();
        let nf = rest.faces.len();
        let nh = rest.hinges.len();
        let edge = (ne > 0).then(|| {
            [0, 1].map(|k| index(&rest.edges.iter().map(|e| e[k]).collect::<Vec<_>>(), device))
        });
        let face = (nf > 0).then(|| {
            [0, 1, 2].map(|k| index(&rest.faces.iter().map(|f| f[k]).collect::<Vec<_>>(), device))
        });
        let face_inv = (nf > 0).then(|| {
            [0, 1, 2, 3].map(|k| col(&rest.face_inv_rest.iter().map(|c| c[k]).collect::<Vec<_>>()))
        });
        let bend = effects.bending && nh > 0;
        let bend = bend && nf > 0;
        let hinge = bend.then(|| {
            let pick =
                |f: &dyn Fn(usize) -> u32| index(&(0..nh).map(f).collect::<Vec<_>>(), device);
            [
                pick(&|h| rest.hinges[h][0]),
                pick(&|h| rest.hinges[h][1]),
                pick(&|h| rest.hinge_faces[h][0]),
                pick(&|h| rest.hinge_faces[h][1]),
            ]
        });
        let hinge_consts = bend.then(|| {
            [
                &rest.hinge_weight,
                &rest.hinge_rest_cos,
                &rest.hinge_rest_sin,
            ]
            .map(|v| col(v))
        });
        let face_normal_scale = bend.then(|| col(&rest.face_normal_scale));
        let pinned =
            (effects.pinning && !rest.pinned.is_empty()).then(|| index(&rest.pinned, device));
        let collide = effects.collision.then(|| {
            col(&rest
                .collide
                .iter()
                .map(|&c| if c { 1.0 } else { 0.0 })
                .collect::<Vec<f64>>())
        });
        Self {
            device: device.clone(),
            dtype,
            vertex_count: rest.vertex_count(),
            mass: col(&rest.mass_kg),
            edge,
            edge_rest: (ne > 0).then(|| col(&rest.edge_rest_m)),
            edge_eps2_m2: rest.edge_eps2_m2,
            face,
            face_inv,
            face_area2: (nf > 0).then(|| col(&rest.face_area2_m2)),
            hinge,
            hinge_consts,
            face_normal_scale,
            pinned,
            collide,
            gravity: Tensor::from_data(
                TensorData::new(vec![gravity.x, gravity.y, gravity.z], [1, 1, 3]),
                (device, dtype),
            ),
        }
    }

    /// Checks that `x` is `[B, V, 3]` for this garment and returns `B`.
    pub fn batch_of(&self, x: &Tensor<3>) -> Result<usize, PhysicsError> {
        let [b, v, c] = x.dims();
        if v != self.vertex_count || c != 3 || b == 0 {
            return Err(PhysicsError::ShapeMismatch {
                what: "garment positions".into(),
                expected: format!("[B>=1, {}, 3]", self.vertex_count),
                found: format!("[{b}, {v}, {c}]"),
            });
        }
        Ok(b)
    }

    /// Zeros of shape `[B]` in this dtype (an energy whose elements are absent).
    pub fn zeros(&self, batch: usize) -> Tensor<1> {
        Tensor::zeros([batch], (&self.device, self.dtype))
    }
}

/// `[1, N, 1]` float tensor.
pub fn column(values: &[f64], device: &Device, dtype: DType) -> Tensor<3> {
    Tensor::from_data(
        TensorData::new(values.to_vec(), [1, values.len(), 1]),
        (device, dtype),
    )
}

/// 1-D index tensor.
pub fn index(values: &[u32], device: &Device) -> Tensor<1, Int> {
    let data: Vec<i64> = values.iter().map(|&v| i64::from(v)).collect();
    Tensor::from_data(TensorData::new(data, [values.len()]), device)
}

/// Row-wise dot product over the last axis: `[B, N, 3] x [B, N, 3] -> [B, N, 1]`.
pub fn dot(a: Tensor<3>, b: Tensor<3>) -> Tensor<3> {
    (a * b).sum_dim(2)
}

/// Squared norm over the last axis: `[B, N, 3] -> [B, N, 1]`.
pub fn norm2(a: Tensor<3>) -> Tensor<3> {
    a.square().sum_dim(2)
}

/// Sum over elements per sample: `[B, N, 1] -> [B]`.
pub fn per_sample(t: Tensor<3>) -> Tensor<1> {
    let b = t.dims()[0];
    t.sum_dim(1).reshape([b])
}

/// Gathers vertices `idx` of `x`: `[B, V, 3] -> [B, N, 3]`.
pub fn gather(x: &Tensor<3>, idx: &Tensor<1, Int>) -> Tensor<3> {
    x.clone().select(1, idx.clone())
}

/// Uploads a batch of position arrays (all the same length) as `[B, V, 3]`.
pub fn positions_tensor(
    frames: &[&[Vec3]],
    device: &Device,
    dtype: DType,
) -> Result<Tensor<3>, PhysicsError> {
    let v = frames.first().map_or(0, |f| f.len());
    if frames.is_empty() || frames.iter().any(|f| f.len() != v) {
        return Err(PhysicsError::ShapeMismatch {
            what: "position batch".into(),
            expected: format!("{} frames of {v} vertices", frames.len().max(1)),
            found: format!(
                "lengths {:?}",
                frames.iter().map(|f| f.len()).collect::<Vec<_>>()
            ),
        });
    }
    let flat: Vec<f32> = frames
        .iter()
        .flat_map(|f| f.iter().flat_map(|p| [p.x, p.y, p.z]))
        .collect();
    Ok(Tensor::from_data(
        TensorData::new(flat, [frames.len(), v, 3]),
        (device, dtype),
    ))
}

/// Reads a tensor back as `f32` values (any float dtype).
pub fn read_f32<const D: usize>(t: Tensor<D>) -> Result<Vec<f32>, PhysicsError> {
    t.try_into_vec_as::<f32>()
        .map_err(|e| PhysicsError::Backend(e.to_string()))
}

/// Reads a tensor back as `f64` values (any float dtype).
pub fn read_f64<const D: usize>(t: Tensor<D>) -> Result<Vec<f64>, PhysicsError> {
    t.try_into_vec_as::<f64>()
        .map_err(|e| PhysicsError::Backend(e.to_string()))
}
