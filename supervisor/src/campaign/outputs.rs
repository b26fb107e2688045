//! What a campaign writes, for a run (`cli`) and for a merge of shards (`merge`) alike: the
//! scenario files of failing runs, summary.json, junit.xml and the lines on standard output.

use super::summary::Summary;
use crate::exit::Ended;
use crate::output::{self, Output};
use crate::scenario::Scenario;
use crate::{Error, Result};
use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;

/// A scenario file: the comment lines `about`, the line that reruns it, and the RON.
pub(super) fn scenario_text(about: &str, s: &Scenario, file: &Path) -> Result<String> {
    let pretty = ron::ser::PrettyConfig::new().struct_names(true);
    let body = ron::ser::to_string_pretty(s, pretty)
        .map_err(|e| Error::Internal(format!("cannot write a scenario as RON: {e}")))?;
    Ok(format!(
        "{about}// Rerun: harvemu scenario {}\n{body}\n",
        file.display()
    ))
}

/// The lines on standard output: the totals and each failing run.
pub(super) fn summary_lines(s: &Summary, out: &Path) -> String {
    let mut text = format!(
        "campaign {} (seed {}, shard {}): {} of {} runs, {} passed, {} failed{}\n",
        s.campaign,
        s.seed,
        s.shard,
        s.done,
        s.runs,
        s.passed,
        s.failed.len(),
        if s.interrupted { ", INTERRUPTED" } else { "" }
    );
    // A terminal's worth; summary.json has them all.
    for f in s.failed.iter().take(SHOWN) {
        let _ = writeln!(
            text,
            "  FAIL run {} (seed {}): {}  {}\n    shrunk from {} to {}: harvemu scenario {}",
            f.run,
            f.seed,
            f.expectation,
            f.observed,
            f.faults_before,
            bus::text::count(f.faults_after as u64, "fault", "faults"),
            out.join(&f.shrunk).display()
        );
    }
    if s.failed.len() > SHOWN {
        let _ = writeln!(
            text,
            "  ... and {} more failing runs: {}",
            s.failed.len() - SHOWN,
            out.join("summary.json").display()
        );
    }
    text
}

/// Failing runs listed on standard output.
const SHOWN: usize = 20;

/// Writes summary.json and junit.xml, then the lines on standard output.
pub(super) fn finish(s: &Summary, out: &Path, text: &str) -> Result<Ended> {
    let json = serde_json::to_string_pretty(s)? + "\n";
    write(&out.join("summary.json"), json.as_bytes())?;
    write(
        &out.join("junit.xml"),
        s.junit().map_err(Error::Internal)?.as_bytes(),
    )?;
    if let Some(signal) = crate::stop::received() {
        crate::say!("harvemu: interrupted by {}", signal.describe());
    }
    output::stdout(text)?;
    Ok(Ended {
        expectations_failed: !s.failed.is_empty(),
        node_down: false,
    })
}

/// Writes a whole output and puts it in place.
pub(super) fn write(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut o = Output::create(path)?;
    o.write_all(bytes)
        .map_err(|e| output::failed("write", o.path(), e))?;
    o.commit()
}
