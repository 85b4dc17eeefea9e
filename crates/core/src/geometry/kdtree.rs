//! A static 3-d tree for nearest-point queries (skin-weight transfer, body distance queries).

use super::Vec3;

/// A balanced k-d tree over a fixed point set, stored implicitly in one permuted index array.
#[derive(Clone, Debug, Default)]
pub struct KdTree {
    points: Vec<Vec3>,
    /// Permutation of point indices; the median of each range is the node.
    order: Vec<u32>,
}

impl KdTree {
    /// Builds the tree in `O(n log n)`. Non-finite points are kept but never returned first
    /// unless they are the only points.
    pub fn new(points: &[Vec3]) -> Self {
        let mut order: Vec<u32> = (0..points.len() as u32).collect();
        build(points, &mut order, 0);
        Self {
            points: points.to_vec(),
            order,
        }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True when the tree holds no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Index and squared distance of the point nearest to `q`, or `None` when empty.
    pub fn nearest(&self, q: &Vec3) -> Option<(u32, f32)> {
        let mut best = (u32::MAX, f32::INFINITY);
        self.search(&self.order, 0, q, &mut best);
        (best.0 != u32::MAX).then_some(best)
    }

    fn search(&self, order: &[u32], depth: usize, q: &Vec3, best: &mut (u32, f32)) {
        if order.is_empty() {
            return;
        }
        let mid = order.len() / 2;
        let idx = order[mid];
        let p = self.points[idx as usize];
        let d2 = (p - q).norm_squared();
        if d2 < best.1 || (best.0 == u32::MAX && !d2.is_nan()) {
            *best = (idx, d2);
        }
        let axis = depth % 3;
        let diff = q[axis] - p[axis];
        let (near, far) = if diff < 0.0 {
            (&order[..mid], &order[mid + 1..])
        } else {
            (&order[mid + 1..], &order[..mid])
        };
        self.search(near, depth + 1, q, best);
        if diff * diff < best.1 {
            self.search(far, depth + 1, q, best);
        }
    }
}

fn build(points: &[Vec3], order: &mut [u32], depth: usize) {
    if order.len() <= 1 {
        return;
    }
    let axis = depth % 3;
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&a, &b| {
        points[a as usize][axis].total_cmp(&points[b as usize][axis])
    });
    let (left, right) = order.split_at_mut(mid);
    build(points, left, depth + 1);
    build(points, &mut right[1..], depth + 1);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_brute_force() {
        let mut s = 12345u32;
        let mut rnd = || {
            s = s.wrapping_mul(1664525).wrapping_add(1013904223);
            (s >> 8) as f32 / (1u32 << 24) as f32 - 0.5
        };
        let pts: Vec<Vec3> = (0..500).map(|_| Vec3::new(rnd(), rnd(), rnd())).collect();
        let tree = KdTree::new(&pts);
        for _ in 0..200 {
            let q = Vec3::new(rnd(), rnd(), rnd()) * 1.5;
            let (i, d2) = tree.nearest(&q).unwrap();
            let brute = pts
                .iter()
                .map(|p| (p - q).norm_squared())
                .fold(f32::INFINITY, f32::min);
            assert_eq!(d2, brute);
            assert_eq!((pts[i as usize] - q).norm_squared(), brute);
        }
        assert!(KdTree::new(&[]).nearest(&Vec3::zeros()).is_none());
    }
}
