//! Body collision: posed bodies with area-weighted vertex normals and a k-d tree, the batched
//! nearest-vertex query (CPU, parallel across the batch) and the collision energy
//! `k_c Σ_v min(d_v - ε, 0)²` with `d_v = n_b·(x_v - b)` the signed distance to the nearest
//! posed body vertex `b` along its normal `n_b` (negative inside).
//!
//! The query runs on a detached CPU copy of the prediction; its result (`Contacts`) is uploaded
//! as `[B, V, 3]` points and normals, so the energy itself is a few element-wise device ops.

use std::sync::Arc;

use burn::tensor::{DType, Device, Tensor, TensorData};
use rayon::prelude::*;

use crate::geometry::{KdTree, TriMesh, Vec3};
use crate::scene::{Avatar, Pose};

use super::PhysicsError;
use super::tensors::{RestTensors, dot, per_sample, read_f32};

/// A body mesh in one pose, ready for distance queries.
#[derive(Clone, Debug)]
pub struct PosedBody {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    tree: KdTree,
}

impl PosedBody {
    /// Builds the query structure for body vertices `positions` joined by `faces` (normals are
    /// area-weighted vertex normals of that mesh).
    pub fn new(positions: Vec<Vec3>, faces: &[[u32; 3]]) -> Result<Self, PhysicsError> {
        let mesh = TriMesh::new(positions, faces.to_vec())
            .map_err(|e| PhysicsError::InvalidBody(e.to_string()))?;
        let normals = mesh.vertex_normals();
        let tree = KdTree::new(&mesh.positions);
        Ok(Self {
            positions: mesh.positions,
            normals,
            tree,
        })
    }

    /// The avatar's body in `pose`.
    pub fn from_avatar(avatar: &Avatar, pose: &Pose) -> Result<Self, PhysicsError> {
        Self::new(avatar.pose_vertices(pose), &avatar.bind_mesh.faces)
    }

    /// Body vertex positions.
    pub fn positions(&self) -> &[Vec3] {
        &self.positions
    }

    /// Area-weighted unit vertex normals.
    pub fn normals(&self) -> &[Vec3] {
        &self.normals
    }

    /// Index of the body vertex nearest to `q` (0 for a non-finite query).
    pub fn nearest(&self, q: &Vec3) -> usize {
        self.tree.nearest(q).map_or(0, |(i, _)| i as usize)
    }

    /// Signed distance estimate `n_b·(q - b)` to the nearest body vertex, in metres.
    pub fn signed_distance(&self, q: &Vec3) -> f32 {
        let i = self.nearest(q);
        self.normals[i].dot(&(q - self.positions[i]))
    }
}

/// One posed body per batch sample (shared, so a trainer can reuse bodies across steps).
#[derive(Clone, Debug, Default)]
pub struct BodyBatch {
    /// Bodies, one per sample of the garment batch.
    pub bodies: Vec<Arc<PosedBody>>,
}

impl BodyBatch {
    /// A batch from bodies.
    pub fn new(bodies: Vec<Arc<PosedBody>>) -> Self {
        Self { bodies }
    }

    /// Number of bodies.
    pub fn len(&self) -> usize {
        self.bodies.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.bodies.is_empty()
    }
}

/// Nearest body points and normals for every garment vertex of a batch, on the device.
#[derive(Clone, Debug)]
pub struct Contacts {
    /// Nearest body vertex per garment vertex, `[B, V, 3]`.
    pub points: Tensor<3>,
    /// Its unit normal, `[B, V, 3]`.
    pub normals: Tensor<3>,
    /// Signed distances at the queried positions, `B·V` values in metres (CPU copy).
    pub distances_m: Vec<f32>,
}

impl Contacts {
    /// Queries `bodies` with the positions `x_flat` (`B·V·3` values, sample-major) and uploads
    /// the result. One k-d tree query per vertex, in parallel.
    pub fn query(
        bodies: &BodyBatch,
        x_flat: &[f32],
        vertices: usize,
        device: &Device,
        dtype: DType,
    ) -> Result<Self, PhysicsError> {
        let b = bodies.len();
        if b == 0 || x_flat.len() != b * vertices * 3 {
            return Err(PhysicsError::ShapeMismatch {
                what: "collision query".into(),
                expected: format!("{b} bodies x {vertices} vertices x 3"),
                found: format!("{} values", x_flat.len()),
            });
        }
        let found: Vec<[f32; 7]> = x_flat
            .par_chunks_exact(3)
            .enumerate()
            .map(|(k, q)| {
                let body = &bodies.bodies[k / vertices.max(1)];
                let q = Vec3::new(q[0], q[1], q[2]);
                let i = body.nearest(&q);
                let (p, n) = (body.positions[i], body.normals[i]);
                [p.x, p.y, p.z, n.x, n.y, n.z, n.dot(&(q - p))]
            })
            .collect();
        let column = |range: std::ops::Range<usize>| -> Tensor<3> {
            let flat: Vec<f32> = found
                .iter()
                .flat_map(|f| f[range.clone()].iter().copied())
                .collect();
            Tensor::from_data(TensorData::new(flat, [b, vertices, 3]), (device, dtype))
        };
        Ok(Self {
            points: column(0..3),
            normals: column(3..6),
            distances_m: found.iter().map(|f| f[6]).collect(),
        })
    }

    /// Queries with the current prediction `x` (`[B, V, 3]`, read back detached).
    pub fn for_prediction(
        bodies: &BodyBatch,
        x: &Tensor<3>,
        dtype: DType,
    ) -> Result<Self, PhysicsError> {
        let [b, v, _] = x.dims();
        if b != bodies.len() {
            return Err(PhysicsError::ShapeMismatch {
                what: "body batch".into(),
                expected: format!("{b} bodies (one per garment sample)"),
                found: format!("{}", bodies.len()),
            });
        }
        let flat = read_f32(x.clone().detach())?;
        Self::query(bodies, &flat, v, &x.device(), dtype)
    }
}

/// Signed distances `[B, V, 1]` of `x` to the contact points, in metres.
pub fn signed_distances(x: &Tensor<3>, contacts: &Contacts) -> Tensor<3> {
    dot(
        x.clone() - contacts.points.clone(),
        contacts.normals.clone(),
    )
}

/// Collision energy `k_c Σ_v mask_v min(d_v - ε, 0)²` per sample, `[B]` joules.
pub fn collision(
    x: &Tensor<3>,
    contacts: &Contacts,
    rt: &RestTensors,
    k_c: f32,
    eps_m: f32,
) -> Tensor<1> {
    let Some(mask) = rt.collide.as_ref() else {
        return rt.zeros(x.dims()[0]);
    };
    let pen = signed_distances(x, contacts)
        .sub_scalar(eps_m)
        .clamp_max(0.0);
    per_sample(pen.square() * mask.clone()).mul_scalar(k_c)
}

/// Fraction of colliding vertices with `d < 0` per sample, `[B]` (the collision metric / 100).
pub fn inside_fraction(
    x: &Tensor<3>,
    contacts: &Contacts,
    rt: &RestTensors,
    colliding: usize,
) -> Option<Tensor<1>> {
    let mask = rt.collide.as_ref()?;
    let d = signed_distances(x, contacts);
    let inside = d.zeros_like().mask_fill(d.lower_elem(0.0), 1.0);
    Some(per_sample(inside * mask.clone()).div_scalar(colliding.max(1) as f64))
}
