//! Coulomb friction between cloth and body, as a dissipation potential of one step (the
//! lagged, smoothed friction of incremental-potential solvers): for every garment vertex `v`
//! in contact,
//!
//! `D(x) = Σ_v w_v (sqrt(|u_T,v|² + δ²) - δ)`, `u_v = (x_v - x_{t-1,v}) - (b_v - b_{t-1,v})`,
//!
//! where `b_v` is the body vertex in contact with `v` (its nearest, from [`Contacts`]) at the
//! end and at the start of the step, `u_T` the part of the relative displacement `u` tangent to
//! the body (normal `n_v` removed) and `δ` = [`SLIP_REGULARISER_M`]. For slips much larger than
//! `δ` the force is `w_v` along the slip (Coulomb's law: the friction force does not depend on
//! the sliding speed); below `δ` it is a stiff spring that holds the vertex where the body
//! carries it. The weight is the Coulomb bound `w_v = μ m_v |g| ρ(d_v)`: the normal force is
//! approximated by the vertex's weight (the common simplification of learned cloth losses; a
//! garment mostly hangs on the body), and `ρ` ramps from 1 at the collision threshold `ε` to 0
//! at `ε +` [`CONTACT_BAND_M`] of signed distance `d_v` (vertices away from the body feel
//! none, and nothing jumps when a vertex leaves the body).
//!
//! Weights, normals and the body's displacement are fixed per contact query (lagged, as the
//! contacts themselves are), and no gradient reaches `x_{t-1}` (the previous frame is given,
//! as for the inertia term). The same function is the training loss and the reference
//! simulator's term, so the two agree on what friction means.

use burn::tensor::{DType, Device, Tensor, TensorData};

use super::PhysicsError;
use super::collision::{BodyBatch, Contacts};
use super::rest::GarmentRest;
use super::tensors::{dot, norm2, per_sample};
use neural_cloth_core::scene::FabricParams;

/// Slip regulariser `δ` in metres of relative displacement per step: below it the friction
/// force grows linearly with the slip (static friction as a stiff spring), above it stays at
/// the Coulomb bound.
pub const SLIP_REGULARISER_M: f64 = 1e-3;

/// Width of the contact band in metres: the friction weight falls linearly from full at the
/// collision threshold to zero this far beyond it.
pub const CONTACT_BAND_M: f64 = 0.004;

/// What the friction term of one batch holds fixed: the body's motion at each vertex's
/// contact, the contact normals and the per-vertex Coulomb weights.
#[derive(Clone, Debug)]
pub struct FrictionContacts {
    /// Displacement of the contact body vertex over the step, `[B, V, 3]` metres.
    pub body_step: Tensor<3>,
    /// Unit body normals at the contacts, `[B, V, 3]`.
    pub normals: Tensor<3>,
    /// Coulomb weight `μ m |g| ρ(d)` per vertex, `[B, V, 1]` newtons (0 away from the body, for
    /// no-collide vertices and for inactive rows).
    pub weight: Tensor<3>,
    /// 1 where a vertex is in the contact band (`ρ > 0`, collides, active row), else 0,
    /// `[B, V, 1]`: the vertices the slip metric averages over.
    pub touching_mask: Tensor<3>,
}

