//! Wavefront OBJ garments: `v`, `vt` and `f` (with `v`, `v/vt`, `v//vn`, `v/vt/vn` corners and
//! negative indices); polygons are fan-triangulated; the vertex order of the file is kept
//! exactly (simulation outputs must line up with the artist's mesh).
//!
//! UVs become per-vertex when every face corner has one; a vertex with several UVs (a seam)
//! keeps its first and the importer warns. Units are given or detected from the size.

use std::path::Path;

use super::units::largest_extent;
use super::{ImportOptions, IoError, LoadedMesh, Units, file_stem, read_bytes};
use crate::geometry::{TriMesh, Vec3};

/// Loads an OBJ file as a garment template.
pub fn load_obj(path: &Path, options: &ImportOptions) -> Result<LoadedMesh, IoError> {
    load_obj_from_bytes(&read_bytes(path)?, path, options)
}

/// Parses OBJ bytes; `path` names the mesh and ends error messages.
pub fn load_obj_from_bytes(
    bytes: &[u8],
    path: &Path,
    options: &ImportOptions,
) -> Result<LoadedMesh, IoError> {
    let text = String::from_utf8_lossy(bytes);
    let syntax = |line: usize, reason: String| IoError::Syntax {
        format: "OBJ",
        line,
        reason,
        path: path.to_path_buf(),
    };
    let mut positions: Vec<Vec3> = Vec::new();
    let mut tex: Vec<[f32; 2]> = Vec::new();
    let mut normals = 0usize;
    let mut faces: Vec<[u32; 3]> = Vec::new();
    let mut vertex_uv: Vec<Option<u32>> = Vec::new();
    let mut seam = Vec::<bool>::new();
    let (mut corner_without_uv, mut ignored) = (false, 0usize);
    let mut corners: Vec<(u32, Option<u32>)> = Vec::new();
    for (k, raw) in text.lines().enumerate() {
        let line_no = k + 1;
        let line = raw.split('#').next().unwrap_or("").trim();
        let mut tokens = line.split_whitespace();
        let Some(keyword) = tokens.next() else {
            continue;
        };
        match keyword {
            "v" => {
                let xyz = parse_floats::<3>(&mut tokens)
                    .map_err(|r| syntax(line_no, format!("vertex: {r}")))?;
                if !xyz.iter().all(|v| v.is_finite()) {
                    return Err(IoError::NonFinite {
                        what: format!("vertex {} at line {line_no}", positions.len() + 1),
                        path: path.to_path_buf(),
                    });
                }
                positions.push(Vec3::from(xyz));
                vertex_uv.push(None);
                seam.push(false);
            }
            "vt" => {
                let u = parse_floats::<1>(&mut tokens)
                    .map_err(|r| syntax(line_no, format!("texture coordinate: {r}")))?[0];
                let v = match tokens.next() {
                    Some(t) => t.parse::<f32>().map_err(|_| {
                        syntax(
                            line_no,
                            format!("texture coordinate: '{t}' is not a number"),
                        )
                    })?,
                    None => 0.0,
                };
                if !(u.is_finite() && v.is_finite()) {
                    return Err(IoError::NonFinite {
                        what: format!("texture coordinate at line {line_no}"),
                        path: path.to_path_buf(),
                    });
                }
                tex.push([u, v]);
            }
            "vn" => normals += 1,
            "f" | "fo" => {
                corners.clear();
                for token in tokens {
                    let mut parts = token.split('/');
                    let v = resolve(parts.next().unwrap_or(""), positions.len(), "vertex")
                        .map_err(|r| syntax(line_no, r))?;
                    let vt = match parts.next() {
                        Some(s) if !s.is_empty() => Some(
                            resolve(s, tex.len(), "texture coordinate")
                                .map_err(|r| syntax(line_no, r))?,
                        ),
                        _ => None,
                    };
                    if let Some(s) = parts.next().filter(|s| !s.is_empty()) {
                        resolve(s, normals, "normal").map_err(|r| syntax(line_no, r))?;
                    }
                    corners.push((v, vt));
                }
                if corners.len() < 3 {
                    return Err(syntax(
                        line_no,
                        format!("face with {} vertices (at least 3 needed)", corners.len()),
                    ));
                }
                for &(v, vt) in &corners {
                    let slot = &mut vertex_uv[v as usize];
                    match (vt, *slot) {
                        (None, _) => corner_without_uv = true,
                        (Some(t), None) => *slot = Some(t),
                        (Some(t), Some(old))
                            if old != t && tex[old as usize] != tex[t as usize] =>
                        {
                            seam[v as usize] = true
                        }
                        _ => {}
                    }
                }
                for i in 1..corners.len() - 1 {
                    faces.push([corners[0].0, corners[i].0, corners[i + 1].0]);
                }
            }
            "l" | "p" | "curv" | "curv2" | "surf" => ignored += 1,
            _ => {}
        }
    }
    if positions.is_empty() || faces.is_empty() {
        return Err(IoError::NoMesh {
            path: path.to_path_buf(),
        });
    }
    let mut warnings = Vec::new();
    if ignored > 0 {
        warnings.push(format!(
            "{ignored} point, line, curve or surface elements ignored"
        ));
    }
    let seams = seam.iter().filter(|&&s| s).count();
    let uvs = if corner_without_uv || tex.is_empty() {
        if !tex.is_empty() {
            warnings.push("some face corners have no texture coordinate; UVs dropped".into());
        }
        None
    } else {
        if seams > 0 {
            warnings.push(format!(
                "{seams} vertices have several UVs (UV seams); the first UV of each is kept"
            ));
        }
        Some(
            vertex_uv
                .iter()
                .map(|t| {
                    t.and_then(|t| tex.get(t as usize).copied())
                        .unwrap_or([0.0, 0.0])
                })
                .collect(),
        )
    };
    let (up, detected) = options.up.resolve(&positions);
    warnings.extend(up.turned_warning(detected));
    let turn = up.to_y_up();
    let extent = largest_extent(&positions);
    let (units, scale) = options.units.resolve(extent, Units::detect_mesh);
    if options.units == Units::Auto && units != Units::Metres {
        warnings.push(format!(
            "units detected as {} from a largest extent of {extent:.3} file units",
            units.label()
        ));
    }
    let mut mesh = TriMesh {
        positions,
        faces,
        uvs,
    };
    mesh.map_positions(|p| turn * p * scale);
    mesh.validate().map_err(|e| IoError::Syntax {
        format: "OBJ",
        line: 0,
        reason: e.to_string(),
        path: path.to_path_buf(),
    })?;
    Ok(LoadedMesh {
        name: file_stem(path),
        mesh,
        units,
        up,
        warnings,
    })
}

