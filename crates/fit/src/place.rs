//! Placing a garment: the alignment's coarse search and refinement of the best candidates,
//! the choice between them (a candidate must wrap the trunk and rest on the body; of the
//! near-best, the lowest), and the dead zone that keeps a garment's own size.

use rayon::prelude::*;

use super::align::{self, AlignSettings, Placement, Points};
use super::probe::BodyProbe;

/// A refined candidate placement and how it fares.
struct Candidate {
    placement: Placement,
    /// Final [`align::score`] (lower is better).
    score: f32,
    /// Whether it rests on the body ([`align::supported`]).
    rests: bool,
    /// Whether its top lies on the trunk ([`wraps_trunk`]) and it goes around the body
    /// ([`BodyProbe::azimuth_coverage`] at least [`MIN_AZIMUTH_COVERAGE`]).
    wraps: bool,
}

/// Whether the garment's top, at `placement`, lies between a little above the crotch and a
/// little above the neck: garments hang from the shoulders or the waist, not from a knee or
/// the head. True when the body has no recognisable trunk.
fn wraps_trunk(probe: &BodyProbe, points: Points<'_>, placement: &Placement) -> bool {
    let Some((crotch, neck)) = probe.trunk_m() else {
        return true;
    };
    let margin = 0.04 * probe.height_m();
    let top = points
        .positions
        .iter()
        .map(|p| placement.apply(p).y)
        .fold(f32::NEG_INFINITY, f32::max);
    (crotch + margin..=neck + margin).contains(&top)
}

/// Coarse search, then refinement of its candidates on a subsample; of the candidates that
/// wrap the trunk and rest on the body (when any does), those whose final score is within
/// [`TIE_MARGIN`] of the best, and of them the lowest, refined on every point. With the
/// scale dead zone applied. `None` when the search found no placement.
pub fn align(
    probe: &BodyProbe,
    points: Points<'_>,
    start: &Placement,
    settings: &AlignSettings,
    dead_zone: f32,
) -> Option<Placement> {
    if let (Some(scale), Some(offset_m)) = (settings.fixed_scale, settings.fixed_offset_m) {
        return Some(Placement {
            scale,
            offset_m,
            ..*start
        });
    }
    let (sub_p, sub_w) = align::subsample(points, REFINE_POINTS);
    let sub = Points {
        positions: &sub_p,
        weights: &sub_w,
    };
    let mut candidates: Vec<Candidate> = align::search(probe, points, start, settings)
        .par_iter()
        .map(|(p, _)| {
            let placement = refine_with_dead_zone(probe, sub, p, settings, dead_zone);
            Candidate {
                score: align::score(
                    probe,
                    sub,
                    &placement,
                    settings.ease_m,
                    align::FINAL_SIGMA_M,
                ),
                rests: align::supported(probe, sub, &placement),
                wraps: wraps_trunk(probe, sub, &placement)
                    && probe.azimuth_coverage(&placement.apply_all(sub.positions))
                        >= MIN_AZIMUTH_COVERAGE,
                placement,
            }
        })
        .collect();
    // Each requirement counts only when some candidate meets it.
    if candidates.iter().any(|c| c.wraps) {
        candidates.retain(|c| c.wraps);
    }
    if candidates.iter().any(|c| c.rests) {
        candidates.retain(|c| c.rests);
    }
    let best = candidates.iter().map(|c| c.score).min_by(f32::total_cmp)?;
    // A loose garment (a bell skirt) rests at several heights, each a little smaller higher
    // up; gravity takes the lowest, and so does the fit.
    let height = |p: &Placement| p.centre_m.y + p.offset_m.y;
    let lowest = candidates
        .into_iter()
        .filter(|c| c.score <= best + TIE_MARGIN)
        .map(|c| c.placement)
        .min_by(|a, b| height(a).total_cmp(&height(b)))?;
    Some(refine_with_dead_zone(
        probe, points, &lowest, settings, dead_zone,
    ))
}

/// Share of the directions around the body that a garment worn around it covers at least.
pub const MIN_AZIMUTH_COVERAGE: f32 = 0.75;

/// Garment points used to refine the candidates of the coarse search.
const REFINE_POINTS: usize = 800;

/// Placements whose final score is within this margin of the best count as equally good;
/// the lowest of them is taken (see [`align`]).
const TIE_MARGIN: f32 = 0.05;

/// [`align::refine`], then, when the scale is free and ended within `dead_zone` of 1, again
/// with the scale fixed at 1.
pub(super) fn refine_with_dead_zone(
    probe: &BodyProbe,
    points: Points<'_>,
    start: &Placement,
    settings: &AlignSettings,
    dead_zone: f32,
) -> Placement {
    let refined = align::refine(probe, points, start, settings);
    if settings.fixed_scale.is_none() && (refined.scale - 1.0).abs() < dead_zone {
        let unit = AlignSettings {
            fixed_scale: Some(1.0),
            ..*settings
        };
        let from = Placement {
            scale: 1.0,
            ..refined
        };
        return align::refine(probe, points, &from, &unit);
    }
    refined
}
