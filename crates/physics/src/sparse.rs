//! A small sparse symmetric positive-definite solver: reverse Cuthill-McKee ordering and an
//! envelope (profile) Cholesky factorisation. The reference simulator factors its constant
//! "projective dynamics" matrix `M/Δt² + K` once per garment and uses the solve as the initial
//! inverse Hessian of L-BFGS (Liu et al. 2017).

use std::collections::VecDeque;

use super::PhysicsError;

/// `L Lᵀ = P A Pᵀ` for a symmetric positive-definite `A`, stored by rows within the envelope.
#[derive(Clone, Debug)]
pub struct EnvelopeCholesky {
    /// `perm[new] = old`.
    perm: Vec<usize>,
    /// First stored column of each (permuted) row.
    first: Vec<usize>,
    /// Offset of each row in `values`.
    offset: Vec<usize>,
    /// Row `i` holds columns `first[i]..=i`.
    values: Vec<f64>,
}

impl EnvelopeCholesky {
    /// Factors the `n x n` matrix given by `(row, col, value)` triplets (duplicates are summed;
    /// give each off-diagonal pair once or both ways, only `row >= col` after ordering is used,
    /// so pass the lower or the upper triangle, not both).
    pub fn factor(n: usize, triplets: &[(usize, usize, f64)]) -> Result<Self, PhysicsError> {
        if let Some(&(i, j, _)) = triplets
            .iter()
            .find(|(i, j, v)| *i >= n || *j >= n || !v.is_finite())
        {
            return Err(PhysicsError::InvalidOptions(format!(
                "bad matrix entry ({i}, {j}) for size {n}"
            )));
        }
        let mut adjacency = vec![Vec::new(); n];
        for &(i, j, _) in triplets {
            if i != j {
                adjacency[i].push(j);
                adjacency[j].push(i);
            }
        }
        for a in &mut adjacency {
            a.sort_unstable();
            a.dedup();
        }
        let perm = reverse_cuthill_mckee(&adjacency);
        let mut inverse = vec![0; n];
        for (new, &old) in perm.iter().enumerate() {
            inverse[old] = new;
        }
        let mut first: Vec<usize> = (0..n).collect();
        for &(i, j, _) in triplets {
            let (a, b) = (inverse[i], inverse[j]);
            let (r, c) = (a.max(b), a.min(b));
            first[r] = first[r].min(c);
        }
        let mut offset = Vec::with_capacity(n + 1);
        let mut total = 0;
        for (i, f) in first.iter().enumerate() {
            offset.push(total);
            total += i - f + 1;
        }
        offset.push(total);
        let mut values = vec![0.0; total];
        for &(i, j, v) in triplets {
            let (a, b) = (inverse[i], inverse[j]);
            let (r, c) = (a.max(b), a.min(b));
            values[offset[r] + c - first[r]] += v;
        }
        for i in 0..n {
            for j in first[i]..i {
                let k0 = first[i].max(first[j]);
                let mut s = values[offset[i] + j - first[i]];
                for k in k0..j {
                    s -= values[offset[i] + k - first[i]] * values[offset[j] + k - first[j]];
                }
                values[offset[i] + j - first[i]] = s / values[offset[j] + j - first[j]];
            }
            let row = &values[offset[i]..offset[i] + i - first[i]];
            let d = values[offset[i] + i - first[i]] - row.iter().map(|v| v * v).sum::<f64>();
            if !(d > 0.0 && d.is_finite()) {
                return Err(PhysicsError::InvalidOptions(format!(
                    "matrix is not positive definite (pivot {d} at row {})",
                    perm[i]
                )));
            }
            values[offset[i] + i - first[i]] = d.sqrt();
        }
        Ok(Self {
            perm,
            first,
            offset,
            values,
        })
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.perm.len()
    }

    /// True for an empty matrix.
    pub fn is_empty(&self) -> bool {
        self.perm.is_empty()
    }

    /// Stored entries (a measure of the factor's cost).
    pub fn stored(&self) -> usize {
        self.values.len()
    }

    /// Solves `A x = b` in place; a `b` of the wrong length is left unchanged.
    pub fn solve_in_place(&self, b: &mut [f64]) {
        if b.len() != self.len() {
            return;
        }
        let n = self.len();
        let mut y: Vec<f64> = (0..n).map(|i| b[self.perm[i]]).collect();
        for i in 0..n {
            let (f, o) = (self.first[i], self.offset[i]);
            let row = &self.values[o..o + i - f];
            let s = y[i] - row.iter().zip(&y[f..i]).map(|(l, yk)| l * yk).sum::<f64>();
            y[i] = s / self.values[o + i - f];
        }
        for i in (0..n).rev() {
            let (f, o) = (self.first[i], self.offset[i]);
            y[i] /= self.values[o + i - f];
            let yi = y[i];
            let row = &self.values[o..o + i - f];
            y[f..i]
                .iter_mut()
                .zip(row)
                .for_each(|(yk, l)| *yk -= l * yi);
        }
        for (i, v) in y.into_iter().enumerate() {
            b[self.perm[i]] = v;
        }
    }

