//! Clean-up of marching-tetrahedra half meshes: greedy shortest-edge collapse down to a
//! vertex budget (keeping the surface manifold, the `x = 0` seam on its plane and clip
//! boundaries in place), then tangential relaxation with projection back onto the iso-surface.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use crate::geometry::{Vec3, safe_normalize};

use super::marching::HalfMesh;

/// A field whose zero set is the surface (positive outside), used to project vertices.
pub type Field<'a> = &'a (dyn Fn(&Vec3) -> f32 + Sync);

/// Mutable triangle mesh with vertex-to-face adjacency for local edits.
struct Editable {
    pos: Vec<Vec3>,
    faces: Vec<[u32; 3]>,
    face_alive: Vec<bool>,
    vf: Vec<Vec<u32>>,
    alive: Vec<bool>,
}

/// How constrained a vertex is: 0 free, 1 on the seam only, 2 on a clip boundary, 3 both.
fn rank(seam: bool, clip: bool) -> u8 {
    match (seam, clip) {
        (false, false) => 0,
        (true, false) => 1,
        (false, true) => 2,
        (true, true) => 3,
    }
}

impl Editable {
    fn new(mesh: &HalfMesh) -> Self {
        let mut vf = vec![Vec::new(); mesh.positions.len()];
        for (f, face) in mesh.faces.iter().enumerate() {
            for &v in face {
                vf[v as usize].push(f as u32);
            }
        }
        Self {
            pos: mesh.positions.clone(),
            faces: mesh.faces.clone(),
            face_alive: vec![true; mesh.faces.len()],
            alive: vf.iter().map(|f| !f.is_empty()).collect(),
            vf,
        }
    }

    fn seam(&self, v: u32) -> bool {
        self.pos[v as usize].x == 0.0
    }

    fn neighbours(&self, v: u32) -> Vec<u32> {
        let mut n: Vec<u32> = self.vf[v as usize]
            .iter()
            .flat_map(|&f| self.faces[f as usize])
            .filter(|&u| u != v)
            .collect();
        n.sort_unstable();
        n.dedup();
        n
    }

    /// Faces containing both `a` and `b`.
    fn edge_faces(&self, a: u32, b: u32) -> Vec<u32> {
        self.vf[a as usize]
            .iter()
            .copied()
            .filter(|&f| self.faces[f as usize].contains(&b))
            .collect()
    }

    /// (on a boundary, on a clip boundary) for vertex `v`.
    fn boundary_kind(&self, v: u32) -> (bool, bool) {
        let mut boundary = false;
        let mut clip = false;
        for n in self.neighbours(v) {
            if self.edge_faces(v, n).len() == 1 {
                boundary = true;
                if !(self.seam(v) && self.seam(n)) {
                    clip = true;
                }
            }
        }
        (boundary, clip)
    }

    fn normal_with(&self, f: u32, moved: &[(u32, Vec3)]) -> Vec3 {
        let p = self.faces[f as usize].map(|v| {
            moved
                .iter()
                .find(|(m, _)| *m == v)
                .map(|(_, p)| *p)
                .unwrap_or(self.pos[v as usize])
        });
        (p[1] - p[0]).cross(&(p[2] - p[0]))
    }

