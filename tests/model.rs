//! Integration tests of the model layer: descriptors, the burn network, tensor skinning and
//! the plain-Rust inference engine, on a small mannequin-like avatar with a tube garment.

use burn::tensor::{Device, Tensor, TensorData};
use neural_cloth::geometry::{Mat4, Quat, SkinWeights, TriMesh, Vec3, rotation_to_6d};
use neural_cloth::model::descriptors::{DYNAMIC_DIM, STATIC_DIM, rotation_part};
use neural_cloth::model::heading::without_heading;
use neural_cloth::model::inference::InferenceScene;
use neural_cloth::model::{
    ClothNet, ClothNetConfig, DescriptorConfig, DescriptorExtractor, Descriptors, EncoderKind,
    GarmentLbs, InferenceEngine, InferenceOptions, InferenceWeights, Precision, RotationFrame,
    SkinMatrixBuilder,
};
use neural_cloth::scene::{
    Avatar, Garment, GarmentOptions, JointTransform, Motion, Pose, Skeleton,
};

const FPS: f32 = 30.0;

/// Counts heap allocations per thread, to check that inference steps allocate nothing.
struct CountingAlloc;

thread_local! {
    static ALLOCATIONS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

fn count_allocation() {
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

unsafe impl std::alloc::GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        count_allocation();
        unsafe { std::alloc::System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        unsafe { std::alloc::System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, new_size: usize) -> *mut u8 {
        count_allocation();
        unsafe { std::alloc::System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: CountingAlloc = CountingAlloc;

fn allocations_on_this_thread() -> usize {
    ALLOCATIONS.with(|c| c.get())
}

/// Held while a test seeds the device's random generator and draws from it.
static INIT_DRAWS: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Deterministic pseudo-random numbers in [-1, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }
    fn vec3(&mut self) -> Vec3 {
        Vec3::new(self.next(), self.next(), self.next())
    }
}

/// Mannequin-like skeleton (procedural names), bind = rest, Y up, metres.
fn skeleton() -> Skeleton {
    let joints: [(&str, Option<usize>, [f32; 3]); 20] = [
        ("Hips", None, [0.0, 1.0, 0.0]),
        ("Spine", Some(0), [0.0, 0.1, 0.0]),
        ("Spine1", Some(1), [0.0, 0.1, 0.0]),
        ("Spine2", Some(2), [0.0, 0.1, 0.0]),
        ("Neck", Some(3), [0.0, 0.15, 0.0]),
        ("Head", Some(4), [0.0, 0.1, 0.0]),
        ("LeftShoulder", Some(3), [0.05, 0.1, 0.0]),
        ("LeftArm", Some(6), [0.1, 0.0, 0.0]),
        ("LeftForeArm", Some(7), [0.25, 0.0, 0.0]),
        ("LeftHand", Some(8), [0.25, 0.0, 0.0]),
        ("RightShoulder", Some(3), [-0.05, 0.1, 0.0]),
        ("RightArm", Some(10), [-0.1, 0.0, 0.0]),
        ("RightForeArm", Some(11), [-0.25, 0.0, 0.0]),
        ("RightHand", Some(12), [-0.25, 0.0, 0.0]),
        ("LeftUpLeg", Some(0), [0.1, -0.05, 0.0]),
        ("LeftLeg", Some(14), [0.0, -0.4, 0.0]),
        ("LeftFoot", Some(15), [0.0, -0.4, 0.0]),
        ("LeftToeBase", Some(16), [0.0, -0.05, 0.1]),
        ("RightUpLeg", Some(0), [-0.1, -0.05, 0.0]),
        ("RightLeg", Some(18), [0.0, -0.4, 0.0]),
    ];
    let n = joints.len();
    let rest: Vec<JointTransform> = joints
        .iter()
        .map(|j| JointTransform {
            translation: Vec3::from(j.2),
            ..Default::default()
        })
        .collect();
    let mut sk = Skeleton::new(
        joints.iter().map(|j| j.0.to_string()).collect(),
        joints.iter().map(|j| j.1).collect(),
        rest,
        vec![Mat4::identity(); n],
        vec![Mat4::identity(); n],
    )
    .unwrap();
    let rest_pose = sk.rest_pose();
    sk.joint_from_bind = sk
        .world_from_joint(&rest_pose)
        .iter()
        .map(|m| m.try_inverse().unwrap())
        .collect();
    sk
}

/// A body made of one small tetrahedron per joint, rigidly bound to it.
fn avatar() -> Avatar {
    let sk = skeleton();
    let joints = sk.joint_positions(&sk.rest_pose());
    let (mut pos, mut faces, mut infl) = (Vec::new(), Vec::new(), Vec::new());
    for (j, p) in joints.iter().enumerate() {
        let b = pos.len() as u32;
        for d in [
            [0.04, 0.0, 0.0],
            [-0.03, 0.0, 0.03],
            [-0.03, 0.0, -0.03],
            [0.0, 0.05, 0.0],
        ] {
            pos.push(p + Vec3::from(d));
            infl.push(vec![(j as u16, 1.0)]);
        }
        faces.extend([
            [b, b + 2, b + 1],
            [b, b + 1, b + 3],
            [b + 1, b + 2, b + 3],
            [b + 2, b, b + 3],
        ]);
    }
    let (skin, _) = SkinWeights::from_influences(infl, 0);
    Avatar::new(
        "tetra-man",
        sk,
        TriMesh::new(pos, faces).unwrap(),
        skin,
        Vec::new(),
    )
    .unwrap()
}

/// An open tube around the torso (hips to chest), weights transferred from the body.
fn garment(avatar: &Avatar) -> Garment {
    let (rings, segments) = (5u32, 10u32);
    let mut pos = Vec::new();
    for r in 0..rings {
        for s in 0..segments {
            let a = s as f32 / segments as f32 * std::f32::consts::TAU;
            pos.push(Vec3::new(
                0.16 * a.cos(),
                0.9 + 0.1 * r as f32,
                0.12 * a.sin(),
            ));
        }
    }
    let mut faces = Vec::new();
    for r in 0..rings - 1 {
        for s in 0..segments {
            let (a, b) = (r * segments + s, r * segments + (s + 1) % segments);
            faces.push([a, b, b + segments]);
            faces.push([a, b + segments, a + segments]);
        }
    }
    Garment::new(
        "tube",
        TriMesh::new(pos, faces).unwrap(),
        avatar,
        &GarmentOptions::default(),
    )
    .unwrap()
}

/// A smooth random motion of `frames` frames followed by `still` copies of its last pose.
fn motion(sk: &Skeleton, frames: usize, still: usize, seed: u64) -> Motion {
    let mut rng = Lcg(seed);
    let axes: Vec<(Vec3, f32, f32)> = (0..sk.len())
        .map(|_| (rng.vec3(), 0.8 * rng.next(), 6.0 * rng.next()))
        .collect();
    let drift = rng.vec3() * 0.5;
    let rest = sk.rest_pose();
    let mut poses: Vec<Pose> = (0..frames)
        .map(|k| {
            let t = k as f32 / FPS;
            let rotations = rest
                .rotations
                .iter()
                .zip(&axes)
                .map(|(q, (axis, amp, freq))| {
                    let axis = nalgebra::Unit::new_normalize(*axis + Vec3::new(0.0, 1e-3, 0.0));
                    q * Quat::from_axis_angle(&axis, amp * (freq * t).sin() + 0.3 * amp)
                })
                .collect();
            Pose {
                rotations,
                root_translation: rest.root_translation + drift * t * t,
            }
        })
        .collect();
    let last = poses.last().cloned().unwrap();
    poses.extend(std::iter::repeat_n(last, still));
    Motion::new("random", FPS, poses, sk.len()).unwrap()
}

fn tensor4(data: &[f32], dims: [usize; 4], device: &Device) -> Tensor<4> {
    Tensor::from_data(TensorData::new(data.to_vec(), dims), device)
}

fn to_vec<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.try_into_vec_as::<f32>().unwrap()
}

fn desc_tensors(d: &Descriptors, device: &Device) -> (Tensor<4>, Tensor<4>) {
    (
        tensor4(&d.static_desc, [1, d.frames, d.joints, STATIC_DIM], device),
        tensor4(
            &d.dynamic_desc,
            [1, d.frames, d.joints, DYNAMIC_DIM],
            device,
        ),
    )
}

/// Architecture with a large enough initialisation that dynamics visibly change the output.
fn lively(kind: EncoderKind) -> ClothNetConfig {
    ClothNetConfig {
        encoder: kind,
        static_hidden: vec![32, 48],
        dynamic_hidden: vec![64, 64],
        latent: 40,
        decoder_hidden: vec![48, 48],
        init_std: 0.15,
        basis_init_gain: 30.0,
        ..Default::default()
    }
}

fn max_abs(v: &[f32]) -> f32 {
    v.iter().fold(0.0f32, |m, x| m.max(x.abs()))
}

fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()))
}

