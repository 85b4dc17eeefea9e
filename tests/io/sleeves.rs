//! Garments made for another limb pose (issue 13): the built-in t-shirt skinned onto the
//! mannequin with its arms raised to a T-pose, written as an OBJ in centimetres and 30 cm too
//! low, is fitted back onto the A-pose mannequin with its sleeves re-posed (by the library and
//! by `fit`, which says so; `--no-repose` keeps them and says that too); shorts made on the
//! mannequin standing with its feet apart are fitted back with their legs re-posed; the
//! training's preflight names both mismatches.

use std::process::Command;

use neural_cloth::fit::repose::Limbs;
use neural_cloth::fit::{FitLimits, FitOptions, RelaxSettings, check_fit, fit_file};
use neural_cloth::geometry::{TriMesh, Vec3};
use neural_cloth::io::Units;
use neural_cloth::io::export::obj_seq::obj_text;
use neural_cloth::physics::PosedBody;
use neural_cloth::scene::procedural::{GarmentKind, builtin_garment, mannequin};

/// Mean distance between corresponding vertices, metres.
fn mean_m(a: &[Vec3], b: &[Vec3]) -> f32 {
    a.iter().zip(b).map(|(p, q)| (p - q).norm()).sum::<f32>() / a.len().max(1) as f32
}

/// Largest distance between corresponding vertices, metres.
fn max_m(a: &[Vec3], b: &[Vec3]) -> f32 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, f32::max)
}

/// The built-in t-shirt (A-pose) and the same shirt on the mannequin with its arms raised
/// `degrees` (42: straight out, a T-pose).
fn shirts(degrees: f32) -> (TriMesh, TriMesh) {
    let avatar = mannequin().unwrap();
    let shirt = builtin_garment(&avatar, GarmentKind::TShirt, 700, None).unwrap();
    let arms = Limbs::arms(&avatar).unwrap();
    let mut raised = shirt.mesh.clone();
    raised.positions = shirt.pose_vertices(&avatar, &arms.pose(&avatar, degrees));
    (shirt.mesh, raised)
}

