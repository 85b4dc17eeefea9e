//! glTF files in which no mesh is skinned: an avatar built only of rigid parts (a common
//! game-asset style: a robot or armoured character made of pieces parented to bones), or a
//! plain mesh such as a garment?
//!
//! Such a file is an avatar when
//! - a skin of the file (used by no mesh) has joints that its meshes hang from: the skeleton
//!   is that skin's joints, with its bind matrices; or
//! - no skin serves, but its meshes hang from a node hierarchy that reads as a skeleton: parts
//!   on nodes nested at least [`MIN_NESTING`] deep (one part under another under another, as
//!   along a limb), or at least [`MIN_NAMED_JOINTS`] nodes named like a body's joints. The
//!   skeleton is that hierarchy from the lowest common ancestor of the nodes the parts hang
//!   from down: every node with children, and every node with neither mesh nor camera (bone
//!   ends such as a head or a toe); the nodes above it only place the skeleton.
//!
//! Either way each mesh then becomes a rigid part of the joint it hangs from, with weight 1
//! (`gltf_body`). Anything else, a single mesh at the scene root or pieces under one empty
//! node, is a plain mesh (usable as a garment), and [`Skinless::Plain`] says why.

use std::collections::HashSet;
use std::fmt;

use super::IoError;
use super::gltf_doc::GltfDoc;
use super::joint_names::classify;

/// Nesting depth of the nodes meshes hang from that makes a node hierarchy a skeleton.
pub const MIN_NESTING: usize = 3;
/// Nodes named like a body's joints that make a node hierarchy a skeleton.
pub const MIN_NAMED_JOINTS: usize = 4;

/// Where the skeleton of a glTF avatar came from.
#[derive(Clone, Debug, PartialEq)]
pub enum SkeletonSource {
    /// The skins of its skinned meshes.
    SkinnedMeshes,
    /// No mesh is skinned: the joints of these skins, which `parts` meshes hang from.
    UnusedSkins {
        /// glTF skin indices.
        skins: Vec<usize>,
        /// Mesh nodes hanging from their joints.
        parts: usize,
    },
    /// No skin serves: the node hierarchy its meshes hang from, and why it reads as a
    /// skeleton.
    NodeHierarchy {
        /// Why, in words.
        why: String,
    },
}

impl fmt::Display for SkeletonSource {
    /// The kind of avatar file, with where its skeleton came from.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::SkinnedMeshes => write!(f, "skinned glTF avatar"),
            Self::UnusedSkins { skins, parts } => {
                let list: Vec<String> = skins.iter().map(usize::to_string).collect();
                write!(
                    f,
                    "glTF avatar of rigid parts (no mesh is skinned: the skeleton is the joints \
                     of skin {}, which {parts} mesh{} hang from)",
                    list.join(", "),
                    if *parts == 1 { "" } else { "es" }
                )
            }
            Self::NodeHierarchy { why } => write!(
                f,
                "glTF avatar of rigid parts (no skin: the skeleton is the node hierarchy its \
                 meshes hang from; {why})"
            ),
        }
    }
}

/// The nodes of the skeleton of a file without skinned meshes.
pub(crate) enum SkeletonNodes {
    /// The joints of these glTF skins.
    Skins(Vec<usize>),
    /// These nodes.
    Nodes(Vec<usize>),
}

/// What a file without skinned meshes is.
pub(crate) enum Skinless {
    /// An avatar of rigid parts.
    Avatar {
        /// Its skeleton's nodes.
        nodes: SkeletonNodes,
        /// Where they came from, in words.
        source: SkeletonSource,
    },
    /// A plain mesh, and why it is not an avatar.
    Plain(String),
}

/// Reads a file in which no node has both a mesh and a skin (see the module text).
pub(crate) fn skinless(doc: &GltfDoc) -> Result<Skinless, IoError> {
    let nodes: Vec<gltf::Node> = doc.doc.nodes().collect();
    let mut meshes: Vec<(usize, Vec<usize>)> = Vec::new();
    for node in nodes.iter().filter(|n| n.mesh().is_some()) {
        meshes.push((node.index(), doc.ancestors(node.index())?));
    }
    if let Some(found) = by_skins(doc, &meshes) {
        return Ok(found);
    }
    by_hierarchy(doc, &nodes, &meshes)
}

/// The skins whose joints some mesh hangs from (the mesh node itself or an ancestor).
fn by_skins(doc: &GltfDoc, meshes: &[(usize, Vec<usize>)]) -> Option<Skinless> {
    let mut skins = Vec::new();
    let mut hung: HashSet<usize> = HashSet::new();
    for skin in doc.doc.skins() {
        let joints: HashSet<usize> = skin.joints().map(|n| n.index()).collect();
        let under: Vec<usize> = meshes
            .iter()
            .filter(|(m, up)| joints.contains(m) || up.iter().any(|a| joints.contains(a)))
            .map(|(m, _)| *m)
            .collect();
        if !under.is_empty() {
            skins.push(skin.index());
            hung.extend(under);
        }
    }
    (!skins.is_empty()).then(|| Skinless::Avatar {
        nodes: SkeletonNodes::Skins(skins.clone()),
        source: SkeletonSource::UnusedSkins {
            skins,
            parts: hung.len(),
        },
    })
}