fn build(
    kind: EncoderKind,
    cfg: ClothNetConfig,
    avatar: &Avatar,
    garment: &Garment,
    device: &Device,
) -> (ClothNet, DescriptorExtractor) {
    let ex = DescriptorExtractor::new(&avatar.skeleton, &DescriptorConfig::default(), FPS).unwrap();
    // The device's generator is shared by the tests running beside this one: seeding it and
    // drawing the initial weights happen under one lock, or another test's draws interleave
    // and the weights (and the errors measured on them) change from run to run.
    let _draws = INIT_DRAWS.lock().unwrap_or_else(|e| e.into_inner());
    device.seed(1234);
    let net = ClothNetConfig {
        encoder: kind,
        ..cfg
    }
    .init(ex.joint_count(), garment.vertex_count(), device)
    .unwrap();
    (net, ex)
}

#[test]
fn input_joints_drop_hands_and_feet() {
    let sk = skeleton();
    let ex = DescriptorExtractor::new(&sk, &DescriptorConfig::default(), FPS).unwrap();
    let names: Vec<&str> = ex
        .input_joints()
        .iter()
        .map(|&j| sk.names[j].as_str())
        .collect();
    assert_eq!(names.len(), 16);
    assert!(names.contains(&"Head") && names.contains(&"Neck") && names.contains(&"LeftForeArm"));
    assert!(
        !names
            .iter()
            .any(|n| n.contains("Hand") || n.contains("Foot") || n.contains("Toe"))
    );
}

