//! The up axis of imported files. Everything inside the tool is Y up (glTF's convention);
//! OBJ and BVH files have no convention and come Z up from some tools (3ds Max, Blender
//! without axis conversion, some motion capture), and glTF exporters sometimes leave a Z-up
//! model as it was. The axis is given, or detected: for a skeleton (BVH, skinned glTF) from
//! its structure, when it reads as a standing body only Z up ([`UpAxis::detect_body`]); for an
//! OBJ mesh from its shape (a body or a garment is taller than it is deep, so a mesh whose Z
//! extent is well over its Y extent lies Z up, [`UpAxis::detect`]). A glTF mesh without a
//! skin is Y up as the format says unless told otherwise. Z-up files are turned Y up by
//! Blender's own glTF convention: `(x, y, z) -> (x, z, -y)` (the -Y forward of a Z-up scene
//! becomes +Z). The setting itself ([`UpAxis`]) lives in the scene layer, where scene files
//! record it per file source; this module adds its detection.

use super::joint_structure::{RigShape, label_by_structure};
use crate::geometry::Vec3;

pub use crate::scene::UpAxis;

/// How much deeper along Z than tall along Y a file must be to be detected Z up. Garments
/// and bodies made Y up are 0.2 to 0.6 times as deep as tall, so 1.5 leaves them alone.
const Z_OVER_Y: f32 = 1.5;

impl UpAxis {
    /// Z when the points' extent along Z is over 1.5 times their extent along Y, else Y (also
    /// for no points or non-finite extents).
    pub fn detect<'a>(points: impl IntoIterator<Item = &'a Vec3>) -> UpAxis {
        let mut it = points.into_iter();
        let Some(first) = it.next() else {
            return UpAxis::Y;
        };
        let (lo, hi) = it.fold((*first, *first), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
        let size = hi - lo;
        if size.z.is_finite() && size.y.is_finite() && size.z > Z_OVER_Y * size.y {
            UpAxis::Z
        } else {
            UpAxis::Y
        }
    }

    /// The up axis of a skeleton (`parents`, rest joint positions `rest` in file axes): Z
    /// when its structure reads as a standing body (see [`label_by_structure`]) turned Y up
    /// from Z up and not as it is, or reads as one both ways but is taller along Z; else Y (a
    /// quadruped, which is longer than tall, stays as it is).
    pub fn detect_body(parents: &[Option<usize>], rest: &[Vec3]) -> UpAxis {
        let turn = UpAxis::Z.to_y_up();
        let turned: Vec<Vec3> = rest.iter().map(|p| turn * p).collect();
        let body = |points: &[Vec3]| {
            label_by_structure(&RigShape {
                parents,
                rest: points,
                frames: &[],
            })
            .is_ok()
        };
        let span = |axis: usize| {
            let v = rest.iter().map(|p| p[axis]);
            v.clone().fold(f32::NEG_INFINITY, f32::max) - v.fold(f32::INFINITY, f32::min)
        };
        match (body(rest), body(&turned)) {
            (false, true) => UpAxis::Z,
            (true, true) if span(2) > span(1) => UpAxis::Z,
            _ => UpAxis::Y,
        }
    }

    /// The axis to use: this one, or for [`UpAxis::Auto`] the one [`UpAxis::detect`] finds in
    /// `points`; and whether it was detected.
    pub fn resolve<'a>(self, points: impl IntoIterator<Item = &'a Vec3>) -> (UpAxis, bool) {
        match self {
            UpAxis::Auto => (UpAxis::detect(points), true),
            given => (given, false),
        }
    }

    /// The axis to use for a skeleton: this one, or for [`UpAxis::Auto`] the one
    /// [`UpAxis::detect_body`] finds; and whether it was detected.
    pub fn resolve_body(self, parents: &[Option<usize>], rest: &[Vec3]) -> (UpAxis, bool) {
        match self {
            UpAxis::Auto => (UpAxis::detect_body(parents, rest), true),
            given => (given, false),
        }
    }

    /// The warning an importer gives when it detected Z up and turned the file.
    pub fn turned_warning(self, detected: bool) -> Option<String> {
        (self == UpAxis::Z && detected).then(|| {
            "Z up detected (the model stands along Z); turned Y up (--up y, or up = \"y\" on the \
             scene file's source, keeps it as it is)"
                .to_string()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_standing_shape_is_detected_either_way() {
        let body = [Vec3::new(-0.8, 0.0, -0.1), Vec3::new(0.8, 1.7, 0.2)];
        assert_eq!(UpAxis::detect(&body), UpAxis::Y);
        let lying: Vec<Vec3> = body.iter().map(|p| Vec3::new(p.x, -p.z, p.y)).collect();
        assert_eq!(UpAxis::detect(&lying), UpAxis::Z);
        assert_eq!(UpAxis::detect(&[]), UpAxis::Y);
        assert_eq!(UpAxis::Y.resolve(&lying), (UpAxis::Y, false));
        assert_eq!(UpAxis::Auto.resolve(&lying), (UpAxis::Z, true));
        assert!(UpAxis::Z.turned_warning(true).is_some());
        assert!(UpAxis::Z.turned_warning(false).is_none());
    }
}
