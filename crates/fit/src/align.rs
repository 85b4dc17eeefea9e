//! Rigid alignment of a garment to the body: a uniform scale about the garment's centre and a
//! translation (optionally after a left/right mirror), chosen so that the garment's surface
//! lies at a small clearance (the ease) outside the body where it is close to it.
//!
//! Two stages:
//! 1. a coarse search over scales and heights, the garment centred in x/z on the body band
//!    it covers, scored by the robust share of its area *not* at the ease;
//! 2. from the best few candidates, a robust Gauss-Newton refinement (a trimmed ICP of the
//!    garment's tightest part against the body's nearest vertices and normals, Geman-McClure
//!    weights whose width shrinks from 5 cm to 1.5 cm) of the scale and the three offsets,
//!    keeping the best final score.
//!
//! The score and the refinement only compare the garment with the body, so the result does
//! not depend on where the garment started or on its size (within the scale range): a
//! displaced or rescaled copy of a garment lands where the garment itself does.

use nalgebra::{Matrix4, Vector4};
use rayon::prelude::*;

use neural_cloth_core::geometry::Vec3;

use super::probe::BodyProbe;

/// Garment points used by the coarse search (a regular subsample of the vertices).
const SEARCH_POINTS: usize = 600;
/// Geometric step between the scales tried by the coarse search.
const SEARCH_SCALE_STEP: f32 = 1.06;
/// Step between the heights tried by the coarse search, metres.
const SEARCH_HEIGHT_STEP_M: f32 = 0.03;
/// Width of the robust score of the coarse search, metres.
const SEARCH_SIGMA_M: f32 = 0.03;
/// Candidates of the coarse search kept per scale tried, for [`refine`].
const PER_SCALE: usize = 2;
/// Width of the robust weights at the start and the end of the refinement, metres.
const REFINE_SIGMA_M: (f32, f32) = (0.05, 0.015);
/// Iterations of the refinement over which the weights' width shrinks.
const ANNEAL_ITERATIONS: usize = 40;
/// Most iterations of the refinement (it stops earlier once the steps vanish).
const REFINE_ITERATIONS: usize = 150;
/// Width of the robust score that ranks refined candidates, metres.
pub const FINAL_SIGMA_M: f32 = 0.015;

/// A placement of the garment: `x' = centre + scale · (m(x) - centre) + offset`, where `m`
/// mirrors left/right (`x ↦ 2 centre.x - x`) when `mirrored`. Metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// The garment's bounding-box centre before placement, metres.
    pub centre_m: Vec3,
    /// Whether the garment is mirrored left/right about its centre first.
    pub mirrored: bool,
    /// Uniform scale about the centre (1 = size unchanged), > 0.
    pub scale: f32,
    /// Translation of the centre, metres.
    pub offset_m: Vec3,
}

impl Placement {
    /// The placement that changes nothing, for a garment centred at `centre_m`.
    pub fn identity(centre_m: Vec3) -> Self {
        Self {
            centre_m,
            mirrored: false,
            scale: 1.0,
            offset_m: Vec3::zeros(),
        }
    }

    /// The point `p` mirrored (when the placement mirrors) and taken relative to the centre.
    fn local(&self, p: &Vec3) -> Vec3 {
        let mut q = p - self.centre_m;
        if self.mirrored {
            q.x = -q.x;
        }
        q
    }

    /// Where the placement puts `p`.
    pub fn apply(&self, p: &Vec3) -> Vec3 {
        self.centre_m + self.local(p) * self.scale + self.offset_m
    }

    /// The point the placement puts at `q` (its inverse; the scale is positive).
    pub fn invert(&self, q: &Vec3) -> Vec3 {
        let mut local = (q - self.offset_m - self.centre_m) / self.scale;
        if self.mirrored {
            local.x = -local.x;
        }
        self.centre_m + local
    }

    /// Where the placement puts every point of `points`.
    pub fn apply_all(&self, points: &[Vec3]) -> Vec<Vec3> {
        points.iter().map(|p| self.apply(p)).collect()
    }
}