#[test]
fn static_descriptors_are_6d_local_rotation_and_unit_unposed_gravity() {
    let sk = skeleton();
    let m = motion(&sk, 6, 0, 3);
    for frame in [RotationFrame::Paper, RotationFrame::HeadingFree] {
        let config = DescriptorConfig {
            rotation_frame: frame,
            ..Default::default()
        };
        let mut ex = DescriptorExtractor::new(&sk, &config, FPS).unwrap();
        let d = ex.motion(&m).unwrap();
        assert_eq!((d.frames, d.joints), (6, 16));
        for t in 0..d.frames {
            let world = sk.world_from_joint(&m.frames[t]);
            for (k, &j) in ex.input_joints().iter().enumerate() {
                let s = &d.static_frame(t).unwrap()[k * STATIC_DIM..(k + 1) * STATIC_DIM];
                let local = m.frames[t].rotations[j].to_rotation_matrix().into_inner();
                let six = if frame == RotationFrame::HeadingFree && sk.parents[j].is_none() {
                    rotation_to_6d(&without_heading(&rotation_part(&world[j]), &Vec3::y()))
                } else {
                    rotation_to_6d(&local)
                };
                assert!(s[..6].iter().zip(&six).all(|(a, b)| (a - b).abs() < 1e-6));
                let g = Vec3::new(s[6], s[7], s[8]);
                assert!(
                    (g.norm() - 1.0).abs() < 1e-5,
                    "gravity part is a unit vector"
                );
                let back = rotation_part(&world[j]) * g;
                assert!(
                    (back - Vec3::new(0.0, -1.0, 0.0)).norm() < 1e-5,
                    "re-posing gives world gravity"
                );
            }
        }
    }
}

#[test]
fn gravity_descriptor_ignores_turning_about_the_vertical() {
    let sk = skeleton();
    let m = motion(&sk, 4, 0, 9);
    let turned: Vec<Pose> = m
        .frames
        .iter()
        .map(|p| {
            let mut p = p.clone();
            p.rotations[0] = Quat::from_axis_angle(&Vec3::y_axis(), 1.3) * p.rotations[0];
            p
        })
        .collect();
    let paper = DescriptorConfig {
        rotation_frame: RotationFrame::Paper,
        ..Default::default()
    };
    let mut ex = DescriptorExtractor::new(&sk, &paper, FPS).unwrap();
    let (a, b) = (ex.poses(&m.frames).unwrap(), ex.poses(&turned).unwrap());
    for t in 0..a.frames {
        for k in 0..a.joints {
            let i = (t * a.joints + k) * STATIC_DIM;
            assert!(max_diff(&a.static_desc[i + 6..i + 9], &b.static_desc[i + 6..i + 9]) < 1e-5);
        }
    }
    assert!(
        max_diff(&a.static_desc, &b.static_desc) > 0.1,
        "the paper's root 6D rotation does change"
    );
    // The default, heading-free descriptors do not change at all.
    let mut ex = DescriptorExtractor::new(&sk, &DescriptorConfig::default(), FPS).unwrap();
    let (a, b) = (ex.poses(&m.frames).unwrap(), ex.poses(&turned).unwrap());
    assert!(max_diff(&a.static_desc, &b.static_desc) < 1e-5);
    // Their rotation rates neither (the accelerations do: the root's path is not turned).
    for (ra, rb) in a
        .dynamic_desc
        .chunks(DYNAMIC_DIM)
        .zip(b.dynamic_desc.chunks(DYNAMIC_DIM))
    {
        assert!(max_diff(&ra[..STATIC_DIM], &rb[..STATIC_DIM]) < 1e-3);
    }
}

