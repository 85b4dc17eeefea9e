//! Garment fitting (issue 13): built-in garments written as OBJ files displaced, scaled by
//! 1.2 and 0.8, in centimetres and mirrored come back to where they were made, with no vertex
//! inside the body; a MakeHuman skirt in decimetres lands on the mannequin's hips; the `fit`
//! command prints what it did; bad input is a clear error naming
//! the file; and training refuses a garment that does not fit, saying what to do.

use std::path::{Path, PathBuf};
use std::process::Command;

use neural_cloth::fit::{FitError, FitLimits, FitOptions, RelaxSettings, check_fit, fit_file};
use neural_cloth::geometry::{TriMesh, Vec3};
use neural_cloth::io::export::obj_seq::obj_text;
use neural_cloth::scene::procedural::{GarmentKind, builtin_garment, mannequin};

use super::{asset, opts};

/// Built-in garments at this resolution (vertices).
const RESOLUTION: usize = 700;

/// Mean and largest distance between corresponding vertices, metres.
fn distances_m(a: &[Vec3], b: &[Vec3]) -> (f32, f32) {
    let d: Vec<f32> = a.iter().zip(b).map(|(p, q)| (p - q).norm()).collect();
    let mean = d.iter().sum::<f32>() / d.len().max(1) as f32;
    (mean, d.iter().copied().fold(0.0, f32::max))
}

/// Writes `mesh` with its positions mapped by `f` as an OBJ in `dir`.
fn write_obj(dir: &Path, name: &str, mesh: &TriMesh, f: impl Fn(Vec3) -> Vec3) -> PathBuf {
    let positions: Vec<Vec3> = mesh.positions.iter().map(|p| f(*p)).collect();
    let path = dir.join(format!("{name}.obj"));
    std::fs::write(&path, obj_text(&positions, &mesh.faces, None, name)).unwrap();
    path
}

