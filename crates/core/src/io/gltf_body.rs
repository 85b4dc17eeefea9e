//! The body of a glTF avatar: every skinned mesh node (in its skin's bind space, with its
//! skin's weights) and every *rigid part* — a mesh node without a skin that hangs under a joint
//! of the skeleton, directly or through non-joint nodes (a common game-asset style: a
//! character built of pieces parented to bones). A rigid part is placed in bind space through
//! the node hierarchy (its transform relative to the joint, then the joint's bind matrix) and
//! each of its vertices is bound with weight 1 to that joint, so it follows the joint exactly
//! as the glTF scene graph would move it.
//!
//! Every mesh of the file is accounted for in a [`MeshUse`]. A mesh node under no joint (a
//! static prop at the scene root, or a mesh under the armature node but not under a bone)
//! would not move with the body and is left out, as is a mesh that no node places or that has
//! no triangles; each is named in a warning. Skinned parts come first in the merged mesh, in
//! node order, then the rigid parts, so a file without rigid parts keeps its vertex order.

use std::collections::HashSet;
use std::fmt;

use super::IoError;
use super::gltf_avatar::{Rig, SkinInfo, primitive_triangles, short_list};
use super::gltf_doc::GltfDoc;
use crate::geometry::{Mat4, SkinWeights, TriMesh, Vec3};

/// Why a mesh node under no joint is left out of the body.
const NOT_UNDER_JOINT: &str =
    "not parented to a joint: a static prop, it would not move with the body";
/// Why a mesh that no node places is left out.
const NO_NODE: &str = "no node places it";
/// Why a mesh without triangles is left out.
const NO_TRIANGLES: &str = "no triangle primitives (points or lines only)";

/// How the avatar importer used one mesh of a glTF file: one entry per mesh node, and one per
/// mesh that no node places.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshUse {
    /// The mesh's name, or `mesh N` when it has none.
    pub mesh: String,
    /// The node that places it (its name, or `node N`); `None` for a mesh no node places.
    pub node: Option<String>,
    /// Vertices of its primitives in the file.
    pub vertices: usize,
    /// What the importer made of it.
    pub usage: MeshUsage,
}

/// What became of one mesh of an avatar file.
#[derive(Clone, Debug, PartialEq)]
pub enum MeshUsage {
    /// Part of the body, deformed by its skin.
    Skinned,
    /// Part of the body as a rigid part: every vertex bound with weight 1 to `joint`.
    Rigid {
        /// The skeleton joint it follows.
        joint: String,
    },
    /// Left out of the body, with a warning.
    Ignored {
        /// Why.
        reason: String,
    },
}

impl MeshUse {
    /// `'mesh'`, with `(node 'name')` when the node's name differs from the mesh's.
    pub fn label(&self) -> String {
        match &self.node {
            Some(node) if node != &self.mesh => format!("'{}' (node '{node}')", self.mesh),
            _ => format!("'{}'", self.mesh),
        }
    }
}

impl fmt::Display for MeshUse {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {} vertices, ", self.label(), self.vertices)?;
        match &self.usage {
            MeshUsage::Skinned => write!(f, "skinned body part"),
            MeshUsage::Rigid { joint } => write!(f, "rigid part of joint '{joint}' (weight 1)"),
            MeshUsage::Ignored { reason } => write!(f, "ignored: {reason}"),
        }
    }
}

/// The merged bind-space mesh of the body with its skin weights.
pub(crate) struct BindMesh {
    /// Bind-space mesh (file units).
    pub mesh: TriMesh,
    /// Weights into the unified skeleton.
    pub skin: SkinWeights,
}

/// How the vertices of one mesh are weighted.
enum Binding<'a> {
    /// By the primitive's JOINTS/WEIGHTS into this skin.
    Skin(&'a SkinInfo),
    /// With weight 1 to this skeleton joint.
    Rigid(u16),
}