#[test]
fn still_pose_has_zero_dynamics_and_constant_velocity_zero_acceleration() {
    let sk = skeleton();
    let mut ex = DescriptorExtractor::new(&sk, &DescriptorConfig::default(), FPS).unwrap();
    let pose = motion(&sk, 3, 0, 5).frames[2].clone();
    let still = ex
        .motion(&Motion::still("still", pose.clone(), FPS, 10))
        .unwrap();
    assert!(still.dynamic_desc.iter().all(|v| *v == 0.0));

    let velocity = Vec3::new(0.7, -0.2, 1.1);
    let glide: Vec<Pose> = (0..10)
        .map(|k| Pose {
            root_translation: pose.root_translation + velocity * (k as f32 / FPS),
            ..pose.clone()
        })
        .collect();
    let d = ex.poses(&glide).unwrap();
    assert!(
        d.dynamic_desc
            .chunks(DYNAMIC_DIM)
            .all(|c| c[..STATIC_DIM].iter().all(|v| *v == 0.0)),
        "no rotation change"
    );
    let worst = d
        .dynamic_desc
        .chunks(DYNAMIC_DIM)
        .map(|c| max_abs(&c[STATIC_DIM..]))
        .fold(0.0, f32::max);
    assert!(worst < 5e-3, "constant velocity, acceleration {worst} m/s²");

    // Constant acceleration a: every joint reports R_globalᵀ a.
    let accel = Vec3::new(0.0, 2.0, -3.0);
    let fall: Vec<Pose> = (0..6)
        .map(|k| {
            let t = k as f32 / FPS;
            Pose {
                root_translation: pose.root_translation + accel * (0.5 * t * t),
                ..pose.clone()
            }
        })
        .collect();
    let d = ex.poses(&fall).unwrap();
    let world = sk.world_from_joint(&pose);
    for t in 2..6 {
        for (k, &j) in ex.input_joints().iter().enumerate() {
            let c =
                &d.dynamic_frame(t).unwrap()[k * DYNAMIC_DIM + STATIC_DIM..(k + 1) * DYNAMIC_DIM];
            let expected = rotation_part(&world[j]).transpose() * accel;
            assert!(
                (Vec3::new(c[0], c[1], c[2]) - expected).norm() < 0.05,
                "frame {t} joint {j}"
            );
        }
    }
}

#[test]
fn descriptors_resample_other_frame_rates() {
    let sk = skeleton();
    let m = motion(&sk, 31, 0, 8);
    let fast = m.resample(60.0).unwrap();
    let mut ex = DescriptorExtractor::new(&sk, &DescriptorConfig::default(), FPS).unwrap();
    let (a, b) = (ex.motion(&m).unwrap(), ex.motion(&fast).unwrap());
    assert_eq!(a.frames, b.frames);
    assert!(max_diff(&a.static_desc, &b.static_desc) < 1e-3);
}