/// The transformed copies of a garment: (name, map of positions).
type Case = (&'static str, Box<dyn Fn(Vec3) -> Vec3>);

fn cases(mesh: &TriMesh) -> Vec<Case> {
    let (lo, hi) = mesh.bounds().unwrap();
    let c = (lo + hi) * 0.5;
    vec![
        ("moved", Box::new(|p| p + Vec3::new(0.15, -0.6, 0.25))),
        ("x1.2", Box::new(move |p| c + (p - c) * 1.2)),
        (
            "x0.8",
            Box::new(move |p| c + (p - c) * 0.8 + Vec3::new(0.0, 0.2, 0.0)),
        ),
        ("cm", Box::new(|p| p * 100.0)),
        ("mirrored", Box::new(|p| Vec3::new(-p.x, p.y, p.z))),
    ]
}

#[test]
fn displaced_resized_cm_and_mirrored_builtin_garments_come_back_outside_the_body() {
    let avatar = mannequin().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let aligned_only = FitOptions {
        relax: None,
        ..Default::default()
    };
    for kind in [GarmentKind::TShirt, GarmentKind::Skirt] {
        let original = builtin_garment(&avatar, kind, RESOLUTION, None)
            .unwrap()
            .mesh;
        for (what, f) in cases(&original) {
            let name = format!("{}-{what}", kind.name());
            let path = write_obj(dir.path(), &name, &original, f);
            let t = std::time::Instant::now();
            let fitted = fit_file(&avatar, &path, &aligned_only).unwrap();
            let (mean, max) = distances_m(&fitted.mesh.positions, &original.positions);
            let r = &fitted.report;
            eprintln!(
                "{name}: mean {:.1} mm, max {:.1} mm from the original; units {}, scale {:.4}, \
                 mirrored {}, inside {} given -> {} aligned of {}; {:.1} s",
                mean * 1e3,
                max * 1e3,
                r.units.label(),
                r.placement.scale,
                r.placement.mirrored,
                r.inside_given,
                r.inside_aligned,
                r.vertices,
                t.elapsed().as_secs_f32()
            );
            assert!(
                mean < 0.010 && max < 0.03,
                "{name}: {mean} m mean, {max} m max"
            );
            assert!(r.inside_aligned * 100 <= r.vertices, "{name}: {r:?}");
            assert_eq!(r.placement.mirrored, what == "mirrored", "{name}");
            let units = if what == "cm" {
                "centimetres"
            } else {
                "metres"
            };
            assert_eq!(r.units.label(), units, "{name}");
        }
    }
}

#[test]
fn relaxing_leaves_no_vertex_inside_the_body() {
    let avatar = mannequin().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let options = FitOptions {
        relax: Some(RelaxSettings {
            settle_secs: 0.5,
            ..Default::default()
        }),
        ..Default::default()
    };
    for kind in [GarmentKind::TShirt, GarmentKind::Skirt] {
        let original = builtin_garment(&avatar, kind, RESOLUTION, None)
            .unwrap()
            .mesh;
        // Kept 8 % too small (a fixed scale): the alignment leaves vertices of the shirt inside.
        let path = write_obj(dir.path(), kind.name(), &original, |p| {
            p - Vec3::new(0.0, 0.3, 0.0)
        });
        let t = std::time::Instant::now();
        let small = FitOptions {
            scale: Some(0.92),
            ..options.clone()
        };
        let fitted = fit_file(&avatar, &path, &small).unwrap();
        let r = &fitted.report;
        let (mean, max) = distances_m(&fitted.mesh.positions, &original.positions);
        let (moved, _) = distances_m(&fitted.mesh.positions, &fitted.aligned);
        eprintln!(
            "{}: inside {} given, {} aligned, {:?} relaxed of {}; relaxed {:.1} mm (mean) from \
             the aligned, mean {:.1} max {:.1} mm from the original; {:.1} s",
            kind.name(),
            r.inside_given,
            r.inside_aligned,
            r.inside_relaxed,
            r.vertices,
            moved * 1e3,
            mean * 1e3,
            max * 1e3,
            t.elapsed().as_secs_f32()
        );
        if kind == GarmentKind::TShirt {
            assert!(r.inside_aligned * 50 > r.vertices, "{r:?}");
        }
        let inside = r.inside_relaxed.unwrap();
        assert!(inside * 200 <= r.vertices, "{r:?}");
    }
}

#[test]
fn a_makehuman_skirt_in_decimetres_fits_around_the_mannequins_hips() {
    // Made for MakeHuman's female body (1.6 m, origin mid-body, decimetres); no sleeves, so
    // its T-pose does not matter.
    let avatar = mannequin().unwrap();
    let file = asset("garments/makehuman_skirt_from_female_elegantsuit01.obj");
    let options = FitOptions {
        relax: Some(RelaxSettings {
            settle_secs: 0.5,
            ..Default::default()
        }),
        ..Default::default()
    };
    let fitted = fit_file(&avatar, &file, &options).unwrap();
    let r = &fitted.report;
    let (lo, hi) = fitted.mesh.bounds().unwrap();
    eprintln!("{r:?}: from {lo:?} to {hi:?}");
    assert_eq!(r.units.label(), "decimetres");
    // The mannequin's waist is at about 1.0 m, its knees at 0.5 m.
    assert!(
        (0.9..1.2).contains(&hi.y) && (0.4..0.9).contains(&lo.y),
        "{lo:?} {hi:?}"
    );
    assert!(r.inside_relaxed.unwrap() * 100 <= r.vertices, "{r:?}");
    // What the fit wrote passes the training's check.
    let limits = FitLimits::default();
    let check = check_fit(&avatar, &fitted.mesh, &limits).unwrap();
    assert!(check.problems(&limits).is_empty(), "{check:?}");
}

/// A scene file with the built-in mannequin and walk and the garment file `garment`.
fn scene_with_garment(dir: &Path, garment: &Path) -> PathBuf {
    let scene = dir.join("scene.toml");
    let text = format!(
        "name = \"misfit\"\ntraining_fps = 30.0\n[avatar]\nbuiltin = \"mannequin\"\n\
         [garment]\npath = {:?}\n[[motions]]\nbuiltin = \"walk\"\nduration_secs = 1.0\n",
        garment.display().to_string()
    );
    std::fs::write(&scene, text).unwrap();
    scene
}

#[test]
fn training_refuses_a_garment_that_does_not_fit_and_says_what_to_do() {
    let avatar = mannequin().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let original = builtin_garment(&avatar, GarmentKind::TShirt, RESOLUTION, None)
        .unwrap()
        .mesh;
    // The file's origin mid-body: the shirt lands at the thighs.
    let low = write_obj(dir.path(), "low", &original, |p| {
        p - Vec3::new(0.0, 0.55, 0.0)
    });
    let scene = scene_with_garment(dir.path(), &low);
    let run = Command::new(env!("CARGO_BIN_EXE_neural-cloth"))
        .args(["train", "--steps", "1", "--scene"])
        .arg(&scene)
        .arg("--out")
        .arg(dir.path().join("run"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "{stderr}");
    let fit = format!(
        "neural-cloth fit --avatar mannequin --garment {}",
        low.display()
    );
    for needle in [fit.as_str(), "--skip-fit-check", "inside the body"] {
        assert!(stderr.contains(needle), "no '{needle}' in:\n{stderr}");
    }
    assert_eq!(stderr.matches("does not fit avatar").count(), 1, "{stderr}");
    // The check itself, and the fitted garment passing it.
    let limits = FitLimits::default();
    let mut mesh = original.clone();
    mesh.map_positions(|p| p - Vec3::new(0.0, 0.55, 0.0));
    let check = check_fit(&avatar, &mesh, &limits).unwrap();
    eprintln!("{check:?}: {:?}", check.problems(&limits));
    assert!(!check.problems(&limits).is_empty());
    let fitted = fit_file(&avatar, &low, &FitOptions::default()).unwrap();
    let check = check_fit(&avatar, &fitted.mesh, &limits).unwrap();
    assert!(check.problems(&limits).is_empty(), "{check:?}");
}

#[test]
fn a_garment_far_from_the_body_is_refused_with_the_fit_command_issue_13() {
    let avatar = mannequin().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let original = builtin_garment(&avatar, GarmentKind::TShirt, RESOLUTION, None)
        .unwrap()
        .mesh;
    // Moved 3 m to the side: too far to bind, so even --skip-fit-check cannot train it.
    let far = write_obj(dir.path(), "far", &original, |p| {
        p + Vec3::new(3.0, 0.0, 0.0)
    });
    let scene = scene_with_garment(dir.path(), &far);
    let run = Command::new(env!("CARGO_BIN_EXE_neural-cloth"))
        .args(["train", "--steps", "1", "--skip-fit-check", "--scene"])
        .arg(&scene)
        .arg("--out")
        .arg(dir.path().join("run"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "{stderr}");
    let fitted = dir.path().join("far-fitted.obj");
    let fit = format!(
        "`neural-cloth fit --avatar mannequin --garment {} --out {}`",
        far.display(),
        fitted.display()
    );
    for needle in [
        "invalid garment 'far': a vertex is",
        fit.as_str(),
        "not even with --skip-fit-check",
    ] {
        assert_eq!(
            stderr.matches(needle).count(),
            1,
            "'{needle}' in:\n{stderr}"
        );
    }
    let line = stderr.lines().find(|l| l.starts_with("error:")).unwrap();
    assert!(line.ends_with(&format!(": {}", far.display())), "{line}");
    assert!(!dir.path().join("run").exists());
}

#[test]
fn a_garment_that_cannot_wrap_the_body_is_an_error_naming_the_file() {
    let avatar = mannequin().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let original = builtin_garment(&avatar, GarmentKind::TShirt, RESOLUTION, None)
        .unwrap()
        .mesh;
    let path = write_obj(dir.path(), "shirt", &original, |p| p);
    // Placed by hand 3 m to the side: no overlap with the body at all.
    let options = FitOptions {
        scale: Some(1.0),
        offset_m: Some(Vec3::new(3.0, 0.0, 0.0)),
        relax: None,
        ..Default::default()
    };
    let err = fit_file(&avatar, &path, &options).unwrap_err();
    assert!(matches!(err, FitError::NoFit { .. }), "{err}");
    let text = err.to_string();
    assert!(text.ends_with(&path.display().to_string()), "{text}");
    assert!(text.contains("does not overlap the body"), "{text}");
    // The front half of the shirt, a flat-ish sheet: it cannot go around the body.
    let front: Vec<[u32; 3]> = original
        .faces
        .iter()
        .copied()
        .filter(|f| f.iter().all(|&v| original.positions[v as usize].z > 0.02))
        .collect();
    let mut index = vec![u32::MAX; original.positions.len()];
    let mut positions = Vec::new();
    let faces: Vec<[u32; 3]> = front
        .iter()
        .map(|f| {
            f.map(|v| {
                if index[v as usize] == u32::MAX {
                    index[v as usize] = positions.len() as u32;
                    positions.push(original.positions[v as usize]);
                }
                index[v as usize]
            })
        })
        .collect();
    let sheet = TriMesh::new(positions, faces).unwrap();
    let path = write_obj(dir.path(), "sheet", &sheet, |p| p);
    let err = fit_file(&avatar, &path, &FitOptions::default()).unwrap_err();
    let text = err.to_string();
    assert!(text.contains("does not go around the body"), "{text}");
    assert!(text.ends_with(&path.display().to_string()), "{text}");
}

#[test]
fn the_fit_command_writes_the_fitted_garment_and_says_what_it_did() {
    let avatar = mannequin().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let original = builtin_garment(&avatar, GarmentKind::TShirt, RESOLUTION, None)
        .unwrap()
        .mesh;
    let path = write_obj(dir.path(), "shirt-cm", &original, |p| {
        (p + Vec3::new(0.0, -0.7, 0.1)) * 100.0
    });
    let out = dir.path().join("fitted.obj");
    let run = Command::new(env!("CARGO_BIN_EXE_neural-cloth"))
        .args(["fit", "--avatar", "mannequin", "--garment"])
        .arg(&path)
        .arg("--out")
        .arg(&out)
        .args(["--relax-secs", "0.2"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stdout}\n{stderr}");
    eprintln!("{stdout}");
    for needle in [
        "units:   centimetres",
        "scale:   1.000",
        "vertices inside the body:",
        "wrote",
    ] {
        assert!(stdout.contains(needle), "no '{needle}' in:\n{stdout}");
    }
    let fitted = neural_cloth::io::load_obj(&out, &opts()).unwrap().mesh;
    assert_eq!(fitted.faces, original.faces);
    let (mean, _) = distances_m(&fitted.positions, &original.positions);
    assert!(mean < 0.03, "{mean} m");
    // No overlap: a clear error naming the file, nothing written.
    let bad_out = dir.path().join("bad.obj");
    let run = Command::new(env!("CARGO_BIN_EXE_neural-cloth"))
        .args(["fit", "--avatar", "mannequin", "--garment"])
        .arg(&path)
        .arg("--out")
        .arg(&bad_out)
        .args(["--scale", "1", "--offset", "0,5,0", "--no-relax"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(stderr.contains("does not overlap the body"), "{stderr}");
    assert!(stderr.contains(&path.display().to_string()), "{stderr}");
    assert!(!bad_out.exists());
}
