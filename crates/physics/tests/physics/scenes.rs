//! The reference simulator on the built-in scene: drape the default t-shirt on the still
//! mannequin, spin with a skirt.

use std::sync::Arc;

use burn::tensor::Device;
use neural_cloth_core::geometry::Vec3;
use neural_cloth_core::scene::Motion;
use neural_cloth_core::scene::procedural::{
    GarmentKind, MotionKind, builtin_garment, builtin_motion, default_scene, mannequin,
};
use neural_cloth_physics::metrics::sequence_metrics;
use neural_cloth_physics::simulator::{SimOptions, simulate};
use neural_cloth_physics::{FabricParams, PhysicsTerms, PosedBody};

#[test]
fn reference_simulator_drapes_the_default_tshirt_on_the_still_mannequin() {
    let scene = default_scene().unwrap();
    let fabric = scene.fabric.clone();
    let device = Device::flex();
    let pose = scene.avatar.skeleton.rest_pose();
    // 10 fps: large implicit steps damp the slow stretch oscillation of the soft default
    // fabric, so 3 s reach rest.
    let fps = 10.0;
    let motion = Motion::still("still", pose.clone(), fps, 31);
    let options = SimOptions {
        iterations_per_step: 25,
        ..SimOptions::default()
    };
    let sim = simulate(
        &scene.avatar,
        &scene.garment,
        &fabric,
        &scene.effects,
        &motion,
        fps,
        &options,
        &device,
        &mut |_| true,
    )
    .unwrap();
    assert_eq!(sim.frames.len(), motion.frames.len());
    let terms = PhysicsTerms::new(&scene.garment, &fabric, &scene.effects, &device).unwrap();
    let body = Arc::new(PosedBody::from_avatar(&scene.avatar, &pose).unwrap());
    let bodies = vec![body; sim.frames.len()];
    let m = sequence_metrics(&terms, &sim.frames, Some(&bodies), 1.0 / fps).unwrap();
    let gravity: Vec<f64> = m.iter().map(|m| m.gravity_j).collect();
    let (first, last) = (gravity[0], gravity[gravity.len() - 1]);
    let late_change = (last - gravity[gravity.len() - 6]).abs();
    eprintln!(
        "t-shirt drape: gravity {first:.5} -> {last:.5} J, last 5 frames {late_change:.2e} J, inside {:?} %",
        m.last().and_then(|m| m.collision_pct)
    );
    assert!(
        last < first,
        "the t-shirt should settle downwards: {gravity:?}"
    );
    assert!(
        late_change < 0.05 * (first - last),
        "gravity energy has not plateaued: {gravity:?}"
    );
    let inside = m.last().and_then(|m| m.collision_pct).unwrap();
    assert!(inside < 0.5, "{inside} % of vertices inside the body");
    assert!(
        sim.reports
            .iter()
            .all(|r| r.residual.is_finite() && r.objective_j.is_finite())
    );
    // The solver converges: the residual force at the end is far below the first frame's.
    let (r0, r1) = (
        sim.reports[0].residual,
        sim.reports[sim.reports.len() - 1].residual,
    );
    eprintln!("residual (force / mean vertex weight): frame 0 {r0:.2}, last {r1:.2}");
    assert!(r1 < 0.5 * r0, "{r0} -> {r1}");
}

#[test]
fn reference_simulator_spins_a_skirt_open() {
    let avatar = mannequin().unwrap();
    let mut skirt = builtin_garment(&avatar, GarmentKind::Skirt, 1200, None).unwrap();
    // The waistband (top 1.5 cm) is held by the body, like an elastic band: pin it.
    let top = skirt
        .mesh
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f32::MIN, f32::max);
    skirt.pinned = (0..skirt.vertex_count() as u32)
        .filter(|&i| skirt.mesh.positions[i as usize].y >= top - 0.015)
        .collect();
    assert!(
        skirt.pinned.len() >= 8,
        "waistband: {} vertices",
        skirt.pinned.len()
    );
    let fabric = FabricParams::default();
    let effects = neural_cloth_physics::Effects {
        pinning: true,
        ..Default::default()
    };
    let device = Device::flex();
    let fps = 30.0;
    let spin = builtin_motion(MotionKind::Spin, fps, 1.5, 1.0, None, None).unwrap();
    let still = Motion::still("still", spin.frames[0].clone(), fps, spin.frames.len());
    let options = SimOptions {
        iterations_per_step: 20,
        settle_secs: 0.3,
        ..SimOptions::default()
    };
    let run = |m: &Motion| {
        simulate(
            &avatar,
            &skirt,
            &fabric,
            &effects,
            m,
            fps,
            &options,
            &device,
            &mut |_| true,
        )
        .unwrap()
    };
    let (spun, rested) = (run(&spin), run(&still));
    // Hem: the lowest fifth of the template; radius about the spin axis through the root.
    let mut heights: Vec<f32> = skirt.mesh.positions.iter().map(|p| p.y).collect();
    heights.sort_by(f32::total_cmp);
    let cut = heights[heights.len() / 5];
    let hem: Vec<usize> = (0..skirt.vertex_count())
        .filter(|&i| skirt.mesh.positions[i].y <= cut)
        .collect();
    let radius = |frame: &[Vec3], k: usize, motion: &Motion| {
        let axis = avatar
            .skeleton
            .joint_positions(&motion.frames[k.min(motion.frames.len() - 1)])[0];
        hem.iter()
            .map(|&i| (frame[i] - axis).xz().norm())
            .sum::<f32>()
            / hem.len() as f32
    };
    let n = spun.frames.len();
    let avg = |sim: &neural_cloth_physics::Simulation, m: &Motion| {
        (n - 10..n)
            .map(|k| radius(&sim.frames[k], k, m))
            .sum::<f32>()
            / 10.0
    };
    let (open, closed) = (avg(&spun, &spin), avg(&rested, &still));
    eprintln!("skirt hem radius: still {closed:.4} m, spinning {open:.4} m");
    assert!(
        open > 1.1 * closed,
        "the spinning skirt should open outwards: {open} vs {closed}"
    );
    let highest = |sim: &neural_cloth_physics::Simulation| {
        hem.iter().map(|&i| sim.frames[n - 1][i].y).sum::<f32>() / hem.len() as f32
    };
    assert!(
        highest(&spun) > highest(&rested),
        "a spinning skirt rises against gravity"
    );
}

