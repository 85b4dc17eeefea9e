//! The trainer-facing loss builder: one [`PhysicsTerms`] per garment holds the rest state on the
//! device and evaluates the enabled terms on batches of predictions.
//!
//! The static energies (cloth, bending, collision, gravity) run either as the fused host kernels
//! of [`super::fused`] with hand-written gradients (the default) or as the burn tensor code of
//! [`super::energies`] (the reference, [`PhysicsTerms::with_fused`]`(false)`); both return the
//! same terms in the same order with the same values and gradients.

use std::sync::Arc;

use burn::tensor::{DType, Device, Tensor};

use neural_cloth_core::scene::Garment;

use super::collision::{self, BodyBatch, Contacts};
use super::energies;
use super::friction::FrictionContacts;
use super::fused::surrogate::{HostPositions, surrogate};
use super::fused::{self, HostContacts, Kernel, ScratchPool};
use super::rest::GarmentRest;
use super::tensors::{RestTensors, read_f32, read_f64};
use super::{ClothModel, Effects, FabricParams, PhysicsError};

/// A named loss term.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Term {
    /// In-plane stretch (mass-spring edges, Baraff-Witkin stretch or StVK).
    Stretch,
    /// Baraff-Witkin shear.
    Shear,
    /// Bending.
    Bending,
    /// Body collision.
    Collision,
    /// Gravity potential.
    Gravity,
    /// Pinning.
    Pinning,
    /// Inertia.
    Inertia,
    /// Cloth-body friction (dissipation of the step's slip over the body).
    Friction,
}

impl Term {
    /// Short lowercase name for logs.
    pub fn name(self) -> &'static str {
        match self {
            Term::Stretch => "stretch",
            Term::Shear => "shear",
            Term::Bending => "bending",
            Term::Collision => "collision",
            Term::Gravity => "gravity",
            Term::Pinning => "pinning",
            Term::Inertia => "inertia",
            Term::Friction => "friction",
        }
    }
}

/// Loss terms, each a `[1]` tensor: the per-sample energy (sum over the mesh) averaged over the
/// batch, as in the official code.
#[derive(Clone, Debug, Default)]
pub struct LossTerms {
    /// The terms in evaluation order.
    pub terms: Vec<(Term, Tensor<1>)>,
}

impl LossTerms {
    /// Sum of all terms (None when empty).
    pub fn total(&self) -> Option<Tensor<1>> {
        self.terms
            .iter()
            .map(|(_, t)| t.clone())
            .reduce(|a, b| a + b)
    }

    /// The term `term`, if present.
    pub fn get(&self, term: Term) -> Option<&Tensor<1>> {
        self.terms.iter().find(|(t, _)| *t == term).map(|(_, v)| v)
    }

    /// Adds a term.
    pub fn push(&mut self, term: Term, value: Tensor<1>) {
        self.terms.push((term, value));
    }

    /// Reads every term back (one device read per term) for logging.
    pub fn values(&self) -> Result<Vec<(Term, f64)>, PhysicsError> {
        self.terms
            .iter()
            .map(|(t, v)| {
                Ok((
                    *t,
                    read_f64(v.clone().detach())?
                        .first()
                        .copied()
                        .unwrap_or(0.0),
                ))
            })
            .collect()
    }
}

/// Physics of one garment: fabric, effects and the rest state uploaded once to a device.
#[derive(Clone, Debug)]
pub struct PhysicsTerms {
    rest: Arc<GarmentRest>,
    fabric: FabricParams,
    effects: Effects,
    tensors: RestTensors,
    /// Static energies through the fused kernels (true) or the burn reference (false).
    fused: bool,
    /// Gradient accumulators of the fused kernels, shared by clones.
    scratch: Arc<ScratchPool>,
}

impl PhysicsTerms {
    /// Builds the terms of `garment` on `device` with the device's default float dtype.
    pub fn new(
        garment: &Garment,
        fabric: &FabricParams,
        effects: &Effects,
        device: &Device,
    ) -> Result<Self, PhysicsError> {
        fabric.validate()?;
        let rest = GarmentRest::from_garment(garment, fabric)?;
        let dtype = device.settings().float_dtype.into();
        Self::from_rest(Arc::new(rest), fabric, effects, device, dtype)
    }

