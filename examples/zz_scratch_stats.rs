use neural_cloth::geometry::{Topology, Vec3, KdTree};
use neural_cloth::scene::procedural::{self, GarmentKind, MotionKind};
use std::time::Instant;
fn main() {
    let t = Instant::now();
    let a = procedural::mannequin().unwrap();
    println!("mannequin {:?} verts {} faces {} height {}", t.elapsed(), a.bind_mesh.vertex_count(), a.bind_mesh.faces.len(), a.height_m());
    let b = a.bind_mesh.bounds().unwrap(); println!("bounds {:?}", b);
    let e = Topology::new(&a.bind_mesh).edge_lengths(&a.bind_mesh.positions);
    let mean: f32 = e.iter().sum::<f32>() / e.len() as f32;
    println!("edge mean {mean} min {} max {}", e.iter().cloned().fold(1.0, f32::min), e.iter().cloned().fold(0.0, f32::max));
    let areas = a.bind_mesh.face_areas();
    println!("min area {}", areas.iter().cloned().fold(1.0, f32::min));
    write_obj("/tmp/body.obj", &a.bind_mesh.positions, &a.bind_mesh.faces);
    let tree = KdTree::new(&a.rest_mesh.positions);
    for kind in GarmentKind::ALL {
        for n in [3400usize, 83333] {
            let t = Instant::now();
            let g = procedural::builtin_garment(&a, kind, n, None).unwrap();
            let topo = &g.topology;
            let e = topo.edge_lengths(&g.mesh.positions);
            let mean: f32 = e.iter().sum::<f32>() / e.len() as f32;
            let mind = g.mesh.positions.iter().map(|p| tree.nearest(p).unwrap().1.sqrt()).fold(1.0, f32::min);
            let areas = g.mesh.face_areas();
            println!("{kind:?} {n}: {:?} verts {} boundary edges {} edge mean {mean} min {} max {} min dist {mind} min area {}", t.elapsed(), g.vertex_count(), topo.boundary_edges.len(), e.iter().cloned().fold(1.0, f32::min), e.iter().cloned().fold(0.0, f32::max), areas.iter().cloned().fold(1.0, f32::min));
            if n == 3400 { write_obj(&format!("/tmp/{}.obj", kind.name()), &g.mesh.positions, &g.mesh.faces); }
        }
    }
    let jump = procedural::motion(MotionKind::Jump, 60.0, 1.8).unwrap();
    let y: Vec<f32> = jump.frames.iter().map(|p| p.root_translation.y).collect();
    println!("jump y min {} max {}", y.iter().cloned().fold(9.0, f32::min), y.iter().cloned().fold(0.0, f32::max));
    let _ = Vec3::zeros();
}
fn write_obj(path: &str, p: &[Vec3], f: &[[u32; 3]]) {
    use std::fmt::Write;
    let mut s = String::new();
    for v in p { writeln!(s, "v {} {} {}", v.x, v.y, v.z).unwrap(); }
    for t in f { writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1).unwrap(); }
    std::fs::write(path, s).unwrap();
}
