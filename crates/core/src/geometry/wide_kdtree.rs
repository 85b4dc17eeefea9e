//! A wide k-d tree (up to [`FAN`] children per node, up to [`LEAF`] points per leaf) for
//! *exact* nearest-point queries: the body distance query of the collision energy.
//!
//! "Exact" has the meaning of [`super::bucket_kdtree`]: the answer is the smallest
//! `(d², index)` over all points whose distance is not NaN, `d²` from [`distance2`] in `f32`,
//! i.e. exactly what a brute-force scan returns, ties included (they go to the lowest index),
//! whatever the tree's shape or the seed given. A subtree is skipped only when the squared
//! per-axis gap between the query and its tight bounding box, summed like [`distance2`],
//! exceeds the best distance found (strictly: a point as far as the best with a lower index
//! must still be found); `f32` subtraction, squaring and addition are monotone, so no point in
//! that box can be nearer.
//!
//! Why wide: the binary [`super::BucketKdTree`] spends most of a query walking its nodes one
//! by one (a few dozen nodes per query on a 6K-vertex body, each a pair of dependent loads and
//! unpredictable branches). Here a node holds its children's boxes as separate coordinate
//! arrays and a leaf its points the same way, so one node or leaf is a fixed-length loop the
//! compiler turns into SIMD, and a 6K-point set is two levels deep.

use super::Vec3;
use super::bucket_kdtree::distance2;

/// Most children per inner node.
pub const FAN: usize = 16;
/// Most points per leaf.
pub const LEAF: usize = 32;

const _: () = assert!(FAN <= 31 && LEAF <= 64 && LEAF.is_multiple_of(8));

/// A child reference with this bit set is a leaf.
const LEAF_BIT: u32 = 1 << 31;

/// An inner node: its children's tight bounding boxes (empty boxes in unused lanes).
#[derive(Clone, Debug)]
struct Inner {
    lo: [[f32; FAN]; 3],
    hi: [[f32; FAN]; 3],
    child: [u32; FAN],
    children: u32,
}

/// A leaf: its points' coordinates (NaN in unused lanes) and original indices.
#[derive(Clone, Debug)]
struct Leaf {
    xyz: [[f32; LEAF]; 3],
    id: [u32; LEAF],
}

/// A static wide tree over a point set for exact nearest-point queries.
#[derive(Clone, Debug, Default)]
pub struct WideKdTree {
    inner: Vec<Inner>,
    leaves: Vec<Leaf>,
    /// The root: an inner node or (`LEAF_BIT` set) a leaf; `None` when empty.
    root: Option<u32>,
    /// Leaf slot (`leaf · LEAF + lane`) of each original index (seeds).
    slot: Vec<u32>,
    /// Inner nodes on the longest path from the root to a leaf.
    depth: usize,
    /// Whether this CPU runs AVX2 (the query is then compiled for it: 8-lane boxes and
    /// distances).
    avx2: bool,
}

/// Squared lower bound of [`distance2`] from `q` to every point of each box, per lane.
#[inline(always)]
fn box_bounds(lo: &[[f32; FAN]; 3], hi: &[[f32; FAN]; 3], q: &Vec3) -> [f32; FAN] {
    let mut out = [0.0f32; FAN];
    for a in 0..3 {
        let (lo, hi, q) = (&lo[a], &hi[a], q[a]);
        for j in 0..FAN {
            let (below, above) = (lo[j] - q, q - hi[j]);
            let g = if below > above { below } else { above };
            let g = if g > 0.0 { g } else { 0.0 };
            out[j] += g * g;
        }
    }
    out
}

impl WideKdTree {
    /// Builds the tree in `O(n log n)`.
    pub fn new(points: &[Vec3]) -> Self {
        let mut tree = Self {
            slot: vec![u32::MAX; points.len()],
            avx2: avx2(),
            ..Self::default()
        };
        if !points.is_empty() && points.len() < LEAF_BIT as usize {
            let mut order: Vec<u32> = (0..points.len() as u32).collect();
            let (root, _, depth) = tree.build(points, &mut order);
            tree.root = Some(root);
            tree.depth = depth;
        }
        tree
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.slot.len()
    }

    /// True when the tree holds no points.
    pub fn is_empty(&self) -> bool {
        self.slot.is_empty()
    }

    /// Bytes held by the tree's arrays.
    pub fn heap_bytes(&self) -> usize {
        self.inner.len() * size_of::<Inner>()
            + self.leaves.len() * size_of::<Leaf>()
            + 4 * self.slot.len()
    }

