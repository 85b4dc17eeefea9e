//! A gradient filter for training: the physics loss's gradient with respect to the posed
//! garment, `g`, replaced by `D (D + βK)⁻¹ g` with `D = M/Δt²` (the inertial diagonal) and `K`
//! the rest membrane stiffness (the reference simulator's initial L-BFGS metric, scaled by β).
//!
//! Why: the per-frame objective is badly conditioned. Stretching modes are hundreds of times
//! stiffer than the smooth modes a swinging garment moves in, so the plain gradient is mostly
//! the force of small stretch errors, and the network's shared weights learn the smooth modes
//! slowly. The filter leaves modes softer than `D` (smooth ones) unchanged and shrinks stiff
//! ones by `d/(d + βk)`, which turns the force into (about) the mass-weighted displacement a
//! Newton step would make. Where the gradient is zero the filtered one is zero too (the matrix
//! is positive definite), so the simulator's answer stays a stationary point.

use rayon::prelude::*;

use super::sparse::EnvelopeCholesky;
use super::{FabricParams, GarmentRest, PhysicsError};

/// `g ↦ D (D + βK)⁻¹ g`, per sample and coordinate, factored once per garment and fabric.
#[derive(Clone, Debug)]
pub struct GradientFilter {
    factor: EnvelopeCholesky,
    /// `m_v / Δt²` per vertex, in N/m.
    inertial: Vec<f64>,
    /// β.
    stiffness_scale: f64,
}

impl GradientFilter {
    /// Factors `D + βK` for `rest` and `fabric` at time step `dt_secs` (s, > 0), with `β =
    /// stiffness_scale` (> 0, finite).
    pub fn new(
        rest: &GarmentRest,
        fabric: &FabricParams,
        dt_secs: f32,
        stiffness_scale: f64,
    ) -> Result<Self, PhysicsError> {
        let valid = dt_secs > 0.0
            && dt_secs.is_finite()
            && stiffness_scale > 0.0
            && stiffness_scale.is_finite();
        if !valid {
            return Err(PhysicsError::InvalidOptions(format!(
                "gradient filter needs a positive time step and stiffness scale, got {dt_secs} s and {stiffness_scale}"
            )));
        }
        let dt2 = f64::from(dt_secs).powi(2);
        let mean = rest.mass_kg.iter().sum::<f64>() / dt2 / rest.mass_kg.len().max(1) as f64;
        // A vertex without mass (in no triangle, or only in degenerate ones) gets a small
        // positive diagonal, used on both sides so that its gradient is kept, not zeroed.
        let inertial: Vec<f64> = rest
            .mass_kg
            .iter()
            .map(|m| (m / dt2).max(1e-6 * mean + 1e-12))
            .collect();
        let mut triplets: Vec<(usize, usize, f64)> = rest
            .membrane_stiffness_triplets(fabric)
            .into_iter()
            .map(|(i, j, k)| (i, j, stiffness_scale * k))
            .collect();
        triplets.extend(inertial.iter().enumerate().map(|(v, d)| (v, v, *d)));
        let factor = EnvelopeCholesky::factor(rest.vertex_count(), &triplets)?;
        Ok(Self {
            factor,
            inertial,
            stiffness_scale,
        })
    }

    /// The stiffness scale β it was factored with.
    pub fn stiffness_scale(&self) -> f64 {
        self.stiffness_scale
    }

    /// Vertices of the garment the filter was built for.
    pub fn vertex_count(&self) -> usize {
        self.inertial.len()
    }

    /// Filters `grad` (`[rows, V, 3]`, sample-major) in place; rows whose gradient is all zero
    /// are skipped.
    pub fn apply(&self, grad: &mut [f32]) -> Result<(), PhysicsError> {
        self.apply_from(grad, 0)
    }

    /// The vertex count, after checking that `grad` holds whole rows of it.
    fn rows_of(&self, grad: &[f32]) -> Result<usize, PhysicsError> {
        let v = self.vertex_count();
        if v == 0 || !grad.len().is_multiple_of(v * 3) {
            return Err(PhysicsError::ShapeMismatch {
                what: "gradient to filter".into(),
                expected: format!("a multiple of {} values", v * 3),
                found: format!("{} values", grad.len()),
            });
        }
        Ok(v)
    }

    /// [`Self::apply`] to rows `first..` only; the rows before keep the plain gradient.
    pub fn apply_from(&self, grad: &mut [f32], first: usize) -> Result<(), PhysicsError> {
        let v = self.rows_of(grad)?;
        let skip = (first * v * 3).min(grad.len());
        grad[skip..].par_chunks_mut(v * 3).for_each(|row| {
            if row.iter().all(|g| *g == 0.0) {
                return;
            }
            let mut columns: Vec<[f64; 3]> = row
                .chunks_exact(3)
                .map(|g| [g[0], g[1], g[2]].map(f64::from))
                .collect();
            self.factor.solve3_in_place(&mut columns);
            for ((out, x), d) in row.chunks_exact_mut(3).zip(&columns).zip(&self.inertial) {
                for c in 0..3 {
                    out[c] = (d * x[c]) as f32;
                }
            }
        });
        Ok(())
    }

