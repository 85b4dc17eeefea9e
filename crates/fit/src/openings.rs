//! What a garment's own shape says about how it is worn: whether it has openings for the
//! arms (sleeves or armholes; a garment without them, such as a skirt, trousers or a tube
//! top, cannot be worn over the shoulders: the arms would have to pass through its cloth),
//! and whether it has one for each leg (trousers, shorts: their legs follow the thighs,
//! where a skirt's or a dress's single hem does not).

use std::collections::HashMap;

use neural_cloth_core::geometry::{Topology, TriMesh, Vec3};

use super::probe::bounds_of;

/// A boundary loop counts as an opening when its length is at least this share of the
/// garment's largest extent (smaller holes are left out).
const MIN_OPENING_SHARE: f32 = 0.1;
/// An opening is at a side when its centre lies at least this share of the garment's width
/// from the garment's middle (a neck, waist or hem opening lies on the middle).
const SIDE_SHARE: f32 = 0.25;
/// An opening is for an arm when its centre lies at least this share of the garment's
/// height above the garment's bottom (trouser legs open at the bottom); one for a leg lies
/// within it.
const ABOVE_BOTTOM_SHARE: f32 = 0.1;
/// An opening at the bottom is for a leg when its centre lies at least this share of the
/// garment's width from the garment's middle (trouser legs sit closer to the middle than
/// sleeves; a hem's centre lies on it).
const LEG_SIDE_SHARE: f32 = 0.1;

/// The root of `v` in the union-find forest `parent`, compressing the path on the way.
fn root(parent: &mut [u32], v: u32) -> u32 {
    let mut r = v;
    while parent[r as usize] != r {
        r = parent[r as usize];
    }
    let mut v = v;
    while parent[v as usize] != r {
        v = std::mem::replace(&mut parent[v as usize], r);
    }
    r
}

/// The boundary loops of `mesh` (connected sets of edges with a single face): per loop, its
/// length and the length-weighted centre of its edges, in the mesh's units; longest first.
pub fn boundary_loops(mesh: &TriMesh) -> Vec<(f32, Vec3)> {
    let edges = Topology::new(mesh).boundary_edges;
    // Union-find over the vertices, joined along the boundary edges.
    let mut parent: Vec<u32> = (0..mesh.vertex_count() as u32).collect();
    for &[a, b] in &edges {
        let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
        parent[ra as usize] = rb;
    }
    let mut loops: HashMap<u32, (f32, Vec3)> = HashMap::new();
    for &[a, b] in &edges {
        let (pa, pb) = (mesh.positions[a as usize], mesh.positions[b as usize]);
        let length = (pb - pa).norm();
        let entry = loops
            .entry(root(&mut parent, a))
            .or_insert((0.0, Vec3::zeros()));
        entry.0 += length;
        entry.1 += (pa + pb) * (0.5 * length);
    }
    let mut out: Vec<(f32, Vec3)> = loops
        .into_values()
        .filter(|(length, _)| *length > 0.0)
        .map(|(length, sum)| (length, sum / length))
        .collect();
    out.sort_by(|a, b| b.0.total_cmp(&a.0));
    out
}

/// Whether `mesh` (Y up, X across the body) has an opening for each arm: a boundary loop on
/// either side of its middle, above its bottom (sleeves of a shirt or a jacket, the armholes
/// of a dress). A skirt, trousers or a tube top has none.
pub fn has_arm_openings(mesh: &TriMesh) -> bool {
    openings_either_side(mesh, false, SIDE_SHARE)
}

/// Whether `mesh` (Y up, X across the body) has an opening for each leg: a boundary loop on
/// either side of its middle, at its bottom (the legs of trousers or shorts). A skirt, a
/// dress or a shirt has one hem across the middle instead.
pub fn has_leg_openings(mesh: &TriMesh) -> bool {
    openings_either_side(mesh, true, LEG_SIDE_SHARE)
}

/// Whether `mesh` has an opening (a boundary loop of at least [`MIN_OPENING_SHARE`] of its
/// largest extent) on either side of its middle, at least `side_share` of its width from it:
/// among the loops within [`ABOVE_BOTTOM_SHARE`] of its height from its bottom when
/// `at_bottom`, else among those above that.
fn openings_either_side(mesh: &TriMesh, at_bottom: bool, side_share: f32) -> bool {
    let Some((lo, hi)) = bounds_of(&mesh.positions) else {
        return false;
    };
    let extent = hi - lo;
    let largest = extent.max();
    let middle = 0.5 * (lo.x + hi.x);
    let bottom = lo.y + ABOVE_BOTTOM_SHARE * extent.y;
    let (mut left, mut right) = (false, false);
    for (length, centre) in boundary_loops(mesh) {
        if length < MIN_OPENING_SHARE * largest || (centre.y <= bottom) != at_bottom {
            continue;
        }
        let side = centre.x - middle;
        left |= side < -side_share * extent.x;
        right |= side > side_share * extent.x;
    }
    left && right
}

/// Horizontal slices [`crotch_height`] looks at.
const CROTCH_SLICES: usize = 64;
/// A slice's piece counts when at least this many faces cross the slice in it.
const MIN_PIECE_FACES: usize = 3;

