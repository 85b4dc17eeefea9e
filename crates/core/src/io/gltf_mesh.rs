//! glTF/GLB meshes as garment templates: every triangle primitive of every mesh node of the
//! default scene, placed by its node's world transform, merged into one [`TriMesh`] in metres.
//! Mesh nodes outside that scene, and meshes no node places, are left out with a warning.

use std::path::Path;

use super::gltf_avatar::primitive_triangles;
use super::gltf_doc::GltfDoc;
use super::units::largest_extent;
use super::{ImportOptions, IoError, LoadedMesh, Units, UpAxis, file_stem, read_bytes};
use crate::geometry::{TriMesh, Vec3};

/// Loads a (possibly unskinned) glTF/GLB mesh as a garment template.
pub fn load_gltf_mesh(path: &Path, options: &ImportOptions) -> Result<LoadedMesh, IoError> {
    load_gltf_mesh_from_bytes(&read_bytes(path)?, path, options)
}

/// Loads a glTF/GLB mesh from bytes; `path` names it, locates external buffers and ends error
/// messages. UVs (`TEXCOORD_0`) are kept when every primitive has them. A skinned node is
/// placed by its node transform like any other (its skin is ignored, with a warning).
pub fn load_gltf_mesh_from_bytes(
    bytes: &[u8],
    path: &Path,
    options: &ImportOptions,
) -> Result<LoadedMesh, IoError> {
    let doc = GltfDoc::parse(bytes, path)?;
    let mut warnings = Vec::new();
    let scene_nodes: Vec<usize> = match doc.doc.default_scene().or_else(|| doc.doc.scenes().next())
    {
        Some(scene) => {
            let mut out = Vec::new();
            let mut stack: Vec<gltf::Node> = scene.nodes().collect();
            while let Some(node) = stack.pop() {
                if out.len() > doc.parents.len() {
                    return Err(doc.invalid("scene graph revisits nodes"));
                }
                out.push(node.index());
                stack.extend(node.children());
            }
            out.sort_unstable();
            out.dedup();
            out
        }
        None => (0..doc.parents.len()).collect(),
    };
    let nodes: Vec<gltf::Node> = doc.doc.nodes().collect();
    warn_unplaced_meshes(&nodes, &scene_nodes, &doc, &mut warnings);
    let mut positions: Vec<Vec3> = Vec::new();
    let mut faces: Vec<[u32; 3]> = Vec::new();
    let mut uvs: Vec<[f32; 2]> = Vec::new();
    let (mut all_uvs, mut skinned, mut skipped) = (true, false, 0usize);
    for n in scene_nodes {
        let Some(node) = nodes.get(n) else {
            continue;
        };
        let Some(mesh) = node.mesh() else {
            continue;
        };
        skinned |= node.skin().is_some();
        let world = doc.world_matrix(n)?;
        let flip = world.fixed_view::<3, 3>(0, 0).determinant() < 0.0;
        for prim in mesh.primitives() {
            let what = format!("mesh {} primitive {}", mesh.index(), prim.index());
            let Some(acc) = prim.get(&gltf::Semantic::Positions) else {
                return Err(doc.invalid(format!("{what} has no POSITION")));
            };
            let pos = doc.read_f32(&acc, 3, &format!("{what} POSITION"))?;
            let count = pos.len() / 3;
            let Some(tris) = primitive_triangles(&doc, &prim, count, &what)? else {
                skipped += 1;
                continue;
            };
            let base = positions.len();
            if base + count > u32::MAX as usize {
                return Err(doc.invalid("too many vertices"));
            }
            positions.extend(pos.chunks_exact(3).map(|c| {
                world
                    .transform_point(&nalgebra::Point3::new(c[0], c[1], c[2]))
                    .coords
            }));
            faces.extend(tris.iter().map(|t| {
                let t = t.map(|i| i + base as u32);
                if flip { [t[0], t[2], t[1]] } else { t }
            }));
            match prim.get(&gltf::Semantic::TexCoords(0)) {
                Some(acc) => {
                    let uv = doc.read_f32(&acc, 2, &format!("{what} TEXCOORD_0"))?;
                    if uv.len() / 2 != count {
                        return Err(IoError::JointCountMismatch {
                            what: format!("{what} TEXCOORD_0 (one per vertex)"),
                            expected: count,
                            found: uv.len() / 2,
                            path: doc.path.clone(),
                        });
                    }
                    uvs.extend(uv.chunks_exact(2).map(|c| [c[0], c[1]]));
                }
                None => all_uvs = false,
            }
        }
    }
    if faces.is_empty() {
        return Err(IoError::NoMesh {
            path: path.to_path_buf(),
        });
    }
    if skinned {
        warnings.push("skinned mesh placed by its node transform; its skin is ignored".into());
    }
    if skipped > 0 {
        warnings.push(format!(
            "{skipped} non-triangle primitives (points/lines) ignored"
        ));
    }
    if !all_uvs && !uvs.is_empty() {
        warnings.push("some primitives have no TEXCOORD_0; UVs dropped".into());
    }
    if !positions.iter().all(|p| p.iter().all(|v| v.is_finite())) {
        return Err(IoError::NonFinite {
            what: "vertex positions after the node transforms".into(),
            path: path.to_path_buf(),
        });
    }
    // glTF is Y up by its specification: turned only when told.
    let up = match options.up {
        UpAxis::Auto => UpAxis::Y,
        given => given,
    };
    let turn = up.to_y_up();
    let extent = largest_extent(&positions);
    let (units, scale) = options.units.resolve(extent, Units::detect_gltf);
    if options.units == Units::Auto && units != Units::Metres {
        warnings.push(format!(
            "units detected as {} from a largest extent of {extent:.3} file units",
            units.label()
        ));
    }
    let uvs = (all_uvs && uvs.len() == positions.len()).then_some(uvs);
    let mut mesh = TriMesh {
        positions,
        faces,
        uvs,
    };
    mesh.map_positions(|p| turn * p * scale);
    mesh.validate()
        .map_err(|e| doc.invalid(format!("mesh: {e}")))?;
    Ok(LoadedMesh {
        name: file_stem(path),
        mesh,
        units,
        up,
        warnings,
    })
}

