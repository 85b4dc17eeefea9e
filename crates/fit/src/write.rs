//! Writing a fitted garment: an OBJ in metres with what the fit did in its comment line, and
//! the millimetre formatting of positions the messages use.

use std::path::Path;

use neural_cloth_core::geometry::Vec3;

use super::{FitError, Fitted};

/// `(x, y, z)` in metres with millimetre precision.
pub fn format_m(v: &Vec3) -> String {
    format!("({:.3}, {:.3}, {:.3}) m", v.x, v.y, v.z)
}

/// Writes the fitted garment as an OBJ in metres (vertex order, faces and UVs kept) through
/// a temporary file renamed into place.
pub fn write_obj(fitted: &Fitted, path: &Path) -> Result<(), FitError> {
    let p = &fitted.report.placement;
    let comment = format!(
        "'{}' fitted: units {}, scale {:.4}, offset {}, mirrored {}",
        fitted.name,
        fitted.report.units.label(),
        p.scale,
        format_m(&p.offset_m),
        p.mirrored
    );
    let text = neural_cloth_core::io::export::obj_seq::obj_text(
        &fitted.mesh.positions,
        &fitted.mesh.faces,
        fitted.mesh.uvs.as_deref(),
        &comment,
    );
    neural_cloth_core::io::export::atomic::write_atomic(path, text.as_bytes())?;
    Ok(())
}
