use neural_cloth::geometry::{Topology, TriMesh};
use neural_cloth::scene::procedural::{self, GarmentKind};
fn stats(name: &str, m: &TriMesh) {
    let topo = Topology::new(m);
    let e = topo.edge_lengths(&m.positions);
    let mean: f32 = e.iter().sum::<f32>() / e.len() as f32;
    let short = e.iter().filter(|&&l| l < 0.25 * mean).count();
    let bnd: std::collections::HashSet<[u32;2]> = topo.boundary_edges.iter().cloned().collect();
    let short_b = topo.edges.iter().zip(&e).filter(|(ed, l)| **l < 0.25 * mean && bnd.contains(*ed)).count();
    let mut angles: Vec<f32> = Vec::new();
    for f in 0..m.faces.len() {
        let c = m.corners(f);
        let mut mn = 180.0f32;
        for k in 0..3 { let a = c[(k+1)%3]-c[k]; let b = c[(k+2)%3]-c[k]; mn = mn.min(a.angle(&b).to_degrees()); }
        angles.push(mn);
    }
    angles.sort_by(|a, b| a.total_cmp(b));
    let n = angles.len();
    println!("{name}: V {} mean edge {mean:.4} short(<25%) {short} (boundary {short_b}) min-angle p0 {:.2} p1 {:.2} p5 {:.2} p50 {:.2}; <10deg: {}", m.vertex_count(), angles[0], angles[n/100], angles[n/20], angles[n/2], angles.iter().filter(|&&a| a < 10.0).count());
}
fn main() {
    let a = procedural::mannequin().unwrap();
    stats("body", &a.bind_mesh);
    for k in GarmentKind::ALL { for n in [3400, 83333] { stats(&format!("{k:?} {n}"), &procedural::garments::garment_mesh(k, n).unwrap()); } }
}
