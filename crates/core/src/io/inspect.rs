//! A human-readable report on any supported file (glb, gltf, obj, bvh): joints as a short
//! tree, vertices and faces, every mesh of an avatar and how it was used (skinned, rigid part
//! of a joint, ignored and why), animations with frame counts and durations, units, the up
//! axis, warnings, and what else the file holds that the tool does not use
//! ([`super::inspect_contents`]: materials, cameras, morph targets, OBJ groups, ...).

use std::fmt::Write as _;
use std::path::Path;

use super::inspect_contents::{bvh_contents, gltf_contents, obj_contents};
use super::joint_map::JointMap;
use super::joint_names::classify;
use super::joint_structure::{RigShape, label_by_structure};
use super::retarget::{SourceMotion, joint_mapping};
use super::{ImportOptions, IoError, LoadedMesh, MeshUsage, MeshUse, Units, UpAxis};
use crate::geometry::TriMesh;

/// Most lines of the joint tree shown before it is cut short.
const MAX_TREE_LINES: usize = 40;

/// Loads `path` by its extension and describes what it holds (units and up axis detected).
pub fn inspect(path: &Path) -> Result<String, IoError> {
    inspect_with(path, &ImportOptions::default())
}

/// Loads `path` by its extension with `options` (units, up axis) and describes what it holds.
pub fn inspect_with(path: &Path, options: &ImportOptions) -> Result<String, IoError> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let options = options.clone();
    let mut out = String::new();
    let _ = writeln!(out, "file: {}", path.display());
    match ext.as_str() {
        "glb" | "gltf" => match super::load_avatar(path, &options) {
            Ok(loaded) => {
                let a = &loaded.avatar;
                let _ = writeln!(out, "kind: {}", loaded.skeleton_source);
                units_line(&mut out, options.units, loaded.units);
                up_line(&mut out, options.up, loaded.up, false);
                let _ = writeln!(out, "height: {:.3} m", a.height_m());
                joint_tree(&mut out, &a.skeleton.names, &a.skeleton.parents);
                mesh_lines(&mut out, "body", &a.bind_mesh);
                mesh_uses(&mut out, &loaded.meshes);
                let _ = writeln!(out, "animations: {}", a.motions.len());
                for m in &a.motions {
                    let _ = writeln!(
                        out,
                        "  '{}': {:.3} s, {} frames at {} fps",
                        m.name,
                        m.duration_secs(),
                        m.frame_count(),
                        m.fps
                    );
                }
                gltf_contents(&mut out, path)?;
                warnings(&mut out, &loaded.warnings);
            }
            Err(IoError::NoSkin { why, .. }) => {
                let loaded = super::load_gltf_mesh(path, &options)?;
                let _ = writeln!(
                    out,
                    "kind: glTF mesh without a skin (usable as a garment; not an avatar of \
                     rigid parts: {why})"
                );
                static_mesh(&mut out, &options, &loaded, true);
                gltf_contents(&mut out, path)?;
                warnings(&mut out, &loaded.warnings);
            }
            Err(e) => return Err(e),
        },
        "obj" => {
            let loaded = super::load_obj(path, &options)?;
            let _ = writeln!(out, "kind: OBJ mesh");
            static_mesh(&mut out, &options, &loaded, false);
            obj_contents(&mut out, path)?;
            warnings(&mut out, &loaded.warnings);
        }
        "bvh" => {
            let mut bvh = super::load_bvh(path)?;
            bvh.up = options.up;
            let (units, scale) = bvh.resolve_units(options.units);
            let (up, detected) = bvh.up_axis();
            bvh.warnings.extend(up.turned_warning(detected));
            let _ = writeln!(out, "kind: BVH motion capture");
            units_line(&mut out, options.units, units);
            up_line(&mut out, options.up, up, false);
            let names: Vec<String> = bvh.joints.iter().map(|j| j.name.clone()).collect();
            let parents: Vec<Option<usize>> = bvh.joints.iter().map(|j| j.parent).collect();
            joint_tree(&mut out, &names, &parents);
            let _ = writeln!(out, "channels: {} per frame", bvh.channel_count);
            let _ = writeln!(
                out,
                "motion: {} frames, frame time {} s ({:.2} fps), {:.3} s",
                bvh.frame_count(),
                bvh.frame_time_secs,
                bvh.fps(),
                bvh.duration_secs()
            );
            let turn = up.to_y_up();
            let rest: Vec<_> = bvh.rest_positions().iter().map(|p| turn * p).collect();
            hip_height(&mut out, &names, &parents, &rest, scale);
            let rig = classify(&names);
            let mut canonical: Vec<&str> = rig.canonical.iter().flatten().copied().collect();
            canonical.sort_unstable();
            let _ = writeln!(
                out,
                "retargetable joints ({} naming, as Mixamo names): {} ({})",
                rig.convention,
                canonical.len(),
                canonical.join(", ")
            );
            bvh_contents(&mut out, &bvh);
            warnings(&mut out, &bvh.warnings);
        }
        _ => {
            return Err(IoError::UnsupportedFormat {
                extension: ext,
                path: path.to_path_buf(),
            });
        }
    }
    Ok(out)
}

