//! Pure numerics behind readable metric curves: exponential smoothing in steps, a y range that
//! the first steps and single spikes cannot set, the "spans more than a decade" test for a log
//! axis, and the improving / flat / diverging verdict on the validation loss.

/// How many of the latest validation passes [`validation_trend`] looks at.
pub const TREND_WINDOW: usize = 10;

/// Fewest validation passes [`validation_trend`] gives a verdict on.
pub const TREND_MIN_PASSES: usize = 4;

/// Exponential moving average of `values` taken at optimiser steps `steps` (same length,
/// increasing) with a time constant of `tau_steps` steps: each value's weight decays by `1/e`
/// every `tau_steps` steps, whatever the spacing of the records. The first output is the first
/// value; non-finite values are skipped (the average carries over them).
pub fn ema(steps: &[f64], values: &[f64], tau_steps: f64) -> Vec<f64> {
    let tau = if tau_steps.is_finite() && tau_steps > 0.0 {
        tau_steps
    } else {
        1.0
    };
    let mut out = Vec::with_capacity(values.len());
    let mut state: Option<(f64, f64)> = None; // (step, average)
    for (&s, &v) in steps.iter().zip(values) {
        let next = match state {
            _ if !v.is_finite() => state,
            None => Some((s, v)),
            Some((prev, avg)) => {
                let alpha = 1.0 - (-(s - prev).max(0.0) / tau).exp();
                Some((s, avg + alpha * (v - avg)))
            }
        };
        state = next;
        out.push(state.map_or(f64::NAN, |(_, avg)| avg));
    }
    out
}

/// A centred (zero-lag) exponential smoothing: the mean of [`ema`] run forwards and run
/// backwards over the records, i.e. a two-sided exponential kernel with time constant
/// `tau_steps` on each side. A one-sided average trails a falling loss by about `tau_steps`
/// steps, which on a log axis reads as a curve sitting visibly above its data; this one does
/// not lag a linear trend.
pub fn centred_ema(steps: &[f64], values: &[f64], tau_steps: f64) -> Vec<f64> {
    let forward = ema(steps, values, tau_steps);
    let rev_steps: Vec<f64> = steps.iter().rev().map(|s| -s).collect();
    let rev_values: Vec<f64> = values.iter().rev().copied().collect();
    let mut backward = ema(&rev_steps, &rev_values, tau_steps);
    backward.reverse();
    forward
        .iter()
        .zip(&backward)
        .map(|(f, b)| 0.5 * (f + b))
        .collect()
}

/// Smoothing time constant, in steps, for a run of `total_steps` steps: about a thirtieth of
/// the run, at least 5 and at most 500 steps.
pub fn smoothing_steps(total_steps: f64) -> f64 {
    (total_steps / 30.0).clamp(5.0, 500.0)
}

/// How many leading records a y range ignores out of `n`: 5 %, and at least 20, but never more
/// than half of them.
pub fn warmup_records(n: usize) -> usize {
    n.div_ceil(20).max(20).min(n / 2)
}

/// The `q`-quantile (0..=1) of `sorted` (ascending, finite), by linear interpolation.
pub fn quantile(sorted: &[f64], q: f64) -> Option<f64> {
    let last = sorted.len().checked_sub(1)?;
    let pos = q.clamp(0.0, 1.0) * last as f64;
    let lo = pos.floor() as usize;
    let hi = pos.ceil() as usize;
    let a = *sorted.get(lo)?;
    let b = *sorted.get(hi)?;
    Some(a + (b - a) * (pos - lo as f64))
}

/// Median of finite `values` (None when there are none).
pub fn median(values: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    quantile(&v, 0.5)
}

/// A y range for a curve from the values it must show: the 1st to 99th percentile of `noisy`
/// (raw per-step values, so a lone spike does not set the scale) widened to every value of
/// `exact` (smoothed and validation values), padded by 5 % of the span on each side. Callers
/// leave the first steps out (see [`warmup_records`]). None when no value is finite.
pub fn robust_range(noisy: &[f64], exact: &[f64]) -> Option<(f64, f64)> {
    let mut sorted: Vec<f64> = noisy.iter().copied().filter(|v| v.is_finite()).collect();
    sorted.sort_by(f64::total_cmp);
    let mut lo = quantile(&sorted, 0.01).unwrap_or(f64::INFINITY);
    let mut hi = quantile(&sorted, 0.99).unwrap_or(f64::NEG_INFINITY);
    for &v in exact.iter().filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !(lo.is_finite() && hi.is_finite()) {
        return None;
    }
    let span = hi - lo;
    let pad = if span > 1e-12 * lo.abs().max(hi.abs()) && span > 0.0 {
        0.05 * span
    } else {
        0.1 * lo.abs().max(1e-9)
    };
    Some((lo - pad, hi + pad))
}

