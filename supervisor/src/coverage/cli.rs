//! `harvemu coverage merge DIR... --out DIR`: the coverage of several runs as one.

use super::read_dir;
use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// Arguments of `harvemu coverage`.
#[derive(clap::Subcommand)]
pub enum Args {
    /// Merge the coverage folders of runs of the same images (`--coverage DIR` of run,
    /// scenario or campaign) into one: counts added, reports written again.
    Merge {
        /// Coverage folders to merge.
        #[arg(value_name = "DIR", required = true)]
        dirs: Vec<PathBuf>,
        /// Where the merged coverage goes (created if needed).
        #[arg(long, value_name = "DIR")]
        out: PathBuf,
    },
}

/// Runs `harvemu coverage`.
pub fn run(args: &Args) -> Result<()> {
    let Args::Merge { dirs, out } = args;
    let inputs: Vec<(&str, &Path)> = dirs.iter().map(|d| ("DIR", d.as_path())).collect();
    crate::output::distinct(&[("--out", Some(out))], &inputs)?;
    let mut merged = super::Coverage::default();
    for dir in dirs {
        let coverage = read_dir(dir)?;
        merged
            .merge(&coverage)
            .map_err(|e| Error::BadInput(format!("{}: {e}", dir.display())))?;
    }
    super::report(out, &merged)
}
