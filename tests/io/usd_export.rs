//! USD export read back by Pixar's own library: a short walk of the built-in scene is baked to
//! PC2 (the reference) and to USD with every preset; `tests/usd/read_stage.py` (usd-core)
//! reads each stage, `tests/usd/usdchecker.py` runs USD's validators on it, and every
//! time-sampled point must equal the PC2 frame under the preset's documented transform, bit
//! for bit. usd-core lives in a virtual environment that `scripts/setup.sh` installs under
//! `$NEURAL_CLOTH_TOOLS` (default `/var/tmp/neural-cloth-tools`); without it the reader tests
//! print why and skip, except under CI (`CI` set), where they fail.
//!
//! Also here, without usd-core: bad input (unknown preset, missing folder, glTF with a preset)
//! and failed or cancelled bakes leave no file.

use std::path::{Path, PathBuf};
use std::process::Command;

use neural_cloth::bake::{
    BakeError, BakeFormat, BakeOptions, BakeReport, FrameSource, Preset, bake,
};
use neural_cloth::geometry::Vec3;
use neural_cloth::io::export::read_pc2;
use neural_cloth::scene::config::SceneConfig;
use neural_cloth::scene::procedural::build_builtin;
use neural_cloth::scene::{Avatar, Garment, Pose, Scene};

const SCENE: &str = r#"
name = "usd"
training_fps = 30.0
[avatar]
builtin = "mannequin"
[garment]
builtin = "tshirt"
resolution = 400
[[motions]]
builtin = "walk"
duration_secs = 0.5
[fabric]
preset = "default"
"#;

/// The built-in scene with per-vertex UVs added to the garment (so `primvars:st` is checked).
fn scene() -> Scene {
    let config = SceneConfig::from_toml_str(SCENE).unwrap();
    let mut scene = build_builtin(&config).unwrap();
    let uvs = scene
        .garment
        .mesh
        .positions
        .iter()
        .map(|p| [p.x * 0.5 + 0.5, p.y * 0.5])
        .collect();
    scene.garment.mesh.uvs = Some(uvs);
    scene
}

/// Skins the garment onto each pose (linear blend skinning): a deterministic moving garment,
/// optionally failing at step `fail_at`.
struct Skinned<'a> {
    avatar: &'a Avatar,
    garment: &'a Garment,
    positions: Vec<Vec3>,
    steps: usize,
    fail_at: Option<usize>,
}

impl<'a> Skinned<'a> {
    fn new(scene: &'a Scene) -> Self {
        Self {
            avatar: &scene.avatar,
            garment: &scene.garment,
            positions: scene.garment.mesh.positions.clone(),
            steps: 0,
            fail_at: None,
        }
    }
}

impl FrameSource for Skinned<'_> {
    fn native_fps(&self) -> f32 {
        30.0
    }

    fn reset(&mut self) {
        self.steps = 0;
    }

    fn step(&mut self, pose: &Pose, _w: f32) -> Result<(), BakeError> {
        if self.fail_at == Some(self.steps) {
            return Err(BakeError::Source("the source failed on purpose".into()));
        }
        self.positions = self.garment.pose_vertices(self.avatar, pose);
        self.steps += 1;
        Ok(())
    }

    fn garment(&self) -> Vec<Vec3> {
        self.positions.clone()
    }

    fn rest(&self) -> Vec<Vec3> {
        self.garment.mesh.positions.clone()
    }
}

fn bake_to(scene: &Scene, options: &BakeOptions) -> Result<BakeReport, BakeError> {
    let motion = &scene.motions[0].0;
    let mut source = Skinned::new(scene);
    bake(
        &scene.avatar,
        &scene.garment,
        motion,
        &mut source,
        options,
        &mut |_, _| true,
    )
}

fn options(format: BakeFormat, out: PathBuf, preset: Option<Preset>) -> BakeOptions {
    BakeOptions {
        format,
        out,
        fps: 30.0,
        include_body: true,
        preset,
        ..Default::default()
    }
}

