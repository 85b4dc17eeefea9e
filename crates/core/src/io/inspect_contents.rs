//! What a file holds besides what the tool uses, for `inspect`: a glTF document's scenes,
//! nodes, meshes with their primitives and morph targets, skins, materials, textures,
//! images, cameras, animation channels by kind, extensions and generator; an OBJ file's
//! objects and groups (with their faces), materials, normals and smoothing groups; a BVH's
//! end sites and position channels. Materials, textures, cameras, lights and normals are
//! listed as not used (the tool draws its own shading and recomputes normals).

use std::fmt::Write as _;
use std::path::Path;

use super::gltf_doc::GltfDoc;
use super::{Bvh, BvhChannel, IoError, read_bytes};

/// Most names listed on one line before the rest are counted.
const MAX_NAMES: usize = 8;

/// `items` joined with ", ", cut after [`MAX_NAMES`] with the count left over.
fn names_list(items: &[String]) -> String {
    if items.is_empty() {
        return "none".into();
    }
    let shown: Vec<&str> = items.iter().take(MAX_NAMES).map(String::as_str).collect();
    match items.len().saturating_sub(MAX_NAMES) {
        0 => shown.join(", "),
        more => format!("{} (+{more} more)", shown.join(", ")),
    }
}

/// Writes the glTF document's contents of the file at `path`.
pub fn gltf_contents(out: &mut String, path: &Path) -> Result<(), IoError> {
    let doc = GltfDoc::parse(&read_bytes(path)?, path)?;
    let d = &doc.doc;
    let primitives: usize = d.meshes().map(|m| m.primitives().count()).sum();
    let morphs: usize = d
        .meshes()
        .flat_map(|m| m.primitives())
        .map(|p| p.morph_targets().count())
        .sum();
    let _ = writeln!(
        out,
        "document: {} scenes, {} nodes, {} meshes ({primitives} primitives, {morphs} morph \
         targets), {} skins, {} animations",
        d.scenes().count(),
        d.nodes().count(),
        d.meshes().count(),
        d.skins().count(),
        d.animations().count(),
    );
    let (mut rotation, mut translation, mut scale, mut weights) = (0, 0, 0, 0);
    for channel in d.animations().flat_map(|a| a.channels()) {
        use gltf::animation::Property;
        match channel.target().property() {
            Property::Rotation => rotation += 1,
            Property::Translation => translation += 1,
            Property::Scale => scale += 1,
            Property::MorphTargetWeights => weights += 1,
        }
    }
    if rotation + translation + scale + weights > 0 {
        let _ = writeln!(
            out,
            "animation channels: {rotation} rotation, {translation} translation, {scale} scale, \
             {weights} morph weights (morph weights are not used)"
        );
    }
    let named = |name: Option<&str>, k: usize, what: &str| {
        name.map_or_else(|| format!("{what} {k}"), |n| format!("'{n}'"))
    };
    let materials: Vec<String> = d
        .materials()
        .enumerate()
        .map(|(k, m)| named(m.name(), k, "material"))
        .collect();
    let _ = writeln!(
        out,
        "materials: {} ({}), {} textures, {} images, {} cameras (not used: the tool shades \
         its own way)",
        materials.len(),
        names_list(&materials),
        d.textures().count(),
        d.images().count(),
        d.cameras().count(),
    );
    let used: Vec<String> = d.extensions_used().map(str::to_string).collect();
    let required: Vec<String> = d.extensions_required().map(str::to_string).collect();
    let _ = writeln!(
        out,
        "extensions: used {}; required {}",
        names_list(&used),
        names_list(&required)
    );
    if let Some(generator) = &d.as_json().asset.generator {
        let _ = writeln!(out, "generator: {generator}");
    }
    Ok(())
}

/// One object or group of an OBJ file and its faces.
struct ObjPart {
    name: String,
    faces: usize,
}

