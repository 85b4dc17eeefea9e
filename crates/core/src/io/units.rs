//! Length units of imported files and their detection from a model's size.

/// Factor from CMU motion-capture units to metres: (1 / 0.45) * 2.54 / 100 (CMU FAQ).
pub const CMU_MOCAP_TO_METRES: f32 = (1.0 / 0.45) * 2.54 / 100.0;

/// The length unit a file is written in.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Units {
    /// Guess from the model's size (see [`Units::detect_gltf`], [`Units::detect_mesh`] and
    /// [`Units::detect_mocap`]).
    #[default]
    Auto,
    /// Metres (glTF's own unit).
    Metres,
    /// Decimetres (MakeHuman base-mesh units).
    Decimetres,
    /// Centimetres (many DCC exports and Daz BVH files).
    Centimetres,
    /// Millimetres.
    Millimetres,
    /// Inches (some DCC and motion-capture exports).
    Inches,
    /// The CMU motion-capture database's units (about 5.6 cm each).
    CmuMocap,
}

impl Units {
    /// Metres per file unit; `None` for [`Units::Auto`].
    pub fn metres_per_unit(self) -> Option<f32> {
        match self {
            Units::Auto => None,
            Units::Metres => Some(1.0),
            Units::Decimetres => Some(0.1),
            Units::Centimetres => Some(0.01),
            Units::Millimetres => Some(0.001),
            Units::Inches => Some(0.0254),
            Units::CmuMocap => Some(CMU_MOCAP_TO_METRES),
        }
    }

    /// Guesses the unit of a body or garment whose largest bounding-box extent is `extent`
    /// file units: up to 3 is metres, up to 30 decimetres, up to 500 centimetres, beyond that
    /// millimetres. (A person is 1.5-2 m tall, so 15-20 dm or 150-200 cm; a garment spans at
    /// least a few decimetres.) Non-finite or non-positive extents give metres.
    pub fn detect_mesh(extent: f32) -> Units {
        if !(extent.is_finite() && extent > 3.0) {
            Units::Metres
        } else if extent <= 30.0 {
            Units::Decimetres
        } else if extent <= 500.0 {
            Units::Centimetres
        } else {
            Units::Millimetres
        }
    }

    /// Guesses the unit of a glTF model whose size (rest height for avatars, largest extent
    /// for meshes) is `size` file units. glTF is specified in metres, so anything up to 10
    /// stays metres; up to 1000 is centimetres (common in exports from DCC tools), beyond that
    /// millimetres.
    pub fn detect_gltf(size: f32) -> Units {
        if !(size.is_finite() && size > 10.0) {
            Units::Metres
        } else if size <= 1000.0 {
            Units::Centimetres
        } else {
            Units::Millimetres
        }
    }

    /// Guesses the unit of a motion-capture skeleton whose rest pose spans `extent` file
    /// units: up to 3 is metres, up to 40 CMU units (a CMU skeleton spans about 24-26), up to
    /// 500 centimetres, beyond that millimetres.
    pub fn detect_mocap(extent: f32) -> Units {
        if !(extent.is_finite() && extent > 3.0) {
            Units::Metres
        } else if extent <= 40.0 {
            Units::CmuMocap
        } else if extent <= 500.0 {
            Units::Centimetres
        } else {
            Units::Millimetres
        }
    }

    /// Resolves `Auto` with `detect`, returning the unit and metres per unit.
    pub fn resolve(self, extent: f32, detect: fn(f32) -> Units) -> (Units, f32) {
        let units = if self == Units::Auto {
            detect(extent)
        } else {
            self
        };
        (units, units.metres_per_unit().unwrap_or(1.0))
    }

    /// Short lower-case name for reports.
    pub fn label(self) -> &'static str {
        match self {
            Units::Auto => "auto",
            Units::Metres => "metres",
            Units::Decimetres => "decimetres",
            Units::Centimetres => "centimetres",
            Units::Millimetres => "millimetres",
            Units::Inches => "inches",
            Units::CmuMocap => "CMU mocap units",
        }
    }
}

/// The largest extent of the bounding box of `points`, or 0 when empty.
pub fn largest_extent<'a>(points: impl IntoIterator<Item = &'a crate::geometry::Vec3>) -> f32 {
    let mut it = points.into_iter();
    let Some(first) = it.next() else {
        return 0.0;
    };
    let (lo, hi) = it.fold((*first, *first), |(lo, hi), p| (lo.inf(p), hi.sup(p)));
    (hi - lo).max()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detection_thresholds() {
        assert_eq!(Units::detect_mesh(1.8), Units::Metres);
        assert_eq!(Units::detect_mesh(16.0), Units::Decimetres);
        assert_eq!(Units::detect_mesh(4.3), Units::Decimetres);
        assert_eq!(Units::detect_mesh(170.0), Units::Centimetres);
        assert_eq!(Units::detect_mesh(1700.0), Units::Millimetres);
        assert_eq!(Units::detect_mesh(f32::NAN), Units::Metres);
        assert_eq!(Units::detect_gltf(9.5), Units::Metres);
        assert_eq!(Units::detect_gltf(79.0), Units::Centimetres);
        assert_eq!(Units::detect_mocap(25.0), Units::CmuMocap);
        assert_eq!(Units::detect_mocap(152.0), Units::Centimetres);
        assert!((CMU_MOCAP_TO_METRES - 0.056444).abs() < 1e-5);
        assert_eq!(
            Units::Metres.resolve(100.0, Units::detect_mesh),
            (Units::Metres, 1.0)
        );
        assert_eq!(
            Units::Auto.resolve(100.0, Units::detect_mesh),
            (Units::Centimetres, 0.01)
        );
    }

    #[test]
    fn extent_of_points() {
        let pts = [
            crate::geometry::Vec3::new(0.0, 0.0, 0.0),
            crate::geometry::Vec3::new(1.0, 5.0, -2.0),
        ];
        assert_eq!(largest_extent(&pts), 5.0);
        assert_eq!(largest_extent(&[]), 0.0);
    }
}
