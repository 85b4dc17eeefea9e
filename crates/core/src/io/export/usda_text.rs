//! Text pieces of the USD ASCII format (`.usda`): numbers, arrays of tuples, quoted strings and
//! prim identifiers. Floats use Rust's shortest round-trip formatting, so USD's parser (which
//! reads a decimal to double and rounds it to float) gets back the same `f32` bits.

use std::fmt::Write as _;

use crate::geometry::Vec3;

/// Appends one float (finite; shortest digits that round-trip, never an exponent).
pub fn push_f32(out: &mut String, value: f32) {
    let _ = write!(out, "{value}");
}

/// Appends a point as `(x, y, z)`.
pub fn push_vec3(out: &mut String, p: &Vec3) {
    out.push('(');
    push_f32(out, p.x);
    out.push_str(", ");
    push_f32(out, p.y);
    out.push_str(", ");
    push_f32(out, p.z);
    out.push(')');
}

/// Appends an array of points as `[(x, y, z), ...]`.
pub fn push_vec3_array(out: &mut String, points: &[Vec3]) {
    out.push('[');
    for (k, p) in points.iter().enumerate() {
        if k > 0 {
            out.push_str(", ");
        }
        push_vec3(out, p);
    }
    out.push(']');
}

/// Appends an array of 2-tuples as `[(u, v), ...]`.
pub fn push_vec2_array(out: &mut String, values: &[[f32; 2]]) {
    out.push('[');
    for (k, uv) in values.iter().enumerate() {
        if k > 0 {
            out.push_str(", ");
        }
        out.push('(');
        push_f32(out, uv[0]);
        out.push_str(", ");
        push_f32(out, uv[1]);
        out.push(')');
    }
    out.push(']');
}

/// Appends an array of integers as `[a, b, ...]`.
pub fn push_int_array(out: &mut String, values: impl IntoIterator<Item = u32>) {
    out.push('[');
    for (k, v) in values.into_iter().enumerate() {
        if k > 0 {
            out.push_str(", ");
        }
        let _ = write!(out, "{v}");
    }
    out.push(']');
}

/// A double-quoted USD string with `\`, `"` and control characters escaped.
pub fn quote(text: &str) -> String {
    let mut s = String::with_capacity(text.len() + 2);
    s.push('"');
    for c in text.chars() {
        match c {
            '"' => s.push_str("\\\""),
            '\\' => s.push_str("\\\\"),
            '\n' => s.push_str("\\n"),
            '\r' => s.push_str("\\r"),
            '\t' => s.push_str("\\t"),
            c if c.is_control() => {
                let _ = write!(s, "\\x{:02x}", c as u32 & 0xff);
            }
            c => s.push(c),
        }
    }
    s.push('"');
    s
}

/// True for a valid prim name: an ASCII letter or `_`, then letters, digits or `_`.
pub fn is_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// A valid prim name made from `name`: other characters become `_`, and a leading digit (or an
/// empty name) gets a `_` in front.
pub fn sanitize_identifier(name: &str) -> String {
    let mut s: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if !s.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_') {
        s.insert(0, '_');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_round_trip_through_double_parsing_like_usd() {
        // USD parses a decimal to f64, then rounds to f32: check that this returns the bits.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut values = vec![0.1, -0.0, 1e-7, 3.5e-8, 1.5e30, f32::MIN_POSITIVE, f32::MAX];
        for _ in 0..20_000 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let v = f32::from_bits(state as u32);
            if v.is_finite() {
                values.push(v);
            }
        }
        for v in values {
            let mut s = String::new();
            push_f32(&mut s, v);
            assert!(!s.contains(['e', 'E', 'N', 'i']), "{s}");
            let back = s.parse::<f64>().unwrap() as f32;
            assert_eq!(back.to_bits(), v.to_bits(), "{v:?} written as {s}");
        }
    }

    #[test]
    fn arrays_and_strings_have_the_usda_syntax() {
        let mut s = String::new();
        push_vec3_array(&mut s, &[Vec3::new(1.0, -0.5, 0.25), Vec3::zeros()]);
        assert_eq!(s, "[(1, -0.5, 0.25), (0, 0, 0)]");
        s.clear();
        push_vec2_array(&mut s, &[[0.5, 1.0]]);
        assert_eq!(s, "[(0.5, 1)]");
        s.clear();
        push_int_array(&mut s, [3, 0, 12]);
        assert_eq!(s, "[3, 0, 12]");
        s.clear();
        push_vec3_array(&mut s, &[]);
        assert_eq!(s, "[]");
        assert_eq!(quote("a \"b\"\\\nc"), r#""a \"b\"\\\nc""#);
    }

    #[test]
    fn identifiers_are_checked_and_made_valid() {
        assert!(is_identifier("Garment_2"));
        assert!(is_identifier("_x"));
        assert!(!is_identifier("2x"));
        assert!(!is_identifier("t-shirt"));
        assert!(!is_identifier(""));
        assert_eq!(sanitize_identifier("t-shirt"), "t_shirt");
        assert_eq!(sanitize_identifier("2 walk"), "_2_walk");
        assert_eq!(sanitize_identifier(""), "_");
        assert!(is_identifier(&sanitize_identifier("é!")));
    }
}