    /// Builds the subtree of `order` and returns its reference, tight box and depth.
    fn build(&mut self, points: &[Vec3], order: &mut [u32]) -> (u32, [[f32; 3]; 2], usize) {
        let bounds = bounding_box(points, order);
        if order.len() <= LEAF {
            // Ascending indices, so that the first lane at the smallest distance is the
            // lowest index there.
            order.sort_unstable();
            let mut leaf = Leaf {
                xyz: [[f32::NAN; LEAF]; 3],
                id: [u32::MAX; LEAF],
            };
            let at = self.leaves.len() as u32;
            for (lane, &i) in order.iter().enumerate() {
                let p = points[i as usize];
                for a in 0..3 {
                    leaf.xyz[a][lane] = p[a];
                }
                leaf.id[lane] = i;
                self.slot[i as usize] = at * LEAF as u32 + lane as u32;
            }
            self.leaves.push(leaf);
            return (at | LEAF_BIT, bounds, 0);
        }
        // Children of about equal size, each a full subtree: the fewest levels below, then
        // the fewest children at this level.
        let mut below = LEAF;
        while below * FAN < order.len() {
            below *= FAN;
        }
        let k = order.len().div_ceil(below).clamp(2, FAN);
        let mut groups = Vec::with_capacity(k);
        split(points, order, k, &mut groups);
        let id = self.inner.len();
        self.inner.push(Inner {
            lo: [[f32::INFINITY; FAN]; 3],
            hi: [[f32::NEG_INFINITY; FAN]; 3],
            child: [u32::MAX; FAN],
            children: k as u32,
        });
        let (mut offset, mut depth) = (0, 0);
        for (j, len) in groups.into_iter().enumerate() {
            let (child, [lo, hi], d) = self.build(points, &mut order[offset..offset + len]);
            depth = depth.max(d + 1);
            offset += len;
            let node = &mut self.inner[id];
            node.child[j] = child;
            for a in 0..3 {
                node.lo[a][j] = lo[a];
                node.hi[a][j] = hi[a];
            }
        }
        (id as u32, bounds, depth)
    }