/// The Python of usd-core's virtual environment, or None (after saying why) to skip.
fn usd_python() -> Option<PathBuf> {
    let tools = std::env::var_os("NEURAL_CLOTH_TOOLS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/var/tmp/neural-cloth-tools"));
    let python = tools.join("usd-venv/bin/python");
    let works = Command::new(&python)
        .args(["-c", "import pxr.Usd"])
        .output()
        .is_ok_and(|o| o.status.success());
    if works {
        return Some(python);
    }
    let why = format!(
        "usd-core is not installed at {} (run scripts/setup.sh)",
        python.display()
    );
    assert!(std::env::var_os("CI").is_none(), "{why}");
    println!("skipped: {why}");
    None
}

/// Runs one of the `tests/usd` scripts and parses the JSON it prints.
fn run_script(
    python: &Path,
    script: &str,
    args: &[&Path],
) -> (std::process::ExitStatus, serde_json::Value) {
    let out = Command::new(python)
        .arg(Path::new("tests/usd").join(script))
        .args(args)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    let json = serde_json::from_str(&text).unwrap_or_else(|e| {
        panic!(
            "{script}: {e}: {text}{}",
            String::from_utf8_lossy(&out.stderr)
        )
    });
    (out.status, json)
}

/// Each mesh's name and its points per time sample.
type MeshSamples = Vec<(String, Vec<Vec<Vec3>>)>;

/// usd-core's view of a stage: its JSON report and each mesh's points per time sample.
fn read_stage(python: &Path, stage: &Path, dir: &Path) -> (serde_json::Value, MeshSamples) {
    let out = dir.join(format!(
        "read-{}",
        stage.file_stem().unwrap().to_string_lossy()
    ));
    std::fs::create_dir(&out).unwrap();
    let (status, json) = run_script(python, "read_stage.py", &[stage, &out]);
    assert!(status.success(), "{json}");
    let mut meshes = Vec::new();
    for (name, mesh) in json["meshes"].as_object().unwrap() {
        let counts = mesh["pointCounts"].as_array().unwrap();
        assert_eq!(counts.len(), 1, "{name}: samples of different sizes");
        let n = counts[0].as_u64().unwrap() as usize;
        let bytes = std::fs::read(out.join(format!("{name}.f32"))).unwrap();
        let values: Vec<f32> = bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        let frames = values
            .chunks_exact(n * 3)
            .map(|f| {
                f.chunks_exact(3)
                    .map(|p| Vec3::new(p[0], p[1], p[2]))
                    .collect()
            })
            .collect();
        meshes.push((name.clone(), frames));
    }
    (json, meshes)
}

/// Asserts that usd-core's validators find no error in `stage`.
fn assert_usdchecker_passes(python: &Path, stage: &Path) {
    let (status, json) = run_script(python, "usdchecker.py", &[stage]);
    assert!(
        status.success() && json["errors"] == 0,
        "usdchecker: {json}"
    );
    assert!(json["validators"].as_u64().unwrap() >= 20, "{json}");
}

/// The documented transform of each preset (README, export table), written out by hand:
/// (up axis, metres per unit, frame of motion frame 0, point map of USD, point map of PC2).
type PointMap = fn(Vec3) -> Vec3;
fn documented(preset: Option<Preset>) -> (&'static str, f64, f64, PointMap, PointMap) {
    match preset {
        None => ("Y", 1.0, 0.0, |p| p, |p| p),
        Some(Preset::Blender) => (
            "Z",
            1.0,
            1.0,
            |p| Vec3::new(p.x, -p.z, p.y),
            |p| Vec3::new(p.x, -p.z, p.y),
        ),
        Some(Preset::Unreal) => (
            "Z",
            0.01,
            0.0,
            |p| Vec3::new(p.x * 100.0, -p.z * 100.0, p.y * 100.0),
            |p| Vec3::new(p.x * 100.0, -p.z * 100.0, p.y * 100.0),
        ),
        // USD stays right-handed (Unity's USD importer mirrors it); raw caches are mirrored.
        Some(Preset::Unity) => ("Y", 1.0, 0.0, |p| p, |p| Vec3::new(-p.x, p.y, p.z)),
        Some(Preset::Maya) => ("Y", 0.01, 1.0, |p| p * 100.0, |p| p * 100.0),
        Some(Preset::Houdini) => ("Y", 1.0, 1.0, |p| p, |p| p),
    }
}

