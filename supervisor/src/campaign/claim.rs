//! A campaign's folder holds one campaign's results: before a campaign or a merge writes into
//! `--out`, what is there is looked at.
//!
//! Contract: a folder with nothing of a campaign in it (no `summary.json`, no files in
//! `failing/`) is taken as it is. A folder whose `summary.json` names the same campaign (its
//! name, scenario fingerprint, seed, run count and shard) is the same campaign run again (a CI
//! retry): its `summary.json`, `junit.xml` and `failing/` are removed first, so that no stale
//! failing run survives beside a summary that does not list it. Anything else (another
//! campaign, a summary that cannot be read, failing runs without a summary) is refused unless
//! `--force`, which removes them the same way. Other files in the folder are left alone.

use super::summary::Summary;
use crate::output;
use crate::{Error, Result};
use std::path::Path;

/// What names a campaign's results: two summaries with the same are the same campaign's.
fn identity(s: &Summary) -> [(&'static str, String); 5] {
    [
        ("campaign", s.campaign.clone()),
        ("scenario", s.scenario_id.clone()),
        ("seed", s.seed.to_string()),
        ("runs", s.runs.to_string()),
        ("shard", s.shard.to_string()),
    ]
}

/// Makes `out` ready for the results of the campaign `this` describes (its counts are not
/// looked at), or refuses it as the contract says.
pub(super) fn claim(out: &Path, this: &Summary, force: bool) -> Result<()> {
    let summary = out.join("summary.json");
    let failing = out.join("failing");
    let holder = if summary.exists() {
        match super::merge::read_summary(&summary)
            .and_then(|t| serde_json::from_str::<Summary>(&t).map_err(|e| Error::BadInput(e.to_string())))
        {
            Ok(s) => {
                let (mine, theirs) = (identity(this), identity(&s));
                let differ: Vec<String> = mine
                    .iter()
                    .zip(&theirs)
                    .filter(|(a, b)| a.1 != b.1)
                    .map(|(a, b)| format!("{} {}, not {}", a.0, b.1, a.1))
                    .collect();
                if differ.is_empty() {
                    None
                } else {
                    Some(format!("the results of another campaign ({})", differ.join("; ")))
                }
            }
            Err(e) => Some(format!("a summary.json that is no campaign summary ({e})")),
        }
    } else if std::fs::read_dir(&failing).is_ok_and(|mut d| d.next().is_some()) {
        Some("failing runs without a summary.json (a campaign stopped before it ended?)".into())
    } else {
        return Ok(());
    };
    if let (Some(what), false) = (&holder, force) {
        return Err(Error::BadInput(format!(
            "--out {} holds {what}: give another folder, or --force to replace its results",
            out.display()
        )));
    }
    for file in ["summary.json", "junit.xml"] {
        let path = out.join(file);
        match std::fs::remove_file(&path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(output::failed("remove", &path, e));
            }
            _ => {}
        }
    }
    match std::fs::remove_dir_all(&failing) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(output::failed("remove", &failing, e)),
        _ => Ok(()),
    }
}
