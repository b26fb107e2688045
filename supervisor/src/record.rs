//! `--record FILE`: where the hub's trace goes.
//!
//! Contract: a file whose name ends in `.asc` (any case) gets Vector ASC, any other file the
//! candump log the hub writes. The file is buffered; the hub flushes it whenever a run pauses, and
//! dropping the writer (the end of a run, an interrupted run, an error) flushes it and, for ASC,
//! ends the measurement. A file that cannot be created is bad input naming the file.

use crate::BadInput;
use bus::tracefile::AscWriter;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::time::SystemTime;

/// True when `path` names an ASC file.
pub fn is_asc(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("asc"))
}

/// Creates the trace file at `path`, in the format its name asks for.
pub fn create(path: &Path) -> anyhow::Result<Box<dyn Write>> {
    let file = std::fs::File::create(path)
        .map_err(|e| BadInput(format!("cannot create {}: {e}", path.display())))?;
    let file = BufWriter::new(file);
    if is_asc(path) {
        let asc = AscWriter::new(file, SystemTime::now())
            .map_err(|e| BadInput(format!("cannot write {}: {e}", path.display())))?;
        Ok(Box::new(asc))
    } else {
        Ok(Box::new(file))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_name_picks_the_format() {
        for (name, asc) in [
            ("run.asc", true),
            ("RUN.ASC", true),
            ("dir.asc/run.log", false),
            ("run.log", false),
            ("asc", false),
            ("run.asc.log", false),
        ] {
            assert_eq!(is_asc(Path::new(name)), asc, "{name}");
        }
    }
}
