//! What a garment's own shape says about how it is worn: whether it has openings for the
//! arms (sleeves or armholes). A garment without them (a skirt, trousers, a tube top) cannot
//! be worn over the shoulders: the arms would have to pass through its cloth.

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
/// height above the garment's bottom (trouser legs open at the bottom).
const ABOVE_BOTTOM_SHARE: f32 = 0.1;

/// The boundary loops of `mesh` (connected sets of edges with a single face): per loop, its
/// length and the length-weighted centre of its edges, in the mesh's units; longest first.
pub fn boundary_loops(mesh: &TriMesh) -> Vec<(f32, Vec3)> {
    let edges = Topology::new(mesh).boundary_edges;
    // Union-find over the vertices, joined along the boundary edges.
    let mut parent: Vec<u32> = (0..mesh.vertex_count() as u32).collect();
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
    let Some((lo, hi)) = bounds_of(&mesh.positions) else {
        return false;
    };
    let extent = hi - lo;
    let largest = extent.max();
    let middle = 0.5 * (lo.x + hi.x);
    let (mut left, mut right) = (false, false);
    for (length, centre) in boundary_loops(mesh) {
        if length < MIN_OPENING_SHARE * largest || centre.y < lo.y + ABOVE_BOTTOM_SHARE * extent.y {
            continue;
        }
        let side = centre.x - middle;
        left |= side < -SIDE_SHARE * extent.x;
        right |= side > SIDE_SHARE * extent.x;
    }
    left && right
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
    }
}