/// Parses the next `N` tokens as floats.
fn parse_floats<'a, const N: usize>(
    tokens: &mut impl Iterator<Item = &'a str>,
) -> Result<[f32; N], String> {
    let mut out = [0.0; N];
    for (i, slot) in out.iter_mut().enumerate() {
        let Some(t) = tokens.next() else {
            return Err(format!("{N} numbers expected, found {i}"));
        };
        *slot = t
            .parse::<f32>()
            .map_err(|_| format!("'{t}' is not a number"))?;
    }
    Ok(out)
}

/// Resolves a 1-based (or negative, relative) OBJ index against `count` defined elements.
fn resolve(token: &str, count: usize, what: &str) -> Result<u32, String> {
    let i: i64 = token
        .parse()
        .map_err(|_| format!("'{token}' is not a {what} index"))?;
    let index = if i > 0 {
        i - 1
    } else if i < 0 {
        count as i64 + i
    } else {
        -1
    };
    if i == 0 || index < 0 || index >= count as i64 || index > u32::MAX as i64 {
        return Err(format!(
            "{what} index {i} is out of range ({count} defined so far)"
        ));
    }
    Ok(index as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(text: &str) -> Result<LoadedMesh, IoError> {
        load_obj_from_bytes(
            text.as_bytes(),
            Path::new("t.obj"),
            &ImportOptions {
                units: Units::Metres,
                ..Default::default()
            },
        )
    }

    #[test]
    fn corner_forms_negative_indices_and_fans() {
        let m = load("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1 4/4/1\nf -4//1 -2//1 -1//1\n").unwrap();
        assert_eq!(m.mesh.faces, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
        assert!(m.mesh.uvs.is_none(), "a corner without vt drops UVs");
        let m = load("v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0.5 0.5\nf 1/1 2/2 3/3\nf 3/4 2/2 1/1\n").unwrap();
        assert_eq!(
            m.mesh.uvs.as_deref(),
            Some(&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]][..])
        );
        assert!(m.warnings.iter().any(|w| w.contains("several UVs")));
    }

    #[test]
    fn errors_carry_line_numbers() {
        let e = load("v 0 0 0\nv 1 0 0\nf 1 2 3\n").unwrap_err();
        assert!(matches!(e, IoError::Syntax { line: 3, .. }), "{e}");
        let e = load("v 0 0\n").unwrap_err();
        assert!(matches!(e, IoError::Syntax { line: 1, .. }), "{e}");
        let e = load("v 0 0 0\nv 1 nan 0\n").unwrap_err();
        assert!(matches!(e, IoError::NonFinite { .. }), "{e}");
        assert!(e.to_string().ends_with("t.obj"));
        let e = load("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n").unwrap_err();
        assert!(matches!(e, IoError::Syntax { line: 4, .. }), "{e}");
        assert!(matches!(load("# nothing\n"), Err(IoError::NoMesh { .. })));
        let e = load("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n").unwrap_err();
        assert!(matches!(e, IoError::Syntax { line: 4, .. }), "{e}");
    }

    #[test]
    fn units_are_detected() {
        let text = "v 0 0 0\nv 10 0 0\nv 0 17 0\nf 1 2 3\n";
        let m = load_obj_from_bytes(
            text.as_bytes(),
            Path::new("t.obj"),
            &ImportOptions::default(),
        )
        .unwrap();
        assert_eq!(m.units, Units::Decimetres);
        assert!((m.mesh.positions[2].y - 1.7).abs() < 1e-6);
    }
}
