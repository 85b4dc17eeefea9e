//! The unit a garment file is read in: given, or chosen from its size against the avatar's
//! height.

use neural_cloth_core::io::Units;

/// The unit of a garment file whose largest extent is `extent` file units, for an avatar
/// `body_height_m` tall: `requested` unless `Auto`; else the size-based guess
/// ([`Units::detect_mesh`]) when the garment then spans 10 % to 130 % of the body's height,
/// else the first of metres, centimetres, millimetres, inches, decimetres that does, else
/// the one nearest to half the body's height.
pub fn choose_units(requested: Units, extent: f32, body_height_m: f32) -> Units {
    if requested != Units::Auto {
        return requested;
    }
    let guess = Units::detect_mesh(extent);
    if !(extent.is_finite() && extent > 0.0 && body_height_m > 0.0) {
        return guess;
    }
    let ratio = |u: Units| extent * u.metres_per_unit().unwrap_or(1.0) / body_height_m;
    let plausible = |u: Units| (0.1..=1.3).contains(&ratio(u));
    let candidates = [
        guess,
        Units::Metres,
        Units::Centimetres,
        Units::Millimetres,
        Units::Inches,
        Units::Decimetres,
    ];
    if let Some(u) = candidates.into_iter().find(|&u| plausible(u)) {
        return u;
    }
    candidates
        .into_iter()
        .min_by(|&a, &b| {
            let d = |u: Units| (ratio(u) / 0.5).ln().abs();
            d(a).total_cmp(&d(b))
        })
        .unwrap_or(guess)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_follow_the_request_then_the_size_against_the_body() {
        assert_eq!(choose_units(Units::Inches, 70.0, 1.7), Units::Inches);
        assert_eq!(choose_units(Units::Auto, 0.7, 1.7), Units::Metres);
        assert_eq!(choose_units(Units::Auto, 70.0, 1.7), Units::Centimetres);
        assert_eq!(choose_units(Units::Auto, 7.0, 1.7), Units::Decimetres);
        // A 25 cm collar read in centimetres, not decimetres as its size alone suggests.
        assert_eq!(choose_units(Units::Auto, 25.0, 1.7), Units::Centimetres);
        assert_eq!(choose_units(Units::Auto, 700.0, 1.7), Units::Millimetres);
        assert_eq!(choose_units(Units::Auto, f32::NAN, 1.7), Units::Metres);
    }
}
