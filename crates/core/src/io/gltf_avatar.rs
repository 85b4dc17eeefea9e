//! Skinned glTF 2.0 / GLB avatars: skeleton from the skin joints, merged bind mesh with skin
//! weights (skinned meshes and rigid parts parented to joints, see `gltf_body`), animations
//! resampled into motions, units converted to metres.
//!
//! Several skins sharing joints become one skeleton. Joints are ordered so that parents come
//! first; non-joint nodes between two joints become (unweighted) joints so local rotations stay
//! exact; non-joint ancestors of root joints fold into `Skeleton::world_from_root_parent`. As
//! the glTF spec requires, a skinned mesh node's own transform is ignored. A file in which no
//! mesh is skinned is an avatar of rigid parts when its meshes hang from a skeleton (a skin's
//! joints or a node hierarchy that reads as one, see `gltf_skinless`), else [`IoError::NoSkin`]
//! says why it is not.

use std::collections::HashMap;
use std::path::Path;

use super::gltf_body::{BindMesh, merge_body};
use super::gltf_doc::GltfDoc;
use super::gltf_skinless::{SkeletonNodes, SkeletonSource, Skinless, skinless};
use super::{ImportOptions, IoError, LoadedAvatar, Units, check_fps, file_stem, read_bytes};
use crate::geometry::{Mat4, Vec3, linear_blend_skin};
use crate::scene::{Avatar, Skeleton};

/// Loads a skinned avatar from a `.glb` or `.gltf` file.
pub fn load_avatar(path: &Path, options: &ImportOptions) -> Result<LoadedAvatar, IoError> {
    load_avatar_from_bytes(&read_bytes(path)?, path, options)
}

/// Loads a skinned avatar from the bytes of a `.glb`/`.gltf` file. `path` names the avatar
/// (file stem), locates external buffers (relative to its folder) and ends error messages.
pub fn load_avatar_from_bytes(
    bytes: &[u8],
    path: &Path,
    options: &ImportOptions,
) -> Result<LoadedAvatar, IoError> {
    let fps = check_fps(options.fps, path)?;
    let doc = GltfDoc::parse(bytes, path)?;
    let mut warnings = Vec::new();
    let rig = build_rig(&doc, &mut warnings)?;
    let (BindMesh { mesh, skin }, meshes) = merge_body(&doc, &rig, &mut warnings)?;
    let skeleton_source = rig.source.clone();
    let mut skeleton = rig.skeleton;
    let scene_err = |source| IoError::Scene {
        source,
        path: path.to_path_buf(),
    };

    // Up axis from the rest mesh's shape, units from its height in file units.
    let rest = linear_blend_skin(
        &mesh.positions,
        &skin,
        &skeleton.skin_from_bind(&skeleton.rest_pose()),
    );
    let joints: Vec<Vec3> = skeleton.joint_positions(&skeleton.rest_pose());
    let (up, detected) = options.up.resolve_body(&skeleton.parents, &joints);
    warnings.extend(up.turned_warning(detected));
    let turn = up.to_y_up();
    let heights = rest.iter().map(|p| (turn * p).y);
    let height =
        heights.clone().fold(f32::NEG_INFINITY, f32::max) - heights.fold(f32::INFINITY, f32::min);
    let (units, scale) = options.units.resolve(height, Units::detect_gltf);
    if options.units == Units::Auto && units != Units::Metres {
        warnings.push(format!(
            "units detected as {} from a rest height of {height:.3} file units",
            units.label()
        ));
    }
    for (j, parent) in skeleton.parents.iter().enumerate() {
        if parent.is_none() {
            skeleton.world_from_root_parent[j] = Mat4::new_scaling(scale)
                * turn.to_homogeneous()
                * skeleton.world_from_root_parent[j];
        }
    }
    report_zero_length_bones(&skeleton, &rig.added, height, &mut warnings);

    let length_tolerance = (1e-3 * height).max(1e-6);
    let motions = super::gltf_anim::load_motions(
        &doc,
        &skeleton,
        &rig.joint_of_node,
        fps,
        length_tolerance,
        &mut warnings,
    )?;
    let avatar = Avatar::new(file_stem(path), skeleton, mesh, skin, motions).map_err(scene_err)?;
    Ok(LoadedAvatar {
        avatar,
        units,
        up,
        warnings,
        meshes,
        skeleton_source,
    })
}

