//! Fused physics kernels: each energy of [`crate::energies`] (and the collision energy
//! of [`crate::collision`]) written once more as plain Rust that computes, for one batch
//! sample, the energy *and* its analytic gradient with respect to the posed vertices in a single
//! pass over the mesh. The burn tensor code stays the reference; these kernels must agree with
//! it (see the tests) and exist only because many small autodiff operations cost far more than
//! the arithmetic they do.
//!
//! - [`Kernel`]: which energy, with its stiffnesses.
//! - [`evaluate`]: runs a set of kernels over a batch of host positions, in parallel over
//!   (kernel, sample) pairs with rayon, accumulating in `f64` into reused scratch buffers.
//! - [`surrogate`]: reads positions from a tensor and hands energies and gradients back to burn
//!   as `e + Σ x·G - sg(Σ x·G)`, whose value is `e` and whose gradient with respect to `x` is
//!   exactly `G`, so everything upstream of `x` (network, basis, skinning) keeps its autodiff.
//! - [`membrane`], [`bending`], [`collision`], [`external`]: the per-sample kernels.
//!
//! Units and conventions are those of [`crate`]: metres, joules, `|cross|`-weighted
//! triangle terms, per-sample sums. Positions come in as `f32` or `f64` (the tensor's dtype);
//! every kernel computes in `f64`.

pub mod bending;
pub mod collision;
pub mod external;
pub mod membrane;
pub mod surrogate;

#[cfg(test)]
mod tests;

use std::sync::Mutex;

use rayon::prelude::*;

use super::PhysicsError;
use super::rest::GarmentRest;

/// One fused energy and its parameters (stiffnesses in the units of
/// [`crate::FabricParams`], converted to `f64`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kernel {
    /// Mass-spring edges `k Σ_e (l_e - l̄_e)²`.
    MassSpring {
        /// Spring weight `k` in N/m.
        k: f64,
    },
    /// Baraff-Witkin stretch `k Σ_f |c̄_f| ((|w_u|-1)² + (|w_v|-1)²)`.
    BaraffWitkinStretch {
        /// Stretch weight in N/m.
        k: f64,
    },
    /// Baraff-Witkin shear `k Σ_f |c̄_f| (w_u·w_v)²`.
    BaraffWitkinShear {
        /// Shear weight in N/m.
        k: f64,
    },
    /// Saint Venant-Kirchhoff `Σ_f |c̄_f| (μ tr(G²) + λ/2 tr(G)²)`.
    Stvk {
        /// First Lamé parameter `λ` in N/m.
        lambda: f64,
        /// Second Lamé parameter `μ` in N/m.
        mu: f64,
    },
    /// Bending `k Σ_h w_h (θ_h - θ̄_h)²`.
    Bending {
        /// Bending stiffness in N·m.
        k: f64,
    },
    /// Collision `k Σ_v mask_v min(n_v·(x_v - p_v) - ε, 0)²` against given contacts.
    Collision {
        /// Collision weight in N/m.
        k: f64,
        /// Threshold `ε` in metres.
        eps_m: f64,
    },
    /// Gravity potential `-Σ_v m_v x_v·g`.
    Gravity {
        /// Gravity acceleration in m/s².
        g: [f64; 3],
    },
}

impl Kernel {
    /// True for kernels that read contacts.
    pub fn needs_contacts(&self) -> bool {
        matches!(self, Kernel::Collision { .. })
    }
}

/// A float type positions can be stored in (`f32` for training, `f64` for reference checks).
pub trait Real: Copy + Send + Sync + 'static {
    /// Widens to `f64`.
    fn to_f64(self) -> f64;
    /// Rounds from `f64`.
    fn from_f64(v: f64) -> Self;
}

impl Real for f32 {
    #[inline(always)]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v as f32
    }
}

impl Real for f64 {
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v
    }
}

/// Vertex `i` of a flat `[V·3]` position slice, widened to `f64`.
#[inline(always)]
pub(crate) fn vertex<T: Real>(x: &[T], i: usize) -> [f64; 3] {
    [
        x[3 * i].to_f64(),
        x[3 * i + 1].to_f64(),
        x[3 * i + 2].to_f64(),
    ]
}

/// Adds `s·v` to vertex `i` of a flat `[V·3]` gradient.
#[inline(always)]
pub(crate) fn add_to(g: &mut [f64], i: usize, v: [f64; 3], s: f64) {
    g[3 * i] += s * v[0];
    g[3 * i + 1] += s * v[1];
    g[3 * i + 2] += s * v[2];
}

#[inline(always)]
pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline(always)]
pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline(always)]
pub(crate) fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

#[inline(always)]
pub(crate) fn axpy(a: [f64; 3], s: f64, b: [f64; 3]) -> [f64; 3] {
    [a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]]
}

/// Host contacts of a batch: nearest body point and its unit normal per garment vertex, each
/// `B·V·3` values (sample-major), in metres.
#[derive(Clone, Debug, Default)]
pub struct HostContacts {
    /// Contact points.
    pub points: Vec<f32>,
    /// Unit normals at the contact points.
    pub normals: Vec<f32>,
}

/// One kernel's result over a batch.
#[derive(Clone, Debug)]
pub struct Evaluation<T> {
    /// Energy per sample, `B` values in joules.
    pub energies: Vec<f64>,
    /// Gradient with respect to the positions, `B·V·3` values (sample-major) in J/m.
    pub gradient: Vec<T>,
}