#[test]
fn zero_dynamics_give_zero_dynamic_code_and_still_body_constant_output() {
    let device = Device::flex();
    let av = avatar();
    let g = garment(&av);
    let (net, mut ex) = build(
        EncoderKind::Disentangled,
        lively(EncoderKind::Disentangled),
        &av,
        &g,
        &device,
    );
    let pose = motion(&av.skeleton, 3, 0, 11).frames[2].clone();
    let d = ex
        .motion(&Motion::still("still", pose.clone(), FPS, 8))
        .unwrap();
    let (s, dy) = desc_tensors(&d, &device);
    let z_d = to_vec(net.encode_dynamic(dy.clone(), None).unwrap());
    assert!(z_d.iter().all(|v| *v == 0.0), "z_D must be exactly zero");
    let out = to_vec(net.forward(s.clone(), Some(dy), 1.0));
    let frame = g.vertex_count() * 3;
    assert!(max_abs(&out) > 1e-3);
    for t in 1..d.frames {
        assert!(max_diff(&out[..frame], &out[t * frame..(t + 1) * frame]) <= 1e-6 * max_abs(&out));
    }
    // The engine skips the dynamic branch and repeats the frame bit for bit.
    let w = InferenceWeights::from_module(&net).unwrap();
    let mut engine = InferenceEngine::from_scene(
        w,
        &av,
        &g,
        &DescriptorConfig::default(),
        FPS,
        InferenceOptions::default(),
    )
    .unwrap();
    engine.step(&pose, 1.0).unwrap();
    let first = engine.garment_positions().to_vec();
    for _ in 0..5 {
        engine.step(&pose, 2.0).unwrap();
        assert!(engine.dynamic_skipped());
        assert_eq!(engine.garment_positions(), &first[..]);
    }
}

#[test]
fn w_zero_is_the_static_decode_and_w_scales_dynamics() {
    let device = Device::flex();
    let av = avatar();
    let g = garment(&av);
    let (net, mut ex) = build(
        EncoderKind::Disentangled,
        lively(EncoderKind::Disentangled),
        &av,
        &g,
        &device,
    );
    let d = ex.motion(&motion(&av.skeleton, 10, 0, 21)).unwrap();
    let (s, dy) = desc_tensors(&d, &device);
    let w0 = to_vec(net.forward(s.clone(), Some(dy.clone()), 0.0));
    let stat = to_vec(net.decode(net.encode_static(s.clone()).unwrap()));
    assert_eq!(w0, stat);
    let w1 = to_vec(net.forward(s.clone(), Some(dy.clone()), 1.0));
    assert!(
        max_diff(&w0, &w1) > 1e-3 * max_abs(&w0),
        "dynamics change the output"
    );
    // forward_last matches the tail of the full forward pass.
    let last = to_vec(net.forward_last(s, Some(dy), 1.0, 3, None, 0));
    let tail = &w1[w1.len() - last.len()..];
    assert!(max_diff(&last, tail) <= 1e-5 * max_abs(tail));
}

/// Runs burn and the engine over the same motion and compares offsets, garment and body.
fn compare_engine_with_burn(
    kind: EncoderKind,
    cfg: ClothNetConfig,
    ws: &[f32],
    options: InferenceOptions,
    tolerance: f32,
) {
    let device = Device::flex();
    let av = avatar();
    let g = garment(&av);
    let (mut net, mut ex) = build(kind, cfg, &av, &g, &device);
    // A trained dynamic basis is not zero: give it values the comparison can see.
    if let Some(b) = net.decoder.dynamic_basis.as_mut() {
        let dims = b.weight.val().dims();
        let scale = 0.05 / net.decoder.dynamic_scale;
        let mut rng = Lcg(11);
        let values: Vec<f32> = (0..dims[0] * dims[1])
            .map(|_| scale as f32 * rng.next())
            .collect();
        b.weight = burn::module::Param::from_tensor(Tensor::from_data(
            burn::tensor::TensorData::new(values, dims),
            &device,
        ));
    }
    let m = motion(&av.skeleton, 14, 6, 42);
    let d = ex.motion(&m).unwrap();
    let (s, dy) = desc_tensors(&d, &device);
    let lbs = GarmentLbs::from_garment(&g, av.skeleton.len(), &device).unwrap();
    let mut builder = SkinMatrixBuilder::new(&av.skeleton);
    let mut mats = Vec::new();
    for p in &m.frames {
        builder.append(p, &mut mats).unwrap();
    }
    let mats = tensor4(&mats, [1, m.frames.len(), av.skeleton.len(), 12], &device);
    let weights = InferenceWeights::from_module(&net).unwrap();
    let mut engine =
        InferenceEngine::from_scene(weights, &av, &g, &DescriptorConfig::default(), FPS, options)
            .unwrap();
    let frame = g.vertex_count() * 3;
    let mut per_w = Vec::new();
    for &w in ws {
        let offsets_t = net.forward(s.clone(), Some(dy.clone()), w);
        let posed = to_vec(lbs.pose(offsets_t.clone(), mats.clone()));
        let offsets = to_vec(offsets_t);
        let scale = max_abs(&offsets);
        assert!(scale > 0.0);
        engine.reset();
        for (t, pose) in m.frames.iter().enumerate() {
            engine.step(pose, w).unwrap();
            let o = &offsets[t * frame..(t + 1) * frame];
            let err = max_diff(engine.offsets(), o);
            assert!(
                err <= tolerance * scale,
                "{kind:?} w {w} frame {t}: offsets differ by {err} (scale {scale})"
            );
            let flat: Vec<f32> = engine
                .garment_positions()
                .iter()
                .flat_map(|p| [p.x, p.y, p.z])
                .collect();
            let err = max_diff(&flat, &posed[t * frame..(t + 1) * frame]);
            assert!(
                err <= tolerance * (1.0 + scale),
                "{kind:?} w {w} frame {t}: garment differs by {err}"
            );
            let body = av.pose_vertices(pose);
            let err = engine
                .body_positions()
                .iter()
                .zip(&body)
                .map(|(a, b)| (a - b).norm())
                .fold(0.0, f32::max);
            assert!(err < 1e-5, "body differs by {err}");
        }
        assert_eq!(engine.frames_seen(), m.frames.len());
        if kind == EncoderKind::Disentangled {
            assert!(
                !engine.dynamic_skipped(),
                "the GRU state is carried into the still tail"
            );
        }
        per_w.push(offsets);
    }
    if kind == EncoderKind::Disentangled && per_w.len() >= 2 {
        let spread = max_diff(&per_w[0], &per_w[per_w.len() - 1]);
        assert!(
            spread > 1e-2 * max_abs(&per_w[0]),
            "w must matter for the comparison to mean something"
        );
    }
}