/// The unified skeleton and how glTF nodes and skins map onto it.
pub(crate) struct Rig {
    /// The skeleton in file units (no unit scale yet).
    pub skeleton: Skeleton,
    /// Skeleton joint of each joint node.
    pub joint_of_node: HashMap<usize, usize>,
    /// Skins used by skinned meshes, with per-skin data.
    pub skins: Vec<SkinInfo>,
    /// Joints that are not skin joints (non-joint nodes between two joints).
    pub added: Vec<usize>,
    /// Where the skeleton came from.
    pub source: SkeletonSource,
}

/// One skin used by a skinned mesh.
pub(crate) struct SkinInfo {
    /// glTF skin index.
    pub index: usize,
    /// Skeleton joint of each of the skin's joints.
    pub joint_map: Vec<usize>,
    /// Maps this skin's bind space into the skeleton's bind space (identity for the first).
    pub bind_fix: Mat4,
}

/// Builds the unified skeleton of all skins used by skinned mesh nodes; in a file without
/// skinned meshes, the skeleton its rigid parts hang from (see `gltf_skinless`).
pub(crate) fn build_rig(doc: &GltfDoc, warnings: &mut Vec<String>) -> Result<Rig, IoError> {
    let mut skin_indices: Vec<usize> = Vec::new();
    for node in doc.doc.nodes() {
        if let (Some(_), Some(skin)) = (node.mesh(), node.skin())
            && !skin_indices.contains(&skin.index())
        {
            skin_indices.push(skin.index());
        }
    }
    // Without skinned meshes: an avatar of rigid parts (the joints of a skin its meshes hang
    // from, or its node hierarchy), or no avatar at all.
    let mut hierarchy: Vec<usize> = Vec::new();
    let source = if skin_indices.is_empty() {
        match skinless(doc)? {
            Skinless::Avatar { nodes, source } => {
                match nodes {
                    SkeletonNodes::Skins(skins) => skin_indices = skins,
                    SkeletonNodes::Nodes(nodes) => hierarchy = nodes,
                }
                source
            }
            Skinless::Plain(why) => {
                return Err(IoError::NoSkin {
                    why,
                    path: doc.path.clone(),
                });
            }
        }
    } else {
        SkeletonSource::SkinnedMeshes
    };
    let skins: Vec<gltf::Skin> = doc
        .doc
        .skins()
        .filter(|s| skin_indices.contains(&s.index()))
        .collect();

    // Joint nodes: union of skin joints (or the hierarchy of rigid parts), then nodes between a
    // joint and its nearest joint ancestor.
    let mut nodes: Vec<usize> = Vec::new();
    for skin in &skins {
        let joints: Vec<usize> = skin.joints().map(|n| n.index()).collect();
        if joints.is_empty() {
            return Err(doc.invalid(format!("skin {} has no joints", skin.index())));
        }
        for n in joints {
            if !nodes.contains(&n) {
                nodes.push(n);
            }
        }
    }
    nodes.extend(hierarchy);
    let mut is_joint: std::collections::HashSet<usize> = nodes.iter().copied().collect();
    let mut added = Vec::new();
    for k in 0..nodes.len() {
        let ancestors = doc.ancestors(nodes[k])?;
        if let Some(pos) = ancestors.iter().position(|a| is_joint.contains(a)) {
            for &between in &ancestors[..pos] {
                if is_joint.insert(between) {
                    nodes.push(between);
                    added.push(between);
                }
            }
        }
    }
    if !added.is_empty() {
        warnings.push(format!(
            "{} non-joint nodes between joints were added to the skeleton as unweighted joints",
            added.len()
        ));
    }

    // Topological order: each joint after its joint ancestors, otherwise keeping skin order.
    if nodes.len() > u16::MAX as usize {
        return Err(doc.invalid(format!("{} joints (at most 65535 supported)", nodes.len())));
    }
    let mut order: Vec<usize> = Vec::with_capacity(nodes.len());
    let mut placed = std::collections::HashSet::new();
    for &n in &nodes {
        let mut chain: Vec<usize> = doc
            .ancestors(n)?
            .into_iter()
            .filter(|a| is_joint.contains(a))
            .collect();
        chain.reverse();
        chain.push(n);
        for c in chain {
            if placed.insert(c) {
                order.push(c);
            }
        }
    }
    let joint_of_node: HashMap<usize, usize> =
        order.iter().enumerate().map(|(j, &n)| (n, j)).collect();

    let all_nodes: Vec<gltf::Node> = doc.doc.nodes().collect();
    let mut names = Vec::with_capacity(order.len());
    let mut parents = Vec::with_capacity(order.len());
    let mut rest_local = Vec::with_capacity(order.len());
    let mut world_from_root_parent = Vec::with_capacity(order.len());
    for &n in &order {
        let Some(node) = all_nodes.get(n) else {
            return Err(doc.invalid(format!("joint node {n} does not exist")));
        };
        let base = node
            .name()
            .filter(|s| !s.trim().is_empty())
            .map(str::to_string)
            .unwrap_or_else(|| format!("node{n}"));
        let name = if names.contains(&base) {
            format!("{base}_{n}")
        } else {
            base
        };
        names.push(name);
        rest_local.push(doc.node_transform(node)?);
        let parent_node = doc.parents.get(n).copied().flatten();
        match parent_node.and_then(|p| joint_of_node.get(&p).copied()) {
            Some(p) => {
                parents.push(Some(p));
                world_from_root_parent.push(Mat4::identity());
            }
            None => {
                parents.push(None);
                world_from_root_parent.push(match parent_node {
                    Some(p) => doc.world_matrix(p)?,
                    None => Mat4::identity(),
                });
            }
        }
    }

    // Inverse bind matrices, unifying skins that share joints.
    let mut joint_from_bind: Vec<Option<Mat4>> = vec![None; order.len()];
    let mut infos = Vec::new();
    for skin in &skins {
        let joints: Vec<usize> = skin
            .joints()
            .filter_map(|n| joint_of_node.get(&n.index()).copied())
            .collect();
        let ibms: Vec<Mat4> = match skin.inverse_bind_matrices() {
            Some(acc) => {
                let flat = doc.read_f32(
                    &acc,
                    16,
                    &format!("skin {} inverse bind matrices", skin.index()),
                )?;
                if flat.len() / 16 < joints.len() {
                    return Err(IoError::JointCountMismatch {
                        what: format!(
                            "skin {} inverse bind matrices (one per joint)",
                            skin.index()
                        ),
                        expected: joints.len(),
                        found: flat.len() / 16,
                        path: doc.path.clone(),
                    });
                }
                flat.chunks_exact(16)
                    .take(joints.len())
                    .map(Mat4::from_column_slice)
                    .collect()
            }
            None => vec![Mat4::identity(); joints.len()],
        };
        let shared: Vec<(usize, Mat4)> = joints
            .iter()
            .zip(&ibms)
            .filter_map(|(&j, m)| {
                joint_from_bind[j]
                    .map(|old| (j, old.try_inverse().unwrap_or_else(Mat4::identity) * m))
            })
            .collect();
        let bind_fix = match shared.first() {
            Some(&(_, fix)) => {
                let worst = shared
                    .iter()
                    .map(|(_, m)| (m - fix).abs().max())
                    .fold(0.0f32, f32::max);
                if worst > 1e-3 * fix.abs().max().max(1.0) {
                    warnings.push(format!("skin {} disagrees with an earlier skin on shared bind matrices; the earlier ones are used", skin.index()));
                }
                fix
            }
            None => Mat4::identity(),
        };
        let fix_inv = bind_fix.try_inverse().unwrap_or_else(Mat4::identity);
        for (&j, m) in joints.iter().zip(&ibms) {
            if joint_from_bind[j].is_none() {
                joint_from_bind[j] = Some(m * fix_inv);
            }
        }
        infos.push(SkinInfo {
            index: skin.index(),
            joint_map: joints,
            bind_fix,
        });
    }
    let mut jfb = Vec::with_capacity(order.len());
    for (j, m) in joint_from_bind.into_iter().enumerate() {
        jfb.push(match m {
            Some(m) => m,
            None => doc
                .world_matrix(order[j])?
                .try_inverse()
                .unwrap_or_else(Mat4::identity),
        });
    }
    let skeleton = Skeleton::new(names, parents, rest_local, jfb, world_from_root_parent).map_err(
        |source| IoError::Scene {
            source,
            path: doc.path.clone(),
        },
    )?;
    let added = added
        .iter()
        .filter_map(|n| joint_of_node.get(n).copied())
        .collect();
    Ok(Rig {
        skeleton,
        joint_of_node,
        skins: infos,
        added,
        source,
    })
}