/// [`inspect`]'s report on a motion file (BVH or glTF), then the joint mapping retargeting
/// would use onto `avatar` (a skinned glTF/GLB, or the built-in `mannequin` when no such file
/// exists) with the user's `joint_map`: each avatar joint and its motion joint, what is left
/// unmapped, and whether every essential joint is mapped.
pub fn inspect_mapping(
    path: &Path,
    avatar: &Path,
    joint_map: Option<&JointMap>,
    options: &ImportOptions,
) -> Result<String, IoError> {
    let mut out = inspect_with(path, options)?;
    let scene_err = |source| IoError::Scene {
        source,
        path: avatar.to_path_buf(),
    };
    let skeleton = if avatar == Path::new("mannequin") && !avatar.exists() {
        crate::scene::procedural::mannequin::skeleton().map_err(scene_err)?
    } else {
        super::load_avatar(avatar, &ImportOptions::default())?
            .avatar
            .skeleton
    };
    let source = match ext_of(path).as_str() {
        "bvh" => {
            let mut bvh = super::load_bvh(path)?;
            bvh.up = options.up;
            SourceMotion::from_bvh(&bvh)
        }
        _ => {
            let rig = super::load_avatar(path, options)?.avatar;
            let rest = crate::scene::Motion::new(
                "rest",
                30.0,
                vec![rig.skeleton.rest_pose()],
                rig.skeleton.len(),
            )
            .map_err(|source| IoError::Scene {
                source,
                path: path.to_path_buf(),
            })?;
            let motion = rig.motions.first().unwrap_or(&rest);
            SourceMotion::from_rig(&rig.skeleton, motion, path)
        }
    };
    let (avatar_names, motion_names) = (&skeleton.names, &source.names);
    let mapping = joint_mapping(&source, &skeleton, joint_map)?;
    let _ = writeln!(out, "retargeting onto: {}", avatar.display());
    out.push_str(&mapping.report(avatar_names, motion_names));
    match mapping.check_essential(avatar_names, motion_names, path) {
        Ok(()) => {
            let _ = writeln!(out, "essential joints: all mapped");
        }
        Err(IoError::UnmappedJoints {
            joints, closest, ..
        }) => {
            let _ = writeln!(
                out,
                "essential joints NOT mapped: {} (closest motion joints: {closest}; give them \
                 with --joint-map)",
                joints.join(", ")
            );
        }
        Err(e) => return Err(e),
    }
    Ok(out)
}

