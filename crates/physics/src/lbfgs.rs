//! A small preconditioned L-BFGS minimiser with a backtracking (Armijo) line search and a cap
//! on how far any vertex may move per step. Plain `f64` CPU code; the objective (value and
//! gradient) is supplied by the caller.

/// Minimiser settings.
#[derive(Clone, Debug, PartialEq)]
pub struct LbfgsOptions {
    /// Iteration budget (each iteration costs at least one objective evaluation). Default 50.
    pub max_iterations: usize,
    /// Stored correction pairs, 1..=64. Default 8.
    pub memory: usize,
    /// Stop when the largest gradient component (N for positions) is at most this. Default 0.
    pub grad_tolerance: f64,
    /// Largest displacement of any 3-vector block per step (m). Default infinity.
    pub max_step: f64,
    /// Armijo sufficient-decrease constant. Default 1e-4.
    pub armijo: f64,
    /// Line-search halvings before giving up on a direction. Default 12.
    pub max_backtracks: usize,
    /// Relative slack on the decrease test that absorbs floating-point noise in the value.
    /// Default 1e-12 (use ~1e-6 when the objective is evaluated in `f32`).
    pub value_noise: f64,
}

impl Default for LbfgsOptions {
    fn default() -> Self {
        Self {
            max_iterations: 50,
            memory: 8,
            grad_tolerance: 0.0,
            max_step: f64::INFINITY,
            armijo: 1e-4,
            max_backtracks: 12,
            value_noise: 1e-12,
        }
    }
}

/// What a minimisation did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LbfgsReport {
    /// Iterations taken.
    pub iterations: usize,
    /// Objective evaluations.
    pub evaluations: usize,
    /// Final objective value.
    pub value: f64,
    /// Final largest absolute gradient component.
    pub grad_inf: f64,
    /// True when the gradient tolerance was met (false: budget spent or line search stalled).
    pub converged: bool,
}

/// The initial inverse-Hessian estimate `H0` of L-BFGS.
pub enum InitialMetric<'a> {
    /// A positive per-component diagonal, rescaled each iteration by `sᵀy / (yᵀ H0 y)`.
    Diagonal(&'a [f64]),
    /// A symmetric positive-definite operator `v -> H0 v` (e.g. a prefactored solve), used
    /// unscaled; steepest-descent fallbacks use it too.
    Operator(&'a dyn Fn(&[f64]) -> Vec<f64>),
}

impl InitialMetric<'_> {
    fn apply(&self, v: &[f64], pairs: &Memory) -> Vec<f64> {
        match self {
            InitialMetric::Diagonal(d) => {
                let diag = |i: usize| {
                    d.get(i)
                        .copied()
                        .filter(|p| p.is_finite() && *p > 0.0)
                        .unwrap_or(1.0)
                };
                let gamma = pairs.back().map_or(1.0, |(_, y, rho)| {
                    let ydy: f64 = y.iter().enumerate().map(|(i, v)| v * v * diag(i)).sum();
                    if ydy > 0.0 { 1.0 / (rho * ydy) } else { 1.0 }
                });
                v.iter()
                    .enumerate()
                    .map(|(i, x)| gamma * diag(i) * x)
                    .collect()
            }
            InitialMetric::Operator(op) => op(v),
        }
    }
}

/// Correction pairs `(s, y, 1/sᵀy)` carried between calls (e.g. when the objective changes
/// only slightly, as when contacts are refreshed).
pub type Memory = std::collections::VecDeque<(Vec<f64>, Vec<f64>, f64)>;

/// Minimises `f` from `x` (updated in place) with initial metric `h0`. `f` returns
/// `(value, gradient)` or an error that aborts the minimisation.
pub fn minimize<E>(
    x: &mut [f64],
    h0: &InitialMetric,
    options: &LbfgsOptions,
    f: impl FnMut(&[f64]) -> Result<(f64, Vec<f64>), E>,
) -> Result<LbfgsReport, E> {
    minimize_with_memory(x, h0, options, &mut Memory::new(), f)
}