/// What the alignment may change and what it aims at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlignSettings {
    /// Clearance the garment should keep outside the body where it is close to it, metres;
    /// [0, 0.1], default 0.015 (the built-in garments' offset).
    pub ease_m: f32,
    /// Smallest and largest scale tried, each > 0; default (0.5, 2.0).
    pub scale_range: (f32, f32),
    /// A fixed scale instead of an estimated one.
    pub fixed_scale: Option<f32>,
    /// A fixed offset of the centre instead of an estimated one, metres.
    pub fixed_offset_m: Option<Vec3>,
    /// Whether the garment has openings for the arms (sleeves or armholes,
    /// [`super::openings::has_arm_openings`]); one without them (a skirt) is placed below
    /// the shoulders.
    pub arm_openings: bool,
}

/// The garment points and their weights (vertex areas), with the placement's centre.
#[derive(Clone, Copy, Debug)]
pub struct Points<'a> {
    /// Vertex positions in metres, before placement.
    pub positions: &'a [Vec3],
    /// Weight of each vertex (its area), >= 0.
    pub weights: &'a [f32],
}

/// Geman-McClure loss `u² / (1 + u²)` of the residual `r` at width `sigma`, in [0, 1).
fn robust_loss(r: f32, sigma: f32) -> f32 {
    let u2 = (r / sigma).powi(2);
    u2 / (1.0 + u2)
}

/// Extra cost of a vertex inside the body in [`score`] (a vertex far from the body costs 1).
const INSIDE_COST: f32 = 3.0;
/// Weight of the prior `(ln scale)²` in [`score`]: the garment is more likely about the
/// right size once its unit is known.
const SCALE_PRIOR: f32 = 0.5;

/// Cost of one vertex at clearance `d_m`: looser than the ease costs the Geman-McClure loss
/// at width `sigma_m` (a loose part is free), closer at half that width, and a vertex inside
/// the body [`INSIDE_COST`] more.
fn vertex_cost(d_m: f32, ease_m: f32, sigma_m: f32) -> f32 {
    let r = d_m - ease_m;
    if r >= 0.0 {
        robust_loss(r, sigma_m)
    } else if d_m >= 0.0 {
        robust_loss(r, 0.5 * sigma_m)
    } else {
        robust_loss(r, 0.5 * sigma_m) + INSIDE_COST
    }
}

/// The cost of a placement, lower is better: the weighted mean [`vertex_cost`] (0 when
/// every vertex is exactly `ease_m` outside the body, about 1 when none is near it, up to
/// 1 + [`INSIDE_COST`] when all are inside) plus the scale prior.
pub fn score(
    probe: &BodyProbe,
    points: Points<'_>,
    placement: &Placement,
    ease_m: f32,
    sigma_m: f32,
) -> f32 {
    let (mut sum, mut total) = (0.0f64, 0.0f64);
    for (p, &w) in points.positions.iter().zip(points.weights) {
        let d = probe.clearance_m(&placement.apply(p));
        sum += f64::from(w * vertex_cost(d, ease_m, sigma_m));
        total += f64::from(w);
    }
    let prior = SCALE_PRIOR * placement.scale.max(1e-6).ln().powi(2);
    if total > 0.0 {
        (sum / total) as f32 + prior
    } else {
        1.0 + INSIDE_COST + prior
    }
}

/// Drop that tests whether a placement rests on the body, metres.
const SUPPORT_DROP_M: f32 = 0.06;
/// Share of the garment's weight that must go inside the body when it drops by
/// [`SUPPORT_DROP_M`] for the placement to count as resting on the body.
const SUPPORT_SHARE: f32 = 0.01;

/// Weighted share of `points` inside the body at `placement`.
fn inside_share(probe: &BodyProbe, points: Points<'_>, placement: &Placement) -> f32 {
    let (mut inside, mut total) = (0.0f64, 0.0f64);
    for (p, &w) in points.positions.iter().zip(points.weights) {
        if probe.clearance_m(&placement.apply(p)) < 0.0 {
            inside += f64::from(w);
        }
        total += f64::from(w);
    }
    if total > 0.0 {
        (inside / total) as f32
    } else {
        0.0
    }
}