/// A JSON array of floats that usd-core widened from `f32`, narrowed back (exact, even when
/// the JSON parse is one double ulp off).
fn f32s(value: &serde_json::Value) -> Vec<f32> {
    value
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap() as f32)
        .collect()
}

fn same_bits(a: &[Vec3], b: &[Vec3]) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(p, q)| {
            p.iter()
                .zip(q.iter())
                .all(|(x, y)| x.to_bits() == y.to_bits())
        })
}

#[test]
fn usd_core_reads_every_preset_exactly_as_the_pc2_of_the_same_bake() {
    let Some(python) = usd_python() else {
        return;
    };
    let scene = scene();
    let dir = tempfile::tempdir().unwrap();
    let reference = dir.path().join("walk.pc2");
    bake_to(&scene, &options(BakeFormat::Pc2, reference.clone(), None)).unwrap();
    let garment_frames = read_pc2(&reference).unwrap().frames;
    let body_frames = read_pc2(&dir.path().join("walk.body.pc2")).unwrap().frames;
    let frames = garment_frames.len();
    assert_eq!(frames, 16, "0.5 s at 30 fps");
    assert!(
        garment_frames[0] != garment_frames[frames - 1],
        "the walk moves"
    );

    let mut presets: Vec<Option<Preset>> = vec![None];
    presets.extend(Preset::ALL.map(Some));
    for preset in presets {
        let tag = preset.map_or("default", Preset::name);
        let (up, meters_per_unit, base, usd_map, pc2_map) = documented(preset);
        let stage = dir.path().join(format!("walk-{tag}.usda"));
        let report = bake_to(&scene, &options(BakeFormat::Usd, stage.clone(), preset)).unwrap();
        assert_eq!(
            report.outputs,
            vec![stage.clone()],
            "{tag}: body in the stage"
        );
        assert_usdchecker_passes(&python, &stage);
        let (json, meshes) = read_stage(&python, &stage, dir.path());

        // Stage metadata.
        assert_eq!(json["upAxis"], up, "{tag}");
        assert_eq!(json["metersPerUnit"], meters_per_unit, "{tag}");
        assert_eq!(json["timeCodesPerSecond"], 30.0, "{tag}");
        assert_eq!(json["framesPerSecond"], 30.0, "{tag}");
        assert_eq!(json["startTimeCode"], base, "{tag}");
        assert_eq!(json["endTimeCode"], base + (frames - 1) as f64, "{tag}");
        assert_eq!(json["defaultPrim"], "Bake", "{tag}");

        // Every sample of both meshes, bit for bit, at the documented time codes.
        let expected = [("Garment", &garment_frames), ("Body", &body_frames)];
        assert_eq!(meshes.len(), 2, "{tag}");
        for (name, reference) in expected {
            let mesh = &json["meshes"][name];
            let times: Vec<f64> = (0..frames).map(|k| base + k as f64).collect();
            assert_eq!(mesh["times"], serde_json::json!(times), "{tag} {name}");
            let (_, read) = meshes.iter().find(|(n, _)| n == name).unwrap();
            assert_eq!(read.len(), frames, "{tag} {name}");
            for (k, (got, want)) in read.iter().zip(reference.iter()).enumerate() {
                let want: Vec<Vec3> = want.iter().map(|&p| usd_map(p)).collect();
                assert!(same_bits(got, &want), "{tag} {name} frame {k} differs");
                // The extent is the bounding box of the sample.
                let lo = want.iter().fold(want[0], |a, p| a.zip_map(p, f32::min));
                let hi = want.iter().fold(want[0], |a, p| a.zip_map(p, f32::max));
                let extent: Vec<f32> = lo.iter().chain(hi.iter()).copied().collect();
                assert_eq!(f32s(&mesh["extents"][k]), extent, "{tag} {name}");
            }
        }
        let garment = &json["meshes"]["Garment"];
        let faces = &scene.garment.mesh.faces;
        assert_eq!(
            garment["faceVertexCounts"],
            serde_json::json!(vec![3; faces.len()])
        );
        let indices: Vec<u32> = faces.iter().flatten().copied().collect();
        assert_eq!(garment["faceVertexIndices"], serde_json::json!(indices));
        assert_eq!(garment["subdivisionScheme"], "none");
        assert_eq!(garment["doubleSided"], true);
        assert_eq!(garment["stInterpolation"], "vertex");
        let uvs = scene.garment.mesh.uvs.as_ref().unwrap();
        let st: Vec<f32> = uvs.iter().flatten().copied().collect();
        assert_eq!(f32s(&garment["st"]), st);
        assert_eq!(json["meshes"]["Body"]["st"], serde_json::Value::Null);

        // The same preset on the PC2 cache: the documented transform and frame numbering.
        let pc2 = dir.path().join(format!("walk-{tag}.pc2"));
        bake_to(&scene, &options(BakeFormat::Pc2, pc2.clone(), preset)).unwrap();
        let cache = read_pc2(&pc2).unwrap();
        assert_eq!(cache.start_frame, base as f32, "{tag}");
        for (got, want) in cache.frames.iter().zip(&garment_frames) {
            let want: Vec<Vec3> = want.iter().map(|&p| pc2_map(p)).collect();
            assert!(same_bits(got, &want), "{tag}: PC2 differs");
        }
    }
}

