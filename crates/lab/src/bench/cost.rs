//! Measures what each loss term costs (forward + backward) on a synthetic garment of a given
//! number of degrees of freedom, against a baseline measured in the same run: the cheapest
//! possible loss on the same input, `Σ x²`. Each static term is timed twice in the same run:
//! as burn tensor code (the reference) and as a fused host kernel with its analytic gradient
//! ([`neural_cloth_physics::fused`]). `neural-cloth bench` prints this table.

use std::sync::Arc;
use std::time::Instant;

use burn::tensor::{Device, Tensor, TensorData};

use rayon::prelude::*;

use neural_cloth_core::geometry::{BucketKdTree, KdTree, Topology, Vec3};

use neural_cloth_physics::collision::{BodyBatch, Contacts, PosedBody};
use neural_cloth_physics::fused::Kernel;
use neural_cloth_physics::rest::GarmentRest;
use neural_cloth_physics::shapes::{tube, uv_sphere};
use neural_cloth_physics::tensors::read_f64;
use neural_cloth_physics::{
    ClothModel, Effects, FabricParams, GradientFilter, PhysicsError, PhysicsTerms, Term,
};

/// A loss on positions `[B, V, 3]`, as timed.
type Loss<'a> = &'a dyn Fn(&Tensor<3>) -> Result<Tensor<1>, PhysicsError>;

/// Cost of one term.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TermCost {
    /// What was measured.
    pub name: String,
    /// Milliseconds per batch of the burn implementation (median of the repeats).
    pub ms: f64,
    /// `ms / baseline ms`.
    pub ratio: f64,
    /// Milliseconds per batch of the fused kernel (None where there is none).
    pub fused_ms: Option<f64>,
    /// `ms / fused_ms`: how many times faster the fused kernel is.
    pub speedup: Option<f64>,
}

/// A cost table.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CostReport {
    /// Degrees of freedom of the garment (3 × vertices).
    pub dof: usize,
    /// Batch size.
    pub batch: usize,
    /// Body vertices of the collision query.
    pub body_vertices: usize,
    /// Device description.
    pub device: String,
    /// Baseline (`Σ x²`, forward + backward) milliseconds.
    pub baseline_ms: f64,
    /// Terms.
    pub terms: Vec<TermCost>,
}

impl CostReport {
    /// The table as Markdown.
    pub fn to_markdown(&self) -> String {
        let mut s = format!(
            "{} DoF garment, batch {}, {} body vertices, {}; baseline Σx² forward+backward = {:.3} ms\n\nReference: the burn tensor code of each term, and in the query rows the first-found k-d tree query of before (or, where the row says so, the exact bucketed k-d tree of before through the same batched query). Fused: the host kernel with its analytic gradient, handed to burn through the surrogate, and the exact wide k-d tree query (seeded with each garment vertex's predecessor).\n\n| term | reference ms / batch | × baseline | fused ms / batch | reference / fused |\n|---|---:|---:|---:|---:|\n",
            self.dof, self.batch, self.body_vertices, self.device, self.baseline_ms
        );
        for t in &self.terms {
            let (fused, speedup) = match (t.fused_ms, t.speedup) {
                (Some(f), Some(r)) => (format!("{f:.3}"), format!("{r:.1}")),
                _ => ("-".into(), "-".into()),
            };
            s += &format!(
                "| {} | {:.3} | {:.1} | {fused} | {speedup} |\n",
                t.name, t.ms, t.ratio
            );
        }
        s
    }
}

/// The collision query as it was before [`neural_cloth_core::geometry::BucketKdTree`]: one first-found
/// k-d tree query per vertex (`trees[b]` over body `b`'s vertices), in parallel, then upload.
fn reference_contacts(
    bodies: &BodyBatch,
    trees: &[KdTree],
    x: &Tensor<3>,
    dtype: burn::tensor::DType,
) -> Result<Contacts, PhysicsError> {
    let [b, v, _] = x.dims();
    let flat = neural_cloth_physics::tensors::read_f32(x.clone().detach())?;
    let found: Vec<([f32; 7], u32)> = flat
        .par_chunks_exact(3)
        .enumerate()
        .map(|(k, q)| {
            let body = &bodies.bodies[k / v.max(1)];
            let q = Vec3::new(q[0], q[1], q[2]);
            let i = trees[k / v.max(1)]
                .nearest(&q)
                .map_or(0, |(i, _)| i as usize);
            let (p, n) = (body.positions()[i], body.normals()[i]);
            ([p.x, p.y, p.z, n.x, n.y, n.z, n.dot(&(q - p))], i as u32)
        })
        .collect();
    let device = x.device();
    let column = |range: std::ops::Range<usize>| -> Tensor<3> {
        let flat: Vec<f32> = found
            .iter()
            .flat_map(|(f, _)| f[range.clone()].iter().copied())
            .collect();
        Tensor::from_data(TensorData::new(flat, [b, v, 3]), (&device, dtype))
    };
    Ok(Contacts {
        points: column(0..3),
        normals: column(3..6),
        distances_m: found.iter().map(|(f, _)| f[6]).collect(),
        indices: found.iter().map(|(_, i)| *i).collect(),
    })
}

