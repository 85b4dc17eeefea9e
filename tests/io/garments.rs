//! OBJ garments (counts and vertex order against the text, units, shared frame with the body
//! proxy, typed errors) and the `inspect` report on every asset.

use std::path::Path;

use neural_cloth::geometry::Vec3;
use neural_cloth::io::{self, ImportOptions, IoError, Units};

use super::avatars::AVATARS;
use super::motions::MOTIONS;
use super::{assert_names_file, asset, files_in, opts};

/// (file, vertices, faces) from LICENSES.md.
const GARMENTS: [(&str, usize, usize); 7] = [
    ("makehuman_tshirt_from_male_casualsuit06.obj", 2822, 2728),
    ("makehuman_tshirt_from_female_casualsuit01.obj", 1311, 1262),
    ("makehuman_skirt_from_female_elegantsuit01.obj", 395, 364),
    ("makehuman_blouse_from_female_elegantsuit01.obj", 1810, 1732),
    ("makehuman_female_elegantsuit01_original.obj", 2205, 2096),
    ("makehuman_male_casualsuit06_original.obj", 3708, 3584),
    ("makehuman_body_proxy_female1605.obj", 1605, 1584),
];

#[test]
fn every_garment_loads_with_exact_vertex_order_in_decimetres() {
    let files = files_in("garments", "obj");
    assert_eq!(files.len(), GARMENTS.len());
    let body = io::load_obj(
        &asset("garments/makehuman_body_proxy_female1605.obj"),
        &opts(),
    )
    .unwrap();
    let (body_lo, body_hi) = body.mesh.bounds().unwrap();
    let body_height = body_hi.y - body_lo.y;
    assert!(
        (1.5..1.8).contains(&body_height),
        "body proxy is {body_height} m tall"
    );
    for path in files {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let (_, vertices, polygons) = *GARMENTS
            .iter()
            .find(|g| g.0 == name)
            .unwrap_or_else(|| panic!("{name} has no facts"));
        let text = std::fs::read_to_string(&path).unwrap();
        let v_lines: Vec<Vec3> = text
            .lines()
            .filter(|l| l.starts_with("v "))
            .map(|l| {
                let c: Vec<f32> = l
                    .split_whitespace()
                    .skip(1)
                    .take(3)
                    .map(|t| t.parse().unwrap())
                    .collect();
                Vec3::new(c[0], c[1], c[2])
            })
            .collect();
        let triangles: usize = text
            .lines()
            .filter(|l| l.starts_with("f "))
            .map(|l| l.split_whitespace().count() - 3)
            .sum();
        let f_lines = text.lines().filter(|l| l.starts_with("f ")).count();
        assert_eq!(
            (v_lines.len(), f_lines),
            (vertices, polygons),
            "{name}: file vs LICENSES"
        );
        let m = io::load_obj(&path, &opts()).unwrap();
        assert_eq!(m.units, Units::Decimetres, "{name}");
        assert_eq!(m.mesh.vertex_count(), vertices, "{name}");
        assert_eq!(m.mesh.faces.len(), triangles, "{name}");
        for (p, v) in m.mesh.positions.iter().zip(&v_lines) {
            assert!(
                (p - v * 0.1).norm() < 1e-6,
                "{name}: vertex order or value changed"
            );
        }
        assert!(
            m.mesh.uvs.as_ref().is_some_and(|u| u.len() == vertices),
            "{name}: UVs"
        );
        // Garments share the body proxy's frame: each lies within the body's bounds (+5 cm).
        let (lo, hi) = m.mesh.bounds().unwrap();
        let margin = Vec3::repeat(0.05);
        assert!(
            lo.iter()
                .zip((body_lo - margin).iter())
                .all(|(a, b)| a >= b)
                && hi
                    .iter()
                    .zip((body_hi + margin).iter())
                    .all(|(a, b)| a <= b),
            "{name}"
        );
    }
    // Explicit units override detection.
    let m = io::load_obj(
        &asset("garments/makehuman_skirt_from_female_elegantsuit01.obj"),
        &ImportOptions {
            units: Units::Centimetres,
            ..opts()
        },
    )
    .unwrap();
    assert_eq!(m.units, Units::Centimetres);
}

#[test]
fn bad_obj_input_is_a_typed_error_with_line_numbers() {
    let path = asset("garments/makehuman_skirt_from_female_elegantsuit01.obj");
    let text = std::fs::read_to_string(&path).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let first_v = lines.iter().position(|l| l.starts_with("v ")).unwrap();
    let mut bad: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    bad[first_v] = "v 0.1 inf 0.2".into();
    let err = io::load_obj_from_bytes(bad.join("\n").as_bytes(), &path, &opts()).unwrap_err();
    assert!(
        matches!(&err, IoError::NonFinite { what, .. } if what.contains(&format!("line {}", first_v + 1))),
        "{err}"
    );
    assert_names_file(&err, "makehuman_skirt_from_female_elegantsuit01.obj");
    // A face referring past the vertices defined so far.
    let first_f = lines.iter().position(|l| l.starts_with("f ")).unwrap();
    let mut bad: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    bad[first_f] = "f 1 2 99999".into();
    let err = io::load_obj_from_bytes(bad.join("\n").as_bytes(), &path, &opts()).unwrap_err();
    assert!(
        matches!(err, IoError::Syntax { line, .. } if line == first_f + 1),
        "{err}"
    );
    // Truncated mid-file: the vertex list is cut, so faces refer to missing vertices.
    let cut = text.find("\nf ").unwrap() / 2;
    assert!(io::load_obj_from_bytes(&text.as_bytes()[..cut], &path, &opts()).is_err());
}

// inspect.

#[test]
fn inspect_reports_every_asset() {
    for (file, joints, vertices, anims, _) in AVATARS {
        let r = io::inspect(&asset(&format!("avatars/{file}"))).unwrap();
        assert!(r.contains(&format!("joints: {joints}\n")), "{r}");
        assert!(r.contains(&format!("{vertices} vertices")), "{r}");
        assert!(r.contains(&format!("animations: {}\n", anims.len())), "{r}");
    }
    for (file, joints, _, frames) in MOTIONS {
        let r = io::inspect(&asset(&format!("motions/{file}"))).unwrap();
        assert!(
            r.contains(&format!("joints: {joints}\n")) && r.contains(&format!("{frames} frames")),
            "{r}"
        );
        assert!(r.contains("LeftUpLeg"), "{r}");
    }
    for (file, vertices, _) in GARMENTS {
        let r = io::inspect(&asset(&format!("garments/{file}"))).unwrap();
        assert!(
            r.contains(&format!("{vertices} vertices")) && r.contains("decimetres"),
            "{r}"
        );
    }
    assert!(matches!(
        io::inspect(&asset("LICENSES.md")),
        Err(IoError::UnsupportedFormat { .. })
    ));
    assert!(matches!(
        io::inspect(Path::new("../shared/assets/missing.obj")),
        Err(IoError::Read { .. })
    ));
}
