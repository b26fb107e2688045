//! `--coverage DIR`: which instructions of each firmware image a run executed, and which way
//! its conditional jumps went, as lcov `.info`, a plain listing and a mergeable record.
//!
//! Contract: a [`Collector`] hands each firmware node of a run the counts of its image
//! ([`nodes::firmware::coverage`]: exact on the path the node takes), one set per image (the
//! image's file and its SHA-256), shared by every node that runs it. [`Collector::take`] gives
//! them as a [`Coverage`], which [`Coverage::merge`] adds to another run's (the same images
//! only) and [`write`] puts in a folder: per image `NAME.coverage.json` (everything, for
//! merging), `NAME.coverage.lst` (every instruction with its counts) and, when the image has debug
//! information, `NAME.info` (lcov) with copies of its sources under `src/`. The reports of
//! images the folder held from an earlier write, and this one has not, are removed.

mod cli;
mod lcov;
mod listing;
mod record;
mod write;

pub use cli::{Args, run};
pub use record::{Coverage, ImageCoverage};
pub use write::{read_dir, write};

use nodes::firmware::FirmwareSpec;
use nodes::firmware::coverage::SharedCounts;
use std::cell::RefCell;
use std::collections::BTreeSet;
use std::rc::Rc;
use std::sync::Arc;

/// Makes sure `dir` can take the coverage before a run begins: created if needed. An
/// [`crate::Error::Output`] naming it when it cannot be.
pub fn prepare(dir: &std::path::Path) -> crate::Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| crate::output::failed("create", dir, e))?;
    // A folder that exists but takes no file is found out now, not after the run.
    tempfile::Builder::new()
        .prefix(".harvemu-coverage.")
        .tempfile_in(dir)
        .map(drop)
        .map_err(|e| crate::output::failed("write", dir, e))
}

/// Refuses, before a run that counts coverage, debug files that lie beside an image of `h`
/// but do not belong to it ([`FirmwareSpec::debug_problems`]): bad input naming each file.
pub fn check(h: &crate::harvester::Harvester) -> crate::Result<()> {
    let problems: Vec<nodes::Problem> = h.firmware.iter().flat_map(|f| f.debug_problems.clone()).collect();
    if problems.is_empty() {
        Ok(())
    } else {
        Err(crate::Error::Config(nodes::Error::Invalid(problems)))
    }
}

/// Writes `coverage` to `dir` and says on stderr what each image's covers.
pub fn report(dir: &std::path::Path, coverage: &Coverage) -> crate::Result<()> {
    if coverage.images.is_empty() {
        crate::say!(
            "harvemu: coverage: no firmware node ran: nothing written to {}",
            dir.display()
        );
        return Ok(());
    }
    for line in write(dir, coverage)? {
        crate::say!("harvemu: coverage: {line}");
    }
    Ok(())
}

/// The counts of a run's images, as its nodes make them (inside the run's actix thread).
#[derive(Default)]
pub struct Collector {
    images: RefCell<Vec<Entry>>,
}

struct Entry {
    spec: Arc<FirmwareSpec>,
    nodes: BTreeSet<String>,
    counts: SharedCounts,
}

/// A collector the run's parts share.
pub type SharedCollector = Rc<Collector>;

impl Collector {
    /// The counts a node of `spec` adds to: its image's.
    pub fn counts_for(&self, spec: &Arc<FirmwareSpec>) -> SharedCounts {
        let mut images = self.images.borrow_mut();
        let same =
            |e: &&mut Entry| e.spec.image_file == spec.image_file && e.spec.image_sha256 == spec.image_sha256;
        if let Some(e) = images.iter_mut().find(|e| same(e)) {
            e.nodes.insert(spec.name.clone());
            return e.counts.clone();
        }
        let counts = SharedCounts::default();
        images.push(Entry {
            spec: spec.clone(),
            nodes: std::iter::once(spec.name.clone()).collect(),
            counts: counts.clone(),
        });
        counts
    }

    /// The counts so far, as one run's coverage.
    pub fn take(&self) -> Coverage {
        let images = self
            .images
            .borrow()
            .iter()
            .map(|e| ImageCoverage::of(&e.spec, e.nodes.iter().cloned().collect(), &e.counts.borrow()))
            .collect();
        Coverage { images }
    }
}