    /// Collapses edge `(a, b)` if that keeps the mesh valid; returns the surviving vertex.
    fn try_collapse(&mut self, a: u32, b: u32, field: Field, max_edge_m: f32) -> Option<u32> {
        let shared = self.edge_faces(a, b);
        if shared.is_empty() || shared.len() > 2 {
            return None;
        }
        let edge_boundary = shared.len() == 1;
        let (bnd_a, clip_a) = self.boundary_kind(a);
        let (bnd_b, clip_b) = self.boundary_kind(b);
        if bnd_a && bnd_b && !edge_boundary {
            return None;
        }
        let (seam_a, seam_b) = (self.seam(a), self.seam(b));
        let (ra, rb) = (rank(seam_a, clip_a), rank(seam_b, clip_b));
        let mid = (self.pos[a as usize] + self.pos[b as usize]) * 0.5;
        let (keep, gone, target) = if seam_a != seam_b {
            let (s, o, rs, ro) = if seam_a {
                (a, b, ra, rb)
            } else {
                (b, a, rb, ra)
            };
            if rs < ro {
                return None;
            }
            (s, o, self.pos[s as usize])
        } else if ra != rb {
            if ra > rb {
                (a, b, self.pos[a as usize])
            } else {
                (b, a, self.pos[b as usize])
            }
        } else {
            match ra {
                0 => (a, b, project(field, mid, false)),
                1 => (a, b, project(field, mid, true)),
                2 => (a, b, mid),
                _ => return None,
            }
        };
        // Link condition: the common neighbours are exactly the opposite vertices.
        let (na, nb) = (self.neighbours(keep), self.neighbours(gone));
        let common: Vec<u32> = na
            .iter()
            .copied()
            .filter(|v| nb.binary_search(v).is_ok())
            .collect();
        let mut opposite: Vec<u32> = shared
            .iter()
            .flat_map(|&f| self.faces[f as usize])
            .filter(|&v| v != a && v != b)
            .collect();
        opposite.sort_unstable();
        opposite.dedup();
        if common != opposite {
            return None;
        }
        for &o in &opposite {
            let (bnd_o, _) = self.boundary_kind(o);
            if self.neighbours(o).len() < if bnd_o { 3 } else { 4 } {
                return None;
            }
        }
        let boundary_after = bnd_a || bnd_b;
        for &n in &nb {
            if n == keep || na.binary_search(&n).is_ok() {
                continue;
            }
            if boundary_after && self.boundary_kind(n).0 && self.edge_faces(gone, n).len() != 1 {
                return None;
            }
            if (self.pos[n as usize] - target).norm() > max_edge_m {
                return None;
            }
        }
        if !seam_a && !seam_b && target.x <= 0.0 {
            return None;
        }
        let keep_seam_after = target.x == 0.0;
        for &f in &self.vf[gone as usize] {
            let face = self.faces[f as usize];
            let all_seam = face.iter().all(|&v| {
                if v == gone || v == keep {
                    keep_seam_after
                } else {
                    self.seam(v)
                }
            });
            if !shared.contains(&f) && all_seam {
                return None;
            }
        }
        let moved = [(keep, target), (gone, target)];
        let around: Vec<u32> = self.vf[keep as usize]
            .iter()
            .chain(&self.vf[gone as usize])
            .copied()
            .collect();
        for &f in &around {
            if shared.contains(&f) {
                continue;
            }
            let (old, new) = (self.normal_with(f, &[]), self.normal_with(f, &moved));
            let (lo, ln) = (old.norm(), new.norm());
            if !(ln > 1e-10 && old.dot(&new) > 0.3 * lo * ln) {
                return None;
            }
        }
        // Apply.
        for &f in &shared {
            self.face_alive[f as usize] = false;
            for v in self.faces[f as usize] {
                self.vf[v as usize].retain(|&g| g != f);
            }
        }
        let moving = std::mem::take(&mut self.vf[gone as usize]);
        for f in moving {
            for v in self.faces[f as usize].iter_mut() {
                if *v == gone {
                    *v = keep;
                }
            }
            self.vf[keep as usize].push(f);
        }
        self.alive[gone as usize] = false;
        self.pos[keep as usize] = target;
        Some(keep)
    }

    fn into_half_mesh(self) -> HalfMesh {
        let faces = self
            .faces
            .iter()
            .zip(&self.face_alive)
            .filter(|(_, a)| **a)
            .map(|(f, _)| *f)
            .collect();
        super::marching::compact(&HalfMesh {
            positions: self.pos,
            faces,
        })
    }
}

/// Numerical gradient of `field` at `p` (central differences, 0.5 mm).
fn gradient(field: Field, p: &Vec3) -> Vec3 {
    let e = 5e-4;
    let d = |v: Vec3| field(&(p + v)) - field(&(p - v));
    Vec3::new(d(Vec3::x() * e), d(Vec3::y() * e), d(Vec3::z() * e)) / (2.0 * e)
}

/// Two Newton steps towards the zero set of `field`; `on_seam` keeps `x` unchanged.
fn project(field: Field, mut p: Vec3, on_seam: bool) -> Vec3 {
    for _ in 0..2 {
        let mut g = gradient(field, &p);
        if on_seam {
            g.x = 0.0;
        }
        let g2 = g.norm_squared();
        let f = field(&p);
        if !(g2 > 1e-6 && f.is_finite()) {
            break;
        }
        let step = g * (f / g2);
        if step.norm() > 0.02 {
            break;
        }
        p -= step;
    }
    p
}

