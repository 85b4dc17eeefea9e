//! The tiny built-in scene several test binaries train on: the mannequin in a coarse t-shirt,
//! two one-second training motions and a validation one.

/// Scene file text of the tiny scene.
pub const TINY: &str = r#"
name = "tiny"
training_fps = 30.0
[avatar]
builtin = "mannequin"
[garment]
builtin = "tshirt"
resolution = 400
[[motions]]
builtin = "walk"
duration_secs = 1.0
[[motions]]
builtin = "spin"
duration_secs = 1.0
[[motions]]
builtin = "turn"
duration_secs = 1.0
split = "validation"
[fabric]
preset = "default"
"#;
