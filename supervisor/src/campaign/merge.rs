//! `harvemu campaign merge DIR... --out DIR`: the shards of a campaign, as one.

use super::outputs::{finish, scenario_text, summary_lines, write};
use super::paths::seen_from;
use super::summary::Summary;
use crate::configs::BUILT_IN;
use crate::exit::Ended;
use crate::output;
use crate::scenario::Scenario;
use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// `harvemu campaign merge`.
pub(super) fn merge(dirs: &[PathBuf], out: &Path, force: bool) -> Result<Ended> {
    let mut parts = Vec::new();
    for d in dirs {
        let path = d.join("summary.json");
        let text = read_summary(&path)?;
        let s: Summary = serde_json::from_str(&text)
            .map_err(|e| Error::BadInput(format!("{}: not a campaign summary: {e}", path.display())))?;
        parts.push((d.display().to_string(), s));
    }
    let merged = super::summary::merge(&parts).map_err(|e| Error::BadInput(format!("cannot merge: {e}")))?;
    super::claim::claim(out, &merged, force)?;
    let failing = out.join("failing");
    std::fs::create_dir_all(&failing).map_err(|e| output::failed("create", &failing, e))?;
    for (dir, s) in &parts {
        for f in &s.failed {
            let from = Path::new(dir).join(&f.shrunk);
            let to = out.join(&f.shrunk);
            write(&to, moved(&from, &to)?.as_bytes())?;
        }
    }
    // The shards' coverage, where each has it in its folder (`--coverage OUT/coverage`).
    let with_coverage: Vec<&PathBuf> = dirs.iter().filter(|d| d.join("coverage").is_dir()).collect();
    if !with_coverage.is_empty() {
        let mut coverage = crate::coverage::Coverage::default();
        for d in with_coverage {
            let dir = d.join("coverage");
            let shard = crate::coverage::read_dir(&dir)?;
            coverage
                .merge(&shard)
                .map_err(|e| Error::BadInput(format!("{}: {e}", dir.display())))?;
        }
        crate::coverage::report(&out.join("coverage"), &coverage)?;
    }
    let text = summary_lines(&merged, out);
    finish(&merged, out, &text)
}

/// Largest summary read: 64 MiB. A failing run is one entry of a few hundred bytes (its number,
/// seed, first failed expectation and observation), so even a 10,000-run campaign whose every
/// run failed is far below it; a larger file is no summary, and reading it stops here
/// (`/dev/zero` costs 64 MiB, not a gigabyte).
pub const MAX_SUMMARY: u64 = 64 << 20;

/// A shard's summary.json as text: at most [`MAX_SUMMARY`] bytes of UTF-8.
pub(super) fn read_summary(path: &Path) -> Result<String> {
    use std::io::Read;
    let bad = |why: String| Error::BadInput(format!("{}: {why}", path.display()));
    let file = std::fs::File::open(path).map_err(|e| bad(format!("cannot read it: {e}")))?;
    let mut bytes = Vec::new();
    file.take(MAX_SUMMARY + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| bad(format!("cannot read it: {e}")))?;
    if bytes.len() as u64 > MAX_SUMMARY {
        return Err(bad(format!(
            "larger than 64 MiB ({MAX_SUMMARY} bytes), the limit for a campaign summary"
        )));
    }
    String::from_utf8(bytes).map_err(|e| bad(format!("not UTF-8 text: {e}")))
}

/// A shrunk scenario's file, as it reads from its new place `to`: its harvester named from
/// there, its comment lines kept.
fn moved(from: &Path, to: &Path) -> Result<String> {
    let text = nodes::file::read_text(from).map_err(Error::Config)?;
    let mut s: Scenario = nodes::parse_ron(&from.display().to_string(), &text).map_err(Error::Config)?;
    let about: String = text
        .lines()
        .take_while(|l| l.starts_with("//"))
        .filter(|l| !l.starts_with("// Rerun:"))
        .map(|l| format!("{l}\n"))
        .collect();
    if !s.config.ends_with(BUILT_IN) && Path::new(&s.config).is_relative() {
        let config = from.parent().unwrap_or(Path::new("")).join(&s.config);
        s.config = seen_from(to, &config);
    }
    scenario_text(&about, &s, to)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_moved_file_names_its_harvester_from_its_new_place() {
        let dir = std::env::temp_dir().join(format!("harvemu-moved-{}", std::process::id()));
        let (old, new) = (dir.join("shard-2/failing"), dir.join("merged/deeper/failing"));
        std::fs::create_dir_all(&old).unwrap();
        let from = old.join("run-5.ron");
        let text = "// Found by harvemu campaign.\n// Rerun: harvemu scenario shard-2/failing/run-5.ron\n\
                    Scenario(name: \"t\", config: \"../../configs/harvester.ron\", duration_s: 1.0, expect: [NoCrashes])\n";
        std::fs::write(&from, text).unwrap();
        let to = new.join("run-5.ron");
        let moved = moved(&from, &to).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(
            moved.starts_with("// Found by harvemu campaign.\n// Rerun: harvemu scenario "),
            "{moved}"
        );
        assert_eq!(moved.matches("// Rerun:").count(), 1, "{moved}");
        // The same file as before: dir/configs/harvester.ron, now three folders up.
        assert!(
            moved.contains("config: \"../../../configs/harvester.ron\""),
            "{moved}"
        );
    }
}
