//! Principal components of a sequence of per-vertex offsets, for compact morph targets.

use crate::geometry::Vec3;

/// A low-rank approximation `offsets[f] ≈ mean + Σ_k weights[f][k] · targets[k]`.
#[derive(Clone, Debug)]
pub struct OffsetBasis {
    /// Mean offset over the frames.
    pub mean: Vec<Vec3>,
    /// Orthonormal components (as flat per-vertex vectors), strongest first.
    pub targets: Vec<Vec<Vec3>>,
    /// Per-frame weights, one per target.
    pub weights: Vec<Vec<f32>>,
    /// Largest vertex distance between the approximation and the input, in metres.
    pub max_error_m: f32,
}

/// Computes up to `max_targets` components of `frames` (each the same length) through the
/// eigen-decomposition of the frame Gram matrix (cheap: frames × frames). Components that move
/// no vertex by more than 0.1 µm, or sit at f32 rounding-noise level, are dropped.
pub fn offset_basis(frames: &[Vec<Vec3>], max_targets: usize) -> OffsetBasis {
    let n = frames.len();
    let v = frames.first().map(|f| f.len()).unwrap_or(0);
    let mut mean = vec![Vec3::zeros(); v];
    for f in frames {
        for (m, p) in mean.iter_mut().zip(f) {
            *m += p / n.max(1) as f32;
        }
    }
    let centered: Vec<Vec<Vec3>> = frames
        .iter()
        .map(|f| f.iter().zip(&mean).map(|(p, m)| p - m).collect())
        .collect();
    // Gram matrix in f64 for accuracy.
    let mut gram = nalgebra::DMatrix::<f64>::zeros(n, n);
    for i in 0..n {
        for j in i..n {
            let d: f64 = centered[i]
                .iter()
                .zip(&centered[j])
                .map(|(a, b)| {
                    a.iter()
                        .zip(b.iter())
                        .map(|(x, y)| f64::from(*x) * f64::from(*y))
                        .sum::<f64>()
                })
                .sum();
            gram[(i, j)] = d;
            gram[(j, i)] = d;
        }
    }
    let mut targets = Vec::new();
    if n > 0 && v > 0 {
        let eig = nalgebra::SymmetricEigen::new(gram);
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
        let top = eig.eigenvalues.iter().cloned().fold(0.0f64, f64::max);
        for &k in order.iter().take(max_targets) {
            let lambda = eig.eigenvalues[k];
            // A component moves no vertex farther than sqrt(lambda) over the whole sequence:
            // drop those below a tenth of a micrometre or at f32 rounding-noise level.
            if !(lambda > top * 1e-10 && lambda.sqrt() > 1e-7) {
                break;
            }
            // Component = Σ_f u_f centered_f / sqrt(lambda): unit norm in vertex space.
            let scale = 1.0 / lambda.sqrt();
            let mut comp = vec![Vec3::zeros(); v];
            for (f, c) in centered.iter().enumerate() {
                let u = (eig.eigenvectors[(f, k)] * scale) as f32;
                if u != 0.0 {
                    for (o, p) in comp.iter_mut().zip(c) {
                        *o += p * u;
                    }
                }
            }
            targets.push(comp);
        }
    }
    let weights: Vec<Vec<f32>> = centered
        .iter()
        .map(|c| {
            targets
                .iter()
                .map(|t| t.iter().zip(c).map(|(a, b)| a.dot(b)).sum())
                .collect()
        })
        .collect();
    let mut max_error_m = 0.0f32;
    for (f, frame) in frames.iter().enumerate() {
        for (i, p) in frame.iter().enumerate() {
            let mut approx = mean[i];
            for (t, w) in targets.iter().zip(&weights[f]) {
                approx += t[i] * *w;
            }
            max_error_m = max_error_m.max((approx - p).norm());
        }
    }
    OffsetBasis {
        mean,
        targets,
        weights,
        max_error_m,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_rank_two_sequence_exactly() {
        let a: Vec<Vec3> = (0..50)
            .map(|i| Vec3::new(i as f32 * 0.01, 0.0, 0.02))
            .collect();
        let b: Vec<Vec3> = (0..50)
            .map(|i| Vec3::new(0.0, (i as f32 * 0.3).sin() * 0.01, 0.0))
            .collect();
        let frames: Vec<Vec<Vec3>> = (0..30)
            .map(|f| {
                let (s, c) = ((f as f32) * 0.2).sin_cos();
                a.iter()
                    .zip(&b)
                    .map(|(x, y)| x * s + y * c + Vec3::new(0.1, 0.0, 0.0))
                    .collect()
            })
            .collect();
        let basis = offset_basis(&frames, 8);
        assert_eq!(basis.targets.len(), 2, "only two independent directions");
        assert!(basis.max_error_m < 1e-5, "{}", basis.max_error_m);
        let one = offset_basis(&frames, 1);
        assert!(
            one.max_error_m > 1e-3,
            "one target cannot represent two directions"
        );
    }
}
