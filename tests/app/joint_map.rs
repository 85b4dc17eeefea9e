//! The Scene section's joint map field (issue 13): a typed joint map is checked when its field
//! is left (one that does not parse is shown under the field, once), applied to the motions
//! loaded next and recorded with them in the scene description; a map naming a joint the
//! motion lacks refuses the motion, with the error under the field.

use egui::accesskit::Role;
use egui_kittest::kittest::Queryable;

use neural_cloth::io::bvh_write::bvh_text;
use neural_cloth::scene::config::MotionSource;
use neural_cloth::scene::procedural::{MotionKind, mannequin};

use super::{click, harness};

#[test]
fn a_typed_joint_map_is_checked_shown_and_applied_to_motions() {
    let dir = tempfile::tempdir().expect("temp dir");
    // The built-in walk as a BVH whose arms carry names no convention knows.
    let avatar = mannequin().expect("mannequin");
    let sk = &avatar.skeleton;
    let walk = neural_cloth::scene::procedural::motion(MotionKind::Walk, 30.0, 1.0).expect("walk");
    let mut names = sk.names.clone();
    for (joint, name) in [("LeftArm", "bone_07"), ("RightArm", "bone_11")] {
        names[sk.index_of(joint).expect("joint")] = name.into();
    }
    let clip = dir.path().join("odd.bvh");
    std::fs::write(
        &clip,
        bvh_text(sk, &walk, &names, 100.0, &clip).expect("bvh"),
    )
    .expect("write");
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "joints = 3\n").expect("write");

    let mut h = harness(None);
    let motions_before = h.state().state.scene.avatar.motions.len();
    // Typing a map that does not parse and leaving the field shows why, under the field, once.
    h.get_by_role_and_label(Role::TextInput, "Joint map")
        .scroll_to_me();
    h.run();
    h.get_by_role_and_label(Role::TextInput, "Joint map")
        .click();
    h.run();
    h.get_by_role_and_label(Role::TextInput, "Joint map")
        .type_text(&bad.display().to_string());
    h.run();
    h.key_press(egui::Key::Enter);
    h.run();
    let error = h
        .state()
        .state
        .typed
        .joint_map_error
        .clone()
        .expect("the map is refused");
    assert!(
        error.contains("[joints]") && error.ends_with("bad.toml"),
        "{error}"
    );
    assert_eq!(h.get_all_by_label_contains("bad.toml").count(), 1);

    // A map naming a joint the motion lacks: the motion is refused, the error under the field.
    let map = dir.path().join("map.toml");
    std::fs::write(&map, "[joints]\nLeftArm = \"bone_7\"\n").expect("write");
    h.state_mut().state.typed.joint_map = map.display().to_string();
    h.state_mut().state.typed.motion = clip.display().to_string();
    h.run();
    click(&mut h, "Load motion");
    h.run();
    let app = h.state();
    assert_eq!(app.state.scene.avatar.motions.len(), motions_before);
    let error = app
        .state
        .typed
        .joint_map_error
        .clone()
        .expect("the motion is refused");
    assert!(
        error.contains("'bone_7'") && error.contains("bone_07") && error.ends_with("map.toml"),
        "{error}"
    );
    assert_eq!(
        h.get_all_by_label_contains("'bone_7'").count(),
        2,
        "the error is shown under the field and in the status line, not again in the Scene \
         section's error line"
    );

    // A good map: the motion loads, retargeted with it, and the description records it.
    std::fs::write(
        &map,
        "[joints]\nLeftArm = \"bone_07\"\nRightArm = \"bone_11\"\n",
    )
    .expect("write");
    click(&mut h, "Load motion");
    h.run();
    let app = h.state();
    assert_eq!(
        app.state.scene.avatar.motions.len(),
        motions_before + 1,
        "{:?}",
        app.state.last_error()
    );
    assert!(app.state.typed.joint_map_error.is_none());
    let recorded = app.state.scene.config.motions.iter().any(|m| {
        matches!(m, MotionSource::File { path, joint_map: Some(j), .. }
            if path.ends_with("odd.bvh") && j.ends_with("map.toml"))
    });
    assert!(recorded, "{:?}", app.state.scene.config.motions);
    assert!(
        !app.state
            .messages
            .iter()
            .any(|m| m.text.contains("skeletons' structure")),
        "the map, not the structure, maps the arms: {:?}",
        app.state.messages
    );
}