    /// [`Self::apply`] solving one coordinate at a time (the path before the three-at-once
    /// solve, kept as the benchmark's reference): the same results to the last bit.
    pub fn apply_per_coordinate(&self, grad: &mut [f32]) -> Result<(), PhysicsError> {
        let v = self.rows_of(grad)?;
        grad.par_chunks_mut(v * 3).for_each(|row| {
            if row.iter().all(|g| *g == 0.0) {
                return;
            }
            let mut column = vec![0.0f64; v];
            for c in 0..3 {
                column
                    .iter_mut()
                    .enumerate()
                    .for_each(|(i, x)| *x = f64::from(row[i * 3 + c]));
                self.factor.solve_in_place(&mut column);
                for (i, x) in column.iter().enumerate() {
                    row[i * 3 + c] = (self.inertial[i] * x) as f32;
                }
            }
        });
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::sheet;
    use neural_cloth_core::geometry::{Topology, Vec3};

    fn filter(beta: f64) -> (GarmentRest, GradientFilter) {
        let mesh = sheet(12, 12, Vec3::zeros(), Vec3::x() * 0.4, Vec3::z() * 0.4);
        let fabric = FabricParams::default();
        let rest = GarmentRest::new(
            &mesh,
            &Topology::new(&mesh),
            &[],
            &[],
            fabric.density_kg_per_m2,
        )
        .unwrap();
        let f = GradientFilter::new(&rest, &fabric, 1.0 / 30.0, beta).unwrap();
        (rest, f)
    }

    #[test]
    fn a_weight_like_gradient_passes_unchanged() {
        // K's rows sum to zero: a translation is a zero-stiffness mode, so a gradient
        // proportional to the masses (gravity's) is kept as it is.
        let (rest, f) = filter(1.0);
        let mut g: Vec<f32> = f
            .inertial
            .iter()
            .flat_map(|d| [0.0, -*d as f32, 0.5 * *d as f32])
            .collect();
        let before = g.clone();
        f.apply(&mut g).unwrap();
        assert_eq!(g.len(), rest.vertex_count() * 3);
        for (a, b) in g.iter().zip(&before) {
            assert!((a - b).abs() <= 1e-3 * b.abs() + 1e-9, "{a} vs {b}");
        }
    }

    #[test]
    fn a_stiff_mode_shrinks_and_a_zero_gradient_stays_zero() {
        let (rest, f) = filter(1.0);
        let n = rest.vertex_count();
        // Alternating signs: the roughest mode, stiffest under the membrane.
        let mut g: Vec<f32> = (0..n)
            .flat_map(|i| [if i % 2 == 0 { 1.0 } else { -1.0 }, 0.0, 0.0])
            .collect();
        f.apply(&mut g).unwrap();
        let norm = g.iter().map(|x| x * x).sum::<f32>().sqrt() / (n as f32).sqrt();
        assert!(norm < 0.2, "rough mode kept {norm} of its size");
        // Rows before `first` keep the plain gradient; the rest equal the filtered rows.
        let rows: Vec<f32> = (0..3 * n * 3)
            .map(|i| ((i * 31) % 17) as f32 - 8.0)
            .collect();
        let mut part = rows.clone();
        f.apply_from(&mut part, 1).unwrap();
        let mut whole = rows.clone();
        f.apply(&mut whole).unwrap();
        assert_eq!(part[..n * 3], rows[..n * 3]);
        assert_eq!(part[n * 3..], whole[n * 3..]);
        assert_ne!(part[n * 3..], rows[n * 3..]);
        let mut zero = vec![0.0f32; 2 * n * 3];
        f.apply(&mut zero).unwrap();
        assert!(zero.iter().all(|x| *x == 0.0));
        assert!(f.apply(&mut [0.0; 5]).is_err());
        assert!(GradientFilter::new(&rest, &FabricParams::default(), 0.0, 1.0).is_err());
    }

    #[test]
    fn the_filter_is_the_inertial_solve() {
        // D (D + βK)⁻¹ g = h  ⟺  (D + βK) D⁻¹ h = g: check with K applied from the triplets.
        let beta = 0.3;
        let (rest, f) = filter(beta);
        let n = rest.vertex_count();
        let g: Vec<f32> = (0..n * 3).map(|i| ((i * 7919) % 13) as f32 - 6.0).collect();
        let mut h = g.clone();
        f.apply(&mut h).unwrap();
        let y: Vec<f64> = (0..n * 3)
            .map(|i| f64::from(h[i]) / f.inertial[i / 3])
            .collect();
        let mut back: Vec<f64> = (0..n * 3).map(|i| f.inertial[i / 3] * y[i]).collect();
        for (i, j, k) in rest.membrane_stiffness_triplets(&FabricParams::default()) {
            for c in 0..3 {
                back[i * 3 + c] += beta * k * y[j * 3 + c];
                if i != j {
                    back[j * 3 + c] += beta * k * y[i * 3 + c];
                }
            }
        }
        for (a, b) in back.iter().zip(&g) {
            assert!(
                (a - f64::from(*b)).abs() < 1e-3 * (1.0 + b.abs() as f64),
                "{a} vs {b}"
            );
        }
        // The per-coordinate path of before gives the same filtered gradient to the last bit
        // (two samples: rows are filtered independently).
        let two: Vec<f32> = g.iter().chain(g.iter().rev()).copied().collect();
        let (mut fast, mut slow) = (two.clone(), two);
        f.apply(&mut fast).unwrap();
        f.apply_per_coordinate(&mut slow).unwrap();
        assert!(
            fast.iter()
                .zip(&slow)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
        assert_eq!(&fast[..n * 3], h.as_slice());
    }
}