    /// Solves `A x = b` for three right-hand sides at once (`b[i]` holds row `i` of each, as
    /// a vertex's x, y, z), reading the factor once: the same operations in the same order as
    /// three calls of [`Self::solve_in_place`], so the same results to the last bit. A `b` of
    /// the wrong length is left unchanged.
    pub fn solve3_in_place(&self, b: &mut [[f64; 3]]) {
        if b.len() != self.len() {
            return;
        }
        let n = self.len();
        let mut y: Vec<[f64; 3]> = (0..n).map(|i| b[self.perm[i]]).collect();
        for i in 0..n {
            let (f, o) = (self.first[i], self.offset[i]);
            let row = &self.values[o..o + i - f];
            let mut s = [0.0f64; 3];
            for (l, yk) in row.iter().zip(&y[f..i]) {
                for c in 0..3 {
                    s[c] += l * yk[c];
                }
            }
            let d = self.values[o + i - f];
            for c in 0..3 {
                y[i][c] = (y[i][c] - s[c]) / d;
            }
        }
        for i in (0..n).rev() {
            let (f, o) = (self.first[i], self.offset[i]);
            let d = self.values[o + i - f];
            let yi = y[i].map(|v| v / d);
            y[i] = yi;
            let row = &self.values[o..o + i - f];
            for (yk, l) in y[f..i].iter_mut().zip(row) {
                for c in 0..3 {
                    yk[c] -= l * yi[c];
                }
            }
        }
        for (i, v) in y.into_iter().enumerate() {
            b[self.perm[i]] = v;
        }
    }
}

/// Reverse Cuthill-McKee ordering (`result[new] = old`), component by component, each started
/// from a pseudo-peripheral vertex.
fn reverse_cuthill_mckee(adjacency: &[Vec<usize>]) -> Vec<usize> {
    let n = adjacency.len();
    let mut order = Vec::with_capacity(n);
    let mut visited = vec![false; n];
    let bfs = |start: usize, visited: &mut Vec<bool>, out: &mut Vec<usize>| {
        let mut queue = VecDeque::from([start]);
        visited[start] = true;
        while let Some(v) = queue.pop_front() {
            out.push(v);
            let mut next: Vec<usize> = adjacency[v]
                .iter()
                .copied()
                .filter(|&u| !visited[u])
                .collect();
            next.sort_by_key(|&u| adjacency[u].len());
            for u in next {
                visited[u] = true;
                queue.push_back(u);
            }
        }
    };
    for seed in 0..n {
        if visited[seed] {
            continue;
        }
        // Pseudo-peripheral start: the last vertex of two BFS sweeps.
        let mut start = seed;
        for _ in 0..2 {
            let mut scratch = visited.clone();
            let mut sweep = Vec::new();
            bfs(start, &mut scratch, &mut sweep);
            start = sweep.last().copied().unwrap_or(start);
        }
        bfs(start, &mut visited, &mut order);
    }
    order.reverse();
    order
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_grid_laplacian_plus_diagonal() {
        // 2-D grid Laplacian (5-point) + 0.01 I, in scrambled vertex order.
        let (w, h) = (13, 9);
        let n = w * h;
        let id = |x: usize, y: usize| (y * w + x) * 37 % n;
        let mut t = Vec::new();
        for y in 0..h {
            for x in 0..w {
                t.push((id(x, y), id(x, y), 0.01));
                for (dx, dy) in [(1, 0), (0, 1)] {
                    if x + dx < w && y + dy < h {
                        let (a, b) = (id(x, y), id(x + dx, y + dy));
                        t.extend([(a, a, 1.0), (b, b, 1.0), (a.max(b), a.min(b), -1.0)]);
                    }
                }
            }
        }
        let chol = EnvelopeCholesky::factor(n, &t).unwrap();
        assert!(
            chol.stored() < n * n / 3,
            "RCM should keep the envelope narrow: {}",
            chol.stored()
        );
        let expected: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut b = vec![0.0; n];
        for &(i, j, v) in &t {
            b[i] += v * expected[j];
            if i != j {
                b[j] += v * expected[i];
            }
        }
        chol.solve_in_place(&mut b);
        for (x, e) in b.iter().zip(&expected) {
            assert!((x - e).abs() < 1e-8, "{x} vs {e}");
        }
        // Three right-hand sides at once give the single solves' results to the last bit.
        let column =
            |c: usize| -> Vec<f64> { (0..n).map(|i| ((i * 3 + c) as f64 * 0.61).cos()).collect() };
        let mut interleaved: Vec<[f64; 3]> = (0..n)
            .map(|i| [column(0)[i], column(1)[i], column(2)[i]])
            .collect();
        chol.solve3_in_place(&mut interleaved);
        for c in 0..3 {
            let mut single = column(c);
            chol.solve_in_place(&mut single);
            for (i, (x, row)) in single.iter().zip(&interleaved).enumerate() {
                assert_eq!(x.to_bits(), row[c].to_bits(), "row {i}, column {c}");
            }
        }
        assert!(EnvelopeCholesky::factor(2, &[(0, 0, 1.0), (1, 1, -1.0)]).is_err());
        assert!(EnvelopeCholesky::factor(2, &[(0, 3, 1.0)]).is_err());
    }
}