/// Height (Y up) of the crotch of a garment with an opening for each leg: the lowest
/// horizontal slice, above one that cuts the garment into two or more pieces (its legs), that
/// cuts it into one (the seat); `None` when no slice cuts it into legs. Trousers made for
/// another stance are placed by the part above it (see [`crate::fit_mesh`]).
pub fn crotch_height(mesh: &TriMesh) -> Option<f32> {
    let (lo, hi) = bounds_of(&mesh.positions)?;
    let mut parent: Vec<u32> = Vec::with_capacity(mesh.vertex_count());
    let mut legs_below = false;
    for k in 0..CROTCH_SLICES {
        let y = lo.y + (k as f32 + 0.5) / CROTCH_SLICES as f32 * (hi.y - lo.y);
        parent.clear();
        parent.extend(0..mesh.vertex_count() as u32);
        let crossing: Vec<&[u32; 3]> = mesh
            .faces
            .iter()
            .filter(|f| {
                let ys = f.map(|v| mesh.positions[v as usize].y);
                ys.iter().any(|&v| v <= y) && ys.iter().any(|&v| v > y)
            })
            .collect();
        for f in &crossing {
            let r0 = root(&mut parent, f[0]);
            for &v in &f[1..] {
                let r = root(&mut parent, v);
                parent[r as usize] = r0;
            }
        }
        let mut faces_per_piece: HashMap<u32, usize> = HashMap::new();
        for f in &crossing {
            *faces_per_piece.entry(root(&mut parent, f[0])).or_default() += 1;
        }
        let pieces = faces_per_piece
            .values()
            .filter(|&&n| n >= MIN_PIECE_FACES)
            .count();
        if pieces >= 2 {
            legs_below = true;
        } else if pieces == 1 && legs_below {
            return Some(y);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use neural_cloth_core::scene::procedural::{GarmentKind, builtin_garment, mannequin};

    #[test]
    fn shirts_and_dresses_have_arm_openings_and_skirts_do_not() {
        let avatar = mannequin().unwrap();
        for (kind, openings) in [
            (GarmentKind::TShirt, true),
            (GarmentKind::Skirt, false),
            (GarmentKind::Dress, true),
        ] {
            let g = builtin_garment(&avatar, kind, 600, None).unwrap();
            let loops = boundary_loops(&g.mesh);
            assert_eq!(has_arm_openings(&g.mesh), openings, "{kind:?}: {loops:?}");
            assert!(!has_leg_openings(&g.mesh), "{kind:?}: {loops:?}");
        }
        // A closed mesh has no openings at all.
        let closed = TriMesh::new(
            vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
                Vec3::new(0.0, 0.0, 1.0),
            ],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        )
        .unwrap();
        assert!(boundary_loops(&closed).is_empty());
        assert!(!has_arm_openings(&closed));
        assert!(!has_leg_openings(&closed));
    }

    /// An open tube of `n` segments round, radius `r`, about the vertical axis through
    /// `(x, z)`, from `y0` to `y1`, appended to `positions` and `faces`.
    fn tube(
        positions: &mut Vec<Vec3>,
        faces: &mut Vec<[u32; 3]>,
        (x, z, r): (f32, f32, f32),
        (y0, y1): (f32, f32),
    ) {
        let n = 12u32;
        let base = positions.len() as u32;
        for y in [y0, y1] {
            for k in 0..n {
                let a = k as f32 / n as f32 * std::f32::consts::TAU;
                positions.push(Vec3::new(x + r * a.cos(), y, z + r * a.sin()));
            }
        }
        for k in 0..n {
            let (a, b) = (base + k, base + (k + 1) % n);
            faces.push([a, b, a + n]);
            faces.push([b, b + n, a + n]);
        }
    }

    #[test]
    fn two_legs_side_by_side_are_leg_openings_and_one_wide_hem_is_not() {
        // Trousers in outline: a waist tube above two leg tubes (three separate pieces, as
        // far as the loops go: a waist, a hem per leg and their tops inside the waist).
        let (mut positions, mut faces) = (Vec::new(), Vec::new());
        tube(&mut positions, &mut faces, (0.0, 0.0, 0.18), (0.8, 1.0));
        tube(&mut positions, &mut faces, (-0.09, 0.0, 0.08), (0.1, 0.8));
        tube(&mut positions, &mut faces, (0.09, 0.0, 0.08), (0.1, 0.8));
        let trousers = TriMesh::new(positions, faces).unwrap();
        assert!(
            has_leg_openings(&trousers),
            "{:?}",
            boundary_loops(&trousers)
        );
        assert!(!has_arm_openings(&trousers));
        // One leg only: no pair.
        let (mut positions, mut faces) = (Vec::new(), Vec::new());
        tube(&mut positions, &mut faces, (0.0, 0.0, 0.18), (0.8, 1.0));
        tube(&mut positions, &mut faces, (0.09, 0.0, 0.08), (0.1, 0.8));
        let one = TriMesh::new(positions, faces).unwrap();
        assert!(!has_leg_openings(&one), "{:?}", boundary_loops(&one));
        // A skirt in outline: one tube, its hem across the middle.
        let (mut positions, mut faces) = (Vec::new(), Vec::new());
        tube(&mut positions, &mut faces, (0.0, 0.0, 0.2), (0.4, 1.0));
        let skirt = TriMesh::new(positions, faces).unwrap();
        assert!(!has_leg_openings(&skirt));
        assert_eq!(crotch_height(&skirt), None);
    }
}