/// Warns about meshes the garment leaves out: mesh nodes outside the scene, meshes no node
/// places.
fn warn_unplaced_meshes(
    nodes: &[gltf::Node],
    scene_nodes: &[usize],
    doc: &GltfDoc,
    warnings: &mut Vec<String>,
) {
    let name = |name: Option<&str>, what: &str, index: usize| {
        name.filter(|s| !s.trim().is_empty())
            .map_or_else(|| format!("{what} {index}"), str::to_string)
    };
    let outside: Vec<String> = nodes
        .iter()
        .filter(|n| n.mesh().is_some() && scene_nodes.binary_search(&n.index()).is_err())
        .map(|n| name(n.name(), "node", n.index()))
        .collect();
    let unplaced: Vec<String> = doc
        .doc
        .meshes()
        .filter(|m| {
            !nodes
                .iter()
                .any(|n| n.mesh().is_some_and(|nm| nm.index() == m.index()))
        })
        .map(|m| name(m.name(), "mesh", m.index()))
        .collect();
    for (list, what, why) in [
        (outside, "mesh node", "outside the default scene"),
        (unplaced, "mesh", "no node places it"),
    ] {
        if !list.is_empty() {
            let refs: Vec<&str> = list.iter().map(String::as_str).collect();
            warnings.push(format!(
                "{} {what}{} ignored ({why}): {}",
                list.len(),
                if list.len() == 1 { "" } else { "s" },
                super::gltf_avatar::short_list(&refs, 8)
            ));
        }
    }
}