#[test]
fn usdchecker_and_the_reader_can_fail() {
    let Some(python) = usd_python() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let scene = scene();
    let stage = dir.path().join("walk.usda");
    bake_to(&scene, &options(BakeFormat::Usd, stage.clone(), None)).unwrap();
    // Without its metadata the same stage fails the checker.
    let text = std::fs::read_to_string(&stage).unwrap();
    let broken = dir.path().join("broken.usda");
    let stripped: String = text
        .lines()
        .filter(|l| !l.contains("metersPerUnit") && !l.contains("defaultPrim"))
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&broken, stripped).unwrap();
    let (status, json) = run_script(&python, "usdchecker.py", &[&broken]);
    assert!(!status.success(), "{json}");
    assert_eq!(json["errors"], 2, "{json}");
    // A garbled stage does not open.
    let garbled = dir.path().join("garbled.usda");
    std::fs::write(&garbled, &text[..text.len() / 2]).unwrap();
    let out = Command::new(&python)
        .arg("tests/usd/read_stage.py")
        .arg(&garbled)
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(!out.status.success());
}

#[test]
fn the_size_estimate_is_within_a_third_of_the_written_stage() {
    let scene = scene();
    let dir = tempfile::tempdir().unwrap();
    let stage = dir.path().join("walk.usda");
    let report = bake_to(
        &scene,
        &BakeOptions {
            include_body: false,
            ..options(BakeFormat::Usd, stage.clone(), Some(Preset::Unreal))
        },
    )
    .unwrap();
    let actual = std::fs::metadata(&stage).unwrap().len() as f64;
    let estimate = BakeFormat::Usd.estimate_bytes(
        report.frames,
        report.vertices,
        scene.garment.mesh.faces.len(),
    ) as f64;
    assert!(
        (estimate / actual - 1.0).abs() < 0.33,
        "estimate {estimate} B, written {actual} B"
    );
}

#[test]
fn bad_input_is_refused_and_failed_bakes_leave_no_file() {
    let scene = scene();
    let dir = tempfile::tempdir().unwrap();
    // Unknown preset: a clear message.
    let err = "cinema4d".parse::<Preset>().unwrap_err().to_string();
    assert_eq!(
        err,
        "unknown preset 'cinema4d' (blender, unreal, unity, maya, houdini)"
    );
    // A missing output folder: refused before any work, naming the folder last.
    let missing = dir.path().join("missing/walk.usda");
    let err = bake_to(&scene, &options(BakeFormat::Usd, missing, None)).unwrap_err();
    let text = err.to_string();
    assert!(
        text.starts_with("output folder does not exist") && text.ends_with("missing"),
        "{text}"
    );
    // glTF takes no preset.
    let glb = dir.path().join("walk.glb");
    let err = bake_to(
        &scene,
        &options(BakeFormat::Gltf, glb, Some(Preset::Blender)),
    );
    assert!(
        err.unwrap_err()
            .to_string()
            .contains("does not apply to glTF"),
        "glTF with a preset"
    );
    // A source that fails half-way, and a cancelled bake: no file, no spill file.
    let stage = dir.path().join("walk.usda");
    let motion = &scene.motions[0].0;
    let mut source = Skinned::new(&scene);
    source.fail_at = Some(8);
    let opts = BakeOptions {
        rest_shapes: true,
        ..options(BakeFormat::Usd, stage.clone(), Some(Preset::Maya))
    };
    let failed = bake(
        &scene.avatar,
        &scene.garment,
        motion,
        &mut source,
        &opts,
        &mut |_, _| true,
    );
    assert!(failed.is_err());
    let mut source = Skinned::new(&scene);
    let cancelled = bake(
        &scene.avatar,
        &scene.garment,
        motion,
        &mut source,
        &opts,
        &mut |done, _| done < 5,
    );
    assert!(matches!(cancelled, Err(BakeError::Cancelled)));
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
    // The same bake run to the end writes the stage and its rest-shape sibling.
    let report = bake_to(&scene, &opts).unwrap();
    assert_eq!(
        report.outputs,
        vec![stage.clone(), dir.path().join("walk.rest.usda")]
    );
}