/// Collapses the shortest edges until the mirrored mesh would have at most `target_vertices`
/// vertices (seam vertices count once) or nothing more can be collapsed.
pub fn simplify(
    mesh: &HalfMesh,
    target_vertices: usize,
    field: Field,
    max_edge_m: f32,
) -> HalfMesh {
    let mut m = Editable::new(mesh);
    let count = |m: &Editable| {
        let alive = m.alive.iter().filter(|&&a| a).count();
        let seam = (0..m.pos.len())
            .filter(|&v| m.alive[v] && m.pos[v].x == 0.0)
            .count();
        2 * alive - seam
    };
    let mut vertices = count(&m);
    let mut heap = BinaryHeap::new();
    let key =
        |m: &Editable, a: u32, b: u32| (m.pos[a as usize] - m.pos[b as usize]).norm().to_bits();
    for f in &m.faces {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            if a < b {
                heap.push(Reverse((key(&m, a, b), a, b)));
            }
        }
    }
    while vertices > target_vertices {
        let Some(Reverse((len, a, b))) = heap.pop() else {
            break;
        };
        if !(m.alive[a as usize] && m.alive[b as usize]) || key(&m, a, b) != len {
            continue;
        }
        let (seam_a, seam_b) = (m.seam(a), m.seam(b));
        if let Some(keep) = m.try_collapse(a, b, field, max_edge_m) {
            vertices -= if seam_a && seam_b { 1 } else { 2 };
            for n in m.neighbours(keep) {
                heap.push(Reverse((key(&m, keep, n), keep.min(n), keep.max(n))));
            }
        }
    }
    m.into_half_mesh()
}

/// Delaunay-style edge flips: an interior edge whose opposite angles sum to more than π is
/// replaced by the other diagonal, unless that edge exists already, would join two seam
/// vertices, or would fold the pair of triangles. `passes` sweeps.
pub fn flip_edges(mesh: &HalfMesh, passes: usize) -> HalfMesh {
    let mut faces = mesh.faces.clone();
    let pos = &mesh.positions;
    let seam = |v: u32| pos[v as usize].x == 0.0;
    let angle = |at: u32, a: u32, b: u32| {
        let (p, u, w) = (pos[at as usize], pos[a as usize], pos[b as usize]);
        (u - p).angle(&(w - p))
    };
    for _ in 0..passes {
        let mut edges: std::collections::HashMap<(u32, u32), Vec<usize>> =
            std::collections::HashMap::new();
        let mut ring: Vec<std::collections::HashSet<u32>> = vec![Default::default(); pos.len()];
        for (f, face) in faces.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (face[k], face[(k + 1) % 3]);
                edges.entry((a.min(b), a.max(b))).or_default().push(f);
                ring[a as usize].insert(b);
                ring[b as usize].insert(a);
            }
        }
        let mut keys: Vec<(u32, u32)> = edges.keys().copied().collect();
        keys.sort_unstable();
        let mut touched = vec![false; faces.len()];
        let mut flipped = 0;
        for (a, b) in keys {
            let [f0, f1] = edges[&(a, b)].as_slice() else {
                continue;
            };
            let (f0, f1) = (*f0, *f1);
            if touched[f0] || touched[f1] {
                continue;
            }
            // Orient so that f0 holds the half-edge a -> b.
            let has = |f: usize, x: u32, y: u32| {
                (0..3).any(|k| faces[f][k] == x && faces[f][(k + 1) % 3] == y)
            };
            let (f0, f1) = if has(f0, a, b) { (f0, f1) } else { (f1, f0) };
            if !has(f0, a, b) || !has(f1, b, a) {
                continue;
            }
            let other = |f: usize| faces[f].iter().copied().find(|&v| v != a && v != b);
            let (Some(c), Some(d)) = (other(f0), other(f1)) else {
                continue;
            };
            if c == d || ring[c as usize].contains(&d) || (seam(c) && seam(d)) {
                continue;
            }
            if angle(c, a, b) + angle(d, a, b) <= std::f32::consts::PI + 1e-3 {
                continue;
            }
            let (n0, n1) = (tri_normal(pos, [a, b, c]), tri_normal(pos, [b, a, d]));
            let (m0, m1) = (tri_normal(pos, [c, a, d]), tri_normal(pos, [d, b, c]));
            let reference = n0 + n1;
            if !(m0.dot(&reference) > 0.0 && m1.dot(&reference) > 0.0 && m0.dot(&m1) > 0.0) {
                continue;
            }
            faces[f0] = [c, a, d];
            faces[f1] = [d, b, c];
            ring[c as usize].insert(d);
            ring[d as usize].insert(c);
            ring[a as usize].remove(&b);
            ring[b as usize].remove(&a);
            touched[f0] = true;
            touched[f1] = true;
            flipped += 1;
        }
        if flipped == 0 {
            break;
        }
    }
    HalfMesh {
        positions: mesh.positions.clone(),
        faces,
    }
}