impl FrictionContacts {
    /// Friction inputs of a batch whose positions at the end of the step were queried as
    /// `contacts` against `now`; `before` holds the same rows' bodies at the start of the step.
    /// `active` (one flag per row, or empty for all) switches rows off (weight 0), e.g. samples
    /// whose previous frame is not their own.
    pub fn new(
        contacts: &Contacts,
        now: &BodyBatch,
        before: &BodyBatch,
        active: &[bool],
        rest: &GarmentRest,
        fabric: &FabricParams,
    ) -> Result<Self, PhysicsError> {
        let [b, v, _] = contacts.normals.dims();
        let n = b * v;
        if now.len() != b
            || before.len() != b
            || contacts.indices.len() != n
            || contacts.distances_m.len() != n
            || rest.vertex_count() != v
            || !(active.is_empty() || active.len() == b)
        {
            return Err(PhysicsError::ShapeMismatch {
                what: "friction contacts".into(),
                expected: format!("{b} bodies before and after, {n} contacts, {v} vertices"),
                found: format!(
                    "{} / {} bodies, {} indices, {} distances, {} vertices, {} row flags",
                    now.len(),
                    before.len(),
                    contacts.indices.len(),
                    contacts.distances_m.len(),
                    rest.vertex_count(),
                    active.len()
                ),
            });
        }
        let bound = f64::from(fabric.friction_coefficient) * f64::from(fabric.gravity().norm());
        let eps = f64::from(fabric.collision_threshold_m);
        let mut step = vec![0.0f32; 3 * n];
        let mut weight = vec![0.0f32; n];
        let mut mask = vec![0.0f32; n];
        for row in 0..b {
            if !(active.is_empty() || active[row]) {
                continue;
            }
            let (p_now, p_before) = (now.bodies[row].positions(), before.bodies[row].positions());
            for vert in 0..v {
                let k = row * v + vert;
                let ramp = ((eps + CONTACT_BAND_M - f64::from(contacts.distances_m[k]))
                    / CONTACT_BAND_M)
                    .clamp(0.0, 1.0);
                let i = contacts.indices[k] as usize;
                if ramp <= 0.0 || !rest.collide[vert] || i >= p_now.len().min(p_before.len()) {
                    continue;
                }
                let w = bound * rest.mass_kg[vert] * ramp;
                let d = p_now[i] - p_before[i];
                step[3 * k..3 * k + 3].copy_from_slice(&[d.x, d.y, d.z]);
                weight[k] = if w.is_finite() { w as f32 } else { 0.0 };
                mask[k] = 1.0;
            }
        }
        let device = contacts.normals.device();
        let dtype = contacts.normals.dtype();
        Ok(Self {
            body_step: upload(step, [b, v, 3], &device, dtype),
            normals: contacts.normals.clone(),
            weight: upload(weight, [b, v, 1], &device, dtype),
            touching_mask: upload(mask, [b, v, 1], &device, dtype),
        })
    }

    /// Number of vertices in the contact band (read back from [`Self::touching_mask`]).
    pub fn touching(&self) -> Result<usize, PhysicsError> {
        Ok(read_sum(self.touching_mask.clone())?.round() as usize)
    }

    /// Rows `start..start + len` of the batch.
    pub fn narrow(&self, start: usize, len: usize) -> Self {
        Self {
            body_step: self.body_step.clone().narrow(0, start, len),
            normals: self.normals.clone().narrow(0, start, len),
            weight: self.weight.clone().narrow(0, start, len),
            touching_mask: self.touching_mask.clone().narrow(0, start, len),
        }
    }
}

fn upload(values: Vec<f32>, shape: [usize; 3], device: &Device, dtype: DType) -> Tensor<3> {
    Tensor::from_data(TensorData::new(values, shape), (device, dtype))
}

fn read_sum(t: Tensor<3>) -> Result<f64, PhysicsError> {
    Ok(super::tensors::read_f64(t.sum())?
        .first()
        .copied()
        .unwrap_or(0.0))
}

/// Squared tangential slip `|u_T|²` of every vertex over the step, `[B, V, 1]` (gradient to
/// `x_t` only).
fn tangential_slip2(x_t: &Tensor<3>, x_t1: &Tensor<3>, fc: &FrictionContacts) -> Tensor<3> {
    let u = x_t.clone() - x_t1.clone().detach() - fc.body_step.clone();
    let normal = dot(u.clone(), fc.normals.clone());
    norm2(u - fc.normals.clone() * normal)
}

/// The friction dissipation `D(x_t)` per sample, `[B]` joules, with `x_{t-1}` detached (see
/// the module docs).
pub fn friction(x_t: &Tensor<3>, x_t1: &Tensor<3>, fc: &FrictionContacts) -> Tensor<1> {
    let d2 = SLIP_REGULARISER_M * SLIP_REGULARISER_M;
    let slip = tangential_slip2(x_t, x_t1, fc)
        .add_scalar(d2)
        .sqrt()
        .sub_scalar(SLIP_REGULARISER_M);
    per_sample(slip * fc.weight.clone())
}

