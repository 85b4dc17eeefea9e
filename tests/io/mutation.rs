//! Mutation test: random byte flips, truncations and splices of every shared asset fed to
//! every importer that reads its format; none may panic.

use std::path::{Path, PathBuf};

use neural_cloth::io::{self, Bvh, ImportOptions, RetargetOptions, Units};
use neural_cloth::scene::Skeleton;

use super::{files_in, mixamo_skeleton};
use proptest::prelude::*;
use std::sync::OnceLock;

struct Corpus {
    files: Vec<(PathBuf, Vec<u8>)>,
    skeleton: Skeleton,
}

fn corpus() -> &'static Corpus {
    static C: OnceLock<Corpus> = OnceLock::new();
    C.get_or_init(|| {
        let mut files = Vec::new();
        for (dir, ext) in [
            ("avatars", "glb"),
            ("avatars", "gltf"),
            ("motions", "bvh"),
            ("garments", "obj"),
        ] {
            for p in files_in(dir, ext) {
                let bytes = std::fs::read(&p).unwrap();
                files.push((p, bytes));
            }
        }
        Corpus {
            files,
            skeleton: mixamo_skeleton(),
        }
    })
}

#[derive(Debug, Clone)]
enum Mutation {
    /// Flip bits at (position seed, xor mask); `near_start` aims at headers and JSON.
    Flips(Vec<(usize, u8)>, bool),
    /// Keep only the first `fraction` (per mille) of the file.
    Truncate(u16),
    /// Copy a chunk from one place to another (overwriting), or insert it.
    Splice {
        from: usize,
        to: usize,
        len: u16,
        insert: bool,
    },
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (
            prop::collection::vec((any::<usize>(), 1u8..=255), 1..8),
            any::<bool>()
        )
            .prop_map(|(f, s)| Mutation::Flips(f, s)),
        (0u16..1000).prop_map(Mutation::Truncate),
        (any::<usize>(), any::<usize>(), 1u16..2048, any::<bool>()).prop_map(
            |(from, to, len, insert)| Mutation::Splice {
                from,
                to,
                len,
                insert
            }
        ),
    ]
}

fn apply(bytes: &[u8], m: &Mutation) -> Vec<u8> {
    let mut out = bytes.to_vec();
    let n = out.len().max(1);
    match m {
        Mutation::Flips(flips, near_start) => {
            let span = if *near_start { n.min(8192) } else { n };
            for &(pos, mask) in flips {
                if let Some(b) = out.get_mut(pos % span) {
                    *b ^= mask;
                }
            }
        }
        Mutation::Truncate(per_mille) => out.truncate(out.len() * *per_mille as usize / 1000),
        Mutation::Splice {
            from,
            to,
            len,
            insert,
        } => {
            let from = from % n;
            let end = (from + *len as usize).min(out.len());
            let chunk = out[from.min(out.len())..end].to_vec();
            let to = to % n;
            if *insert {
                out.splice(to..to, chunk);
            } else {
                for (k, b) in chunk.into_iter().enumerate() {
                    if let Some(slot) = out.get_mut(to + k) {
                        *slot = b;
                    }
                }
            }
        }
    }
    out
}

/// Feeds `bytes` (damaged `path`) to every importer that reads its format.
fn feed(path: &Path, bytes: &[u8], skeleton: &Skeleton) {
    let ext = path
        .extension()
        .unwrap()
        .to_string_lossy()
        .to_ascii_lowercase();
    let o = ImportOptions::default();
    match ext.as_str() {
        "glb" | "gltf" => {
            let _ = io::load_avatar_from_bytes(bytes, path, &o);
            let _ = io::load_gltf_mesh_from_bytes(bytes, path, &o);
        }
        "obj" => {
            let _ = io::load_obj_from_bytes(bytes, path, &o);
        }
        _ => {
            if let Ok(bvh) = Bvh::parse(bytes, path) {
                let _ = bvh.to_motion_for_own_skeleton(Units::Auto);
                let _ = io::retarget_bvh(&bvh, skeleton, &RetargetOptions::default());
            }
        }
    }
}

fn config(cases: u32) -> ProptestConfig {
    ProptestConfig {
        cases,
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

fn run_on(filter: fn(&Path) -> bool, file: usize, m: &Mutation) {
    let c = corpus();
    let chosen: Vec<&(PathBuf, Vec<u8>)> = c.files.iter().filter(|(p, _)| filter(p)).collect();
    let (path, bytes) = chosen[file % chosen.len()];
    feed(path, &apply(bytes, m), &c.skeleton);
}

fn is_gltf(p: &Path) -> bool {
    p.extension().is_some_and(|e| e == "glb" || e == "gltf")
}
fn is_obj(p: &Path) -> bool {
    p.extension().is_some_and(|e| e == "obj")
}
fn is_bvh(p: &Path) -> bool {
    p.extension().is_some_and(|e| e == "bvh")
}

proptest! {
    #![proptest_config(config(5000))]
    #[test]
    fn damaged_gltf_never_panics(file in 0usize..16, m in mutation()) {
        run_on(is_gltf, file, &m);
    }
}

proptest! {
    #![proptest_config(config(1500))]
    #[test]
    fn damaged_obj_never_panics(file in 0usize..16, m in mutation()) {
        run_on(is_obj, file, &m);
    }
}

proptest! {
    #![proptest_config(config(1500))]
    #[test]
    fn damaged_bvh_never_panics(file in 0usize..16, m in mutation()) {
        run_on(is_bvh, file, &m);
    }
}
