//! `harvemu import FILE.dbc --out DIR`: a runnable network from a DBC file.
//!
//! Contract: the DBC is read whole (at most [`nodes::file::MAX_FILE`] bytes, UTF-8 or, failing
//! that, Windows-1252 as DBC editors write it) and parsed by [`protocol::database`]; a file that
//! does not parse is exit code 2 at its line and column. DIR gets `network.ron` (a `Network` of
//! the database's name and bit rate), a copy of the DBC under its own name, as UTF-8 (the
//! scripts name it as `../NAME.dbc`), and `nodes/NODE.ron`, one behaviour script per node (one
//! that sends nothing only listens) ([`plan`]). Nothing is written when DIR holds anything and
//! `--force` is not given (exit code 2), nor when the file has no node and no transmitter.
//! Every case the scripts cannot do as the DBC says is a warning on standard error, and a
//! comment in the script of the node it concerns where there is one (a message's sender).

mod plan;

pub use plan::{Plan, Signals, plan};

use crate::Error;
use crate::output::{self, failed};
use protocol::database::Database;
use std::path::{Path, PathBuf};

/// Arguments of `harvemu import`.
#[derive(clap::Args)]
pub struct Args {
    /// The DBC file.
    #[arg(value_name = "FILE")]
    dbc: PathBuf,
    /// The folder to write the network into (made when missing).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Write into DIR even when it holds files (those of the same names are replaced).
    #[arg(long)]
    force: bool,
    /// What the scripts send in each signal: its initial value, or a sine, ramp or random walk
    /// across its range (the multiplexor of a multiplexed message goes through its pages).
    #[arg(long, value_enum, default_value = "initial", value_name = "KIND")]
    signals: Signals,
}

/// Runs `harvemu import`.
pub fn run(args: &Args) -> crate::Result<()> {
    let bytes = read(&args.dbc)?;
    let text = protocol::database::text_of(&bytes);
    let name = args.dbc.display().to_string();
    let db = Database::parse(&name, &text).map_err(|e| Error::BadInput(e.to_string()))?;
    let file_name = args
        .dbc
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "network.dbc".into());
    let stem = Path::new(&file_name)
        .file_stem()
        .map_or("network".into(), |s| s.to_string_lossy().into_owned());
    let plan = plan(&db, &file_name, &stem, args.signals);
    if plan.counts.0 == 0 {
        return Err(Error::BadInput(format!(
            "{name}: no nodes (BU_) and no message with a transmitter: nothing to run"
        )));
    }
    let dir = &args.out;
    if std::fs::metadata(dir).is_ok_and(|m| !m.is_dir()) {
        return Err(Error::BadInput(format!("--out {}: not a folder", dir.display())));
    }
    if !args.force
        && let Ok(mut entries) = std::fs::read_dir(dir)
        && entries.next().is_some()
    {
        return Err(Error::BadInput(format!(
            "--out {}: the folder holds files: nothing written (--force writes into it)",
            dir.display()
        )));
    }
    for w in &plan.warnings {
        crate::say!("harvemu: warning: {w}");
    }
    let mut written = vec![(dir.join(&file_name), text.into_bytes())];
    written.extend(
        plan.files
            .iter()
            .map(|f| (dir.join(&f.path), f.text.clone().into_bytes())),
    );
    for (path, bytes) in &written {
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent).map_err(|e| failed("create", parent, e))?;
        }
        output::write_whole(path, bytes)?;
    }
    let (nodes, own, events) = plan.counts;
    if events > 0 {
        crate::say!(
            "harvemu: a DBC holds no protocol logic (requests, acknowledgements, calibration, states): \
             the event messages above are for reactions you add to send"
        );
    }
    let network = dir.join("network.ron");
    crate::say!(
        "harvemu: wrote {}: {}, {} sent on their own, {} for actions to send; {}. Run it: harvemu run {}",
        network.display(),
        counted(nodes, "node"),
        counted(own, "message"),
        counted(events, "event message"),
        counted(plan.warnings.len(), "warning"),
        network.display()
    );
    Ok(())
}

/// `3 nodes`, `1 node`.
fn counted(n: usize, what: &str) -> String {
    if n == 1 {
        format!("1 {what}")
    } else {
        format!("{n} {what}s")
    }
}

/// The file's bytes, at most [`nodes::file::MAX_FILE`].
fn read(path: &Path) -> crate::Result<Vec<u8>> {
    use std::io::Read;
    let limit = nodes::file::MAX_FILE;
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(limit + 1).read_to_end(&mut bytes))
        .map_err(|source| Error::Input {
            path: path.to_path_buf(),
            source,
        })?;
    if bytes.len() as u64 > limit {
        return Err(Error::BadInput(format!(
            "{}: larger than {} MiB, the limit for an input file",
            path.display(),
            limit >> 20
        )));
    }
    Ok(bytes)
}