#[test]
fn engine_matches_burn_disentangled_for_w_0_1_2() {
    // Without a dynamic basis, as every run saved before it existed.
    compare_engine_with_burn(
        EncoderKind::Disentangled,
        ClothNetConfig {
            dynamic_basis: false,
            ..lively(EncoderKind::Disentangled)
        },
        &[0.0, 1.0, 2.0],
        InferenceOptions::exact(),
        1e-5,
    );
}

#[test]
fn engine_matches_burn_with_a_dynamic_basis_for_w_0_1_2() {
    compare_engine_with_burn(
        EncoderKind::Disentangled,
        ClothNetConfig {
            dynamic_basis: true,
            // Unlike the basis's scale: the export must rescale the appended rows.
            dynamic_basis_lr_scale: 1.0 / 64.0,
            ..lively(EncoderKind::Disentangled)
        },
        &[0.0, 1.0, 2.0],
        InferenceOptions::exact(),
        1e-5,
    );
}

#[test]
fn engine_matches_burn_with_default_architecture_and_threads() {
    let options = InferenceOptions {
        threads: 2,
        parallel_min_values: 1,
        ..InferenceOptions::exact()
    };
    compare_engine_with_burn(
        EncoderKind::Disentangled,
        ClothNetConfig::default(),
        &[1.0],
        options,
        1e-5,
    );
}

#[test]
fn engine_matches_burn_entangled_and_static_only() {
    compare_engine_with_burn(
        EncoderKind::Entangled,
        lively(EncoderKind::Entangled),
        &[1.0],
        InferenceOptions::exact(),
        1e-5,
    );
    compare_engine_with_burn(
        EncoderKind::StaticOnly,
        lively(EncoderKind::StaticOnly),
        &[1.0],
        InferenceOptions::exact(),
        1e-5,
    );
}

/// Relative tolerance of the f16 engine (all matrices in f16) against burn's f32 forward pass:
/// f16 rounds each weight by at most 2⁻¹¹ relative; over the encoder, GRU and decoder layers
/// the measured worst offset error is a few 10⁻⁴ of the largest offset (see
/// `f16_engine_error_is_measured_and_small`), so 2e-3 bounds it with margin.
const F16_TOLERANCE: f32 = 2e-3;

#[test]
fn f16_engine_matches_burn_within_its_tolerance_for_w_0_1_2() {
    for (basis, layers) in [
        (Precision::F16, Precision::F32),
        (Precision::F16, Precision::F16),
    ] {
        let options = InferenceOptions {
            basis_precision: basis,
            layer_precision: layers,
            ..InferenceOptions::default()
        };
        compare_engine_with_burn(
            EncoderKind::Disentangled,
            lively(EncoderKind::Disentangled),
            &[0.0, 1.0, 2.0],
            options.clone(),
            F16_TOLERANCE,
        );
        compare_engine_with_burn(
            EncoderKind::Disentangled,
            ClothNetConfig::default(),
            &[1.0],
            InferenceOptions {
                threads: 2,
                parallel_min_values: 1,
                ..options
            },
            F16_TOLERANCE,
        );
    }
}

