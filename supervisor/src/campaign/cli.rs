//! `harvemu campaign SCENARIO --runs N --out DIR` and `harvemu campaign merge DIR... --out DIR`.

use super::outputs::{finish, scenario_text, summary_lines, write};
use super::runs::Campaign;
use super::shard::{INDEX_VAR, SHARDS_VAR, Shard};
use super::summary::{self, Failed, Summary};
use crate::configs;
use crate::exit::Ended;
use crate::output;
use crate::{Error, Result};
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Arguments of `harvemu campaign`.
#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct Args {
    #[command(subcommand)]
    merge: Option<MergeCommand>,
    /// The campaign's scenario: a file with a `random_faults` section, or the name of a built-in
    /// campaign (`harvest` for configs/campaigns/harvest.ron).
    #[arg(required = true, value_name = "SCENARIO")]
    scenario: Option<PathBuf>,
    /// Runs in the whole campaign (over all shards).
    #[arg(long, required = true, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    runs: Option<u64>,
    /// The campaign's seed: run i draws its faults from a seed made of this and i (default: the
    /// scenario's seed, else its config's).
    #[arg(long, value_name = "S")]
    seed: Option<u64>,
    /// Take only shard K of M: the runs i with i mod M = K - 1. Default: Kubernetes'
    /// JOB_COMPLETION_INDEX + 1 of HARVEMU_SHARDS when set, else the whole campaign.
    #[arg(long, value_name = "K/M", value_parser = Shard::parse)]
    shard: Option<Shard>,
    /// Runs played at the same time, 1 to 1024 (default: the machine's cores).
    #[arg(long, value_name = "J", value_parser = clap::value_parser!(u64).range(1..=1024))]
    jobs: Option<u64>,
    /// Most candidate runs spent shrinking one failing run (0: write it unshrunk).
    #[arg(long, value_name = "N", default_value_t = 400)]
    shrink_trials: u32,
    /// Folder for summary.json, junit.xml and failing/run-<i>.ron (created if needed).
    #[arg(long, required = true, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Run the campaign against this harvester config instead of the one its scenario names
    /// (e.g. configs/harvester-firmware.ron, every field node as firmware); the shrunk failing
    /// runs name it.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Write the firmware images' code coverage, merged over the runs done, to this folder
    /// (docs/FIRMWARE.md, "Coverage"). `OUT/coverage` is where `campaign merge` finds a
    /// shard's.
    #[arg(long, value_name = "DIR")]
    coverage: Option<PathBuf>,
    /// Write into --out even when it holds another campaign's results (another scenario, seed,
    /// run count or shard, as its summary.json says): they are removed first. The same
    /// campaign run again needs no --force; its old results are removed all the same.
    #[arg(long)]
    force: bool,
}

#[derive(clap::Subcommand)]
enum MergeCommand {
    /// Merge the folders of a campaign's shards into one, as if it had run as one shard.
    Merge {
        /// The shards' folders (each with its summary.json and failing/).
        #[arg(required = true, value_name = "DIR")]
        dirs: Vec<PathBuf>,
        /// The merged campaign's folder.
        #[arg(long, value_name = "DIR")]
        out: PathBuf,
        /// Write into --out even when it holds another campaign's results (they are removed
        /// first).
        #[arg(long)]
        force: bool,
    },
}