/// Reusable `f64` gradient accumulators, one per concurrently running task, kept between calls
/// so that a training step allocates only its outputs.
#[derive(Default)]
pub struct ScratchPool {
    free: Mutex<Vec<Vec<f64>>>,
}

impl std::fmt::Debug for ScratchPool {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let free = self.free.lock().map_or(0, |buffers| buffers.len());
        f.debug_struct("ScratchPool").field("free", &free).finish()
    }
}

impl ScratchPool {
    /// A zeroed buffer of `len` values (reused when one is free).
    fn take(&self, len: usize) -> Vec<f64> {
        let reused = self
            .free
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .pop();
        let mut buf = reused.unwrap_or_default();
        buf.clear();
        buf.resize(len, 0.0);
        buf
    }

    /// Returns a buffer for reuse.
    fn give(&self, buf: Vec<f64>) {
        self.free
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .push(buf);
    }
}

/// Positions and contacts of one batch sample, as the kernels see them.
struct Sample<'a, T> {
    x: &'a [T],
    contacts: Option<(&'a [f32], &'a [f32])>,
}

/// Runs one kernel on one sample, accumulating its gradient into `g` (zeroed, `V·3`); kernels
/// that need more scratch take it from `pool`.
fn run<T: Real>(
    kernel: &Kernel,
    rest: &GarmentRest,
    s: &Sample<'_, T>,
    g: &mut [f64],
    pool: &ScratchPool,
) -> f64 {
    match *kernel {
        Kernel::MassSpring { k } => membrane::mass_spring(rest, k, s.x, g),
        Kernel::BaraffWitkinStretch { k } => membrane::baraff_witkin_stretch(rest, k, s.x, g),
        Kernel::BaraffWitkinShear { k } => membrane::baraff_witkin_shear(rest, k, s.x, g),
        Kernel::Stvk { lambda, mu } => membrane::stvk(rest, lambda, mu, s.x, g),
        Kernel::Bending { k } => {
            let mut scratch = pool.take(0);
            let e = bending::bending(rest, k, s.x, g, &mut scratch);
            pool.give(scratch);
            e
        }
        Kernel::Collision { k, eps_m } => match s.contacts {
            Some((points, normals)) => {
                collision::collision(rest, k, eps_m, s.x, points, normals, g)
            }
            None => 0.0,
        },
        Kernel::Gravity { g: gravity } => external::gravity(rest, gravity, s.x, g),
    }
}

/// Evaluates `kernels` on `batch` samples of positions `x` (`B·V·3` values, sample-major) of the
/// garment `rest`, with `contacts` for the collision kernel. Returns one [`Evaluation`] per
/// kernel, in order. Work is spread over (kernel, sample) pairs, so even one sample runs its
/// kernels in parallel.
pub fn evaluate<T: Real>(
    rest: &GarmentRest,
    kernels: &[Kernel],
    x: &[T],
    batch: usize,
    contacts: Option<&HostContacts>,
    pool: &ScratchPool,
) -> Result<Vec<Evaluation<T>>, PhysicsError> {
    let n3 = rest.vertex_count() * 3;
    if batch == 0 || x.len() != batch * n3 {
        return Err(PhysicsError::ShapeMismatch {
            what: "fused physics positions".into(),
            expected: format!("{batch} samples x {n3} values (B >= 1)"),
            found: format!("{} values", x.len()),
        });
    }
    if kernels.iter().any(Kernel::needs_contacts) {
        let ok = contacts.is_some_and(|c| c.points.len() == x.len() && c.normals.len() == x.len());
        if !ok {
            return Err(PhysicsError::ShapeMismatch {
                what: "fused collision contacts".into(),
                expected: format!("{} points and normals", x.len()),
                found: contacts.map_or("none".into(), |c| {
                    format!("{} points, {} normals", c.points.len(), c.normals.len())
                }),
            });
        }
    }
    let mut gradients: Vec<Vec<T>> = kernels
        .iter()
        .map(|_| vec![T::from_f64(0.0); x.len()])
        .collect();
    let mut tasks: Vec<(usize, usize, &mut [T])> = Vec::with_capacity(kernels.len() * batch);
    for (t, g) in gradients.iter_mut().enumerate() {
        for (b, chunk) in g.chunks_mut(n3).enumerate() {
            tasks.push((t, b, chunk));
        }
    }
    let energies: Vec<f64> = tasks
        .into_par_iter()
        .map(|(t, b, out)| {
            let range = b * n3..(b + 1) * n3;
            let sample = Sample {
                x: &x[range.clone()],
                contacts: contacts.map(|c| (&c.points[range.clone()], &c.normals[range.clone()])),
            };
            let mut g = pool.take(n3);
            let e = run(&kernels[t], rest, &sample, &mut g, pool);
            for (o, v) in out.iter_mut().zip(&g) {
                *o = T::from_f64(*v);
            }
            pool.give(g);
            e
        })
        .collect();
    Ok(gradients
        .into_iter()
        .zip(energies.chunks(batch))
        .map(|(gradient, e)| Evaluation {
            energies: e.to_vec(),
            gradient,
        })
        .collect())
}