/// The node hierarchy the meshes hang from, when it reads as a skeleton.
fn by_hierarchy(
    doc: &GltfDoc,
    nodes: &[gltf::Node],
    meshes: &[(usize, Vec<usize>)],
) -> Result<Skinless, IoError> {
    // The scene tree holding most meshes that hang from another node.
    let parented: Vec<&(usize, Vec<usize>)> =
        meshes.iter().filter(|(_, up)| !up.is_empty()).collect();
    let mut roots: Vec<(usize, usize)> = Vec::new();
    for (_, up) in &parented {
        let root = up.last().copied().unwrap_or_default();
        match roots.iter_mut().find(|(r, _)| *r == root) {
            Some((_, count)) => *count += 1,
            None => roots.push((root, 1)),
        }
    }
    let Some(&(root, _)) = roots.iter().rev().max_by_key(|(_, count)| *count) else {
        return Ok(Skinless::Plain(
            "no mesh is parented to another node".into(),
        ));
    };
    let has_children = |n: usize| nodes.get(n).is_some_and(|n| n.children().len() > 0);
    // The node each part hangs from: itself when it has children (it is a joint), else its
    // parent; each with itself and its ancestors, nearest first.
    let mut holders: Vec<Vec<usize>> = Vec::new();
    let mut parts = 0;
    for (m, up) in parented.iter().filter(|(_, up)| up.last() == Some(&root)) {
        parts += 1;
        let chain: Vec<usize> = if has_children(*m) {
            std::iter::once(*m).chain(up.iter().copied()).collect()
        } else {
            up.clone()
        };
        if !holders.iter().any(|h| h.first() == chain.first()) {
            holders.push(chain);
        }
    }
    let Some(lowest) = holders.first().and_then(|first| {
        first
            .iter()
            .copied()
            .find(|n| holders.iter().all(|h| h.contains(n)))
    }) else {
        return Ok(Skinless::Plain(
            "no mesh is parented to another node".into(),
        ));
    };
    let heads: HashSet<usize> = holders.iter().filter_map(|h| h.first().copied()).collect();
    let nesting = holders
        .iter()
        .map(|h| h.iter().filter(|n| heads.contains(n)).count())
        .max()
        .unwrap_or(0);

    // The skeleton: the subtree of the lowest common ancestor, less its leaf meshes and
    // cameras.
    let mut joints = Vec::new();
    let mut stack = vec![lowest];
    while let Some(n) = stack.pop() {
        let Some(node) = nodes.get(n) else {
            return Err(doc.invalid(format!("node {n} does not exist")));
        };
        if node.children().len() > 0 || (node.mesh().is_none() && node.camera().is_none()) {
            joints.push(n);
        }
        let children: Vec<usize> = node.children().map(|c| c.index()).collect();
        stack.extend(children.into_iter().rev());
    }
    let names: Vec<String> = joints
        .iter()
        .map(|&n| {
            nodes
                .get(n)
                .and_then(|node| node.name())
                .unwrap_or_default()
                .to_string()
        })
        .collect();
    let named = classify(&names).canonical.iter().flatten().count();
    let why = format!(
        "{parts} mesh{} hang from {} node{} nested {nesting} deep, {named} node name{} read as \
         body joints",
        if parts == 1 { "" } else { "es" },
        heads.len(),
        if heads.len() == 1 { "" } else { "s" },
        if named == 1 { "" } else { "s" },
    );
    if nesting >= MIN_NESTING || named >= MIN_NAMED_JOINTS {
        Ok(Skinless::Avatar {
            nodes: SkeletonNodes::Nodes(joints),
            source: SkeletonSource::NodeHierarchy { why },
        })
    } else {
        Ok(Skinless::Plain(format!(
            "{why}; an avatar of rigid parts needs meshes on nodes nested at least \
             {MIN_NESTING} deep or {MIN_NAMED_JOINTS} nodes named like a body's joints"
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_source_reads_as_a_kind() {
        assert_eq!(
            SkeletonSource::SkinnedMeshes.to_string(),
            "skinned glTF avatar"
        );
        let skins = SkeletonSource::UnusedSkins {
            skins: vec![0],
            parts: 20,
        };
        assert_eq!(
            skins.to_string(),
            "glTF avatar of rigid parts (no mesh is skinned: the skeleton is the joints of \
             skin 0, which 20 meshes hang from)"
        );
        let nodes = SkeletonSource::NodeHierarchy { why: "why".into() };
        assert!(
            nodes
                .to_string()
                .ends_with("the node hierarchy its meshes hang from; why)")
        );
    }
}
