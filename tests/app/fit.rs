//! "Fit garment" (issue 13): a garment file in centimetres, 70 cm too low to even load onto
//! the mannequin, is fitted on the fit thread from the typed path; the fitted copy is written
//! beside it and becomes the scene's garment, shown on the avatar before any training.

use std::time::{Duration, Instant};

use neural_cloth::geometry::Vec3;
use neural_cloth::io::export::obj_seq::obj_text;
use neural_cloth::scene::procedural::{GarmentKind, builtin_garment, mannequin};

use neural_cloth::app::LoadKind;

use super::{click, harness};

#[test]
fn fit_garment_fits_a_garment_that_did_not_load_and_shows_it() {
    let dir = tempfile::tempdir().expect("temp dir");
    let avatar = mannequin().expect("mannequin");
    let shirt = builtin_garment(&avatar, GarmentKind::TShirt, 600, None).expect("shirt");
    let moved: Vec<Vec3> = shirt
        .mesh
        .positions
        .iter()
        .map(|p| (p - Vec3::new(0.0, 0.7, 0.0)) * 100.0)
        .collect();
    let file = dir.path().join("low_shirt.obj");
    std::fs::write(&file, obj_text(&moved, &shirt.mesh.faces, None, "low")).expect("write");
    let mut h = harness(None);
    h.state_mut().state.typed.garment = file.display().to_string();
    h.run();
    click(&mut h, "Fit garment");
    let start = Instant::now();
    while h.state().state.scene_file(LoadKind::Garment)
        != Some(dir.path().join("low_shirt-fitted.obj"))
    {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "the fit did not finish"
        );
        std::thread::sleep(Duration::from_millis(50));
        h.step();
    }
    h.run();
    let app = h.state();
    let garment = app.state.scene.garment.clone().expect("a garment");
    assert_eq!(garment.vertex_count(), shirt.vertex_count());
    let mean = garment
        .mesh
        .positions
        .iter()
        .zip(&shirt.mesh.positions)
        .map(|(p, q)| (p - q).norm())
        .sum::<f32>()
        / shirt.vertex_count() as f32;
    assert!(
        mean < 0.01,
        "the fitted shirt is {mean} m from where it was made"
    );
    let info = app
        .state
        .messages
        .iter()
        .any(|m| m.text.contains("fitted garment written") && m.text.contains("centimetres"));
    assert!(info, "{:?}", app.state.messages);
}