/// Merges every skinned mesh node and every rigid part into one bind-space mesh and says what
/// became of each mesh of the file (ignored ones also as warnings).
pub(crate) fn merge_body(
    doc: &GltfDoc,
    rig: &Rig,
    warnings: &mut Vec<String>,
) -> Result<(BindMesh, Vec<MeshUse>), IoError> {
    let mut body = BodyBuilder::default();
    let mut uses = Vec::new();
    let mut placed = HashSet::new();
    let nodes: Vec<gltf::Node> = doc.doc.nodes().collect();
    for node in &nodes {
        let (Some(mesh), Some(skin)) = (node.mesh(), node.skin()) else {
            continue;
        };
        placed.insert(mesh.index());
        let usage = match rig.skins.iter().find(|s| s.index == skin.index()) {
            Some(info) => {
                let added = body.add_mesh(doc, &mesh, &info.bind_fix, &Binding::Skin(info))?;
                used_or_empty(added, MeshUsage::Skinned)
            }
            None => ignored("its skin is not part of the skeleton"),
        };
        uses.push(mesh_use(node, &mesh, usage));
    }
    for node in &nodes {
        let Some(mesh) = node.mesh().filter(|_| node.skin().is_none()) else {
            continue;
        };
        placed.insert(mesh.index());
        let usage = match rigid_placement(doc, rig, node.index())? {
            Some((joint, bind_from_mesh)) => {
                let j = u16::try_from(joint)
                    .map_err(|_| doc.invalid(format!("joint {joint} beyond 65535")))?;
                let added = body.add_mesh(doc, &mesh, &bind_from_mesh, &Binding::Rigid(j))?;
                let joint = rig.skeleton.names.get(joint).cloned().unwrap_or_default();
                used_or_empty(added, MeshUsage::Rigid { joint })
            }
            None => ignored(NOT_UNDER_JOINT),
        };
        uses.push(mesh_use(node, &mesh, usage));
    }
    for mesh in doc.doc.meshes().filter(|m| !placed.contains(&m.index())) {
        uses.push(MeshUse {
            mesh: mesh_name(&mesh),
            node: None,
            vertices: file_vertices(&mesh),
            usage: ignored(NO_NODE),
        });
    }
    warn_ignored(&uses, warnings);
    Ok((body.finish(doc, warnings)?, uses))
}

/// The joint a skinless mesh node follows and the matrix that takes its vertices into bind
/// space: the nearest joint among the node itself and its ancestors; `None` when there is none.
fn rigid_placement(
    doc: &GltfDoc,
    rig: &Rig,
    node: usize,
) -> Result<Option<(usize, Mat4)>, IoError> {
    let bind_from = |joint: usize, joint_from_mesh: Mat4| {
        let joint_from_bind = rig.skeleton.joint_from_bind.get(joint).copied();
        match joint_from_bind.and_then(|m| m.try_inverse()) {
            Some(bind_from_joint) => Ok(Some((joint, bind_from_joint * joint_from_mesh))),
            None => Err(doc.invalid(format!(
                "the bind matrix of joint '{}' is not invertible",
                rig.skeleton.names.get(joint).map_or("?", String::as_str)
            ))),
        }
    };
    if let Some(&joint) = rig.joint_of_node.get(&node) {
        return bind_from(joint, Mat4::identity());
    }
    let mut joint_from_mesh = doc.local_matrix(node)?;
    for a in doc.ancestors(node)? {
        if let Some(&joint) = rig.joint_of_node.get(&a) {
            return bind_from(joint, joint_from_mesh);
        }
        joint_from_mesh = doc.local_matrix(a)? * joint_from_mesh;
    }
    Ok(None)
}

fn ignored(reason: &str) -> MeshUsage {
    MeshUsage::Ignored {
        reason: reason.to_string(),
    }
}

/// `usage`, or ignored when the mesh gave no triangles.
fn used_or_empty(added_vertices: usize, usage: MeshUsage) -> MeshUsage {
    if added_vertices == 0 {
        ignored(NO_TRIANGLES)
    } else {
        usage
    }
}

fn mesh_name(mesh: &gltf::Mesh) -> String {
    mesh.name()
        .filter(|s| !s.trim().is_empty())
        .map_or_else(|| format!("mesh {}", mesh.index()), str::to_string)
}

/// Vertices of a mesh's primitives as the file declares them (POSITION counts).
fn file_vertices(mesh: &gltf::Mesh) -> usize {
    mesh.primitives()
        .filter_map(|p| p.get(&gltf::Semantic::Positions))
        .map(|a| a.count())
        .sum()
}

fn mesh_use(node: &gltf::Node, mesh: &gltf::Mesh, usage: MeshUsage) -> MeshUse {
    let node_name = node
        .name()
        .filter(|s| !s.trim().is_empty())
        .map_or_else(|| format!("node {}", node.index()), str::to_string);
    MeshUse {
        mesh: mesh_name(mesh),
        node: Some(node_name),
        vertices: file_vertices(mesh),
        usage,
    }
}

