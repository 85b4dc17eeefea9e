use neural_cloth::geometry::{Vec3, Quat};
use neural_cloth::scene::procedural::{self, GarmentKind, MotionKind};
use neural_cloth::scene::Pose;

struct Img { w: usize, h: usize, z: Vec<f32>, c: Vec<[u8; 3]> }
impl Img {
    fn new(w: usize, h: usize) -> Self { Self { w, h, z: vec![f32::INFINITY; w * h], c: vec![[255, 255, 255]; w * h] } }
    // view: rotate about Y by yaw, orthographic, looking along -Z (camera at +Z)
    fn draw(&mut self, p: &[Vec3], f: &[[u32; 3]], yaw: f32, col: [f32; 3], center: Vec3, scale: f32) {
        let r = Quat::from_axis_angle(&Vec3::y_axis(), yaw);
        let q: Vec<Vec3> = p.iter().map(|v| r * (v - center)).collect();
        for t in f {
            let a = q[t[0] as usize]; let b = q[t[1] as usize]; let c = q[t[2] as usize];
            let n = (b - a).cross(&(c - a));
            let nn = n.norm(); if nn == 0.0 { continue; }
            let n = n / nn;
            let shade = if n.z > 0.0 { 0.3 + 0.7 * n.z } else { 0.15 + 0.2 * (-n.z) };
            let backface = n.z <= 0.0;
            let px = |v: Vec3| ((v.x * scale + self.w as f32 / 2.0), (self.h as f32 / 2.0 - v.y * scale), -v.z);
            let (p0, p1, p2) = (px(a), px(b), px(c));
            let minx = p0.0.min(p1.0).min(p2.0).floor().max(0.0) as usize;
            let maxx = p0.0.max(p1.0).max(p2.0).ceil().min(self.w as f32 - 1.0) as usize;
            let miny = p0.1.min(p1.1).min(p2.1).floor().max(0.0) as usize;
            let maxy = p0.1.max(p1.1).max(p2.1).ceil().min(self.h as f32 - 1.0) as usize;
            let area = (p1.0 - p0.0) * (p2.1 - p0.1) - (p2.0 - p0.0) * (p1.1 - p0.1);
            if area.abs() < 1e-9 { continue; }
            for y in miny..=maxy { for x in minx..=maxx {
                let (fx, fy) = (x as f32 + 0.5, y as f32 + 0.5);
                let w0 = ((p1.0 - fx) * (p2.1 - fy) - (p2.0 - fx) * (p1.1 - fy)) / area;
                let w1 = ((p2.0 - fx) * (p0.1 - fy) - (p0.0 - fx) * (p2.1 - fy)) / area;
                let w2 = 1.0 - w0 - w1;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 { continue; }
                let z = w0 * p0.2 + w1 * p1.2 + w2 * p2.2;
                let i = y * self.w + x;
                if z < self.z[i] { self.z[i] = z;
                    let cc = if backface { [0.9, 0.2, 0.2] } else { col };
                    self.c[i] = [(cc[0] * shade * 255.0) as u8, (cc[1] * shade * 255.0) as u8, (cc[2] * shade * 255.0) as u8]; }
            }}
        }
    }
    fn save(&self, path: &str) {
        let mut buf = image::RgbImage::new(self.w as u32, self.h as u32);
        for (i, c) in self.c.iter().enumerate() { buf.put_pixel((i % self.w) as u32, (i / self.w) as u32, image::Rgb(*c)); }
        buf.save(path).unwrap();
    }
}

fn main() {
    let a = procedural::mannequin().unwrap();
    let args: Vec<String> = std::env::args().collect();
    let which = args.get(1).cloned().unwrap_or("body".into());
    let center = Vec3::new(0.0, 0.9, 0.0);
    let scale = 220.0;
    let mut views = Vec::new();
    let (pose, motion_pose): (Pose, bool) = match which.as_str() {
        "elbow" => { let mut p = a.skeleton.rest_pose(); p.rotations[8] = Quat::from_axis_angle(&Vec3::x_axis(), -1.57); (p, true) }
        "leg" => { let mut p = a.skeleton.rest_pose(); p.rotations[14] = Quat::from_axis_angle(&Vec3::x_axis(), -1.05); (p, true) }
        m if MotionKind::from_name(m).is_some() => { let mo = procedural::motion(MotionKind::from_name(m).unwrap(), 30.0, 4.0).unwrap(); let t: usize = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(20); (mo.frames[t].clone(), true) }
        _ => (a.skeleton.rest_pose(), false),
    };
    let _ = motion_pose;
    let body = a.pose_vertices(&pose);
    let kind = args.get(3).and_then(|s| GarmentKind::from_name(s));
    let g = kind.map(|k| procedural::builtin_garment(&a, k, 3400, None).unwrap());
    let g = g.or_else(|| match which.as_str() { "tshirt" | "skirt" | "dress" => Some(procedural::builtin_garment(&a, GarmentKind::from_name(&which).unwrap(), 3400, None).unwrap()), "elbow" => Some(procedural::builtin_garment(&a, GarmentKind::TShirt, 3400, None).unwrap()), "leg" => Some(procedural::builtin_garment(&a, GarmentKind::Skirt, 3400, None).unwrap()), _ => None });
    let root = pose.root_translation - Vec3::new(0.0, 0.95, 0.0);
    for yaw in [0.0f32, 1.5708, 3.1416] {
        let mut img = Img::new(440, 440);
        img.draw(&body, &a.bind_mesh.faces, yaw, [0.8, 0.8, 0.8], center + root, scale);
        if let Some(g) = &g { let gp = g.pose_vertices(&a, &pose); img.draw(&gp, &g.mesh.faces, yaw, [0.3, 0.5, 0.9], center + root, scale); }
        views.push(img);
    }
    let mut out = Img::new(440 * 3, 440);
    for (k, v) in views.iter().enumerate() { for y in 0..440 { for x in 0..440 { out.c[y * out.w + k * 440 + x] = v.c[y * 440 + x]; } } }
    out.save(&format!("/tmp/render_{which}.png"));
}