    /// Index and squared distance of the point nearest to `q`, ties going to the lowest index:
    /// exactly a brute-force scan's answer (see the module docs). `seed` is any point index,
    /// ideally a good guess (e.g. the answer for a nearby query); its distance bounds the
    /// search from the start. `None` when the tree is empty or `q` is not a number.
    pub fn nearest(&self, q: &Vec3, seed: Option<u32>) -> Option<(u32, f32)> {
        let mut best = (u32::MAX, f32::INFINITY);
        if let Some(&s) = seed.and_then(|i| self.slot.get(i as usize)) {
            let (leaf, lane) = (&self.leaves[s as usize / LEAF], s as usize % LEAF);
            let p = Vec3::new(leaf.xyz[0][lane], leaf.xyz[1][lane], leaf.xyz[2][lane]);
            let d2 = distance2(&p, q);
            if !d2.is_nan() {
                best = (leaf.id[lane], d2);
            }
        }
        let root = self.root?;
        if q.iter().any(|v| v.is_nan()) {
            // A NaN query is at a NaN distance from every point.
            return None;
        }
        // The stack holds at most FAN - 1 waiting siblings per level and the children just
        // pushed: `depth · (FAN - 1) + 1` entries (46 for a tree of up to 131072 points).
        let shallow = self.depth <= 3;
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: AVX2 was detected on this CPU when the tree was built.
            return unsafe {
                if shallow {
                    self.search_avx2::<{ 3 * FAN }>(root, q, best)
                } else {
                    self.search_avx2::<{ 9 * FAN }>(root, q, best)
                }
            };
        }
        if shallow {
            self.search::<{ 3 * FAN }>(root, q, best)
        } else {
            self.search::<{ 9 * FAN }>(root, q, best)
        }
    }

    /// [`WideKdTree::search`] compiled for AVX2 (the same operations in 8-lane registers, so
    /// the same results).
    ///
    /// # Safety
    /// AVX2 must be available.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn search_avx2<const S: usize>(
        &self,
        root: u32,
        q: &Vec3,
        best: (u32, f32),
    ) -> Option<(u32, f32)> {
        self.search::<S>(root, q, best)
    }

    /// The search from `root` with the best so far `best`, on a stack of `S` entries.
    #[inline(always)]
    fn search<const S: usize>(
        &self,
        root: u32,
        q: &Vec3,
        mut best: (u32, f32),
    ) -> Option<(u32, f32)> {
        // Depth-first, nearest child first; each entry carries its bound, re-checked on pop
        // because the best may have improved since it was pushed.
        let mut stack = [(0u32, 0.0f32); S];
        stack[0] = (root, 0.0);
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (n, b) = stack[top];
            if b > best.1 {
                continue;
            }
            if n & LEAF_BIT != 0 {
                self.scan(&self.leaves[(n & !LEAF_BIT) as usize], q, &mut best);
                continue;
            }
            let node = &self.inner[n as usize];
            let bounds = box_bounds(&node.lo, &node.hi, q);
            // The children to visit, the nearest pushed last so that it is searched first
            // (the others are mostly skipped on pop once it has tightened the best).
            let mut mask = 0u32;
            for (j, &b) in bounds.iter().enumerate() {
                mask |= u32::from(b <= best.1) << j;
            }
            mask &= (1u32 << node.children) - 1;
            let mut nearest = None;
            while mask != 0 {
                let j = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let mut entry = (node.child[j], bounds[j]);
                match &mut nearest {
                    None => {
                        nearest = Some(entry);
                        continue;
                    }
                    Some(n) if entry.1 < n.1 => std::mem::swap(n, &mut entry),
                    Some(_) => {}
                }
                stack[top] = entry;
                top += 1;
            }
            if let Some(entry) = nearest {
                stack[top] = entry;
                top += 1;
            }
        }
        (best.0 != u32::MAX).then_some(best)
    }

    /// Scans a leaf into `best`.
    #[inline(always)]
    fn scan(&self, leaf: &Leaf, q: &Vec3, best: &mut (u32, f32)) {
        let [xs, ys, zs] = &leaf.xyz;
        let mut d2 = [0.0f32; LEAF];
        for j in 0..LEAF {
            let (dx, dy, dz) = (xs[j] - q.x, ys[j] - q.y, zs[j] - q.z);
            d2[j] = dx * dx + dy * dy + dz * dz;
        }
        // The leaf's smallest distance (NaN, as in unused lanes, ignored), in lanes of 8 so
        // that it vectorises, then its lowest index at that distance.
        let mut lanes = [f32::INFINITY; 8];
        for chunk in d2.chunks_exact(8) {
            for (m, &d) in lanes.iter_mut().zip(chunk) {
                *m = if d < *m { d } else { *m };
            }
        }
        let m = lanes
            .iter()
            .fold(f32::INFINITY, |m, &d| if d < m { d } else { m });
        if m > best.1 {
            return;
        }
        let mut at = 0u64;
        for (j, &d) in d2.iter().enumerate() {
            at |= u64::from(d == m) << j;
        }
        let id = leaf.id[at.trailing_zeros() as usize];
        if m < best.1 || id < best.0 {
            *best = (id, m);
        }
    }
}