#[test]
fn f16_engine_error_is_measured_and_small() {
    // Default architecture (512-d latent), a long walk-like motion with the state carried:
    // the f16 engine's garment stays within 1e-3 of the offset scale of the f32 engine's, and
    // the f16 engine is not secretly f32 (it does differ, and stores half the bytes).
    let device = Device::flex();
    let av = avatar();
    let g = garment(&av);
    let (net, _) = build(
        EncoderKind::Disentangled,
        ClothNetConfig {
            basis_init_gain: 30.0,
            ..ClothNetConfig::default()
        },
        &av,
        &g,
        &device,
    );
    let w = InferenceWeights::from_module(&net).unwrap();
    let engine = |options: InferenceOptions| {
        InferenceEngine::from_scene(
            w.clone(),
            &av,
            &g,
            &DescriptorConfig::default(),
            FPS,
            options,
        )
        .unwrap()
    };
    let mut exact = engine(InferenceOptions::exact());
    let mut half = engine(InferenceOptions::default());
    assert_eq!(half.basis_precision(), Precision::F16);
    assert_eq!(half.basis_bytes() * 2, exact.basis_bytes());
    assert!(half.weight_bytes() * 2 <= exact.weight_bytes() + 4 * 1024 * 8);
    let m = motion(&av.skeleton, 90, 10, 5);
    let (mut worst_offset, mut worst_posed, mut scale) = (0.0f32, 0.0f32, 0.0f32);
    for pose in &m.frames {
        exact.step(pose, 1.0).unwrap();
        half.step(pose, 1.0).unwrap();
        scale = scale.max(max_abs(exact.offsets()));
        worst_offset = worst_offset.max(max_diff(exact.offsets(), half.offsets()));
        for (a, b) in exact
            .garment_positions()
            .iter()
            .zip(half.garment_positions())
        {
            worst_posed = worst_posed.max((a - b).norm());
        }
        assert_eq!(exact.body_positions(), half.body_positions());
    }
    eprintln!(
        "f16 vs f32: worst offset error {worst_offset:e} m, posed {worst_posed:e} m, offsets up \
         to {scale} m"
    );
    assert!(
        scale > 1e-3,
        "offsets must be large enough to matter ({scale})"
    );
    assert!(worst_offset > 0.0, "f16 storage must change something");
    assert!(
        worst_offset <= 1e-3 * scale && worst_posed <= 2e-3 * scale,
        "f16 error {worst_offset} m (posed {worst_posed} m) against offsets of {scale} m"
    );
}

#[test]
fn engine_rejects_mismatched_scenes_and_bad_input() {
    let device = Device::flex();
    let av = avatar();
    let g = garment(&av);
    let (net, _) = build(
        EncoderKind::Disentangled,
        lively(EncoderKind::Disentangled),
        &av,
        &g,
        &device,
    );
    let w = InferenceWeights::from_module(&net).unwrap();
    let mut fewer = DescriptorConfig::default();
    fewer.exclude_patterns.push("arm".into());
    assert!(
        InferenceEngine::from_scene(w.clone(), &av, &g, &fewer, FPS, InferenceOptions::default())
            .is_err()
    );
    let short = &g.mesh.positions[..g.vertex_count() - 1];
    let scene = InferenceScene {
        template: short,
        ..InferenceScene::new(&av, &g)
    };
    assert!(
        InferenceEngine::new(
            w.clone(),
            scene,
            &DescriptorConfig::default(),
            FPS,
            InferenceOptions::default()
        )
        .is_err()
    );
    let mut engine = InferenceEngine::from_scene(
        w.clone(),
        &av,
        &g,
        &DescriptorConfig::default(),
        FPS,
        InferenceOptions::default(),
    )
    .unwrap();
    let mut pose = av.skeleton.rest_pose();
    assert!(engine.step(&pose, f32::NAN).is_err());
    pose.root_translation.y = f32::INFINITY;
    assert!(engine.step(&pose, 1.0).is_err());
    pose.rotations.truncate(3);
    assert!(engine.step(&pose, 1.0).is_err());
    // A snapshot for another garment size is refused; one of the same layout is taken.
    let (other, _) = build(
        EncoderKind::Disentangled,
        lively(EncoderKind::Disentangled),
        &av,
        &g,
        &device,
    );
    assert!(
        engine
            .set_weights(InferenceWeights::from_module(&other).unwrap())
            .is_ok()
    );
    let mut wrong = w;
    wrong.vertices += 1;
    assert!(engine.set_weights(wrong).is_err());
}