/// Whether the garment rests on the body at `placement`: dropped by a few centimetres, a
/// share of it goes into the body (a shirt on the shoulders, a skirt on the hips). A
/// garment that would slide down (a skirt around the shins) does not.
pub fn supported(probe: &BodyProbe, points: Points<'_>, placement: &Placement) -> bool {
    let dropped = Placement {
        offset_m: placement.offset_m - Vec3::new(0.0, SUPPORT_DROP_M, 0.0),
        ..*placement
    };
    inside_share(probe, points, &dropped) - inside_share(probe, points, placement) > SUPPORT_SHARE
}

/// The scales the coarse search tries: powers of [`SEARCH_SCALE_STEP`] within the range
/// (1 included when in range), or the fixed scale alone.
fn search_scales(settings: &AlignSettings) -> Vec<f32> {
    if let Some(s) = settings.fixed_scale {
        return vec![s];
    }
    let (lo, hi) = settings.scale_range;
    let step = SEARCH_SCALE_STEP.ln();
    let k_lo = (lo.ln() / step).ceil() as i32;
    let k_hi = (hi.ln() / step).floor() as i32;
    (k_lo..=k_hi.max(k_lo))
        .map(|k| (step * k as f32).exp().clamp(lo, hi))
        .collect()
}

/// Coarse search: the best few placements (lowest [`score`] on a subsample), each with its
/// score, best first. The garment is centred in x/z on the body band it covers at each
/// scale and height tried (or keeps the fixed offset).
pub fn search(
    probe: &BodyProbe,
    points: Points<'_>,
    start: &Placement,
    settings: &AlignSettings,
) -> Vec<(Placement, f32)> {
    let (sub_p, sub_w) = subsample(points, SEARCH_POINTS);
    let sub = Points {
        positions: &sub_p,
        weights: &sub_w,
    };
    let local: Vec<Vec3> = sub_p.iter().map(|p| start.local(p)).collect();
    let Some((lo_local, hi_local)) = super::probe::bounds_of(&local) else {
        return Vec::new();
    };
    let (body_lo, body_hi) = probe.bounds_m();
    let heights: Vec<f32> = match settings.fixed_offset_m {
        Some(_) => vec![0.0],
        None => {
            let n = ((body_hi.y - body_lo.y) / SEARCH_HEIGHT_STEP_M).ceil() as usize + 1;
            (0..n)
                .map(|k| body_lo.y + k as f32 * SEARCH_HEIGHT_STEP_M)
                .collect()
        }
    };
    let mut tries: Vec<(f32, f32)> = Vec::new();
    for &s in &search_scales(settings) {
        tries.extend(heights.iter().map(|&y| (s, y)));
    }
    let mut scored: Vec<(Placement, f32)> = tries
        .par_iter()
        .filter_map(|&(scale, y)| {
            let offset_m = match settings.fixed_offset_m {
                Some(o) => o,
                None => {
                    let (band_lo, band_hi) = (y + scale * lo_local.y, y + scale * hi_local.y);
                    let (bx, bz) = probe.band_centre_xz(band_lo, band_hi)?;
                    let c = start.centre_m;
                    let mid = (lo_local + hi_local) * 0.5 * scale;
                    Vec3::new(bx - c.x - mid.x, y - c.y, bz - c.z - mid.z)
                }
            };
            let placement = Placement {
                scale,
                offset_m,
                ..*start
            };
            let s = score(probe, sub, &placement, settings.ease_m, SEARCH_SIGMA_M);
            Some((placement, s))
        })
        .collect();
    scored.sort_by(|a, b| a.1.total_cmp(&b.1));
    distinct_best(scored)
}

/// Of `sorted` (best first), the best [`PER_SCALE`] placements of each scale whose heights
/// differ by more than 9 cm, best first.
fn distinct_best(sorted: Vec<(Placement, f32)>) -> Vec<(Placement, f32)> {
    let mut kept: Vec<(Placement, f32)> = Vec::new();
    for (p, s) in sorted {
        let same_scale = kept.iter().filter(|(q, _)| q.scale == p.scale);
        let mut count = 0;
        let mut close = false;
        for (q, _) in same_scale {
            count += 1;
            close |= (p.offset_m.y - q.offset_m.y).abs() < 0.09;
        }
        if count < PER_SCALE && !close {
            kept.push((p, s));
        }
    }
    kept
}