fn ext_of(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

fn units_line(out: &mut String, asked: Units, used: Units) {
    let how = if asked == Units::Auto {
        "detected"
    } else {
        "given"
    };
    let _ = writeln!(
        out,
        "units: {} ({how}; {} m per unit)",
        used.label(),
        used.metres_per_unit().unwrap_or(1.0)
    );
}

/// Writes the rest hip height above the lowest end joint, in metres (`scale` per file unit):
/// of the hips the names give, else the skeleton's structure, else the root joint.
fn hip_height(
    out: &mut String,
    names: &[String],
    parents: &[Option<usize>],
    rest: &[crate::geometry::Vec3],
    scale: f32,
) {
    let shape = RigShape {
        parents,
        rest,
        frames: &[],
    };
    let (hips, how) = match classify(names).joint_of("Hips") {
        Some(h) => (h, "named"),
        None => match label_by_structure(&shape)
            .ok()
            .and_then(|l| l.iter().position(|c| *c == Some("Hips")))
        {
            Some(h) => (h, "found by structure"),
            None => (0, "the root joint"),
        },
    };
    let mut has_child = vec![false; rest.len()];
    for p in parents.iter().flatten() {
        if let Some(c) = has_child.get_mut(*p) {
            *c = true;
        }
    }
    let low = rest
        .iter()
        .zip(&has_child)
        .filter(|(_, c)| !**c)
        .map(|(p, _)| p.y)
        .fold(f32::INFINITY, f32::min);
    if let Some(h) = rest.get(hips)
        && low.is_finite()
    {
        let _ = writeln!(
            out,
            "hip height (rest, above the lowest end joint): {:.3} m ('{}', {how})",
            (h.y - low) * scale,
            names.get(hips).map_or("?", String::as_str)
        );
    }
}

/// Writes `up: AXIS (given, detected or as glTF specifies[; turned Y up])`.
fn up_line(out: &mut String, asked: UpAxis, used: UpAxis, gltf_mesh: bool) {
    let how = match (asked, gltf_mesh) {
        (UpAxis::Auto, false) => "detected",
        (UpAxis::Auto, true) => "as glTF specifies",
        _ => "given",
    };
    let turned = if used == UpAxis::Z {
        "; turned Y up"
    } else {
        ""
    };
    let _ = writeln!(out, "up: {} ({how}{turned})", used.label());
}

fn static_mesh(out: &mut String, options: &ImportOptions, loaded: &LoadedMesh, gltf: bool) {
    units_line(out, options.units, loaded.units);
    up_line(out, options.up, loaded.up, gltf);
    mesh_lines(out, "mesh", &loaded.mesh);
    if let Some((lo, hi)) = loaded.mesh.bounds() {
        let size = hi - lo;
        let _ = writeln!(out, "size: {:.3} x {:.3} x {:.3} m", size.x, size.y, size.z);
    }
}

fn mesh_lines(out: &mut String, what: &str, mesh: &TriMesh) {
    let _ = writeln!(
        out,
        "{what}: {} vertices, {} triangles, UVs {}",
        mesh.vertex_count(),
        mesh.faces.len(),
        if mesh.uvs.is_some() { "yes" } else { "no" }
    );
}

/// Writes `meshes: N (...)` and one line per mesh of an avatar file: skinned, rigid part of a
/// joint, or ignored and why.
fn mesh_uses(out: &mut String, meshes: &[MeshUse]) {
    let count = |f: fn(&MeshUsage) -> bool| meshes.iter().filter(|m| f(&m.usage)).count();
    let _ = writeln!(
        out,
        "meshes: {} ({} skinned, {} rigid parts, {} ignored)",
        meshes.len(),
        count(|u| matches!(u, MeshUsage::Skinned)),
        count(|u| matches!(u, MeshUsage::Rigid { .. })),
        count(|u| matches!(u, MeshUsage::Ignored { .. })),
    );
    for m in meshes {
        let _ = writeln!(out, "  {m}");
    }
}

fn warnings(out: &mut String, warnings: &[String]) {
    if warnings.is_empty() {
        let _ = writeln!(out, "warnings: none");
    } else {
        let _ = writeln!(out, "warnings: {}", warnings.len());
        for w in warnings {
            let _ = writeln!(out, "  - {w}");
        }
    }
}

/// Writes `joints: N` and an indented tree (parents precede children), cut after
/// [`MAX_TREE_LINES`] lines.
fn joint_tree(out: &mut String, names: &[String], parents: &[Option<usize>]) {
    let _ = writeln!(out, "joints: {}", names.len());
    let mut children = vec![Vec::new(); names.len()];
    let mut roots = Vec::new();
    for (j, p) in parents.iter().enumerate() {
        match p.filter(|&p| p < names.len()) {
            Some(p) => children[p].push(j),
            None => roots.push(j),
        }
    }
    let mut stack: Vec<(usize, usize)> = roots.iter().rev().map(|&r| (r, 1)).collect();
    let mut shown = 0;
    while let Some((j, depth)) = stack.pop() {
        if shown == MAX_TREE_LINES {
            let _ = writeln!(out, "  ... (+{} more joints)", names.len() - shown);
            break;
        }
        let _ = writeln!(out, "{}{}", "  ".repeat(depth.min(20)), names[j]);
        shown += 1;
        stack.extend(children[j].iter().rev().map(|&c| (c, depth + 1)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tree_is_indented_and_cut() {
        let names: Vec<String> = (0..50).map(|i| format!("j{i}")).collect();
        let parents: Vec<Option<usize>> = (0..50)
            .map(|i| if i == 0 { None } else { Some(0) })
            .collect();
        let mut out = String::new();
        joint_tree(&mut out, &names, &parents);
        assert!(out.starts_with("joints: 50\n  j0\n    j1\n"));
        assert!(out.contains("(+10 more joints)"));
    }

    #[test]
    fn unknown_extension_is_an_error() {
        let err = inspect(Path::new("model.fbx")).unwrap_err();
        assert!(matches!(err, IoError::UnsupportedFormat { .. }));
        assert!(err.to_string().ends_with("model.fbx"));
    }
}