/// Yaw of a sheet draped on a spinning sphere after `spin_frames` frames at `omega` rad/s
/// (after 10 frames of settling), relative to the centre: mean over vertices of the change of
/// their azimuth, radians.
fn sheet_yaw_on_spinning_sphere(friction: bool, omega: f32, spin_frames: usize) -> f32 {
    use neural_cloth_core::geometry::Quat;
    use neural_cloth_physics::shapes::{sheet, uv_sphere};
    use neural_cloth_physics::simulator::{StepInput, Stepper};

    use super::common::{all_effects, rest_of};

    let c0 = Vec3::new(0.0, 1.0, 0.0);
    let radius = 0.25;
    let body0 = uv_sphere(c0, radius, 12, 18);
    let size = 0.4;
    let mesh = sheet(
        8,
        8,
        c0 + Vec3::new(-size / 2.0, radius + 0.003, size / 2.0),
        Vec3::x() * size,
        -Vec3::z() * size,
    );
    let fabric = FabricParams::default();
    let rest = rest_of(&mesh, &[], &[], &fabric);
    let effects = neural_cloth_physics::Effects {
        pinning: false,
        friction,
        ..all_effects()
    };
    let fps = 30.0;
    let options = SimOptions {
        iterations_per_step: 30,
        ..SimOptions::default()
    };
    let mut stepper = Stepper::new(
        rest,
        &fabric,
        &effects,
        &mesh.positions,
        1.0 / fps,
        &options,
        &Device::flex(),
    )
    .unwrap();
    let settle = 10;
    let mut start = Vec::new();
    let mut x = Vec::new();
    for k in 0..settle + spin_frames {
        let angle = omega * (k.saturating_sub(settle) as f32) / fps;
        let rot = Quat::from_axis_angle(&Vec3::y_axis(), angle);
        let positions = body0
            .positions
            .iter()
            .map(|p| c0 + rot * (p - c0))
            .collect();
        let body = PosedBody::new(positions, &body0.faces).unwrap();
        let input = StepInput {
            body: Some(Arc::new(body)),
            ..Default::default()
        };
        x = stepper.step(&input).unwrap().0;
        if k + 1 == settle {
            start = x.clone();
        }
    }
    let azimuth = |p: &Vec3| (p.z - c0.z).atan2(p.x - c0.x);
    let turns: Vec<f32> = start
        .iter()
        .zip(&x)
        .filter(|(a, _)| (a.x - c0.x).hypot(a.z - c0.z) > 0.05)
        .map(|(a, b)| {
            let d = azimuth(a) - azimuth(b);
            d.sin().atan2(d.cos())
        })
        .collect();
    turns.iter().sum::<f32>() / turns.len().max(1) as f32
}

/// Friction carries cloth along with a turning body where frictionless contact lets it slip
/// (the frictionless simulator's t-shirt lags the spinning mannequin, docs/TRAINING.md round 5).
#[test]
fn friction_turns_a_draped_sheet_with_its_spinning_body() {
    let (omega, frames) = (2.0, 15);
    let body_turn = omega * frames as f32 / 30.0;
    let with = sheet_yaw_on_spinning_sphere(true, omega, frames);
    let without = sheet_yaw_on_spinning_sphere(false, omega, frames);
    eprintln!("sheet yaw: body {body_turn:.3} rad, friction {with:.3}, frictionless {without:.3}");
    assert!(with.is_finite() && without.is_finite());
    assert!(
        with > 0.5 * body_turn,
        "with friction the sheet turned {with} rad of the body's {body_turn}"
    );
    assert!(
        without.abs() < 0.5 * with,
        "frictionless, the sheet turned {without} rad against {with} with friction"
    );
}

