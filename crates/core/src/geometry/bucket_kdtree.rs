//! A k-d tree with leaf buckets for *exact* nearest-point queries (the body distance query of
//! the collision energy).
//!
//! "Exact" means: the answer is the smallest `(d², index)` over all points whose distance is not
//! NaN, with `d²` from [`distance2`] in `f32`, i.e. exactly what a brute-force scan returns, ties
//! included (they go to the lowest index), whatever the tree's shape or the seed given. The
//! pruning bounds keep this guarantee in floating point: a node is skipped only when the squared
//! length of the per-axis gap between the query and the node's tight bounding box exceeds the
//! best distance, and since `f32` subtraction, squaring and addition are monotone, no point in
//! that box can have a smaller `d²`.
//!
//! Layout: nodes split at the median of their widest axis down to at most [`LEAF`] points;
//! leaves hold their points contiguously as separate `x`, `y`, `z` arrays, so a leaf is scanned
//! without indirection.

use super::Vec3;

/// Most points per leaf.
pub const LEAF: usize = 16;

/// Squared distance `dx² + dy² + dz²`, summed in that order (the order the pruning bound
/// relies on).
#[inline(always)]
pub fn distance2(p: &Vec3, q: &Vec3) -> f32 {
    let (dx, dy, dz) = (p.x - q.x, p.y - q.y, p.z - q.z);
    dx * dx + dy * dy + dz * dz
}

/// One node: its points' tight bounding box, and either two children or a range of points.
#[derive(Clone, Debug)]
struct Node {
    lo: [f32; 3],
    hi: [f32; 3],
    /// Children (inner node) or `u32::MAX` (leaf).
    left: u32,
    right: u32,
    /// Range of points in leaf order (leaves only).
    start: u32,
    end: u32,
}

/// A static tree over a point set for exact nearest-point queries.
#[derive(Clone, Debug, Default)]
pub struct BucketKdTree {
    nodes: Vec<Node>,
    /// Coordinates in leaf order.
    xs: Vec<f32>,
    ys: Vec<f32>,
    zs: Vec<f32>,
    /// Original index of each point in leaf order.
    ids: Vec<u32>,
    /// Points in their original order (seeds).
    points: Vec<Vec3>,
}