    /// Builds the terms from a precomputed rest state with an explicit float dtype (`F64` is
    /// useful for reference checks on backends that support it).
    pub fn from_rest(
        rest: Arc<GarmentRest>,
        fabric: &FabricParams,
        effects: &Effects,
        device: &Device,
        dtype: DType,
    ) -> Result<Self, PhysicsError> {
        fabric.validate()?;
        let tensors = RestTensors::new(&rest, fabric.gravity(), effects, device, dtype);
        Ok(Self {
            rest,
            fabric: fabric.clone(),
            effects: *effects,
            tensors,
            fused: true,
            scratch: Arc::new(ScratchPool::default()),
        })
    }

    /// Evaluates the static energies with the fused kernels (`true`, the default) or with the
    /// burn tensor code they are checked against (`false`).
    pub fn with_fused(mut self, fused: bool) -> Self {
        self.fused = fused;
        self
    }

    /// True when the static energies run as fused kernels.
    pub fn fused(&self) -> bool {
        self.fused
    }

    /// The rest state.
    pub fn rest(&self) -> &GarmentRest {
        &self.rest
    }

    /// The fabric.
    pub fn fabric(&self) -> &FabricParams {
        &self.fabric
    }

    /// The effects.
    pub fn effects(&self) -> &Effects {
        &self.effects
    }

    /// The device tensors.
    pub fn tensors(&self) -> &RestTensors {
        &self.tensors
    }

    /// Float dtype of the terms.
    pub fn dtype(&self) -> DType {
        self.tensors.dtype
    }

    /// Device of the terms.
    pub fn device(&self) -> &Device {
        &self.tensors.device
    }

    /// Nearest-vertex contacts of `x` against `body` (detached CPU query, then upload).
    pub fn contacts(&self, x: &Tensor<3>, body: &BodyBatch) -> Result<Contacts, PhysicsError> {
        self.tensors.batch_of(x)?;
        Contacts::for_prediction(body, x, self.tensors.dtype)
    }

    /// In-plane energy terms per sample (`[B]` each): stretch, plus shear for Baraff-Witkin.
    pub fn cloth_energies(&self, x: &Tensor<3>) -> Result<Vec<(Term, Tensor<1>)>, PhysicsError> {
        self.tensors.batch_of(x)?;
        if self.fused {
            self.fused_energies(x, &self.cloth_kernels(), None)
        } else {
            Ok(self.reference_cloth_energies(x))
        }
    }

    /// Every enabled static energy per sample (`[B]` each): cloth, bending, collision (with
    /// `contacts`, required when collision is on), gravity.
    pub fn static_energies(
        &self,
        x: &Tensor<3>,
        contacts: Option<&Contacts>,
    ) -> Result<Vec<(Term, Tensor<1>)>, PhysicsError> {
        self.tensors.batch_of(x)?;
        if self.effects.collision {
            let contacts = contacts.ok_or(PhysicsError::MissingBody)?;
            if contacts.points.dims() != x.dims() {
                return Err(PhysicsError::ShapeMismatch {
                    what: "collision contacts".into(),
                    expected: format!("{:?}", x.dims()),
                    found: format!("{:?}", contacts.points.dims()),
                });
            }
        }
        if !self.fused {
            return Ok(self.reference_static_energies(x, contacts));
        }
        let mut kernels = self.cloth_kernels();
        let f = &self.fabric;
        if self.effects.bending {
            kernels.push((
                Term::Bending,
                Kernel::Bending {
                    k: f64::from(f.bending_stiffness),
                },
            ));
        }
        if self.effects.collision {
            kernels.push((
                Term::Collision,
                Kernel::Collision {
                    k: f64::from(f.collision_stiffness),
                    eps_m: f64::from(f.collision_threshold_m),
                },
            ));
        }
        if self.effects.gravity {
            let g = f.gravity();
            kernels.push((
                Term::Gravity,
                Kernel::Gravity {
                    g: [g.x, g.y, g.z].map(f64::from),
                },
            ));
        }
        self.fused_energies(x, &kernels, contacts)
    }