/// A regular subsample of at most `count` of the points (all of them when fewer).
pub fn subsample(points: Points<'_>, count: usize) -> (Vec<Vec3>, Vec<f32>) {
    let stride = points.positions.len().div_ceil(count.max(1)).max(1);
    (
        points.positions.iter().step_by(stride).copied().collect(),
        points.weights.iter().step_by(stride).copied().collect(),
    )
}

/// Robust Gauss-Newton refinement of the free parameters (scale unless fixed, offset unless
/// fixed) from `start`, a trimmed ICP: each iteration matches every garment vertex to its
/// nearest body vertex, keeps the tightest [`TRIM_SHARE`] of the garment's area (smallest
/// clearance: its inner surface, e.g. a skirt's waistband, a shirt's shoulders and chest) and
/// moves the placement so that their clearances approach the ease. Loose parts (a flare, a
/// hem) do not pull.
pub fn refine(
    probe: &BodyProbe,
    points: Points<'_>,
    start: &Placement,
    settings: &AlignSettings,
) -> Placement {
    let mut placement = *start;
    for it in 0..REFINE_ITERATIONS {
        let t = (it as f32 / ANNEAL_ITERATIONS as f32).min(1.0);
        let sigma = REFINE_SIGMA_M.0 * (REFINE_SIGMA_M.1 / REFINE_SIGMA_M.0).powf(t);
        let Some(moved) = step(probe, points, &mut placement, settings, sigma, TRIM_SHARE) else {
            break;
        };
        if t >= 1.0 && moved < 1e-5 {
            break;
        }
    }
    placement
}

/// One clamped Gauss-Newton step of `placement` on its free parameters; returns how far it
/// moved (relative scale change plus offset change in metres), `None` when nothing
/// constrains it.
fn step(
    probe: &BodyProbe,
    points: Points<'_>,
    placement: &mut Placement,
    settings: &AlignSettings,
    sigma_m: f32,
    trim: f32,
) -> Option<f32> {
    let scale_free = settings.fixed_scale.is_none();
    let offset_free = settings.fixed_offset_m.is_none();
    let free = [scale_free, offset_free, offset_free, offset_free];
    let delta = gauss_newton_step(
        probe,
        points,
        placement,
        settings.ease_m,
        sigma_m,
        trim,
        free,
    )?;
    let ds = if scale_free {
        delta[0].clamp(-0.05, 0.05) as f32
    } else {
        0.0
    };
    let dt = if offset_free {
        Vec3::new(delta[1] as f32, delta[2] as f32, delta[3] as f32)
    } else {
        Vec3::zeros()
    };
    let dt = if dt.norm() > 0.05 {
        dt * (0.05 / dt.norm())
    } else {
        dt
    };
    let (lo, hi) = settings.scale_range;
    placement.scale = (placement.scale * (1.0 + ds)).clamp(lo, hi);
    placement.offset_m += dt;
    Some(ds.abs() + dt.norm())
}

/// Share of the garment's area (the tightest) that the refinement fits to the ease.
pub const TRIM_SHARE: f32 = 0.1;

/// One vertex as the refinement sees it: clearance, nearest body normal, lever arm of the
/// scale, weight.
struct Match {
    d_m: f32,
    normal: Vec3,
    arm: Vec3,
    weight: f32,
}

/// The clearance below which lie the tightest `share` of the total weight of `matches`.
fn trim_threshold(matches: &[Match], share: f32) -> f32 {
    let mut order: Vec<(f32, f32)> = matches.iter().map(|m| (m.d_m, m.weight)).collect();
    order.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f32 = order.iter().map(|o| o.1).sum();
    let mut acc = 0.0;
    for (d, w) in &order {
        acc += w;
        if acc >= share * total {
            return *d;
        }
    }
    order.last().map_or(0.0, |o| o.0)
}

