//! Trace files in any format harvemu knows, opened for reading.
//!
//! Contract: [`open`] takes the format from the file's first bytes and checks it against its
//! name: a file whose extension names one format (`.log`, `.asc`, `.blf`, `.pcapng`, `.pcap`,
//! `.mf4`) and whose bytes are another is bad input naming both, never misread (`.log` and
//! `.asc` are both text and read by the one text reader, which tells them apart itself; `.pcap`
//! and `.pcapng` both take either pcap format). A name with any other extension is read as what
//! its bytes are. Every record error is bad input naming the file and the line (text) or the
//! record and byte offset (binary). The file is read as it is taken.

use crate::{Error, Result};
use bus::tracefile::{self, ErrorFrames, FileFormat, Items, Sniffed};
use std::io::Read;
use std::path::Path;

/// Reads `--format`'s value.
pub fn parse_format(text: &str) -> std::result::Result<FileFormat, String> {
    FileFormat::parse(text).ok_or_else(|| {
        format!(
            "{} is not a trace format: {}",
            bus::text::quote(text),
            FileFormat::ALL.map(FileFormat::extension).join(", ")
        )
    })
}

/// The format a file's extension names, if it names one.
pub fn named(path: &Path) -> Option<FileFormat> {
    let ext = path.extension()?.to_str()?;
    if ext.eq_ignore_ascii_case("pcap") {
        return Some(FileFormat::Pcapng);
    }
    FileFormat::parse(ext)
}

fn is_text(f: FileFormat) -> bool {
    matches!(f, FileFormat::Log | FileFormat::Asc)
}

/// What a file is, from its first bytes, checked against its name.
pub fn format_of(path: &Path) -> Result<FileFormat> {
    let input = |source| Error::Input {
        path: path.to_path_buf(),
        source,
    };
    let mut file = std::fs::File::open(path).map_err(input)?;
    let mut head = [0u8; 16];
    let mut got = 0;
    while got < head.len() {
        match file.read(&mut head[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(input(e)),
        }
    }
    let shown = path.display();
    let is = match FileFormat::sniff(&head[..got]) {
        Sniffed::Format(f) => f,
        Sniffed::Pcap => FileFormat::Pcapng,
        Sniffed::OldMdf => {
            return Err(Error::BadInput(format!(
                "{shown}: an MDF file older than version 4: harvemu reads MF4 (MDF 4.x)"
            )));
        }
        // Not text by its first byte: the text reader names the line if it is meant as text.
        Sniffed::Unknown => match named(path) {
            Some(f) if !is_text(f) => {
                return Err(Error::BadInput(format!(
                    "{shown}: its name says {f}, but its first bytes are {:02X?}, which are not",
                    &head[..got.min(8)]
                )));
            }
            _ => FileFormat::Log,
        },
    };
    match named(path) {
        Some(name) if !is_text(name) && got == 0 => Err(Error::BadInput(format!(
            "{shown}: the file is empty, and {name} has a header"
        ))),
        Some(name) if name != is && !(is_text(name) && is_text(is)) => {
            let what = if is_text(is) {
                "text (a candump log or ASC)"
            } else {
                is.describe()
            };
            Err(Error::BadInput(format!(
                "{shown}: this is {what}, but its name says {name}: rename it to .{}",
                is.extension()
            )))
        }
        _ => Ok(is),
    }
}

/// Numbered records of a trace, each a bad-input error naming the file when it cannot be read.
pub type Records = Box<dyn Iterator<Item = Result<(u64, tracefile::Item)>>>;

/// The records of the trace at `path`, in its format ([`format_of`]).
pub fn open(path: &Path, errors: ErrorFrames) -> Result<(FileFormat, Records)> {
    let format = format_of(path)?;
    let file = std::fs::File::open(path).map_err(|source| Error::Input {
        path: path.to_path_buf(),
        source,
    })?;
    let items: Items<'static> = tracefile::items(file, format, errors).map_err(|e| bad(path, e))?;
    let path = path.to_path_buf();
    Ok((format, Box::new(items.map(move |r| r.map_err(|e| bad(&path, e))))))
}

/// A record error as bad input naming the file: `file:line: why` for a text trace.
pub fn bad(path: &Path, e: bus::Error) -> Error {
    match e {
        bus::Error::TraceLine { line, reason } => {
            Error::BadInput(format!("{}:{line}: {reason}", path.display()))
        }
        other => Error::BadInput(format!("{}: {other}", path.display())),
    }
}
