//! `neural-cloth inspect FILE`.

use std::path::Path;

/// Prints the inspection report of `file`.
pub fn run(file: &Path) -> anyhow::Result<()> {
    let report = neural_cloth::io::inspect(file)?;
    println!("{report}");
    Ok(())
}