    /// The fused kernels of the in-plane model, with their terms.
    fn cloth_kernels(&self) -> Vec<(Term, Kernel)> {
        let f = &self.fabric;
        let k = f64::from(f.stretch_stiffness);
        match f.cloth_model {
            ClothModel::MassSpring => vec![(Term::Stretch, Kernel::MassSpring { k })],
            ClothModel::BaraffWitkin => vec![
                (Term::Stretch, Kernel::BaraffWitkinStretch { k }),
                (
                    Term::Shear,
                    Kernel::BaraffWitkinShear {
                        k: f64::from(f.shear_stiffness),
                    },
                ),
            ],
            ClothModel::Stvk => vec![(
                Term::Stretch,
                Kernel::Stvk {
                    lambda: f64::from(f.lame_lambda),
                    mu: f64::from(f.lame_mu),
                },
            )],
        }
    }

    /// Evaluates `kernels` on `x` (`[B, V, 3]`, read back once) on the host and returns each
    /// term as a `[B]` tensor whose gradient with respect to `x` is the kernel's analytic one.
    /// `contacts` is required when a kernel needs it.
    pub fn fused_energies(
        &self,
        x: &Tensor<3>,
        kernels: &[(Term, Kernel)],
        contacts: Option<&Contacts>,
    ) -> Result<Vec<(Term, Tensor<1>)>, PhysicsError> {
        let b = self.tensors.batch_of(x)?;
        let host_contacts = if kernels.iter().any(|(_, k)| k.needs_contacts()) {
            let c = contacts.ok_or(PhysicsError::MissingBody)?;
            Some(HostContacts {
                points: read_f32(c.points.clone())?,
                normals: read_f32(c.normals.clone())?,
            })
        } else {
            None
        };
        let only: Vec<Kernel> = kernels.iter().map(|(_, k)| *k).collect();
        let (rest, pool, dtype) = (&*self.rest, &*self.scratch, self.tensors.dtype);
        let values = match HostPositions::read(x)? {
            HostPositions::F32(v) => {
                fused::evaluate(rest, &only, &v, b, host_contacts.as_ref(), pool)?
                    .into_iter()
                    .map(|e| surrogate(x, e, dtype))
                    .collect::<Result<Vec<_>, _>>()?
            }
            HostPositions::F64(v) => {
                fused::evaluate(rest, &only, &v, b, host_contacts.as_ref(), pool)?
                    .into_iter()
                    .map(|e| surrogate(x, e, dtype))
                    .collect::<Result<Vec<_>, _>>()?
            }
        };
        Ok(kernels.iter().map(|(t, _)| *t).zip(values).collect())
    }

    /// The burn reference of [`Self::cloth_energies`].
    fn reference_cloth_energies(&self, x: &Tensor<3>) -> Vec<(Term, Tensor<1>)> {
        let f = &self.fabric;
        let rt = &self.tensors;
        match f.cloth_model {
            ClothModel::MassSpring => vec![(
                Term::Stretch,
                energies::mass_spring(x, rt, f.stretch_stiffness),
            )],
            ClothModel::BaraffWitkin => {
                let (stretch, shear) =
                    energies::baraff_witkin(x, rt, f.stretch_stiffness, f.shear_stiffness);
                vec![(Term::Stretch, stretch), (Term::Shear, shear)]
            }
            ClothModel::Stvk => vec![(
                Term::Stretch,
                energies::stvk(x, rt, f.lame_lambda, f.lame_mu),
            )],
        }
    }