impl BucketKdTree {
    /// Builds the tree in `O(n log n)`.
    pub fn new(points: &[Vec3]) -> Self {
        let mut order: Vec<u32> = (0..points.len() as u32).collect();
        let mut tree = Self {
            nodes: Vec::with_capacity(2 * points.len() / LEAF + 2),
            points: points.to_vec(),
            ..Self::default()
        };
        if !points.is_empty() {
            tree.build(points, &mut order, 0);
        }
        tree.xs = order.iter().map(|&i| points[i as usize].x).collect();
        tree.ys = order.iter().map(|&i| points[i as usize].y).collect();
        tree.zs = order.iter().map(|&i| points[i as usize].z).collect();
        tree.ids = order;
        tree
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when the tree holds no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Builds the node of `order` (which starts at `offset` in leaf order) and returns its id.
    fn build(&mut self, points: &[Vec3], order: &mut [u32], offset: usize) -> u32 {
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for &i in order.iter() {
            let p = points[i as usize];
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        let id = self.nodes.len() as u32;
        self.nodes.push(Node {
            lo,
            hi,
            left: u32::MAX,
            right: u32::MAX,
            start: offset as u32,
            end: (offset + order.len()) as u32,
        });
        if order.len() > LEAF {
            let axis = (0..3)
                .max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b])))
                .unwrap_or(0);
            let mid = order.len() / 2;
            order.select_nth_unstable_by(mid, |&a, &b| {
                points[a as usize][axis].total_cmp(&points[b as usize][axis])
            });
            let (left, right) = order.split_at_mut(mid);
            let l = self.build(points, left, offset);
            let r = self.build(points, right, offset + mid);
            let node = &mut self.nodes[id as usize];
            node.left = l;
            node.right = r;
        }
        id
    }

    /// Squared length of the per-axis gap from `q` to node `n`'s box (0 inside), summed like
    /// [`distance2`]: a lower bound of `distance2` to every point of the node.
    #[inline(always)]
    fn bound(&self, n: u32, q: &Vec3) -> f32 {
        let node = &self.nodes[n as usize];
        let gap = |a: usize| {
            let (below, above) = (node.lo[a] - q[a], q[a] - node.hi[a]);
            let g = if below > above { below } else { above };
            if g > 0.0 { g } else { 0.0 }
        };
        let (gx, gy, gz) = (gap(0), gap(1), gap(2));
        gx * gx + gy * gy + gz * gz
    }

    /// Index and squared distance of the point nearest to `q`, ties going to the lowest index:
    /// exactly a brute-force scan's answer (see the module docs). `seed` is any point index,
    /// ideally a good guess (e.g. the answer for a nearby query); its distance bounds the
    /// search from the start. `None` when the tree is empty or `q` is not a number.
    pub fn nearest(&self, q: &Vec3, seed: Option<u32>) -> Option<(u32, f32)> {
        let mut best = (u32::MAX, f32::INFINITY);
        if let Some((i, p)) = seed.and_then(|i| Some((i, self.points.get(i as usize)?))) {
            let d2 = distance2(p, q);
            if !d2.is_nan() {
                best = (i, d2);
            }
        }
        if self.nodes.is_empty() || q.iter().any(|v| v.is_nan()) {
            // A NaN query is at a NaN distance from every point.
            return None;
        }
        // Depth-first, nearer child first; each entry carries its bound, re-checked on pop
        // because the best may have improved since it was pushed. Each level adds at most one
        // entry and the tree is balanced (depth about log2(n / LEAF) + 1), so a fixed stack
        // suffices for any point count that fits in `u32`.
        let mut stack = [(0u32, 0.0f32); 64];
        stack[0] = (0, self.bound(0, q));
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let (n, b) = stack[top];
            if b > best.1 {
                continue;
            }
            let node = &self.nodes[n as usize];
            if node.left == u32::MAX {
                self.scan(node.start as usize, node.end as usize, q, &mut best);
                continue;
            }
            let (l, r) = (node.left, node.right);
            let (bl, br) = (self.bound(l, q), self.bound(r, q));
            // Push the farther child first so that the nearer one is searched first.
            let (first, second) = if bl <= br {
                ((l, bl), (r, br))
            } else {
                ((r, br), (l, bl))
            };
            for entry in [second, first] {
                if entry.1 <= best.1 && top < stack.len() {
                    stack[top] = entry;
                    top += 1;
                }
            }
        }
        (best.0 != u32::MAX).then_some(best)
    }

    /// Scans points `start..end` (leaf order) into `best`.
    #[inline(always)]
    fn scan(&self, start: usize, end: usize, q: &Vec3, best: &mut (u32, f32)) {
        let (xs, ys, zs) = (
            &self.xs[start..end],
            &self.ys[start..end],
            &self.zs[start..end],
        );
        let ids = &self.ids[start..end];
        let mut d2 = [f32::NAN; LEAF];
        for (((d, x), y), z) in d2.iter_mut().zip(xs).zip(ys).zip(zs) {
            let (dx, dy, dz) = (x - q.x, y - q.y, z - q.z);
            *d = dx * dx + dy * dy + dz * dz;
        }
        // The leaf's smallest distance (NaN ignored), then its lowest index at that distance.
        let m = d2.iter().fold(f32::INFINITY, |m, &d| m.min(d));
        if m > best.1 {
            return;
        }
        for (&d, &id) in d2.iter().zip(ids) {
            if d == m && (d < best.1 || id < best.0) {
                *best = (id, d);
            }
        }
    }
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

    #[test]
    fn equals_brute_force_with_ties_and_any_seed() {
        let mut s = 777u32;
        let mut rnd = || {
            s = s.wrapping_mul(1664525).wrapping_add(1013904223);
            (s >> 8) as f32 / (1u32 << 24) as f32 - 0.5
        };
        // A lattice (many exactly equidistant points), duplicates, random points.
        let mut pts: Vec<Vec3> = Vec::new();
        for i in 0..8 {
            for j in 0..8 {
                for k in 0..4 {
                    pts.push(Vec3::new(i as f32, j as f32, k as f32) * 0.125);
                }
            }
        }
        pts.extend(pts.clone().into_iter().rev().take(40));
        pts.extend((0..300).map(|_| Vec3::new(rnd(), rnd(), rnd()) * 2.0));
        let tree = BucketKdTree::new(&pts);
        let mut queries: Vec<Vec3> = (0..300)
            .map(|_| Vec3::new(rnd(), rnd(), rnd()) * 3.0)
            .collect();
        // Lattice midpoints: equidistant from 2, 4 or 8 lattice points.
        queries.extend((0..60).map(|i| {
            Vec3::new(
                0.0625 + 0.125 * (i % 7) as f32,
                0.0625 * (i % 5) as f32,
                0.125 * (i % 3) as f32,
            )
        }));
        let mut ties = 0;
        for (n, q) in queries.iter().enumerate() {
            let want = brute(&pts, q);
            let d2 = want.map_or(f32::NAN, |w| w.1);
            ties += usize::from(pts.iter().filter(|p| distance2(p, q) == d2).count() > 1);
            for seed in [
                None,
                Some(0),
                Some(n as u32 % pts.len() as u32),
                want.map(|w| w.0),
            ] {
                assert_eq!(tree.nearest(q, seed), want, "query {q:?} seed {seed:?}");
            }
        }
        assert!(
            ties > 20,
            "only {ties} queries with ties: the tie rule is not exercised"
        );
        assert!(
            tree.nearest(&Vec3::new(f32::NAN, 0.0, 0.0), Some(3))
                .is_none()
        );
        assert!(
            BucketKdTree::new(&[])
                .nearest(&Vec3::zeros(), Some(0))
                .is_none()
        );
        let one = BucketKdTree::new(&[Vec3::x()]);
        assert_eq!(one.nearest(&Vec3::zeros(), Some(7)), Some((0, 1.0)));
    }
}
