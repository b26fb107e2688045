//! A campaign's results: `summary.json`, its JUnit XML, and the merge of shards.
//!
//! Contract: a summary depends only on the campaign (scenario, seed, run count), the shard and
//! the runs' results, never on the wall clock or the machine, so that [`merge`] of all the
//! shards of a campaign gives, run for run and byte for byte, the summary of the campaign run
//! as one shard. [`merge`] refuses summaries of different campaigns, of different shard counts,
//! a shard twice or missing, and an interrupted shard.

use super::shard::Shard;
use crate::scenario::junit::escape;
use serde::{Deserialize, Serialize};

/// `summary.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Summary {
    /// The scenario's name.
    pub campaign: String,
    /// A fingerprint of the scenario's text (FNV-1a): shards of one campaign share it.
    pub scenario_id: String,
    /// Runs in the whole campaign.
    pub runs: u64,
    /// The campaign's seed.
    pub seed: u64,
    /// `K/M`.
    pub shard: String,
    /// Runs this summary covers (the shard's).
    pub done: u64,
    /// Of those, how many passed.
    pub passed: u64,
    /// The failing runs, in run order.
    pub failed: Vec<Failed>,
    /// True when a stop signal ended the shard before its last run.
    pub interrupted: bool,
}

/// A failing run in `summary.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Failed {
    /// Its number.
    pub run: u64,
    /// Its seed.
    pub seed: u64,
    /// The first expectation it failed.
    pub expectation: String,
    /// What was observed.
    pub observed: String,
    /// The shrunk scenario, relative to the campaign's folder.
    pub shrunk: String,
    /// Faults drawn.
    pub faults_before: usize,
    /// Faults left after shrinking.
    pub faults_after: usize,
    /// Candidates run while shrinking.
    pub shrink_trials: u32,
    /// False when shrinking stopped at its budget.
    pub shrink_complete: bool,
}

/// The shrunk scenario's file of run `i`, relative to the campaign's folder.
pub fn shrunk_file(i: u64) -> String {
    format!("failing/run-{i}.ron")
}

impl Summary {
    /// The shard it covers.
    pub fn shard(&self) -> Result<Shard, String> {
        Shard::parse(&self.shard)
    }

    /// JUnit XML: one test suite, one test case per run of the summary.
    pub fn junit(&self) -> Result<String, String> {
        let shard = self.shard()?;
        let mut out = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites>\n");
        out += &format!(
            "  <testsuite name=\"{}\" tests=\"{}\" failures=\"{}\">\n    <properties><property name=\"seed\" value=\"{}\"/><property name=\"shard\" value=\"{}\"/><property name=\"runs\" value=\"{}\"/></properties>\n",
            escape(&self.campaign),
            self.done,
            self.failed.len(),
            self.seed,
            escape(&self.shard),
            self.runs
        );
        let mut failed = self.failed.iter().peekable();
        for i in shard.runs(self.runs).take(self.done as usize) {
            out += &format!(
                "    <testcase classname=\"{}\" name=\"run {i}\"",
                escape(&self.campaign)
            );
            match failed.next_if(|f| f.run == i) {
                None => out += "/>\n",
                Some(f) => {
                    out += &format!(
                        ">\n      <failure message=\"{}\">{}: {}; shrunk from {} to {}; reproduce: harvemu scenario {}</failure>\n    </testcase>\n",
                        escape(&f.expectation),
                        escape(&f.expectation),
                        escape(&f.observed),
                        f.faults_before,
                        bus::text::count(f.faults_after as u64, "fault", "faults"),
                        escape(&f.shrunk)
                    );
                }
            }
        }
        out += "  </testsuite>\n</testsuites>\n";
        Ok(out)
    }
}

/// The merge of the shards of one campaign: the summary of the campaign as one shard.
pub fn merge(parts: &[(String, Summary)]) -> Result<Summary, String> {
    let Some((first_name, first)) = parts.first() else {
        return Err("nothing to merge".into());
    };
    let m = first.shard().map_err(|e| format!("{first_name}: shard {e}"))?.m;
    let mut seen: Vec<Option<&str>> = vec![None; m as usize];
    for (name, s) in parts {
        for (what, a, b) in [
            ("scenario", &s.campaign, &first.campaign),
            ("scenario text", &s.scenario_id, &first.scenario_id),
        ] {
            if a != b {
                return Err(format!(
                    "{name} is another campaign than {first_name}: {what} {a:?}, not {b:?}"
                ));
            }
        }
        for (what, a, b) in [("seed", s.seed, first.seed), ("runs", s.runs, first.runs)] {
            if a != b {
                return Err(format!(
                    "{name} is another campaign than {first_name}: {what} {a}, not {b}"
                ));
            }
        }
        let shard = s.shard().map_err(|e| format!("{name}: shard {e}"))?;
        if shard.m != m {
            return Err(format!(
                "{name} is shard {shard} but {first_name} is one of {m} shards"
            ));
        }
        if let Some(other) = seen[(shard.k - 1) as usize].replace(name) {
            return Err(format!("{name} and {other} are both shard {shard}"));
        }
        if s.interrupted {
            return Err(format!(
                "{name} (shard {shard}) was interrupted after {}: run it again",
                bus::text::count(s.done, "run", "runs")
            ));
        }
        // Every failing run is one of the shard's, once, in order, with its own file in
        // failing/ (a summary from elsewhere names no other file to copy).
        let mut last = None;
        for f in &s.failed {
            if !shard.takes(f.run) || f.run >= s.runs || last.is_some_and(|l| f.run <= l) {
                return Err(format!(
                    "{name}: run {} is not a run of shard {shard} in order",
                    f.run
                ));
            }
            if f.shrunk != shrunk_file(f.run) {
                return Err(format!(
                    "{name}: run {}'s shrunk file is {:?}, not {:?}",
                    f.run,
                    f.shrunk,
                    shrunk_file(f.run)
                ));
            }
            last = Some(f.run);
        }
        let expected = shard.count(s.runs);
        if s.done != expected || s.passed + s.failed.len() as u64 != s.done {
            return Err(format!(
                "{name} (shard {shard}) covers {}, {} passed and {} failed: shard {shard} of {} runs has {expected}",
                bus::text::count(s.done, "run", "runs"),
                s.passed,
                s.failed.len(),
                s.runs
            ));
        }
    }
    let missing: Vec<String> = (1..=m)
        .filter(|k| seen[(*k - 1) as usize].is_none())
        .map(|k| format!("{k}/{m}"))
        .collect();
    if !missing.is_empty() {
        let which = if missing.len() == 1 { "shard" } else { "shards" };
        return Err(format!("{which} {} missing", missing.join(", ")));
    }
    let mut failed: Vec<Failed> = parts.iter().flat_map(|(_, s)| s.failed.clone()).collect();
    failed.sort_by_key(|f| f.run);
    Ok(Summary {
        campaign: first.campaign.clone(),
        scenario_id: first.scenario_id.clone(),
        runs: first.runs,
        seed: first.seed,
        shard: Shard::ALL.to_string(),
        done: parts.iter().map(|(_, s)| s.done).sum(),
        passed: parts.iter().map(|(_, s)| s.passed).sum(),
        failed,
        interrupted: false,
    })
}

#[cfg(test)]
mod tests;
