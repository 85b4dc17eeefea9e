//! `neural-cloth inspect FILE [--avatar AVATAR] [--joint-map MAP]`.

use std::path::Path;

use neural_cloth::io::JointMap;

/// Prints the inspection report of `file`; with `avatar`, also the joint mapping that
/// retargeting the file's motion onto it would use (with the user's `joint_map`).
pub fn run(file: &Path, avatar: Option<&Path>, joint_map: Option<&Path>) -> anyhow::Result<()> {
    let report = match avatar {
        Some(avatar) => {
            let map = joint_map.map(JointMap::load).transpose()?;
            neural_cloth::io::inspect::inspect_mapping(file, avatar, map.as_ref())?
        }
        None => {
            anyhow::ensure!(
                joint_map.is_none(),
                "--joint-map needs --avatar (the avatar whose joints it maps)"
            );
            neural_cloth::io::inspect(file)?
        }
    };
    println!("{report}");
    Ok(())
}
