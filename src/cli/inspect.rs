//! `neural-cloth inspect FILE [--avatar AVATAR] [--joint-map MAP] [--up auto|y|z]`.

use std::path::Path;

use neural_cloth::io::inspect::{inspect_mapping, inspect_with};
use neural_cloth::io::{ImportOptions, JointMap, UpAxis};

/// Prints the inspection report of `file` read with the `up` axis; with `avatar`, also the
/// joint mapping that retargeting the file's motion onto it would use (with the user's
/// `joint_map`).
pub fn run(
    file: &Path,
    avatar: Option<&Path>,
    joint_map: Option<&Path>,
    up: UpAxis,
) -> anyhow::Result<()> {
    let options = ImportOptions {
        up,
        ..Default::default()
    };
    let report = match avatar {
        Some(avatar) => {
            let map = joint_map.map(JointMap::load).transpose()?;
            inspect_mapping(file, avatar, map.as_ref(), &options)?
        }
        None => {
            anyhow::ensure!(
                joint_map.is_none(),
                "--joint-map needs --avatar (the avatar whose joints it maps)"
            );
            inspect_with(file, &options)?
        }
    };
    println!("{report}");
    Ok(())
}