    /// The burn reference of [`Self::static_energies`] (arguments already checked).
    fn reference_static_energies(
        &self,
        x: &Tensor<3>,
        contacts: Option<&Contacts>,
    ) -> Vec<(Term, Tensor<1>)> {
        let f = &self.fabric;
        let rt = &self.tensors;
        let mut out = self.reference_cloth_energies(x);
        if self.effects.bending {
            out.push((Term::Bending, energies::bending(x, rt, f.bending_stiffness)));
        }
        if let (true, Some(contacts)) = (self.effects.collision, contacts) {
            out.push((
                Term::Collision,
                collision::collision(
                    x,
                    contacts,
                    rt,
                    f.collision_stiffness,
                    f.collision_threshold_m,
                ),
            ));
        }
        if self.effects.gravity {
            out.push((Term::Gravity, energies::gravity(x, rt)));
        }
        out
    }

    /// Static losses of the last predicted frame `x` (`[B, V, 3]`), batch means. `body` is
    /// required when collision is on (its nearest-vertex query runs here).
    pub fn static_losses(
        &self,
        x: &Tensor<3>,
        body: Option<&BodyBatch>,
    ) -> Result<LossTerms, PhysicsError> {
        let contacts = match (self.effects.collision, body) {
            (true, Some(body)) => Some(self.contacts(x, body)?),
            (true, None) => return Err(PhysicsError::MissingBody),
            (false, _) => None,
        };
        self.static_losses_with(x, contacts.as_ref())
    }

    /// Like [`Self::static_losses`] with precomputed contacts.
    pub fn static_losses_with(
        &self,
        x: &Tensor<3>,
        contacts: Option<&Contacts>,
    ) -> Result<LossTerms, PhysicsError> {
        let terms = self.static_energies(x, contacts)?;
        Ok(LossTerms {
            terms: terms.into_iter().map(|(t, v)| (t, v.mean())).collect(),
        })
    }

    /// Inertia loss (batch mean) of `x_t` given the two previous frames (all three `[B, V, 3]`);
    /// gradients reach only `x_t`. None when dynamics is off.
    pub fn inertia(
        &self,
        x_t: &Tensor<3>,
        x_t1: &Tensor<3>,
        x_t2: &Tensor<3>,
        dt_secs: f32,
    ) -> Option<Tensor<1>> {
        self.effects
            .dynamics
            .then(|| energies::inertia(x_t, x_t1, x_t2, &self.tensors, dt_secs).mean())
    }

    /// True when friction acts: the friction effect with collision and dynamics (friction
    /// needs contacts and a previous frame).
    pub fn friction_on(&self) -> bool {
        let e = &self.effects;
        e.friction && e.collision && e.dynamics
    }

    /// The friction inputs of `contacts` (queried at the end of the step against `now`;
    /// `before` holds the bodies at its start, `active` the rows friction acts on, empty for
    /// all). None when friction is off.
    pub fn friction_contacts(
        &self,
        contacts: &Contacts,
        now: &BodyBatch,
        before: &BodyBatch,
        active: &[bool],
    ) -> Result<Option<FrictionContacts>, PhysicsError> {
        if !self.friction_on() {
            return Ok(None);
        }
        FrictionContacts::new(contacts, now, before, active, &self.rest, &self.fabric).map(Some)
    }

    /// Friction loss (batch mean) of `x_t` given the previous frame `x_t1` (both `[B, V, 3]`;
    /// gradients reach only `x_t`). None when friction is off.
    pub fn friction(
        &self,
        x_t: &Tensor<3>,
        x_t1: &Tensor<3>,
        fc: &FrictionContacts,
    ) -> Option<Tensor<1>> {
        self.friction_on()
            .then(|| super::friction::friction(x_t, x_t1, fc).mean())
    }

    /// Pinning loss (batch mean) pulling pinned vertices of `x` to the same rows of `target`
    /// (`[B, V, 3]`, detached). None when pinning is off or nothing is pinned.
    pub fn pinning(&self, x: &Tensor<3>, target: &Tensor<3>) -> Option<Tensor<1>> {
        let pinned = self.tensors.pinned.as_ref()?;
        Some(energies::pinning(x, target, pinned, self.fabric.pinning_stiffness).mean())
    }
}