#[test]
fn a_t_pose_shirt_is_re_posed_onto_the_a_pose_mannequin() {
    let avatar = mannequin().unwrap();
    let (original, t_shirt) = shirts(42.0);
    assert!(max_m(&original.positions, &t_shirt.positions) > 0.1);
    let dir = tempfile::tempdir().unwrap();
    let low: Vec<Vec3> = t_shirt
        .positions
        .iter()
        .map(|p| (p - Vec3::new(0.0, 0.3, 0.0)) * 100.0)
        .collect();
    let path = dir.path().join("t_shirt_cm.obj");
    std::fs::write(&path, obj_text(&low, &t_shirt.faces, None, "t")).unwrap();
    let options = FitOptions {
        relax: Some(RelaxSettings {
            settle_secs: 0.5,
            ..Default::default()
        }),
        ..Default::default()
    };
    let fitted = fit_file(&avatar, &path, &options).unwrap();
    let r = &fitted.report;
    assert!(r.reposed && (r.sleeves_deg - 42.0).abs() <= 5.0, "{r:?}");
    let (mean, max) = (
        mean_m(&fitted.aligned, &original.positions),
        max_m(&fitted.aligned, &original.positions),
    );
    assert!(
        mean < 0.015 && max < 0.04,
        "re-posed {mean} m (mean), {max} m (max) from the A-pose shirt: {r:?}"
    );
    let inside = r.inside_relaxed.unwrap();
    assert!(inside * 200 <= r.vertices, "{r:?}");
    // Without re-posing the sleeves stay up, and the report says where they point.
    let kept = fit_file(
        &avatar,
        &path,
        &FitOptions {
            repose: false,
            relax: None,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(!kept.report.reposed && kept.report.sleeves_deg > 30.0);
    assert!(max_m(&kept.aligned, &original.positions) > 0.1);
}

#[test]
fn the_fit_command_and_the_preflight_say_the_sleeves_were_made_for_other_arms() {
    let avatar = mannequin().unwrap();
    let (original, t_shirt) = shirts(42.0);
    // The preflight, on the T-pose shirt in place.
    let limits = FitLimits::default();
    let problems = check_fit(&avatar, &t_shirt, &limits)
        .unwrap()
        .problems(&limits);
    assert!(
        problems
            .iter()
            .any(|p| p.contains("sleeves were made") && p.contains("degrees above")),
        "{problems:?}"
    );
    let check = check_fit(&avatar, &original, &limits).unwrap();
    assert_eq!(check.sleeves_deg, 0.0, "{check:?}");
    // The command.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t_shirt.obj");
    std::fs::write(
        &path,
        obj_text(&t_shirt.positions, &t_shirt.faces, None, "t"),
    )
    .unwrap();
    let run = |extra: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_neural-cloth"))
            .args(["fit", "--avatar", "mannequin", "--no-relax", "--garment"])
            .arg(&path)
            .arg("--out")
            .arg(dir.path().join("out.obj"))
            .args(extra)
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
        assert!(
            out.status.success(),
            "{stdout}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        stdout
    };
    let text = run(&[]);
    assert!(
        text.contains("sleeves: made") && text.contains("re-posed to its rest pose"),
        "{text}"
    );
    let text = run(&["--no-repose"]);
    assert!(text.contains("not re-posed (--no-repose)"), "{text}");
}

/// Shorts cut from the mannequin's own surface (the band from 0.3 m below to 0.08 m above the
/// hip joints, the arms and hands left out, pushed out by the fit's 15 mm ease): on the
/// rest pose, and on the mannequin with its thighs spread `degrees` apart.
fn shorts(degrees: f32) -> (TriMesh, TriMesh) {
    let avatar = mannequin().unwrap();
    let sk = &avatar.skeleton;
    let legs = Limbs::legs(&avatar).unwrap();
    let arms = Limbs::arms(&avatar).unwrap().moved_joints(sk);
    let hip_y = sk.joint_positions(&sk.rest_pose())[legs.joints()[0]].y;
    let at = |pose| {
        let body = PosedBody::from_avatar(&avatar, &pose).unwrap();
        body.positions()
            .iter()
            .zip(body.normals())
            .map(|(p, n)| p + n * 0.015)
            .collect::<Vec<Vec3>>()
    };
    let rest = at(sk.rest_pose());
    let keep: Vec<bool> = (0..rest.len())
        .map(|v| {
            let skin = &avatar.skin;
            let on_arm: f32 = skin.joints[v]
                .iter()
                .zip(skin.weights[v])
                .filter(|(j, _)| arms[usize::from(**j)])
                .map(|(_, w)| w)
                .sum();
            let y = avatar.bind_mesh.positions[v].y;
            on_arm < 0.01 && y > hip_y - 0.3 && y < hip_y + 0.15
        })
        .collect();
    let mut index = vec![u32::MAX; rest.len()];
    let mut kept = Vec::new();
    for v in (0..rest.len()).filter(|&v| keep[v]) {
        index[v] = kept.len() as u32;
        kept.push(v);
    }
    let faces: Vec<[u32; 3]> = avatar
        .bind_mesh
        .faces
        .iter()
        .filter(|f| f.iter().all(|&v| keep[v as usize]))
        .map(|f| f.map(|v| index[v as usize]))
        .collect();
    let mesh =
        |all: &[Vec3]| TriMesh::new(kept.iter().map(|&v| all[v]).collect(), faces.clone()).unwrap();
    (mesh(&rest), mesh(&at(legs.pose(&avatar, degrees))))
}

#[test]
fn shorts_made_with_the_feet_apart_are_re_posed_onto_the_mannequin() {
    let avatar = mannequin().unwrap();
    let (original, spread) = shorts(15.0);
    assert!(max_m(&original.positions, &spread.positions) > 0.05);
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, mesh: &TriMesh| {
        let path = dir.path().join(name);
        std::fs::write(&path, obj_text(&mesh.positions, &mesh.faces, None, "s")).unwrap();
        path
    };
    // The spread shorts as a file in centimetres, 20 cm too low.
    let mut moved = spread.clone();
    moved.map_positions(|p| (p - Vec3::new(0.0, 0.2, 0.0)) * 100.0);
    let (spread_path, original_path) = (
        write("spread_cm.obj", &moved),
        write("shorts.obj", &original),
    );
    let options = FitOptions {
        relax: None,
        ..Default::default()
    };
    let fitted = fit_file(&avatar, &spread_path, &options).unwrap();
    let r = &fitted.report;
    assert_eq!(r.units, Units::Centimetres, "{r:?}");
    let legs = r.legs_deg.unwrap();
    assert!(
        r.reposed && (legs - 15.0).abs() <= 2.5 && r.sleeves_deg == 0.0,
        "{r:?}"
    );
    let (mean, max) = (
        mean_m(&fitted.aligned, &original.positions),
        max_m(&fitted.aligned, &original.positions),
    );
    assert!(
        mean < 0.01 && max < 0.04,
        "re-posed {mean} m (mean), {max} m (max) from the shorts: {r:?}"
    );
    // The shorts made for the mannequin's own stance keep their legs.
    let kept = fit_file(&avatar, &original_path, &options).unwrap();
    assert_eq!(kept.report.legs_deg, Some(0.0), "{:?}", kept.report);
    assert!(!kept.report.reposed);
    // A skirt has no leg openings: its legs are not measured.
    let skirt = builtin_garment(&avatar, GarmentKind::Skirt, 600, None).unwrap();
    let skirt_path = write("skirt.obj", &skirt.mesh);
    let skirt = fit_file(&avatar, &skirt_path, &options).unwrap();
    assert_eq!(skirt.report.legs_deg, None, "{:?}", skirt.report);
    // The preflight names the stance; the shorts that match pass.
    let limits = FitLimits::default();
    let problems = check_fit(&avatar, &spread, &limits)
        .unwrap()
        .problems(&limits);
    assert!(
        problems
            .iter()
            .any(|p| p.contains("legs were made") && p.contains("wider apart")),
        "{problems:?}"
    );
    let problems = check_fit(&avatar, &original, &limits)
        .unwrap()
        .problems(&limits);
    assert!(problems.is_empty(), "{problems:?}");
    // The command says what it did.
    let out = Command::new(env!("CARGO_BIN_EXE_neural-cloth"))
        .args(["fit", "--avatar", "mannequin", "--no-relax", "--garment"])
        .arg(&spread_path)
        .arg("--out")
        .arg(dir.path().join("out.obj"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(
        text.contains("legs:    made ")
            && text.contains("degrees wider apart than the avatar's; re-posed"),
        "{text}"
    );
}