fn tri_normal(pos: &[Vec3], f: [u32; 3]) -> Vec3 {
    let p = f.map(|v| pos[v as usize]);
    (p[1] - p[0]).cross(&(p[2] - p[0]))
}

/// Tangential Laplacian relaxation with re-projection onto the zero set of `field`.
/// Clip-boundary vertices slide along the boundary (re-projected onto the zero set of
/// `region` too), or stay fixed without a region; seam vertices stay on `x = 0`; vertices on
/// both stay fixed. A step that would flip a triangle is undone for that triangle's vertices.
pub fn relax(mesh: &HalfMesh, field: Field, region: Option<Field>, iterations: usize) -> HalfMesh {
    let m = Editable::new(mesh);
    let n = m.pos.len();
    let kinds: Vec<(bool, bool)> = (0..n as u32).map(|v| m.boundary_kind(v)).collect();
    let neighbours: Vec<Vec<u32>> = (0..n as u32).map(|v| m.neighbours(v)).collect();
    let boundary_ring: Vec<Vec<u32>> = (0..n as u32)
        .map(|v| {
            if !kinds[v as usize].1 {
                return Vec::new();
            }
            neighbours[v as usize]
                .iter()
                .copied()
                .filter(|&u| m.edge_faces(v, u).len() == 1)
                .collect()
        })
        .collect();
    let mut pos = m.pos.clone();
    for _ in 0..iterations {
        let next: Vec<Vec3> = (0..n)
            .map(|v| {
                let p = pos[v];
                let seam = p.x == 0.0;
                if kinds[v].1 {
                    let (Some(region), false, [a, b]) = (region, seam, boundary_ring[v].as_slice())
                    else {
                        return p;
                    };
                    let mut q = p + ((pos[*a as usize] + pos[*b as usize]) * 0.5 - p) * 0.5;
                    for _ in 0..2 {
                        q = project(region, project(field, q, false), false);
                    }
                    return if q.x > 0.0 && (q - p).norm() < 0.02 {
                        q
                    } else {
                        p
                    };
                }
                if neighbours[v].is_empty() {
                    return p;
                }
                let c = neighbours[v].iter().map(|&u| pos[u as usize]).sum::<Vec3>()
                    / neighbours[v].len() as f32;
                let mut g = gradient(field, &p);
                if seam {
                    g.x = 0.0;
                }
                let normal = safe_normalize(g).unwrap_or_else(Vec3::zeros);
                let mut delta = c - p;
                delta -= normal * normal.dot(&delta);
                if seam {
                    delta.x = 0.0;
                }
                let q = project(field, p + delta * 0.6, seam);
                if seam {
                    Vec3::new(0.0, q.y, q.z)
                } else if q.x > 0.0 {
                    q
                } else {
                    p
                }
            })
            .collect();
        let mut accept = vec![true; n];
        for f in &m.faces {
            let old = f.map(|v| pos[v as usize]);
            let new = f.map(|v| next[v as usize]);
            let no = (old[1] - old[0]).cross(&(old[2] - old[0]));
            let nn = (new[1] - new[0]).cross(&(new[2] - new[0]));
            if !(no.dot(&nn) > 0.0 && nn.norm() > 1e-10) {
                for v in f {
                    accept[*v as usize] = false;
                }
            }
        }
        for v in 0..n {
            if accept[v] {
                pos[v] = next[v];
            }
        }
    }
    HalfMesh {
        positions: pos,
        faces: m.faces,
    }
}
