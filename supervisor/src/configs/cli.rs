//! `harvemu config export DIR` and `harvemu config list`: the built-in configs, written out for
//! editing or named.
//!
//! Contract: `export` writes every built-in file to DIR under its path inside `configs/`
//! (`DIR/harvester.ron`, `DIR/nodes/d0.ron`, ...), byte for byte. It refuses, before writing
//! anything, when any of those files is already there, unless `--force` (exit code 2), and when
//! DIR is something other than a folder. Each file is written whole or not at all
//! ([`crate::output`]); a file or folder that cannot be written stops the export with exit
//! code 3, leaving the files written before it.

use super::FILES;
use crate::Error;
use crate::output::{self, failed};
use std::path::{Path, PathBuf};

/// `harvemu config ...`.
#[derive(clap::Subcommand)]
pub enum Command {
    /// Write the built-in configs into a folder to edit them: DIR/harvester.ron, DIR/nodes/, ...
    ///
    /// `harvemu config export configs` makes them the working directory's, which then win over
    /// the built-in ones. Files already there are left alone, and nothing is written, unless
    /// --force.
    Export(ExportArgs),
    /// Name every built-in config file.
    List,
}

/// Arguments of `harvemu config export`.
#[derive(clap::Args)]
pub struct ExportArgs {
    /// The folder to write into; made when missing.
    #[arg(value_name = "DIR")]
    dir: PathBuf,
    /// Overwrite files that are already there.
    #[arg(long)]
    force: bool,
}

/// Runs `harvemu config ...`.
pub fn run(command: &Command) -> crate::Result<()> {
    match command {
        Command::Export(args) => export(args),
        Command::List => {
            let names: String = FILES.iter().map(|(name, _)| format!("{name}\n")).collect();
            Ok(output::stdout(&names)?)
        }
    }
}

fn export(args: &ExportArgs) -> crate::Result<()> {
    let dir = &args.dir;
    if std::fs::metadata(dir).is_ok_and(|m| !m.is_dir()) {
        return Err(Error::BadInput(format!("{}: not a folder", dir.display())));
    }
    let files: Vec<(PathBuf, &[u8])> = FILES
        .iter()
        .map(|(name, bytes)| (dir.join(inside(name)), *bytes))
        .collect();
    if !args.force {
        let there: Vec<String> = files
            .iter()
            .filter(|(path, _)| std::fs::symlink_metadata(path).is_ok())
            .map(|(path, _)| path.display().to_string())
            .collect();
        if let Some(first) = there.first() {
            let more = match there.len() {
                1 => String::new(),
                n => format!(" and {} more", n - 1),
            };
            return Err(Error::BadInput(format!(
                "{first}{more} already there: nothing written (--force overwrites them)"
            )));
        }
    }
    for (path, bytes) in &files {
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(|e| failed("create", parent, e))?;
        }
        output::write_whole(path, bytes)?;
    }
    crate::say!("harvemu: wrote {} files under {}", files.len(), dir.display());
    Ok(())
}

/// A built-in file's path inside `configs/`.
fn inside(name: &str) -> &Path {
    Path::new(name.strip_prefix("configs/").unwrap_or(name))
}