/// Triangles of a primitive given its vertex count and mode; `None` for non-triangle modes.
pub(crate) fn primitive_triangles(
    doc: &GltfDoc,
    prim: &gltf::Primitive,
    vertices: usize,
    what: &str,
) -> Result<Option<Vec<[u32; 3]>>, IoError> {
    let indices: Vec<u32> = match prim.indices() {
        Some(acc) => doc.read_u32(&acc, 1, &format!("{what} indices"))?,
        None => (0..vertices as u32).collect(),
    };
    if let Some(&bad) = indices.iter().find(|&&i| i as usize >= vertices) {
        return Err(doc.invalid(format!(
            "{what}: index {bad} out of range ({vertices} vertices)"
        )));
    }
    let tris: Vec<[u32; 3]> = match prim.mode() {
        gltf::mesh::Mode::Triangles => indices
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect(),
        gltf::mesh::Mode::TriangleStrip => indices
            .windows(3)
            .enumerate()
            .map(|(k, w)| {
                if k % 2 == 0 {
                    [w[0], w[1], w[2]]
                } else {
                    [w[1], w[0], w[2]]
                }
            })
            .collect(),
        gltf::mesh::Mode::TriangleFan => match indices.first() {
            Some(&c) => indices[1..].windows(2).map(|w| [c, w[0], w[1]]).collect(),
            None => Vec::new(),
        },
        _ => return Ok(None),
    };
    Ok(Some(tris))
}

/// Warns about non-root joints that sit exactly on their parent (zero-length bones).
pub(crate) fn report_zero_length_bones(
    skeleton: &Skeleton,
    skip: &[usize],
    size: f32,
    warnings: &mut Vec<String>,
) {
    let tol = (1e-6 * size).max(1e-9);
    let zero: Vec<&str> = (0..skeleton.len())
        .filter(|&j| {
            skeleton.parents[j].is_some()
                && !skip.contains(&j)
                && skeleton.rest_local[j].translation.norm() <= tol
        })
        .map(|j| skeleton.names[j].as_str())
        .collect();
    if !zero.is_empty() {
        warnings.push(format!(
            "{} zero-length bones (joint on its parent): {}",
            zero.len(),
            short_list(&zero, 8)
        ));
    }
}

/// `a, b, c, ... (+n more)`.
pub(crate) fn short_list(items: &[&str], max: usize) -> String {
    let mut s = items
        .iter()
        .take(max)
        .copied()
        .collect::<Vec<_>>()
        .join(", ");
    if items.len() > max {
        s.push_str(&format!(", ... (+{} more)", items.len() - max));
    }
    s
}
