//! The coverage folder: written whole file by file ([`crate::output`]), and read back for a
//! merge.

use super::listing;
use super::record::{Coverage, FORMAT, ImageCoverage};
use crate::output::{failed, write_whole};
use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// The largest `NAME.coverage.json` read: a 64 KiB image's record is well under 1 MiB.
pub const MAX_RECORD: u64 = 16 << 20;

/// Writes `coverage` to `dir` (created if needed), and returns one line per image saying what
/// it covers and where its reports are. An output that cannot be written is an
/// [`Error::Output`] naming it.
pub fn write(dir: &Path, coverage: &Coverage) -> Result<Vec<String>> {
    std::fs::create_dir_all(dir).map_err(|e| failed("create", dir, e))?;
    // The sources are copied beside the reports: lcov's SF names them by absolute path.
    let absolute = std::path::absolute(dir).map_err(|e| failed("create", dir, e))?;
    let mut lines = Vec::new();
    let mut stems: Vec<String> = Vec::new();
    for image in &coverage.images {
        // Two images of one name in a run (from two folders) keep apart.
        let mut stem = image.stem();
        if stems.contains(&stem) {
            stem = format!("{stem}-{}", image.sha256.get(..12).unwrap_or(&image.sha256));
        }
        stems.push(stem.clone());
        let code = image.code_bytes();
        let counts = image.counts();
        let items = listing::items(&code, &image.written, &counts);
        let json = serde_json::to_string(image)?;
        write_whole(
            &dir.join(format!("{stem}.coverage.json")),
            format!("{json}\n").as_bytes(),
        )?;
        write_whole(
            &dir.join(format!("{stem}.coverage.lst")),
            listing::text(image, &code, &counts, &items).as_bytes(),
        )?;
        let mut reports = vec![format!("{stem}.coverage.lst")];
        let mut missing = Vec::new();
        if let Some(debug) = &image.debug {
            let src = dir.join("src").join(&stem);
            let mut paths = Vec::new();
            for s in &debug.sources {
                let Some(text) = &s.text else {
                    missing.push(s.path.clone());
                    paths.push((s.name.clone(), s.path.clone()));
                    continue;
                };
                let name = Path::new(&s.name)
                    .file_name()
                    .map_or_else(|| "source".into(), |n| n.to_string_lossy().into_owned());
                std::fs::create_dir_all(&src).map_err(|e| failed("create", &src, e))?;
                write_whole(&src.join(&name), text.as_bytes())?;
                let copy = absolute.join("src").join(&stem).join(&name);
                paths.push((s.name.clone(), copy.display().to_string()));
            }
            let path_of = |file: &str| {
                paths
                    .iter()
                    .find(|(n, _)| n == file)
                    .map_or_else(|| file.to_string(), |(_, p)| p.clone())
            };
            if let Some(info) = super::lcov::tracefile(image, &counts, &items, path_of) {
                write_whole(&dir.join(format!("{stem}.info")), info.as_bytes())?;
                reports.push(format!("{stem}.info"));
            }
        }
        let totals = listing::totals(&items, &counts);
        let mut line = format!(
            "{} ({}): {}; {} in {}",
            image.source,
            image.nodes.join(" "),
            listing::describe(&totals),
            reports.join(", "),
            dir.display()
        );
        if !missing.is_empty() {
            line.push_str(&format!(" (sources not found: {})", missing.join(", ")));
        }
        lines.push(line);
    }
    remove_stale(dir, &stems)?;
    Ok(lines)
}

/// Removes the reports of images this write did not have (a folder used again): a record left
/// from an earlier run would otherwise be merged with this one's. Only harvemu's own names go:
/// `NAME.coverage.json` with its `NAME.coverage.lst`, `NAME.info` and `src/NAME/`.
fn remove_stale(dir: &Path, written: &[String]) -> Result<()> {
    let entries = std::fs::read_dir(dir).map_err(|e| failed("write", dir, e))?;
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let Some(stem) = name.strip_suffix(".coverage.json") else {
            continue;
        };
        if written.iter().any(|w| w == stem) {
            continue;
        }
        for file in [
            format!("{stem}.coverage.lst"),
            format!("{stem}.info"),
            name.clone(),
        ] {
            match std::fs::remove_file(dir.join(&file)) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(failed("write", &dir.join(&file), e));
                }
                _ => {}
            }
        }
        let _ = std::fs::remove_dir_all(dir.join("src").join(stem));
    }
    Ok(())
}

/// Reads the coverage records (`*.coverage.json`) of `dir`. A record that cannot be read, is
/// too large or is not one is bad input naming the file; a folder without any, too.
pub fn read_dir(dir: &Path) -> Result<Coverage> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::Input {
        path: dir.to_path_buf(),
        source: e,
    })?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.to_string_lossy().ends_with(".coverage.json"))
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(Error::BadInput(format!(
            "{}: no coverage records (NAME.coverage.json) in it",
            dir.display()
        )));
    }
    let mut coverage = Coverage::default();
    for f in files {
        let image = read_record(&f)?;
        coverage
            .merge(&Coverage { images: vec![image] })
            .map_err(|e| Error::BadInput(format!("{}: {e}", f.display())))?;
    }
    Ok(coverage)
}

fn read_record(path: &Path) -> Result<ImageCoverage> {
    use std::io::Read;
    let file = std::fs::File::open(path).map_err(|e| Error::Input {
        path: path.to_path_buf(),
        source: e,
    })?;
    let mut text = String::new();
    file.take(MAX_RECORD + 1)
        .read_to_string(&mut text)
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::InvalidData => Error::BadInput(format!(
                "{}: not a coverage record: not UTF-8 text",
                path.display()
            )),
            _ => Error::Input {
                path: path.to_path_buf(),
                source: e,
            },
        })?;
    if text.len() as u64 > MAX_RECORD {
        return Err(Error::BadInput(format!(
            "{}: larger than {} MiB: not a coverage record",
            path.display(),
            MAX_RECORD >> 20
        )));
    }
    let image: ImageCoverage = serde_json::from_str(&text)
        .map_err(|e| Error::BadInput(format!("{}: not a coverage record: {e}", path.display())))?;
    if image.format != FORMAT {
        return Err(Error::BadInput(format!(
            "{}: format `{}`, expected `{FORMAT}`",
            path.display(),
            image.format
        )));
    }
    Ok(image)
}