/// Writes what an OBJ file holds besides vertices and faces: its objects and groups (all
/// merged into one mesh), materials, normals and smoothing groups.
pub fn obj_contents(out: &mut String, path: &Path) -> Result<(), IoError> {
    let bytes = read_bytes(path)?;
    let text = String::from_utf8_lossy(&bytes);
    let mut parts: Vec<ObjPart> = Vec::new();
    let (mut libraries, mut materials) = (Vec::<String>::new(), Vec::<String>::new());
    let (mut normals, mut smoothing) = (0usize, false);
    let mut unnamed_faces = 0usize;
    for line in text.lines() {
        let mut tokens = line.split_whitespace();
        let Some(key) = tokens.next() else { continue };
        let rest = tokens.collect::<Vec<_>>().join(" ");
        match key {
            "o" | "g" => parts.push(ObjPart {
                name: format!("{} '{rest}'", if key == "o" { "object" } else { "group" }),
                faces: 0,
            }),
            "f" => match parts.last_mut() {
                Some(p) => p.faces += 1,
                None => unnamed_faces += 1,
            },
            "vn" => normals += 1,
            "s" => smoothing |= !matches!(rest.as_str(), "off" | "0" | ""),
            "mtllib" if !libraries.contains(&rest) => libraries.push(rest),
            "usemtl" if !materials.contains(&rest) => materials.push(rest),
            _ => {}
        }
    }
    let mut listed: Vec<String> = Vec::new();
    if unnamed_faces > 0 {
        listed.push(format!("(no name): {unnamed_faces} faces"));
    }
    listed.extend(
        parts
            .iter()
            .map(|p| format!("{}: {} faces", p.name, p.faces)),
    );
    let _ = writeln!(
        out,
        "objects and groups: {} ({}; merged into one mesh)",
        listed.len(),
        names_list(&listed)
    );
    if materials.is_empty() && libraries.is_empty() {
        let _ = writeln!(out, "materials: none");
    } else {
        let _ = writeln!(
            out,
            "materials: {} from {} (not used: the tool shades its own way)",
            names_list(&materials),
            names_list(&libraries)
        );
    }
    let _ = writeln!(
        out,
        "normals: {normals} (not used: recomputed from the faces); smoothing groups: {}",
        if smoothing { "yes (not used)" } else { "none" }
    );
    Ok(())
}

/// Writes what a BVH holds besides its joints and frames: end sites and position channels
/// below the root.
pub fn bvh_contents(out: &mut String, bvh: &Bvh) {
    let end_sites = bvh.joints.iter().filter(|j| j.end_site.is_some()).count();
    let positions = |j: &super::BvhJoint| {
        j.channels.iter().any(|c| {
            matches!(
                c,
                BvhChannel::Xposition | BvhChannel::Yposition | BvhChannel::Zposition
            )
        })
    };
    let moving: Vec<String> = bvh
        .joints
        .iter()
        .filter(|j| j.parent.is_some() && positions(j))
        .map(|j| j.name.clone())
        .collect();
    let _ = writeln!(
        out,
        "end sites: {end_sites}; joints below the root with position channels: {} ({})",
        moving.len(),
        names_list(&moving)
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn obj_parts_materials_and_normals_are_listed() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("two.obj");
        std::fs::write(
            &path,
            "mtllib shirt.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1 2 3\no Shirt\n\
             usemtl cloth\ns 1\nf 1 2 3\nf 1 3 2\ng Buttons\nusemtl metal\nf 2 3 1\n",
        )
        .unwrap();
        let mut out = String::new();
        obj_contents(&mut out, &path).unwrap();
        assert!(
            out.contains(
                "objects and groups: 3 ((no name): 1 faces, object 'Shirt': 2 faces, group \
                 'Buttons': 1 faces; merged into one mesh)"
            ),
            "{out}"
        );
        assert!(
            out.contains("materials: cloth, metal from shirt.mtl"),
            "{out}"
        );
        assert!(out.contains("normals: 1 (not used"), "{out}");
        assert!(out.contains("smoothing groups: yes"), "{out}");
    }
}