#[test]
fn a_step_from_a_set_history_is_the_step_the_stepper_took() {
    use neural_cloth_physics::simulator::StepInput;

    let (_, new_stepper) = falling_sheet();
    let mut falling = new_stepper();
    let input = StepInput::default();
    let frames: Vec<Vec<Vec3>> = (0..4).map(|_| falling.step(&input).unwrap().0).collect();
    let mut fresh = new_stepper();
    fresh.set_history(&frames[1], &frames[2]).unwrap();
    let (x, _) = fresh.step(&input).unwrap();
    let far = x
        .iter()
        .zip(&frames[3])
        .map(|(a, b)| (a - b).norm())
        .fold(0.0f32, f32::max);
    assert!(far < 1e-6, "{far} m from the step taken in sequence");
    // Falling, the history matters: from rest at the same place the step falls less far.
    fresh.set_history(&frames[2], &frames[2]).unwrap();
    let (from_rest, _) = fresh.step(&input).unwrap();
    assert!(
        from_rest[0].y > x[0].y + 1e-4,
        "{} against {}",
        from_rest[0].y,
        x[0].y
    );
    assert!(fresh.set_history(&frames[1][1..], &frames[2]).is_err());
    let mut broken = frames[2].clone();
    broken[3].x = f32::NAN;
    assert!(fresh.set_history(&frames[1], &broken).is_err());
}

#[test]
fn a_start_jitter_moves_the_garment_by_at_most_its_amplitude_and_keeps_its_velocity() {
    use neural_cloth_physics::simulator::{StepInput, start_jitter};

    let jitter = start_jitter(50, 1e-6);
    assert_eq!(jitter, start_jitter(50, 1e-6), "the same on every call");
    let largest = jitter
        .iter()
        .flat_map(|p| p.iter().map(|c| c.abs()))
        .fold(0.0f32, f32::max);
    assert!(
        largest <= 1e-6 && largest > 5e-7,
        "largest coordinate {largest}"
    );
    assert!(
        jitter.windows(2).all(|w| w[0] != w[1]),
        "each vertex its own"
    );

    let (mesh, new_stepper) = falling_sheet();
    let input = StepInput::default();
    let (mut plain, mut moved) = (new_stepper(), new_stepper());
    for _ in 0..3 {
        plain.step(&input).unwrap();
        moved.step(&input).unwrap();
    }
    // A rigid shift of a falling sheet without a body falls exactly as before, shifted: the
    // velocity is kept (moving only the last frame would change it by 1 cm / Δt).
    let shift = vec![Vec3::new(0.01, 0.0, 0.0); mesh.positions.len()];
    moved.displace(&shift).unwrap();
    let (a, _) = plain.step(&input).unwrap();
    let (b, _) = moved.step(&input).unwrap();
    let off = a
        .iter()
        .zip(&b)
        .map(|(a, b)| (b - a - shift[0]).norm())
        .fold(0.0f32, f32::max);
    assert!(off < 1e-5, "{off} m from the shifted step");
    assert!(moved.displace(&shift[1..]).is_err());
    let mut broken = shift.clone();
    broken[2].y = f32::INFINITY;
    assert!(moved.displace(&broken).is_err());
    let bad = SimOptions {
        start_jitter_m: 0.1,
        ..SimOptions::default()
    };
    assert!(bad.validate().is_err(), "10 cm is not a jitter");
}

/// A 6 x 6 sheet 1 m up without a body (collision, pinning and friction off) and a maker of
/// steppers that start it at rest, at 30 fps with 20 iterations a step.
fn falling_sheet() -> (
    neural_cloth_core::geometry::TriMesh,
    impl Fn() -> neural_cloth_physics::simulator::Stepper,
) {
    use neural_cloth_physics::shapes::sheet;
    use neural_cloth_physics::simulator::Stepper;

    use super::common::{all_effects, rest_of};

    let mesh = sheet(
        6,
        6,
        Vec3::new(-0.2, 1.0, 0.2),
        Vec3::x() * 0.4,
        -Vec3::z() * 0.4,
    );
    let fabric = FabricParams::default();
    let effects = neural_cloth_physics::Effects {
        collision: false,
        pinning: false,
        friction: false,
        ..all_effects()
    };
    let options = SimOptions {
        iterations_per_step: 20,
        ..SimOptions::default()
    };
    let rest = rest_of(&mesh, &[], &[], &fabric);
    let start = mesh.positions.clone();
    let new_stepper = move || {
        Stepper::new(
            rest.clone(),
            &fabric,
            &effects,
            &start,
            1.0 / 30.0,
            &options,
            &Device::flex(),
        )
        .unwrap()
    };
    (mesh, new_stepper)
}