/// Measures every term at about `dof` degrees of freedom (a flared tube around a sphere) with
/// `batch` samples, `repeats` timed runs each (after one warm-up), on `device` (autodiff is
/// enabled on it for the backward passes).
pub fn measure_term_costs(
    device: &Device,
    dof: usize,
    batch: usize,
    repeats: usize,
) -> Result<CostReport, PhysicsError> {
    let device = device.clone().autodiff();
    let dtype = device.settings().float_dtype.into();
    let batch = batch.clamp(1, 256);
    let repeats = repeats.clamp(1, 1000);
    let vertices = (dof / 3).max(16);
    let around = ((vertices as f32 * 2.0).sqrt().round() as usize).max(4);
    let rows = (vertices / around).max(2) - 1;
    let mesh = tube(
        Vec3::new(0.0, 1.0, 0.0),
        0.31,
        0.45,
        0.25,
        -0.35,
        around,
        rows,
    );
    let topology = Topology::new(&mesh);
    let top: Vec<u32> = (0..around as u32).collect();
    let fabric = FabricParams::default();
    let rest = Arc::new(GarmentRest::new(
        &mesh,
        &topology,
        &top,
        &[],
        fabric.density_kg_per_m2,
    )?);
    let body_mesh = uv_sphere(Vec3::new(0.0, 1.0, 0.0), 0.32, 72, 96);
    let body = Arc::new(PosedBody::new(
        body_mesh.positions.clone(),
        &body_mesh.faces,
    )?);
    let bodies = BodyBatch::new(vec![body; batch]);
    let v = mesh.positions.len();
    let flat: Vec<f32> = (0..batch)
        .flat_map(|b| {
            mesh.positions.iter().enumerate().flat_map(move |(i, p)| {
                let wobble = 0.01 * ((i * 7 + b * 13) as f32).sin();
                [p.x * (1.0 + wobble), p.y + wobble, p.z * (1.0 - wobble)]
            })
        })
        .collect();
    let x0 = Tensor::<3>::from_data(
        TensorData::new(flat.clone(), [batch, v, 3]),
        (&device, dtype),
    );
    let all = Effects {
        gravity: true,
        bending: true,
        collision: true,
        dynamics: true,
        pinning: true,
        friction: true,
    };
    let terms_of = |model: ClothModel| {
        let f = FabricParams {
            cloth_model: model,
            ..fabric.clone()
        };
        PhysicsTerms::from_rest(rest.clone(), &f, &all, &device, dtype)
    };
    let bw = terms_of(ClothModel::BaraffWitkin)?;
    let ms = terms_of(ClothModel::MassSpring)?;
    let stvk = terms_of(ClothModel::Stvk)?;
    let no_collision = PhysicsTerms::from_rest(
        rest.clone(),
        &fabric,
        &Effects {
            collision: false,
            ..all
        },
        &device,
        dtype,
    )?;
    let contacts = Contacts::query(&bodies, &flat, v, &device, dtype)?;
    let (prev1, prev2) = (x0.clone().mul_scalar(0.999), x0.clone().mul_scalar(0.998));

    let time =
        |f: &dyn Fn(&Tensor<3>) -> Result<Tensor<1>, PhysicsError>| -> Result<f64, PhysicsError> {
            let mut samples = Vec::with_capacity(repeats);
            for k in 0..=repeats {
                let x = x0.clone().require_grad();
                let start = Instant::now();
                let loss = f(&x)?;
                let grads = loss.backward();
                if let Some(g) = x.grad(&grads) {
                    read_f64(g.sum())?;
                }
                if k > 0 {
                    samples.push(start.elapsed().as_secs_f64() * 1e3);
                }
            }
            samples.sort_by(f64::total_cmp);
            Ok(samples[samples.len() / 2])
        };
    let rt = bw.tensors();
    let sum_terms = |t: Vec<(Term, Tensor<1>)>| {
        t.into_iter()
            .map(|(_, v)| v.sum())
            .reduce(|a, b| a + b)
            .ok_or(PhysicsError::MissingBody)
    };
    // One fused kernel (or a pair) as a loss, through the same surrogate the trainer gets.
    let fused = |terms: &PhysicsTerms,
                 x: &Tensor<3>,
                 kernels: &[(Term, Kernel)],
                 contacts: Option<&Contacts>| {
        sum_terms(terms.fused_energies(x, kernels, contacts)?)
    };
    let baseline = time(&|x| Ok(x.clone().square().sum()))?;
    let mut rows_out: Vec<(String, f64, Option<f64>)> = Vec::new();
    let mut add = |name: &str, reference: Loss, fused: Option<Loss>| -> Result<(), PhysicsError> {
        let fused_ms = fused.map(&time).transpose()?;
        rows_out.push((name.to_string(), time(reference)?, fused_ms));
        Ok(())
    };
    let stretch = (Term::Stretch, Kernel::BaraffWitkinStretch { k: 10.0 });
    let shear = (Term::Shear, Kernel::BaraffWitkinShear { k: 1.0 });
    let collide = (
        Term::Collision,
        Kernel::Collision {
            k: 10.0,
            eps_m: f64::from(0.004f32),
        },
    );
    add(
        "baraff-witkin stretch+shear",
        &|x| {
            let (a, b) = neural_cloth_physics::energies::baraff_witkin(x, rt, 10.0, 1.0);
            Ok((a + b).sum())
        },
        Some(&|x| fused(&bw, x, &[stretch, shear], None)),
    )?;
    add(
        "mass-spring",
        &|x| Ok(neural_cloth_physics::energies::mass_spring(x, ms.tensors(), 10.0).sum()),
        Some(&|x| {
            fused(
                &ms,
                x,
                &[(Term::Stretch, Kernel::MassSpring { k: 10.0 })],
                None,
            )
        }),
    )?;
    add(
        "stvk",
        &|x| Ok(neural_cloth_physics::energies::stvk(x, stvk.tensors(), 20.9, 11.1).sum()),
        Some(&|x| {
            let k = Kernel::Stvk {
                lambda: f64::from(20.9f32),
                mu: f64::from(11.1f32),
            };
            fused(&stvk, x, &[(Term::Stretch, k)], None)
        }),
    )?;
    add(
        "bending",
        &|x| Ok(neural_cloth_physics::energies::bending(x, rt, 2e-5).sum()),
        Some(&|x| {
            let k = Kernel::Bending {
                k: f64::from(2e-5f32),
            };
            fused(&bw, x, &[(Term::Bending, k)], None)
        }),
    )?;
    add(
        "collision energy (contacts given)",
        &|x| Ok(neural_cloth_physics::collision::collision(x, &contacts, rt, 10.0, 0.004).sum()),
        Some(&|x| fused(&bw, x, &[collide], Some(&contacts))),
    )?;
    // Today's query as it was before the bucketed tree: one first-found k-d tree query per
    // vertex, the reference of the query rows.
    let trees: Vec<KdTree> = bodies
        .bodies
        .iter()
        .map(|b| KdTree::new(b.positions()))
        .collect();
    let reference_query = |x: &Tensor<3>| reference_contacts(&bodies, &trees, x, dtype);
    // The exact bucketed k-d tree that the wide tree replaced (issue 12), through the same
    // batched query: old against new in the same run.
    let buckets: Vec<BucketKdTree> = bodies
        .bodies
        .iter()
        .map(|b| BucketKdTree::new(b.positions()))
        .collect();
    let bucket_query = |x: &Tensor<3>| {
        let [_, v, _] = x.dims();
        let flat = neural_cloth_physics::tensors::read_f32(x.clone().detach())?;
        Contacts::query_with(&bodies, &flat, v, &x.device(), dtype, |b, _, q, _| {
            buckets[b].nearest(q, None).map_or(0, |(i, _)| i as usize)
        })
    };
    // The query alone (its loss only touches `x` so that the backward pass has a graph).
    let touch = |x: &Tensor<3>, c: Contacts| x.clone().sum().mul_scalar(0.0) + c.points.sum();
    add(
        "collision query + upload (no energy)",
        &|x| Ok(touch(x, reference_query(x)?)),
        Some(&|x| Ok(touch(x, Contacts::for_prediction(&bodies, x, dtype)?))),
    )?;
    add(
        "collision query + upload (no energy), bucket k-d tree of before as reference",
        &|x| Ok(touch(x, bucket_query(x)?)),
        Some(&|x| Ok(touch(x, Contacts::for_prediction(&bodies, x, dtype)?))),
    )?;
    add(
        "collision query + upload + energy",
        &|x| {
            let c = reference_query(x)?;
            Ok(neural_cloth_physics::collision::collision(x, &c, rt, 10.0, 0.004).sum())
        },
        Some(&|x| {
            let c = Contacts::for_prediction(&bodies, x, dtype)?;
            fused(&bw, x, &[collide], Some(&c))
        }),
    )?;
    // What the trainer pays per step when the posed bodies are not kept between steps: one
    // body (normals and query tree) per sample, built serially as `Dataset::body` does.
    add(
        "posed bodies built for the batch (no query)",
        &|x| {
            let built = (0..batch)
                .map(|_| PosedBody::new(body_mesh.positions.clone(), &body_mesh.faces))
                .collect::<Result<Vec<_>, _>>()?;
            Ok(x.clone()
                .sum()
                .mul_scalar(0.0)
                .add_scalar(built.len() as f32))
        },
        None,
    )?;
    add(
        "gravity",
        &|x| Ok(neural_cloth_physics::energies::gravity(x, rt).sum()),
        Some(&|x| {
            let g = fabric.gravity();
            let k = Kernel::Gravity {
                g: [g.x, g.y, g.z].map(f64::from),
            };
            fused(&bw, x, &[(Term::Gravity, k)], None)
        }),
    )?;
    add(
        "inertia",
        &|x| Ok(neural_cloth_physics::energies::inertia(x, &prev1, &prev2, rt, 1.0 / 30.0).sum()),
        None,
    )?;
    add(
        "pinning",
        &|x| bw.pinning(x, &prev1).ok_or(PhysicsError::MissingBody),
        None,
    )?;
    let friction = bw
        .friction_contacts(&contacts, &bodies, &bodies, &[])?
        .ok_or(PhysicsError::MissingBody)?;
    add(
        "friction (contacts given)",
        &|x| {
            bw.friction(x, &prev1, &friction)
                .ok_or(PhysicsError::MissingBody)
        },
        None,
    )?;
    let reference_bw = bw.clone().with_fused(false);
    add(
        "all static terms, collision on (static_losses)",
        &|x| {
            reference_bw
                .static_losses_with(x, Some(&reference_query(x)?))?
                .total()
                .ok_or(PhysicsError::MissingBody)
        },
        Some(&|x| {
            bw.static_losses(x, Some(&bodies))?
                .total()
                .ok_or(PhysicsError::MissingBody)
        }),
    )?;
    let reference_no_collision = no_collision.clone().with_fused(false);
    add(
        "all static terms, collision off",
        &|x| sum_terms(reference_no_collision.static_energies(x, None)?),
        Some(&|x| sum_terms(no_collision.static_energies(x, None)?)),
    )?;
    // The training gradient filter on a batch of gradients (host data, as the trainer hands
    // it over): reference = one solve per coordinate, fused = the three coordinates at once.
    let filter = GradientFilter::new(&rest, &fabric, 1.0 / 30.0, 0.01)?;
    let gradient: Vec<f32> = (0..flat.len()).map(|i| (i as f32 * 0.37).sin()).collect();
    let time_host =
        |f: &dyn Fn(&mut [f32]) -> Result<(), PhysicsError>| -> Result<f64, PhysicsError> {
            let mut samples = Vec::with_capacity(repeats);
            for k in 0..=repeats {
                let mut g = gradient.clone();
                let start = Instant::now();
                f(&mut g)?;
                if k > 0 {
                    samples.push(start.elapsed().as_secs_f64() * 1e3);
                }
            }
            samples.sort_by(f64::total_cmp);
            Ok(samples[samples.len() / 2])
        };
    rows_out.push((
        "gradient filter β = 0.01 (one solve per coordinate → three at once)".into(),
        time_host(&|g| filter.apply_per_coordinate(g))?,
        Some(time_host(&|g| filter.apply(g))?),
    ));
    let device_name = format!("{:?}", device.clone().without_autodiff());
    Ok(CostReport {
        dof: 3 * v,
        batch,
        body_vertices: body_mesh.positions.len(),
        device: device_name,
        baseline_ms: baseline,
        terms: rows_out
            .into_iter()
            .map(|(name, ms, fused_ms)| TermCost {
                ratio: ms / baseline.max(1e-9),
                speedup: fused_ms.map(|f| ms / f.max(1e-9)),
                fused_ms,
                name,
                ms,
            })
            .collect(),
    })
}