/// One warning per reason, naming the meshes left out for it.
fn warn_ignored(uses: &[MeshUse], warnings: &mut Vec<String>) {
    let mut by_reason: Vec<(&str, Vec<String>)> = Vec::new();
    for u in uses {
        if let MeshUsage::Ignored { reason } = &u.usage {
            match by_reason.iter_mut().find(|(r, _)| r == reason) {
                Some((_, labels)) => labels.push(u.label()),
                None => by_reason.push((reason, vec![u.label()])),
            }
        }
    }
    for (reason, labels) in by_reason {
        let refs: Vec<&str> = labels.iter().map(String::as_str).collect();
        warnings.push(format!(
            "{} mesh{} left out of the body ({reason}): {}",
            labels.len(),
            if labels.len() == 1 { "" } else { "es" },
            short_list(&refs, 8)
        ));
    }
}

/// The merged mesh as it is built.
#[derive(Default)]
struct BodyBuilder {
    positions: Vec<Vec3>,
    faces: Vec<[u32; 3]>,
    uvs: Vec<[f32; 2]>,
    missing_uvs: bool,
    influences: Vec<Vec<(u16, f32)>>,
    skipped_primitives: usize,
    morphs: bool,
}

impl BodyBuilder {
    /// Adds the triangle primitives of `mesh`, its vertices taken into bind space by
    /// `bind_from_mesh` (faces flipped when it mirrors); returns the vertices added.
    fn add_mesh(
        &mut self,
        doc: &GltfDoc,
        mesh: &gltf::Mesh,
        bind_from_mesh: &Mat4,
        binding: &Binding,
    ) -> Result<usize, IoError> {
        let flip = bind_from_mesh.fixed_view::<3, 3>(0, 0).determinant() < 0.0;
        let mut added = 0;
        for prim in mesh.primitives() {
            let what = format!("mesh {} primitive {}", mesh.index(), prim.index());
            self.morphs |= prim.morph_targets().next().is_some();
            let Some(pos_acc) = prim.get(&gltf::Semantic::Positions) else {
                return Err(doc.invalid(format!("{what} has no POSITION")));
            };
            let pos = doc.read_f32(&pos_acc, 3, &format!("{what} POSITION"))?;
            let n = pos.len() / 3;
            let Some(tris) = primitive_triangles(doc, &prim, n, &what)? else {
                self.skipped_primitives += 1;
                continue;
            };
            let base = self.positions.len();
            if base + n > u32::MAX as usize {
                return Err(doc.invalid("too many vertices"));
            }
            self.positions.extend(pos.chunks_exact(3).map(|c| {
                bind_from_mesh
                    .transform_point(&nalgebra::Point3::new(c[0], c[1], c[2]))
                    .coords
            }));
            self.faces.extend(tris.iter().map(|t| {
                let t = t.map(|i| i + base as u32);
                if flip { [t[0], t[2], t[1]] } else { t }
            }));
            match prim.get(&gltf::Semantic::TexCoords(0)) {
                Some(acc) => {
                    let uv = doc.read_f32(&acc, 2, &format!("{what} TEXCOORD_0"))?;
                    if uv.len() / 2 != n {
                        return Err(count_mismatch(doc, &what, "TEXCOORD_0", n, uv.len() / 2));
                    }
                    self.uvs.extend(uv.chunks_exact(2).map(|c| [c[0], c[1]]));
                }
                None => self.missing_uvs = true,
            }
            match binding {
                Binding::Skin(info) => self
                    .influences
                    .extend(skin_influences(doc, &prim, info, n, &what)?),
                Binding::Rigid(joint) => self
                    .influences
                    .extend(std::iter::repeat_n(vec![(*joint, 1.0)], n)),
            }
            added += n;
        }
        Ok(added)
    }

    /// The finished mesh and weights, with warnings about what was dropped on the way.
    fn finish(self, doc: &GltfDoc, warnings: &mut Vec<String>) -> Result<BindMesh, IoError> {
        if self.skipped_primitives > 0 {
            warnings.push(format!(
                "{} non-triangle primitives (points/lines) ignored",
                self.skipped_primitives
            ));
        }
        if self.morphs {
            warnings.push("morph targets present but ignored".into());
        }
        if self.faces.is_empty() {
            return Err(IoError::NoMesh {
                path: doc.path.clone(),
            });
        }
        let (skin, fallbacks) = SkinWeights::from_influences(self.influences, 0);
        if fallbacks > 0 {
            warnings.push(format!(
                "{fallbacks} vertices had no usable skin weight and were bound to the root joint"
            ));
        }
        if self.missing_uvs && !self.uvs.is_empty() {
            warnings.push("some primitives have no TEXCOORD_0; UVs dropped".into());
        }
        let uvs = (!self.missing_uvs && self.uvs.len() == self.positions.len()).then_some(self.uvs);
        let mesh = TriMesh {
            positions: self.positions,
            faces: self.faces,
            uvs,
        };
        mesh.validate()
            .map_err(|e| doc.invalid(format!("bind mesh: {e}")))?;
        Ok(BindMesh { mesh, skin })
    }
}