/// Like [`minimize`], starting from and updating the correction pairs in `pairs`.
pub fn minimize_with_memory<E>(
    x: &mut [f64],
    h0: &InitialMetric,
    options: &LbfgsOptions,
    pairs: &mut Memory,
    mut f: impl FnMut(&[f64]) -> Result<(f64, Vec<f64>), E>,
) -> Result<LbfgsReport, E> {
    let memory = options.memory.clamp(1, 64);
    let (mut fx, mut g) = f(x)?;
    let mut report = LbfgsReport {
        evaluations: 1,
        value: fx,
        grad_inf: inf_norm(&g),
        ..Default::default()
    };
    while report.iterations < options.max_iterations {
        if report.grad_inf <= options.grad_tolerance {
            report.converged = true;
            break;
        }
        report.iterations += 1;
        let mut d = direction(&g, pairs, h0);
        let mut gd = dot(&g, &d);
        if !(gd < 0.0 && gd.is_finite()) {
            pairs.clear();
            d = h0.apply(&g, pairs).into_iter().map(|v| -v).collect();
            gd = dot(&g, &d);
            if gd.partial_cmp(&0.0) != Some(std::cmp::Ordering::Less) {
                break;
            }
        }
        let block_max = d
            .chunks(3)
            .map(|b| b.iter().map(|v| v * v).sum::<f64>().sqrt())
            .fold(0.0, f64::max);
        let mut alpha = if block_max > options.max_step {
            options.max_step / block_max
        } else {
            1.0
        };
        let slack = options.value_noise * fx.abs().max(1e-30);
        let mut accepted = None;
        for _ in 0..=options.max_backtracks {
            let xn: Vec<f64> = x.iter().zip(&d).map(|(a, b)| a + alpha * b).collect();
            let (fn_, gn) = f(&xn)?;
            report.evaluations += 1;
            if fn_.is_finite() && fn_ <= fx + options.armijo * alpha * gd + slack {
                accepted = Some((xn, fn_, gn));
                break;
            }
            // Quadratic interpolation of the step, kept within [0.1, 0.5] of the last one.
            let denom = 2.0 * (fn_ - fx - gd * alpha);
            let guess = if denom.is_finite() && denom > 0.0 {
                -gd * alpha * alpha / denom
            } else {
                0.5 * alpha
            };
            alpha = guess.clamp(0.1 * alpha, 0.5 * alpha);
        }
        let Some((xn, fn_, gn)) = accepted else {
            if pairs.is_empty() {
                break;
            }
            pairs.clear();
            continue;
        };
        let s: Vec<f64> = xn.iter().zip(x.iter()).map(|(a, b)| a - b).collect();
        let y: Vec<f64> = gn.iter().zip(&g).map(|(a, b)| a - b).collect();
        let sy = dot(&s, &y);
        if sy > 1e-12 * dot(&y, &y).sqrt() * dot(&s, &s).sqrt() && sy.is_finite() {
            if pairs.len() == memory {
                pairs.pop_front();
            }
            pairs.push_back((s, y, 1.0 / sy));
        }
        x.copy_from_slice(&xn);
        fx = fn_;
        g = gn;
        report.value = fx;
        report.grad_inf = inf_norm(&g);
    }
    if report.grad_inf <= options.grad_tolerance {
        report.converged = true;
    }
    Ok(report)
}

/// Two-loop recursion: `-H g` starting from `H0`.
fn direction(g: &[f64], pairs: &Memory, h0: &InitialMetric) -> Vec<f64> {
    let mut q = g.to_vec();
    let mut alphas = Vec::with_capacity(pairs.len());
    for (s, y, rho) in pairs.iter().rev() {
        let a = rho * dot(s, &q);
        q.iter_mut().zip(y).for_each(|(qi, yi)| *qi -= a * yi);
        alphas.push(a);
    }
    let mut r = h0.apply(&q, pairs);
    for ((s, y, rho), a) in pairs.iter().zip(alphas.iter().rev()) {
        let b = rho * dot(y, &r);
        r.iter_mut().zip(s).for_each(|(ri, si)| *ri += (a - b) * si);
    }
    r.iter_mut().for_each(|v| *v = -*v);
    r
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

fn inf_norm(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |m, x| {
        if x.is_nan() {
            f64::INFINITY
        } else {
            m.max(x.abs())
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn minimises_an_ill_conditioned_quadratic_and_rosenbrock() {
        // f = Σ c_i (x_i - i)², condition number 1e4, preconditioned by 1/(2c).
        let c: Vec<f64> = (0..9).map(|i| 10f64.powi(i % 5)).collect();
        let mut x = vec![0.0; 9];
        let pre: Vec<f64> = c.iter().map(|c| 0.5 / c).collect();
        let opts = LbfgsOptions {
            grad_tolerance: 1e-9,
            ..Default::default()
        };
        let r = minimize::<()>(&mut x, &InitialMetric::Diagonal(&pre), &opts, |x| {
            let v = x
                .iter()
                .enumerate()
                .map(|(i, xi)| c[i] * (xi - i as f64).powi(2))
                .sum();
            Ok((
                v,
                x.iter()
                    .enumerate()
                    .map(|(i, xi)| 2.0 * c[i] * (xi - i as f64))
                    .collect(),
            ))
        })
        .unwrap();
        assert!(r.converged && r.iterations <= 3, "{r:?}");
        assert!(
            x.iter()
                .enumerate()
                .all(|(i, xi)| (xi - i as f64).abs() < 1e-8)
        );
        let mut x = vec![-1.2, 1.0, 0.0];
        let opts = LbfgsOptions {
            max_iterations: 200,
            grad_tolerance: 1e-8,
            ..Default::default()
        };
        let r = minimize::<()>(&mut x, &InitialMetric::Diagonal(&[1.0; 3]), &opts, |x| {
            let (a, b) = (x[0], x[1]);
            let v = (1.0 - a).powi(2) + 100.0 * (b - a * a).powi(2) + x[2] * x[2];
            Ok((
                v,
                vec![
                    -2.0 * (1.0 - a) - 400.0 * a * (b - a * a),
                    200.0 * (b - a * a),
                    2.0 * x[2],
                ],
            ))
        })
        .unwrap();
        assert!(r.converged, "{r:?}");
        assert!((x[0] - 1.0).abs() < 1e-5 && (x[1] - 1.0).abs() < 1e-5);
    }

    #[test]
    fn step_cap_limits_block_displacement() {
        let mut x = vec![0.0; 3];
        let opts = LbfgsOptions {
            max_iterations: 1,
            max_step: 0.1,
            ..Default::default()
        };
        minimize::<()>(&mut x, &InitialMetric::Diagonal(&[1.0; 3]), &opts, |x| {
            Ok((
                x.iter().map(|v| (v - 10.0).powi(2)).sum(),
                x.iter().map(|v| 2.0 * (v - 10.0)).collect(),
            ))
        })
        .unwrap();
        let moved = x.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(moved <= 0.1 + 1e-12 && moved > 0.09, "{moved}");
    }
}