/// Runs `harvemu campaign` (or its `merge`): exit code 1 when a run failed.
pub fn run(args: &Args) -> Result<Ended> {
    if let Some(MergeCommand::Merge { dirs, out, force }) = &args.merge {
        let inputs: Vec<(&str, &Path)> = dirs.iter().map(|d| ("DIR", d.as_path())).collect();
        output::distinct(&[("--out", Some(out))], &inputs)?;
        return super::merge::merge(dirs, out, *force);
    }
    let (Some(scenario), Some(runs), Some(out)) = (&args.scenario, args.runs, &args.out) else {
        return Err(Error::BadInput("give SCENARIO, --runs and --out".into()));
    };
    let mut inputs = vec![("SCENARIO", scenario.as_path())];
    if let Some(c) = &args.config {
        inputs.push(("--config", c));
    }
    output::distinct(
        &[("--out", Some(out)), ("--coverage", args.coverage.as_deref())],
        &inputs,
    )?;
    let shard = match args.shard {
        Some(s) => s,
        None => Shard::from_env(
            std::env::var(INDEX_VAR).ok().as_deref(),
            std::env::var(SHARDS_VAR).ok().as_deref(),
        )
        .map_err(Error::BadInput)?,
    };
    let mut campaign = Campaign::open(
        &configs::by_name(scenario, "campaigns"),
        args.seed,
        args.config.as_deref(),
    )?;
    let this = Summary {
        campaign: campaign.name().to_string(),
        scenario_id: campaign.id.clone(),
        runs,
        seed: campaign.seed,
        shard: shard.to_string(),
        done: 0,
        passed: 0,
        failed: Vec::new(),
        interrupted: false,
    };
    if args.coverage.is_some() {
        crate::coverage::check(&campaign.base.harvester)?;
    }
    // Checked everything else first: what claiming removes is only removed for a campaign
    // that then runs.
    super::claim::claim(out, &this, args.force)?;
    campaign.coverage = args.coverage.is_some();
    if let Some(dir) = &args.coverage {
        crate::coverage::prepare(dir)?;
    }
    let mut coverage = crate::coverage::Coverage::default();
    let failing = out.join("failing");
    std::fs::create_dir_all(&failing).map_err(|e| output::failed("create", &failing, e))?;
    let jobs = args.jobs.map_or_else(
        || std::thread::available_parallelism().map_or(1, |n| n.get()),
        |j| j as usize,
    );
    let count = shard.count(runs);
    let started = Instant::now();
    let bar = Progress::new(campaign.name(), count);
    // Each shrunk run is written as soon as it comes: a campaign killed outright still leaves
    // what it found. The first write that fails ends the campaign with its error.
    let mut failed = BTreeMap::new();
    let mut broken = None;
    let done = super::runs::play(&campaign, shard, runs, jobs, args.shrink_trials, |r| {
        bar.add(r.failure.is_some());
        if let Some(c) = &r.coverage
            && let Err(e) = coverage.merge(c)
        {
            broken = Some(Error::Internal(e));
            return false;
        }
        let Some(f) = &r.failure else { return true };
        let file = summary::shrunk_file(r.run);
        let path = out.join(&file);
        match shrunk_text(&campaign, f, &path).and_then(|text| write(&path, text.as_bytes())) {
            Ok(()) => {
                failed.insert(r.run, failed_entry(r.run, r.seed, f, file));
                true
            }
            Err(e) => {
                broken = Some(e);
                false
            }
        }
    });
    bar.finish();
    if let Some(e) = broken {
        return Err(e);
    }
    if let Some(dir) = &args.coverage {
        crate::coverage::report(dir, &coverage)?;
    }
    let done = done.map_err(Error::Internal)?;
    let wall = started.elapsed().as_secs_f64();
    // Interrupted: the summary covers the runs before the first one left undone, and says so;
    // failures found past it are left out, their files removed.
    let last = (done > 0).then(|| shard.k - 1 + (done - 1) * shard.m);
    let (failed, past): (Vec<Failed>, Vec<Failed>) = failed
        .into_values()
        .partition(|f| last.is_some_and(|l| f.run <= l));
    for f in past {
        let _ = std::fs::remove_file(out.join(&f.shrunk));
    }
    let s = Summary {
        campaign: campaign.name().to_string(),
        scenario_id: campaign.id.clone(),
        runs,
        seed: campaign.seed,
        shard: shard.to_string(),
        done,
        passed: done - failed.len() as u64,
        failed,
        interrupted: done < count,
    };
    // The threads play() started: no more than the shard has runs.
    let used = jobs.min(count as usize).max(1);
    let mut text = summary_lines(&s, out);
    let _ = writeln!(
        text,
        "{:.1} s wall, {:.0} runs per hour on {used} job{}",
        wall,
        done as f64 * 3600.0 / wall.max(1e-9),
        if used == 1 { "" } else { "s" }
    );
    finish(&s, out, &text)
}

/// A failing run's entry in the summary.
fn failed_entry(run: u64, seed: u64, f: &super::runs::Failure, shrunk: String) -> Failed {
    Failed {
        run,
        seed,
        expectation: f.expectation.clone(),
        observed: f.observed.clone(),
        shrunk,
        faults_before: f.faults_before,
        faults_after: f.faults_after,
        shrink_trials: f.trials,
        shrink_complete: f.complete,
    }
}

/// Progress: a bar on a terminal, a line per tenth of the runs in a log.
struct Progress {
    bar: ProgressBar,
    total: u64,
    done: std::cell::Cell<u64>,
    failed: std::cell::Cell<u64>,
    started: Instant,
    log: bool,
}

impl Progress {
    fn new(name: &str, total: u64) -> Progress {
        let bar = ProgressBar::new(total);
        bar.set_style(
            ProgressStyle::with_template("{prefix} {bar:30} {pos}/{len} runs, {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar.set_prefix(name.to_string());
        Progress {
            bar,
            total,
            done: 0.into(),
            failed: 0.into(),
            started: Instant::now(),
            log: !std::io::stderr().is_terminal(),
        }
    }

    fn line(&self) -> String {
        let rate = self.done.get() as f64 * 3600.0 / self.started.elapsed().as_secs_f64().max(1e-9);
        format!("{} failed, {rate:.0} runs/h", self.failed.get())
    }

    fn add(&self, failed: bool) {
        let before = self.done.get();
        self.done.set(before + 1);
        self.failed.set(self.failed.get() + u64::from(failed));
        self.bar.set_message(self.line());
        self.bar.inc(1);
        // A tenth of the way more (or the last run): a line for a log that has no bar.
        if self.log && (before * 10 / self.total.max(1) != self.done.get() * 10 / self.total.max(1)) {
            crate::say!(
                "harvemu: campaign {}: {}/{} runs, {}",
                self.bar.prefix(),
                self.done.get(),
                self.total,
                self.line()
            );
        }
    }

    pub(super) fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

/// The shrunk scenario's file: what it is, in comment lines, then the scenario in RON with
/// its harvester named from where the file lies.
fn shrunk_text(c: &Campaign, f: &super::runs::Failure, file: &Path) -> Result<String> {
    let mut s = f.scenario.clone();
    s.config = super::paths::config_field(&c.base.harvester.source, file);
    let about = format!(
        "// Found by harvemu campaign, shrunk from {} to {} in {}{}.\n// It fails {}: {}\n",
        f.faults_before,
        bus::text::count(f.faults_after as u64, "fault", "faults"),
        bus::text::count(u64::from(f.trials), "trial", "trials"),
        if f.complete {
            ""
        } else {
            " (stopped at the trial budget)"
        },
        f.expectation,
        // One comment line, whatever the observation holds.
        f.shrunk_observed
            .chars()
            .map(|c| if c.is_control() { ' ' } else { c })
            .collect::<String>(),
    );
    scenario_text(&about, &s, file)
}