/// True when the query can run its AVX2 build on this CPU.
fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Tight bounding box `[lo, hi]` of `points[order]` (NaN coordinates ignored).
fn bounding_box(points: &[Vec3], order: &[u32]) -> [[f32; 3]; 2] {
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for &i in order {
        let p = points[i as usize];
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    [lo, hi]
}

/// Splits `order` into `k` spatially compact groups of about equal size (recursive median
/// cuts along the widest axis) and appends their lengths, in order, to `groups`.
fn split(points: &[Vec3], order: &mut [u32], k: usize, groups: &mut Vec<usize>) {
    if k <= 1 {
        groups.push(order.len());
        return;
    }
    let [lo, hi] = bounding_box(points, order);
    let axis = (0..3)
        .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
        .unwrap_or(0);
    let k1 = k / 2;
    let cut = order.len() * k1 / k;
    order.select_nth_unstable_by(cut, |&a, &b| {
        points[a as usize][axis].total_cmp(&points[b as usize][axis])
    });
    let (left, right) = order.split_at_mut(cut);
    split(points, left, k1, groups);
    split(points, right, k - k1, groups);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The smallest `(d², index)` by brute force.
    fn brute(pts: &[Vec3], q: &Vec3) -> Option<(u32, f32)> {
        pts.iter()
            .enumerate()
            .map(|(i, p)| (i as u32, distance2(p, q)))
            .filter(|(_, d2)| !d2.is_nan())
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
    }

    fn lcg(seed: u32) -> impl FnMut() -> f32 {
        let mut s = seed;
        move || {
            s = s.wrapping_mul(1664525).wrapping_add(1013904223);
            (s >> 8) as f32 / (1u32 << 24) as f32 - 0.5
        }
    }

    /// Both builds of the query (AVX2 where the CPU has it, and the portable one).
    fn both(tree: &WideKdTree) -> [WideKdTree; 2] {
        let mut portable = tree.clone();
        portable.avx2 = false;
        [tree.clone(), portable]
    }

    #[test]
    fn equals_brute_force_with_ties_and_any_seed() {
        let mut rnd = lcg(777);
        // A lattice (many exactly equidistant points), duplicates, random points.
        let mut pts: Vec<Vec3> = Vec::new();
        for i in 0..16 {
            for j in 0..8 {
                for k in 0..4 {
                    pts.push(Vec3::new(i as f32, j as f32, k as f32) * 0.125);
                }
            }
        }
        pts.extend(pts.clone().into_iter().rev().take(100));
        pts.extend((0..700).map(|_| Vec3::new(rnd(), rnd(), rnd()) * 2.0));
        let mut queries: Vec<Vec3> = (0..300)
            .map(|_| Vec3::new(rnd(), rnd(), rnd()) * 3.0)
            .collect();
        // Lattice midpoints: equidistant from 2, 4 or 8 lattice points; lattice points.
        queries.extend((0..60).map(|i| {
            Vec3::new(
                0.0625 + 0.125 * (i % 7) as f32,
                0.0625 * (i % 5) as f32,
                0.125 * (i % 3) as f32,
            )
        }));
        queries.extend(pts.iter().step_by(11).copied());
        // Far away and infinite (every distance infinite: the lowest index).
        queries.extend([
            Vec3::new(1e3, -2e3, 5e2),
            Vec3::new(f32::INFINITY, 0.0, 0.0),
            Vec3::new(0.0, f32::NEG_INFINITY, 1.0),
        ]);
        let mut ties = 0;
        for size in [1, 5, 32, 33, 500, pts.len()] {
            let pts = &pts[..size];
            let tree = WideKdTree::new(pts);
            assert_eq!(tree.len(), size);
            for tree in both(&tree) {
                for (n, q) in queries.iter().enumerate() {
                    let want = brute(pts, q);
                    let d2 = want.map_or(f32::NAN, |w| w.1);
                    ties += usize::from(pts.iter().filter(|p| distance2(p, q) == d2).count() > 1);
                    for seed in [
                        None,
                        Some(0),
                        Some(n as u32 % size as u32),
                        want.map(|w| w.0),
                        Some(u32::MAX),
                    ] {
                        assert_eq!(
                            tree.nearest(q, seed),
                            want,
                            "{size} points, query {q:?} seed {seed:?}"
                        );
                    }
                }
            }
        }
        assert!(
            ties > 100,
            "only {ties} queries with ties: the tie rule is not exercised"
        );
    }

    #[test]
    fn deep_trees_equal_brute_force_and_bad_queries_find_nothing() {
        // 140 000 points: four levels of inner nodes (the larger stack).
        let mut rnd = lcg(31);
        let pts: Vec<Vec3> = (0..140_000)
            .map(|_| Vec3::new(rnd(), rnd() * 0.1, rnd()))
            .collect();
        let tree = WideKdTree::new(&pts);
        assert_eq!(tree.depth, 4);
        for tree in both(&tree) {
            let mut seed = None;
            for _ in 0..60 {
                let q = Vec3::new(rnd(), rnd() * 0.3, rnd()) * 1.2;
                let want = brute(&pts, &q);
                assert_eq!(tree.nearest(&q, seed), want);
                assert_eq!(tree.nearest(&q, None), want);
                seed = want.map(|w| w.0);
            }
            assert!(
                tree.nearest(&Vec3::new(f32::NAN, 0.0, 0.0), Some(3))
                    .is_none()
            );
        }
        assert!(
            WideKdTree::new(&[])
                .nearest(&Vec3::zeros(), Some(0))
                .is_none()
        );
        let one = WideKdTree::new(&[Vec3::x()]);
        assert_eq!(one.nearest(&Vec3::zeros(), Some(7)), Some((0, 1.0)));
        assert_eq!(
            WideKdTree::new(&[Vec3::x(); 40]).nearest(&Vec3::zeros(), Some(9)),
            Some((0, 1.0))
        );
    }
}