/// Mean tangential slip of the touching vertices relative to the body over the step, in
/// metres (the friction metric: how far the cloth slides over the skin per frame), or None
/// when no vertex touches.
pub fn mean_slip_m(
    x_t: &Tensor<3>,
    x_t1: &Tensor<3>,
    fc: &FrictionContacts,
) -> Result<Option<f64>, PhysicsError> {
    let slip = tangential_slip2(&x_t.clone().detach(), x_t1, fc).sqrt();
    let count = read_sum(fc.touching_mask.clone())?;
    if count <= 0.0 {
        return Ok(None);
    }
    Ok(Some(read_sum(slip * fc.touching_mask.clone())? / count))
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use burn::tensor::{DType, Device};

    use super::*;
    use crate::PosedBody;
    use crate::shapes::{sheet, uv_sphere};
    use crate::tensors::{positions_tensor, read_f64};
    use neural_cloth_core::geometry::{Topology, Vec3};

    /// A 5 x 5 sheet lying on top of a sphere of radius 0.25 m (its centre vertex on the
    /// pole), the body moved by `shift` between the two frames, and the sheet's positions.
    struct Case {
        rest: GarmentRest,
        contacts: Contacts,
        now: BodyBatch,
        before: BodyBatch,
        x: Vec<Vec3>,
        fabric: FabricParams,
    }

    fn case(shift: Vec3, lift_m: f32) -> Case {
        let c = Vec3::new(0.0, 1.0, 0.0);
        let sphere = uv_sphere(c, 0.25, 10, 16);
        let size = 0.2;
        let mesh = sheet(
            4,
            4,
            c + Vec3::new(-size / 2.0, 0.25 + lift_m, size / 2.0),
            Vec3::x() * size,
            -Vec3::z() * size,
        );
        let fabric = FabricParams::default();
        let rest = GarmentRest::new(
            &mesh,
            &Topology::new(&mesh),
            &[],
            &[],
            fabric.density_kg_per_m2,
        )
        .unwrap();
        let before = PosedBody::new(sphere.positions.clone(), &sphere.faces).unwrap();
        let moved: Vec<Vec3> = sphere.positions.iter().map(|p| p + shift).collect();
        let now = PosedBody::new(moved, &sphere.faces).unwrap();
        let x: Vec<Vec3> = mesh.positions.iter().map(|p| p + shift).collect();
        let flat: Vec<f32> = x.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
        let now = BodyBatch::new(vec![Arc::new(now)]);
        let contacts = Contacts::query(&now, &flat, x.len(), &Device::flex(), DType::F32).unwrap();
        Case {
            rest,
            contacts,
            now,
            before: BodyBatch::new(vec![Arc::new(before)]),
            x: mesh.positions,
            fabric,
        }
    }

    fn energy(c: &Case, fc: &FrictionContacts, x_t: &[Vec3]) -> f64 {
        let device = Device::flex();
        let xt = positions_tensor(&[x_t], &device, DType::F32).unwrap();
        let xt1 = positions_tensor(&[c.x.as_slice()], &device, DType::F32).unwrap();
        read_f64(friction(&xt, &xt1, fc)).unwrap()[0]
    }

    fn contacts_of(c: &Case) -> FrictionContacts {
        FrictionContacts::new(&c.contacts, &c.now, &c.before, &[], &c.rest, &c.fabric).unwrap()
    }

    #[test]
    fn cloth_carried_by_the_body_feels_no_friction() {
        let shift = Vec3::new(0.03, 0.0, -0.01);
        let c = case(shift, 0.0);
        let fc = contacts_of(&c);
        assert!(
            fc.touching().unwrap() > 0,
            "the sheet's centre lies on the sphere"
        );
        let carried: Vec<Vec3> = c.x.iter().map(|p| p + shift).collect();
        assert!(energy(&c, &fc, &carried).abs() < 1e-9);
        // Left behind where the body moved away: it slid 3.2 cm over the skin.
        assert!(energy(&c, &fc, &c.x) > 0.0);
    }

    #[test]
    fn a_long_slide_costs_the_coulomb_bound_and_lifting_off_costs_nothing() {
        let c = case(Vec3::zeros(), 0.0);
        let fc = contacts_of(&c);
        let weights = read_f64(fc.weight.clone().sum()).unwrap()[0];
        assert!(weights > 0.0);
        // The pole vertex (centre of the sheet) is the one exactly on the body: move only it.
        let centre = 12;
        let w = read_f64(fc.weight.clone().narrow(1, centre, 1).sum()).unwrap()[0];
        let g = f64::from(c.fabric.gravity().norm());
        let bound = f64::from(c.fabric.friction_coefficient) * g * c.rest.mass_kg[centre];
        assert!((w - bound).abs() < 1e-6 * bound, "{w} vs {bound}");
        let slide = 0.5;
        let mut x = c.x.clone();
        x[centre] += Vec3::new(slide, 0.0, 0.0);
        let e = energy(&c, &fc, &x);
        let expected = w * (f64::from(slide).hypot(SLIP_REGULARISER_M) - SLIP_REGULARISER_M);
        assert!((e - expected).abs() < 1e-4 * expected, "{e} vs {expected}");
        // Straight up, along the pole's normal: no slip, no friction.
        let mut lifted = c.x.clone();
        lifted[centre] += Vec3::new(0.0, 0.01, 0.0);
        assert!(energy(&c, &fc, &lifted).abs() < 1e-9);
    }

    #[test]
    fn cloth_away_from_the_body_and_inactive_rows_feel_none() {
        let fabric = FabricParams::default();
        let far = case(
            Vec3::zeros(),
            fabric.collision_threshold_m + CONTACT_BAND_M as f32 + 0.002,
        );
        let fc = contacts_of(&far);
        assert_eq!(fc.touching().unwrap(), 0);
        let moved: Vec<Vec3> = far.x.iter().map(|p| p + Vec3::x() * 0.1).collect();
        assert_eq!(energy(&far, &fc, &moved), 0.0);
        let near = case(Vec3::zeros(), 0.0);
        let off = FrictionContacts::new(
            &near.contacts,
            &near.now,
            &near.before,
            &[false],
            &near.rest,
            &near.fabric,
        )
        .unwrap();
        assert_eq!(off.touching().unwrap(), 0);
        let moved: Vec<Vec3> = near.x.iter().map(|p| p + Vec3::x() * 0.1).collect();
        assert_eq!(energy(&near, &off, &moved), 0.0);
    }

    #[test]
    fn friction_contacts_refuse_mismatched_batches() {
        let c = case(Vec3::zeros(), 0.0);
        let two = BodyBatch::new(vec![c.now.bodies[0].clone(), c.now.bodies[0].clone()]);
        assert!(
            FrictionContacts::new(&c.contacts, &two, &c.before, &[], &c.rest, &c.fabric).is_err()
        );
        assert!(
            FrictionContacts::new(
                &c.contacts,
                &c.now,
                &c.before,
                &[true, true],
                &c.rest,
                &c.fabric
            )
            .is_err()
        );
    }

    #[test]
    fn slip_metric_reads_the_tangential_slide_in_metres() {
        let c = case(Vec3::zeros(), 0.0);
        let fc = contacts_of(&c);
        let device = Device::flex();
        let xt1 = positions_tensor(&[c.x.as_slice()], &device, DType::F32).unwrap();
        let slid: Vec<Vec3> = c.x.iter().map(|p| p + Vec3::new(0.0, 0.0, 0.01)).collect();
        let xt = positions_tensor(&[slid.as_slice()], &device, DType::F32).unwrap();
        let slip = mean_slip_m(&xt, &xt1, &fc).unwrap().unwrap();
        // Tangential at the pole, a little less where the sphere's normal tilts.
        assert!(slip > 0.008 && slip <= 0.010 + 1e-6, "{slip}");
    }
}