/// One damped Gauss-Newton step `(relative scale change, offset change)` of the weighted
/// least-squares problem `Σ w_v (d_v - ease)²` over the tightest vertices; `None` when
/// nothing constrains it.
fn gauss_newton_step(
    probe: &BodyProbe,
    points: Points<'_>,
    placement: &Placement,
    ease_m: f32,
    sigma_m: f32,
    trim: f32,
    free: [bool; 4],
) -> Option<Vector4<f64>> {
    let matches: Vec<Match> = points
        .positions
        .par_iter()
        .zip(points.weights.par_iter())
        .map(|(p, &weight)| {
            let x = placement.apply(p);
            let (b, normal) = probe.nearest(&x);
            Match {
                d_m: normal.dot(&(x - b)),
                normal,
                // d(x)/d(ln scale) = scale · (m(p) - centre).
                arm: placement.local(p) * placement.scale,
                weight,
            }
        })
        .collect();
    let threshold = trim_threshold(&matches, trim);
    let (mut h, mut g) = (Matrix4::<f64>::zeros(), Vector4::<f64>::zeros());
    for m in matches.iter().filter(|m| m.d_m <= threshold) {
        let r = m.d_m - ease_m;
        let u2 = (r / sigma_m).powi(2);
        let weight = f64::from(m.weight) / f64::from((1.0 + u2).powi(2));
        let n = m.normal;
        let j = Vector4::new(
            f64::from(n.dot(&m.arm)),
            f64::from(n.x),
            f64::from(n.y),
            f64::from(n.z),
        );
        h += j * j.transpose() * weight;
        g += j * (weight * f64::from(r));
    }
    // Fixed parameters: their rows and columns decouple and their step is zero.
    for (k, _) in free.iter().enumerate().filter(|(_, f)| !**f) {
        h.set_row(k, &Vector4::zeros().transpose());
        h.set_column(k, &Vector4::zeros());
        g[k] = 0.0;
    }
    let trace = h.trace();
    if !(trace.is_finite() && trace > 0.0) {
        return None;
    }
    for (k, _) in free.iter().enumerate().filter(|(_, f)| !**f) {
        h[(k, k)] = trace;
    }
    let damped =
        h + Matrix4::from_diagonal(&h.diagonal()) * 0.1 + Matrix4::identity() * (1e-6 * trace);
    let step = damped.cholesky()?.solve(&(-g));
    step.iter().all(|v| v.is_finite()).then_some(step)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placements_mirror_scale_and_move_about_the_centre() {
        let p = Placement {
            centre_m: Vec3::new(1.0, 2.0, 3.0),
            mirrored: true,
            scale: 2.0,
            offset_m: Vec3::new(0.0, -1.0, 0.5),
        };
        let close = |a: Vec3, b: Vec3| assert!((a - b).norm() < 1e-6, "{a:?} {b:?}");
        close(p.apply(&p.centre_m), Vec3::new(1.0, 1.0, 3.5));
        close(
            p.apply(&Vec3::new(2.0, 2.0, 3.0)),
            Vec3::new(-1.0, 1.0, 3.5),
        );
        let id = Placement::identity(Vec3::new(1.0, 1.0, 1.0));
        close(
            id.apply(&Vec3::new(0.3, 0.2, 0.1)),
            Vec3::new(0.3, 0.2, 0.1),
        );
    }

    #[test]
    fn search_scales_cover_the_range_or_the_fixed_scale() {
        let mut s = AlignSettings {
            ease_m: 0.015,
            scale_range: (0.5, 2.0),
            fixed_scale: None,
            fixed_offset_m: None,
            arm_openings: true,
        };
        let scales = search_scales(&s);
        assert!(scales.iter().any(|&x| (x - 1.0).abs() < 1e-6));
        assert!(scales[0] >= 0.5 && *scales.last().unwrap() <= 2.0);
        assert!(scales.len() > 20);
        s.fixed_scale = Some(1.3);
        assert_eq!(search_scales(&s), vec![1.3]);
        assert!(robust_loss(0.0, 0.01) == 0.0 && robust_loss(1.0, 0.01) > 0.99);
        assert!(vertex_cost(-0.001, 0.015, 0.03) > INSIDE_COST);
        assert!(vertex_cost(0.015, 0.015, 0.03) == 0.0);
        assert!(vertex_cost(0.5, 0.015, 0.03) < 1.0);
    }
}