/// True when no finite value is negative and the largest non-zero value is more than ten times
/// the smallest, so the curve reads better on a log axis (zeros, e.g. no collisions at all,
/// cannot be drawn there and are left out).
pub fn spans_decades(values: &[f64]) -> bool {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for &v in values.iter().filter(|v| v.is_finite() && **v != 0.0) {
        if v < 0.0 {
            return false;
        }
        lo = lo.min(v);
        hi = hi.max(v);
    }
    lo.is_finite() && hi > 10.0 * lo
}

/// Where the validation loss is heading.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Trend {
    /// Falling by more than its noise.
    Improving,
    /// Changing by less than its noise: training has converged or stalled.
    Flat,
    /// Rising by more than its noise.
    Diverging,
}

impl Trend {
    /// One word for the indicator.
    pub fn label(self) -> &'static str {
        match self {
            Trend::Improving => "improving",
            Trend::Flat => "flat",
            Trend::Diverging => "diverging",
        }
    }
}

/// A [`Trend`] with the numbers behind it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrendReport {
    /// The verdict.
    pub trend: Trend,
    /// Change of the fitted line over the window, relative to the line's value at the start of
    /// the window (-0.25: a quarter lower).
    pub relative_change: f64,
    /// Validation passes the fit used.
    pub passes: usize,
}

