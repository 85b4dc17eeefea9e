//! Body collision: posed bodies with area-weighted vertex normals and a wide k-d tree, the
//! batched nearest-vertex query (CPU, parallel across the batch) and the collision energy
//! `k_c Σ_v min(d_v - ε, 0)²` with `d_v = n_b·(x_v - b)` the signed distance to the nearest
//! posed body vertex `b` along its normal `n_b` (negative inside).
//!
//! The query runs on a detached CPU copy of the prediction; its result (`Contacts`) is uploaded
//! as `[B, V, 3]` points and normals, so the energy itself is a few element-wise device ops.

use std::sync::Arc;

use burn::tensor::{DType, Device, Tensor, TensorData};
use rayon::prelude::*;

use neural_cloth_core::geometry::{TriMesh, Vec3, WideKdTree};
use neural_cloth_core::scene::{Avatar, Pose};

use super::PhysicsError;
use super::tensors::{RestTensors, dot, per_sample, read_f32};

/// Garment vertices per task of the batched query.
const QUERY_CHUNK: usize = 256;

/// A body mesh in one pose, ready for distance queries.
#[derive(Clone, Debug)]
pub struct PosedBody {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    tree: WideKdTree,
}

impl PosedBody {
    /// Builds the query structure for body vertices `positions` joined by `faces` (normals are
    /// area-weighted vertex normals of that mesh).
    pub fn new(positions: Vec<Vec3>, faces: &[[u32; 3]]) -> Result<Self, PhysicsError> {
        let mesh = TriMesh::new(positions, faces.to_vec())
            .map_err(|e| PhysicsError::InvalidBody(e.to_string()))?;
        let normals = mesh.vertex_normals();
        let tree = WideKdTree::new(&mesh.positions);
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

    /// Index of the body vertex nearest to `q`, ties going to the lowest index (0 for a
    /// non-finite query). Exact: the same vertex as a scan of every body vertex.
    pub fn nearest(&self, q: &Vec3) -> usize {
        self.nearest_from(q, None)
    }

    /// [`PosedBody::nearest`] seeded with a body vertex `seed` near the answer (e.g. the
    /// answer for a neighbouring garment vertex): the same exact answer whatever the seed,
    /// found faster the nearer the seed is.
    pub fn nearest_from(&self, q: &Vec3, seed: Option<usize>) -> usize {
        let seed = seed.and_then(|s| u32::try_from(s).ok());
        self.tree.nearest(q, seed).map_or(0, |(i, _)| i as usize)
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
    /// Nearest body vertex index per garment vertex, `B·V` values (CPU copy; friction reads
    /// the body's motion at these vertices).
    pub indices: Vec<u32>,
}

impl Contacts {
    /// Queries `bodies` with the positions `x_flat` (`B·V·3` values, sample-major) and uploads
    /// the result. One exact query per vertex (nearest body vertex, ties to the lowest index,
    /// whatever the distance), in parallel over chunks of vertices; each query is seeded with
    /// the answer of the previous vertex of its sample (neighbours in the garment's vertex
    /// order are mostly neighbours on the garment), which only makes it faster.
    pub fn query(
        bodies: &BodyBatch,
        x_flat: &[f32],
        vertices: usize,
        device: &Device,
        dtype: DType,
    ) -> Result<Self, PhysicsError> {
        Self::query_with(
            bodies,
            x_flat,
            vertices,
            device,
            dtype,
            |_, body, q, seed| body.nearest_from(q, seed),
        )
    }

    /// [`Contacts::query`] with another nearest-vertex function `nearest(sample, body, q,
    /// seed)` (the cost benchmark times the query of before through it, with everything else
    /// the same).
    pub fn query_with(
        bodies: &BodyBatch,
        x_flat: &[f32],
        vertices: usize,
        device: &Device,
        dtype: DType,
        nearest: impl Fn(usize, &PosedBody, &Vec3, Option<usize>) -> usize + Sync,
    ) -> Result<Self, PhysicsError> {
        let b = bodies.len();
        if b == 0 || x_flat.len() != b * vertices * 3 {
            return Err(PhysicsError::ShapeMismatch {
                what: "collision query".into(),
                expected: format!("{b} bodies x {vertices} vertices x 3"),
                found: format!("{} values", x_flat.len()),
            });
        }
        let mut points = vec![0.0f32; x_flat.len()];
        let mut normals = vec![0.0f32; x_flat.len()];
        let mut distances_m = vec![0.0f32; x_flat.len() / 3];
        let mut indices = vec![0u32; x_flat.len() / 3];
        points
            .par_chunks_mut(3 * QUERY_CHUNK)
            .zip(normals.par_chunks_mut(3 * QUERY_CHUNK))
            .zip(distances_m.par_chunks_mut(QUERY_CHUNK))
            .zip(indices.par_chunks_mut(QUERY_CHUNK))
            .enumerate()
            .for_each(|(chunk, (((points, normals), distances), found))| {
                let first = chunk * QUERY_CHUNK;
                let mut seed = None;
                for (j, (d, found)) in distances.iter_mut().zip(found).enumerate() {
                    let k = first + j;
                    if k.is_multiple_of(vertices.max(1)) {
                        seed = None;
                    }
                    let sample = k / vertices.max(1);
                    let body = &bodies.bodies[sample];
                    let q = Vec3::new(x_flat[3 * k], x_flat[3 * k + 1], x_flat[3 * k + 2]);
                    let i = nearest(sample, body, &q, seed);
                    seed = Some(i);
                    *found = i as u32;
                    let (p, n) = (body.positions[i], body.normals[i]);
                    points[3 * j..3 * j + 3].copy_from_slice(&[p.x, p.y, p.z]);
                    normals[3 * j..3 * j + 3].copy_from_slice(&[n.x, n.y, n.z]);
                    *d = n.dot(&(q - p));
                }
            });
        let upload = |flat: Vec<f32>| -> Tensor<3> {
            Tensor::from_data(TensorData::new(flat, [b, vertices, 3]), (device, dtype))
        };
        Ok(Self {
            points: upload(points),
            normals: upload(normals),
            distances_m,
            indices,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::{tube, uv_sphere};
    use neural_cloth_core::geometry::bucket_kdtree::distance2;
    use neural_cloth_core::geometry::{BucketKdTree, KdTree};
    use neural_cloth_core::scene::procedural::{
        GarmentKind, MotionKind, builtin_garment, mannequin, motion,
    };

    /// Posed garments against posed bodies: the t-shirt and skirt on the mannequin along walk
    /// and run frames, with millimetres of noise and every other sample squeezed into the body;
    /// plus the cost benchmark's flared tube around a sphere.
    fn cases() -> Vec<(String, BodyBatch, Vec<f32>, usize)> {
        let avatar = mannequin().unwrap();
        let mut out = Vec::new();
        let mut s = 99u32;
        let mut noise = move || {
            s = s.wrapping_mul(1664525).wrapping_add(1013904223);
            ((s >> 8) as f32 / (1u32 << 24) as f32 - 0.5) * 0.01
        };
        for kind in [GarmentKind::TShirt, GarmentKind::Skirt] {
            let garment = builtin_garment(&avatar, kind, 3400, None).unwrap();
            let mut bodies = Vec::new();
            let mut x = Vec::new();
            for m in [MotionKind::Walk, MotionKind::Run] {
                let frames = motion(m, 30.0, 1.0).unwrap().frames;
                for (f, pose) in frames.iter().step_by(7).enumerate() {
                    bodies.push(Arc::new(PosedBody::from_avatar(&avatar, pose).unwrap()));
                    let squeeze = if f % 2 == 1 { 0.93 } else { 1.0 };
                    let hips = avatar
                        .pose_vertices(pose)
                        .iter()
                        .fold(Vec3::zeros(), |a, p| a + p)
                        / avatar.bind_mesh.positions.len() as f32;
                    for p in garment.pose_vertices(&avatar, pose) {
                        let mut q = p - hips;
                        q.x *= squeeze;
                        q.z *= squeeze;
                        let q = q + hips;
                        x.extend([q.x + noise(), q.y + noise(), q.z + noise()]);
                    }
                }
            }
            out.push((
                kind.name().to_string(),
                BodyBatch::new(bodies),
                x,
                garment.vertex_count(),
            ));
        }
        let mesh = tube(Vec3::new(0.0, 1.0, 0.0), 0.22, 0.45, 0.25, -0.35, 81, 39);
        let sphere = uv_sphere(Vec3::new(0.0, 1.0, 0.0), 0.32, 72, 96);
        let body = Arc::new(PosedBody::new(sphere.positions, &sphere.faces).unwrap());
        let x: Vec<f32> = (0..4)
            .flat_map(|b| {
                mesh.positions.iter().enumerate().flat_map(move |(i, p)| {
                    let wobble = 0.01 * ((i * 7 + b * 13) as f32).sin();
                    [p.x * (1.0 + wobble), p.y + wobble, p.z * (1.0 - wobble)]
                })
            })
            .collect();
        out.push((
            "tube around a sphere".into(),
            BodyBatch::new(vec![body; 4]),
            x,
            mesh.positions.len(),
        ));
        out
    }

    #[test]
    fn contacts_equal_todays_query_wherever_the_energy_is_non_zero() {
        let device = Device::flex();
        let eps = crate::FabricParams::default().collision_threshold_m;
        for (name, bodies, x, v) in cases() {
            let today: Vec<KdTree> = bodies
                .bodies
                .iter()
                .map(|b| KdTree::new(&b.positions))
                .collect();
            let c = Contacts::query(&bodies, &x, v, &device, DType::F32).unwrap();
            let points = read_f32(c.points.clone()).unwrap();
            let normals = read_f32(c.normals.clone()).unwrap();
            let (mut touching, mut differ) = (0, 0);
            for (k, q) in x.chunks_exact(3).enumerate() {
                let body = &bodies.bodies[k / v];
                let q = Vec3::new(q[0], q[1], q[2]);
                // Today's query: the k-d tree's first-found nearest vertex.
                let old = today[k / v].nearest(&q).map_or(0, |(i, _)| i as usize);
                let (p, n) = (body.positions[old], body.normals[old]);
                let new = Vec3::new(points[3 * k], points[3 * k + 1], points[3 * k + 2]);
                let new_n = Vec3::new(normals[3 * k], normals[3 * k + 1], normals[3 * k + 2]);
                let d_old = n.dot(&(q - p));
                if d_old < eps || c.distances_m[k] < eps {
                    touching += 1;
                    assert_eq!((new, new_n), (p, n), "{name}: vertex {k}: contact differs");
                    assert_eq!(c.distances_m[k], d_old, "{name}: vertex {k}");
                }
                differ += usize::from(new != p);
                // Everywhere: the brute-force nearest (ties to the lowest index).
                let brute = body
                    .positions
                    .iter()
                    .enumerate()
                    .map(|(i, b)| (distance2(b, &q), i))
                    .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
                    .map_or(0, |(_, i)| i);
                assert_eq!(
                    new, body.positions[brute],
                    "{name}: vertex {k}: not the nearest"
                );
            }
            assert!(
                touching > 20,
                "{name}: only {touching} vertices near the body"
            );
            assert_eq!(
                differ, 0,
                "{name}: {differ} contacts away from the body differ"
            );
        }
    }

    /// The nearest body vertex by brute force, ties to the lowest index (0 when every
    /// distance is NaN, as for a NaN query).
    fn brute(body: &PosedBody, q: &Vec3) -> usize {
        body.positions
            .iter()
            .enumerate()
            .map(|(i, b)| (distance2(b, q), i))
            .filter(|(d2, _)| !d2.is_nan())
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
            .map_or(0, |(_, i)| i)
    }

    #[test]
    fn contacts_are_the_brute_force_nearest_near_far_on_the_surface_and_not_finite() {
        let device = Device::flex();
        let avatar = mannequin().unwrap();
        let pose = &motion(MotionKind::Run, 30.0, 0.5).unwrap().frames[7];
        let sphere = uv_sphere(Vec3::new(0.0, 1.0, 0.0), 0.32, 24, 32);
        let mut s = 5u32;
        let mut rnd = move || {
            s = s.wrapping_mul(1664525).wrapping_add(1013904223);
            (s >> 8) as f32 / (1u32 << 24) as f32 - 0.5
        };
        for body in [
            PosedBody::from_avatar(&avatar, pose).unwrap(),
            PosedBody::new(sphere.positions.clone(), &sphere.faces).unwrap(),
        ] {
            let (p, n) = (&body.positions, &body.normals);
            let mut x: Vec<Vec3> = Vec::new();
            // On the surface: every vertex (the answer is itself or an earlier duplicate),
            // edge midpoints (equidistant from two vertices up to rounding).
            x.extend(p.iter().copied());
            x.extend(p.windows(2).step_by(5).map(|w| (w[0] + w[1]) * 0.5));
            // Along the normals: inside, at and just beyond the collision threshold (4 mm),
            // centimetres and metres away.
            for (k, off) in [-0.02, -0.001, 0.0039, 0.004, 0.0065, 0.03, 0.3, 10.0]
                .into_iter()
                .enumerate()
            {
                x.extend((k..p.len()).step_by(13).map(|i| p[i] + n[i] * off));
            }
            // Random points in and around the body's box, and very far away.
            let (lo, hi) = p
                .iter()
                .fold((p[0], p[0]), |(l, h), q| (l.inf(q), h.sup(q)));
            x.extend((0..3000).map(|_| {
                let t = Vec3::new(rnd(), rnd(), rnd()) * 1.6 + Vec3::repeat(0.5);
                lo + (hi - lo).component_mul(&t)
            }));
            x.extend([
                Vec3::new(1e4, -3e4, 2e4),
                Vec3::new(-1e30, 1e30, 0.0),
                Vec3::new(f32::NAN, 1.0, 0.0),
                Vec3::new(0.0, f32::INFINITY, 0.0),
                Vec3::new(f32::NEG_INFINITY, 0.0, f32::NAN),
            ]);
            // Twice, as two samples of one batch (the seeds restart per sample).
            let v = x.len();
            let flat: Vec<f32> = x.iter().chain(&x).flat_map(|q| [q.x, q.y, q.z]).collect();
            let shared = Arc::new(body.clone());
            let bodies = BodyBatch::new(vec![shared.clone(), shared]);
            let c = Contacts::query(&bodies, &flat, v, &device, DType::F32).unwrap();
            let points = read_f32(c.points.clone()).unwrap();
            let today = BucketKdTree::new(p);
            for (k, q) in x.iter().chain(&x).enumerate() {
                let want = brute(&body, q);
                // Today's query (the bucketed k-d tree): the same vertex everywhere.
                let old = today.nearest(q, None).map_or(0, |(i, _)| i as usize);
                assert_eq!(want, old, "vertex {k} at {q:?}: brute force against today");
                assert_eq!(c.indices[k] as usize, want, "vertex {k} at {q:?}");
                assert_eq!(body.nearest(q), want, "vertex {k} at {q:?}");
                assert_eq!(body.nearest_from(q, Some(k % p.len())), want);
                let got = Vec3::new(points[3 * k], points[3 * k + 1], points[3 * k + 2]);
                assert_eq!(got, p[want], "vertex {k}");
                let d = n[want].dot(&(q - p[want]));
                let got = c.distances_m[k];
                assert!(
                    got == d || (got.is_nan() && d.is_nan()),
                    "vertex {k}: {got} {d}"
                );
            }
            // Non-finite queries keep today's answer: vertex 0.
            assert!(c.indices[v - 3..v].iter().all(|&i| i == 0));
        }
    }

    #[test]
    #[ignore = "timing: run with --ignored --nocapture"]
    fn query_cost_today_and_now() {
        let device = Device::flex();
        for (name, bodies, x, v) in cases() {
            let n = x.len() / 3;
            let today: Vec<KdTree> = bodies
                .bodies
                .iter()
                .map(|b| KdTree::new(&b.positions))
                .collect();
            // This thread's CPU time over ten passes (the machine may be shared; the counter
            // advances in scheduler ticks).
            let cpu_ns = || -> f64 {
                std::fs::read_to_string("/proc/thread-self/schedstat")
                    .ok()
                    .and_then(|s| s.split_whitespace().next()?.parse().ok())
                    .unwrap_or(0.0)
            };
            let time = |f: &dyn Fn(usize, &Vec3, Option<u32>) -> u32| {
                let start = cpu_ns();
                for _ in 0..10 {
                    let mut hint = None;
                    for (k, q) in x.chunks_exact(3).enumerate() {
                        let i = f(k, &Vec3::new(q[0], q[1], q[2]), hint);
                        hint = (k % v != v - 1).then_some(i);
                    }
                }
                (cpu_ns() - start) / (10 * n) as f64
            };
            let buckets: Vec<BucketKdTree> = bodies
                .bodies
                .iter()
                .map(|b| BucketKdTree::new(&b.positions))
                .collect();
            let old = time(&|k, q, _| today[k / v].nearest(q).map_or(0, |r| r.0));
            let bucket = time(&|k, q, _| buckets[k / v].nearest(q, None).map_or(0, |r| r.0));
            let bucket_seeded = time(&|k, q, h| buckets[k / v].nearest(q, h).map_or(0, |r| r.0));
            let new = time(&|k, q, _| {
                bodies.bodies[k / v]
                    .tree
                    .nearest(q, None)
                    .map_or(0, |r| r.0)
            });
            let seeded =
                time(&|k, q, h| bodies.bodies[k / v].tree.nearest(q, h).map_or(0, |r| r.0));
            let mut c = None;
            let all = (0..5)
                .map(|_| {
                    let start = std::time::Instant::now();
                    c = Contacts::query(&bodies, &x, v, &device, DType::F32).ok();
                    start.elapsed().as_secs_f64() * 1e3
                })
                .fold(f64::INFINITY, f64::min);
            let c = c.unwrap();
            println!(
                "{name}: {n} queries on {} bodies, CPU ns/query: first-found k-d tree {old:.0}, \
                 bucket tree {bucket:.0} (seeded {bucket_seeded:.0}), wide tree {new:.0} \
                 (seeded {seeded:.0}); Contacts::query {all:.2} ms",
                c.distances_m.len() / v
            );
        }
    }
}