#[test]
fn engine_steps_allocate_nothing() {
    let device = Device::flex();
    let av = avatar();
    let g = garment(&av);
    for kind in [
        EncoderKind::Disentangled,
        EncoderKind::Entangled,
        EncoderKind::StaticOnly,
    ] {
        let (net, _) = build(kind, lively(kind), &av, &g, &device);
        let w = InferenceWeights::from_module(&net).unwrap();
        let mut engine = InferenceEngine::from_scene(
            w,
            &av,
            &g,
            &DescriptorConfig::default(),
            FPS,
            InferenceOptions::default(),
        )
        .unwrap();
        let m = motion(&av.skeleton, 12, 3, 77);
        engine.step(&m.frames[0], 1.0).unwrap();
        let before = allocations_on_this_thread();
        for (k, p) in m.frames.iter().enumerate().skip(1) {
            engine.step(p, k as f32 * 0.15).unwrap();
        }
        engine.reset();
        engine.step(&m.frames[0], 1.0).unwrap();
        let after = allocations_on_this_thread();
        assert_eq!(
            after - before,
            0,
            "{kind:?}: {} allocations in {} steps",
            after - before,
            m.frames.len()
        );
    }
    // The counter does count: building vectors allocates.
    let before = allocations_on_this_thread();
    let v: Vec<u8> = std::hint::black_box(vec![1, 2, 3]);
    assert!(allocations_on_this_thread() > before && v.len() == 3);
}

/// Profiling driver, not a test: steps the default f16 engine on the benchmark scene for
/// `NC_PROFILE_SECS` seconds (default 10) at `NC_PROFILE_DOF` degrees of freedom (default
/// 10 000) on `NC_PROFILE_THREADS` threads (default 1; `NC_PROFILE_EXACT=1` for f32 weights)
/// and prints the median frame time, e.g. under
/// `perf record -g target/release/deps/model-* profile_inference --ignored --nocapture`.
#[test]
#[ignore]
fn profile_inference() {
    use neural_cloth::bench::{bench_avatar, bench_motion, random_weights, scene_with_dof};
    let env = |k: &str, d: f64| {
        std::env::var(k)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(d)
    };
    let secs = env("NC_PROFILE_SECS", 10.0);
    let dof = env("NC_PROFILE_DOF", 10_000.0) as usize;
    let exact = env("NC_PROFILE_EXACT", 0.0) != 0.0;
    let av = bench_avatar().unwrap();
    let g = scene_with_dof(&av, dof).unwrap();
    let ex = DescriptorExtractor::new(&av.skeleton, &DescriptorConfig::default(), FPS).unwrap();
    let w = random_weights(ex.joint_count(), g.vertex_count()).unwrap();
    let threads = env("NC_PROFILE_THREADS", 1.0) as usize;
    let options = InferenceOptions {
        threads,
        parallel_min_values: 0,
        ..if exact {
            InferenceOptions::exact()
        } else {
            InferenceOptions::default()
        }
    };
    let mut engine =
        InferenceEngine::from_scene(w, &av, &g, &DescriptorConfig::default(), FPS, options)
            .unwrap();
    // NC_PROFILE_PAIRED=<MB>: after each frame, time a streaming read of that many MB.
    let paired = env("NC_PROFILE_PAIRED", 0.0);
    let buffer = neural_cloth::bench::floor_buffer((paired * 1e6) as usize);
    let walk = bench_motion().unwrap();
    let start = std::time::Instant::now();
    let (mut times, mut reads) = (Vec::new(), Vec::new());
    for pose in walk.frames.iter().cycle() {
        let t = std::time::Instant::now();
        engine.step(pose, 1.0).unwrap();
        times.push(t.elapsed().as_secs_f64());
        if paired > 0.0 {
            reads.push(neural_cloth::bench::read_pass_secs(&buffer, threads));
        }
        if start.elapsed().as_secs_f64() > secs {
            break;
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(0.0) * 1e3
    };
    eprintln!(
        "{} DoF, {} frames, median {:.4} ms, paired read of {paired} MB {:.4} ms, body {} vertices",
        g.vertex_count() * 3,
        times.len(),
        median(&mut times),
        median(&mut reads),
        engine.body_positions().len()
    );
}