/// The trend of the validation loss `losses` (one per pass, oldest first) over its last
/// [`TREND_WINDOW`] finite passes: a Theil-Sen line (median of pairwise slopes, robust to a
/// single outlier) whose change across the window is compared with the noise (1.4826 times the
/// median absolute residual, i.e. one standard deviation for Gaussian noise) and with 1 % of
/// the loss. Improving or diverging when the change exceeds three times the larger of the two
/// (about 8 % false verdicts on pure Gaussian noise over 10 passes), flat otherwise; None with fewer than [`TREND_MIN_PASSES`] finite passes.
pub fn validation_trend(losses: &[f64]) -> Option<TrendReport> {
    let finite: Vec<f64> = losses.iter().copied().filter(|v| v.is_finite()).collect();
    let window = finite.get(finite.len().saturating_sub(TREND_WINDOW)..)?;
    let n = window.len();
    if n < TREND_MIN_PASSES {
        return None;
    }
    let mut slopes = Vec::with_capacity(n * (n - 1) / 2);
    for (i, a) in window.iter().enumerate() {
        for (j, b) in window.iter().enumerate().skip(i + 1) {
            slopes.push((b - a) / (j - i) as f64);
        }
    }
    let slope = median(&slopes)?;
    let intercepts: Vec<f64> = window
        .iter()
        .enumerate()
        .map(|(i, y)| y - slope * i as f64)
        .collect();
    let intercept = median(&intercepts)?;
    let residuals: Vec<f64> = window
        .iter()
        .enumerate()
        .map(|(i, y)| (y - intercept - slope * i as f64).abs())
        .collect();
    let noise = 1.4826 * median(&residuals)?;
    let level = median(window)?.abs();
    let change = slope * (n - 1) as f64;
    let threshold = 3.0 * noise.max(0.01 * level).max(f64::MIN_POSITIVE);
    let trend = if change < -threshold {
        Trend::Improving
    } else if change > threshold {
        Trend::Diverging
    } else {
        Trend::Flat
    };
    Some(TrendReport {
        trend,
        relative_change: if intercept.abs() > 0.0 {
            change / intercept.abs()
        } else {
            0.0
        },
        passes: n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic, patternless noise in -1..=1 (no RNG crate needed).
    fn noise(k: usize) -> f64 {
        ((k * 7919 + 13) % 101) as f64 / 50.0 - 1.0
    }

    #[test]
    fn ema_follows_a_step_with_the_time_constant() {
        let steps: Vec<f64> = (0..=40).map(f64::from).collect();
        let values: Vec<f64> = steps
            .iter()
            .map(|&s| if s < 1.0 { 0.0 } else { 1.0 })
            .collect();
        let out = ema(&steps, &values, 10.0);
        assert_eq!(out.len(), values.len());
        assert_eq!(out[0], 0.0);
        // After one time constant the average has covered 1 - 1/e of the jump.
        assert!(
            (out[10] - (1.0 - (-1.0f64).exp())).abs() < 1e-9,
            "{}",
            out[10]
        );
        assert!(out.windows(2).all(|w| w[1] >= w[0]));
    }

    #[test]
    fn ema_is_in_steps_not_records_and_skips_nan() {
        // Records every 5 steps smooth like records every step.
        let dense: Vec<f64> = (0..=50).map(f64::from).collect();
        let sparse: Vec<f64> = (0..=10).map(|k| f64::from(k) * 5.0).collect();
        let a = ema(&dense, &dense.iter().map(|_| 1.0).collect::<Vec<_>>(), 10.0);
        let mut ones = vec![1.0; sparse.len()];
        ones[0] = 0.0;
        let mut dense_values = vec![1.0; dense.len()];
        dense_values[0] = 0.0;
        let d = ema(&dense, &dense_values, 10.0);
        let s = ema(&sparse, &ones, 10.0);
        assert!((d[50] - s[10]).abs() < 1e-9);
        assert!(a.iter().all(|v| (*v - 1.0).abs() < 1e-12));
        let with_nan = ema(&[0.0, 1.0, 2.0], &[2.0, f64::NAN, 2.0], 3.0);
        assert_eq!(with_nan, vec![2.0, 2.0, 2.0]);
        assert!(ema(&[0.0], &[f64::NAN], 3.0)[0].is_nan());
    }

    #[test]
    fn the_centred_average_does_not_lag_a_trend() {
        let steps: Vec<f64> = (0..200).map(f64::from).collect();
        let values: Vec<f64> = steps.iter().map(|s| 10.0 - 0.01 * s).collect();
        let one_sided = ema(&steps, &values, 10.0);
        let centred = centred_ema(&steps, &values, 10.0);
        assert!((one_sided[100] - values[100]).abs() > 0.09);
        assert!(
            (centred[100] - values[100]).abs() < 1e-6,
            "{}",
            centred[100]
        );
        assert_eq!(centred.len(), values.len());
    }

    #[test]
    fn smoothing_reduces_the_noise() {
        let steps: Vec<f64> = (0..400).map(f64::from).collect();
        let values: Vec<f64> = (0..400).map(|k| 0.02 + 0.01 * noise(k)).collect();
        let out = centred_ema(&steps, &values, smoothing_steps(400.0));
        let spread = |v: &[f64]| {
            let m = v.iter().sum::<f64>() / v.len() as f64;
            (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len() as f64).sqrt()
        };
        assert!(spread(&out[100..]) < 0.3 * spread(&values[100..]));
    }

    #[test]
    fn a_spike_does_not_set_the_range() {
        let mut values: Vec<f64> = (0..400).map(|k| 0.02 + 0.01 * noise(k)).collect();
        values[200] = 5.0;
        let (lo, hi) = robust_range(&values, &[0.021]).unwrap();
        assert!(lo > 0.0 && lo < 0.015, "{lo}");
        assert!(hi > 0.025 && hi < 0.04, "{hi}");
        assert_eq!(warmup_records(400), 20);
        assert_eq!(warmup_records(10_000), 500);
        assert_eq!(warmup_records(10), 5);
        assert_eq!(robust_range(&[f64::NAN], &[]), None);
        let (lo, hi) = robust_range(&[2.0, 2.0], &[]).unwrap();
        assert!(lo < 2.0 && hi > 2.0);
    }

    #[test]
    fn decades_need_positive_values() {
        assert!(spans_decades(&[25.0, 3.0, 0.5]));
        assert!(!spans_decades(&[2.0, 0.5]));
        assert!(!spans_decades(&[25.0, -0.5]));
        assert!(!spans_decades(&[]));
        assert!(spans_decades(&[25.0, 0.0, 0.5]));
    }

    #[test]
    fn trend_of_a_falling_loss_is_improving() {
        let losses: Vec<f64> = (0..12)
            .map(|k| 2.0 * (-(k as f64) / 6.0).exp() + 0.02 * noise(k))
            .collect();
        let report = validation_trend(&losses).unwrap();
        assert_eq!(report.trend, Trend::Improving, "{report:?}");
        assert!(report.relative_change < -0.3 && report.relative_change > -1.0);
        assert_eq!(report.passes, TREND_WINDOW);
    }

    #[test]
    fn trend_of_a_noisy_level_loss_is_flat() {
        let losses: Vec<f64> = (0..20).map(|k| 0.5 + 0.05 * noise(k)).collect();
        assert_eq!(validation_trend(&losses).unwrap().trend, Trend::Flat);
        // A single outlier does not make it move.
        let mut spiked = losses.clone();
        spiked[17] = 3.0;
        assert_eq!(validation_trend(&spiked).unwrap().trend, Trend::Flat);
        // Perfectly constant: flat, not a division by zero.
        assert_eq!(validation_trend(&[1.0; 6]).unwrap().trend, Trend::Flat);
    }

    #[test]
    fn trend_of_a_rising_loss_is_diverging() {
        let mut losses: Vec<f64> = (0..10).map(|k| 1.0 - 0.05 * k as f64).collect();
        losses.extend((0..8).map(|k| 0.55 + 0.15 * k as f64 + 0.02 * noise(k)));
        assert_eq!(validation_trend(&losses).unwrap().trend, Trend::Diverging);
    }

    #[test]
    fn too_few_passes_give_no_verdict() {
        assert_eq!(validation_trend(&[1.0, 0.5, f64::NAN, 0.2]), None);
        assert_eq!(validation_trend(&[]), None);
    }
}