/// The skin influences of each of a primitive's `n` vertices (JOINTS_0/WEIGHTS_0 and, when
/// present, set 1), as skeleton joints.
fn skin_influences(
    doc: &GltfDoc,
    prim: &gltf::Primitive,
    info: &SkinInfo,
    n: usize,
    what: &str,
) -> Result<Vec<Vec<(u16, f32)>>, IoError> {
    let mut lists: Vec<Vec<(u16, f32)>> = vec![Vec::new(); n];
    for set in 0..2u32 {
        let (Some(ja), Some(wa)) = (
            prim.get(&gltf::Semantic::Joints(set)),
            prim.get(&gltf::Semantic::Weights(set)),
        ) else {
            if set == 0 {
                return Err(doc.invalid(format!(
                    "{what} of a skinned mesh has no JOINTS_0/WEIGHTS_0"
                )));
            }
            continue;
        };
        let joints = doc.read_u32(&ja, 4, &format!("{what} JOINTS_{set}"))?;
        let weights = doc.read_f32(&wa, 4, &format!("{what} WEIGHTS_{set}"))?;
        if joints.len() / 4 != n || weights.len() / 4 != n {
            return Err(count_mismatch(
                doc,
                what,
                &format!("JOINTS_{set}/WEIGHTS_{set}"),
                n,
                (joints.len() / 4).min(weights.len() / 4),
            ));
        }
        for (v, list) in lists.iter_mut().enumerate() {
            for k in 0..4 {
                let (j, w) = (joints[v * 4 + k] as usize, weights[v * 4 + k]);
                if w == 0.0 {
                    continue;
                }
                let Some(&sj) = info.joint_map.get(j) else {
                    return Err(IoError::JointCountMismatch {
                        what: format!(
                            "{what} JOINTS_{set} refers to joint {j} of skin {}, joints in the skin",
                            info.index
                        ),
                        expected: info.joint_map.len(),
                        found: j + 1,
                        path: doc.path.clone(),
                    });
                };
                list.push((sj as u16, w));
            }
        }
    }
    Ok(lists)
}

fn count_mismatch(doc: &GltfDoc, what: &str, attr: &str, expected: usize, found: usize) -> IoError {
    IoError::JointCountMismatch {
        what: format!("{what} {attr} (one per vertex)"),
        expected,
        found,
        path: doc.path.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn use_of(mesh: &str, node: Option<&str>, usage: MeshUsage) -> MeshUse {
        MeshUse {
            mesh: mesh.into(),
            node: node.map(str::to_string),
            vertices: 8,
            usage,
        }
    }

    #[test]
    fn each_use_reads_as_one_line() {
        let rigid = use_of(
            "Box",
            Some("Helmet"),
            MeshUsage::Rigid {
                joint: "Head".into(),
            },
        );
        assert_eq!(
            rigid.to_string(),
            "'Box' (node 'Helmet'): 8 vertices, rigid part of joint 'Head' (weight 1)"
        );
        let skinned = use_of("Body", Some("Body"), MeshUsage::Skinned);
        assert_eq!(skinned.to_string(), "'Body': 8 vertices, skinned body part");
        let unplaced = use_of("Spare", None, ignored(NO_NODE));
        assert_eq!(
            unplaced.to_string(),
            "'Spare': 8 vertices, ignored: no node places it"
        );
    }

    #[test]
    fn ignored_meshes_warn_once_per_reason() {
        let uses = vec![
            use_of("Body", Some("Body"), MeshUsage::Skinned),
            use_of("Crate", Some("Crate"), ignored(NOT_UNDER_JOINT)),
            use_of("Spare", None, ignored(NO_NODE)),
            use_of("Box", Some("Chair"), ignored(NOT_UNDER_JOINT)),
        ];
        let mut warnings = Vec::new();
        warn_ignored(&uses, &mut warnings);
        assert_eq!(
            warnings,
            vec![
                format!(
                    "2 meshes left out of the body ({NOT_UNDER_JOINT}): 'Crate', 'Box' (node 'Chair')"
                ),
                format!("1 mesh left out of the body ({NO_NODE}): 'Spare'"),
            ]
        );
        assert_eq!(used_or_empty(0, MeshUsage::Skinned), ignored(NO_TRIANGLES));
        assert_eq!(used_or_empty(3, MeshUsage::Skinned), MeshUsage::Skinned);
    }
}