#[test]
fn the_cli_refuses_an_unknown_preset_and_a_missing_folder() {
    let exe = env!("CARGO_BIN_EXE_neural-cloth");
    let out = Command::new(exe)
        .args(["simulate", "--motion", "walk", "--format", "usd"])
        .args(["--preset", "cinema4d"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("unknown preset 'cinema4d' (blender, unreal, unity, maya, houdini)"),
        "{err}"
    );
    let out = Command::new(exe)
        .args(["simulate", "--motion", "walk", "--format", "usda"])
        .args(["--out", "/nonexistent-folder/walk.usda"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("output folder does not exist: /nonexistent-folder"),
        "{err}"
    );
}

#[test]
fn mdd_and_obj_follow_the_documented_preset_too() {
    let scene = scene();
    let dir = tempfile::tempdir().unwrap();
    let reference = dir.path().join("ref.pc2");
    bake_to(&scene, &options(BakeFormat::Pc2, reference.clone(), None)).unwrap();
    let frames = read_pc2(&reference).unwrap().frames;
    // MDD for Unity: mirrored X (a raw cache), times from 0 s.
    let mdd = dir.path().join("walk.mdd");
    bake_to(
        &scene,
        &options(BakeFormat::Mdd, mdd.clone(), Some(Preset::Unity)),
    )
    .unwrap();
    let cache = neural_cloth::io::export::read_mdd(&mdd).unwrap();
    let (.., unity_pc2) = documented(Some(Preset::Unity));
    for (got, want) in cache.frames.iter().zip(&frames) {
        let want: Vec<Vec3> = want.iter().map(|&p| unity_pc2(p)).collect();
        assert!(same_bits(got, &want), "MDD for Unity");
    }
    assert_eq!(cache.times_secs[0], 0.0);
    // OBJ for Maya: centimetres, files numbered from frame 1; Unreal numbers from 0.
    for (preset, first) in [(Preset::Maya, 1), (Preset::Unreal, 0)] {
        let folder = dir.path().join(format!("walk-{preset}"));
        bake_to(
            &scene,
            &BakeOptions {
                include_body: false,
                ..options(BakeFormat::Obj, folder.clone(), Some(preset))
            },
        )
        .unwrap();
        let (_, _, _, obj_map, _) = documented(Some(preset));
        let stem = format!("walk-{preset}");
        for (k, want) in frames.iter().enumerate() {
            let file = folder.join(format!("{stem}_{:04}.obj", first + k));
            let text = std::fs::read_to_string(&file).unwrap();
            let got: Vec<Vec3> = text
                .lines()
                .filter_map(|l| l.strip_prefix("v "))
                .map(|l| {
                    let c: Vec<f32> = l.split(' ').map(|x| x.parse().unwrap()).collect();
                    Vec3::new(c[0], c[1], c[2])
                })
                .collect();
            let want: Vec<Vec3> = want.iter().map(|&p| obj_map(p)).collect();
            assert!(same_bits(&got, &want), "{}", file.display());
        }
        assert_eq!(std::fs::read_dir(&folder).unwrap().count(), frames.len());
    }
}
