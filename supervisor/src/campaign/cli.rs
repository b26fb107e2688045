//! `harvemu campaign SCENARIO --runs N --out DIR` and `harvemu campaign merge DIR... --out DIR`.

use super::runs::Campaign;
use super::shard::{INDEX_VAR, SHARDS_VAR, Shard};
use super::summary::{self, Failed, Summary};
use crate::configs::{self, BUILT_IN, Source};
use crate::exit::Ended;
use crate::output::{self, Output};
use crate::scenario::Scenario;
use crate::{Error, Result};
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::{IsTerminal, Write};
use std::path::{Component, Path, PathBuf};
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
    },
}

/// Runs `harvemu campaign` (or its `merge`): exit code 1 when a run failed.
pub fn run(args: &Args) -> Result<Ended> {
    if let Some(MergeCommand::Merge { dirs, out }) = &args.merge {
        return merge(dirs, out);
    }
    let (Some(scenario), Some(runs), Some(out)) = (&args.scenario, args.runs, &args.out) else {
        return Err(Error::BadInput("give SCENARIO, --runs and --out".into()));
    };
    let shard = match args.shard {
        Some(s) => s,
        None => Shard::from_env(
            std::env::var(INDEX_VAR).ok().as_deref(),
            std::env::var(SHARDS_VAR).ok().as_deref(),
        )
        .map_err(Error::BadInput)?,
    };
    let campaign = Campaign::open(&configs::by_name(scenario, "campaigns"), args.seed, runs)?;
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
    let mut text = summary_lines(&s, out);
    let _ = writeln!(
        text,
        "{:.1} s wall, {:.0} runs per hour on {jobs} job(s)",
        wall,
        done as f64 * 3600.0 / wall.max(1e-9)
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
            eprintln!(
                "harvemu: campaign {}: {}/{} runs, {}",
                self.bar.prefix(),
                self.done.get(),
                self.total,
                self.line()
            );
        }
    }

    fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

/// The shrunk scenario's file: what it is, in comment lines, then the scenario in RON with
/// its harvester named from where the file lies.
fn shrunk_text(c: &Campaign, f: &super::runs::Failure, file: &Path) -> Result<String> {
    let mut s = f.scenario.clone();
    s.config = config_field(&c.base.harvester.source, file);
    let about = format!(
        "// Found by harvemu campaign, shrunk from {} to {} fault(s) in {} trial(s){}.\n// It fails {}: {}\n",
        f.faults_before,
        f.faults_after,
        f.trials,
        if f.complete {
            ""
        } else {
            " (stopped at the trial budget)"
        },
        f.expectation,
        f.observed.replace('\n', " "),
    );
    scenario_text(&about, &s, file)
}

/// A scenario file: the comment lines `about`, the line that reruns it, and the RON.
fn scenario_text(about: &str, s: &Scenario, file: &Path) -> Result<String> {
    let pretty = ron::ser::PrettyConfig::new().struct_names(true);
    let body = ron::ser::to_string_pretty(s, pretty)
        .map_err(|e| Error::Internal(format!("cannot write a scenario as RON: {e}")))?;
    Ok(format!(
        "{about}// Rerun: harvemu scenario {}\n{body}\n",
        file.display()
    ))
}

/// The harvester config as the scenario `file` names it: a built-in one as `PATH (built in)`,
/// an absolute path as it is, a relative one relative to the file's folder.
fn config_field(source: &Source, file: &Path) -> String {
    if source.built_in {
        return format!("{}{BUILT_IN}", source.path.display());
    }
    if source.path.is_absolute() {
        return normal(&source.path).display().to_string();
    }
    seen_from(file, &source.path)
}

/// `target` (a path relative to the working directory, or absolute) as the file `file` names
/// it: relative to the file's folder.
fn seen_from(file: &Path, target: &Path) -> String {
    let dir = file.parent().unwrap_or(Path::new(""));
    match (std::path::absolute(target), std::path::absolute(dir)) {
        (Ok(to), Ok(from)) => relative(&normal(&from), &normal(&to)).display().to_string(),
        (Ok(to), Err(_)) => normal(&to).display().to_string(),
        _ => target.display().to_string(),
    }
}

/// A path with `.` and `..` taken out lexically.
fn normal(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

/// `to` relative to the folder `from` (both absolute and normal).
fn relative(from: &Path, to: &Path) -> PathBuf {
    let (a, b): (Vec<_>, Vec<_>) = (from.components().collect(), to.components().collect());
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut out = PathBuf::new();
    for _ in common..a.len() {
        out.push("..");
    }
    for c in &b[common..] {
        out.push(c);
    }
    out
}

/// The lines on standard output: the totals and each failing run.
fn summary_lines(s: &Summary, out: &Path) -> String {
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
    for f in &s.failed {
        let _ = writeln!(
            text,
            "  FAIL run {} (seed {}): {}  {}\n    shrunk from {} to {} fault(s): harvemu scenario {}",
            f.run,
            f.seed,
            f.expectation,
            f.observed,
            f.faults_before,
            f.faults_after,
            out.join(&f.shrunk).display()
        );
    }
    text
}

/// Writes summary.json and junit.xml, then the lines on standard output.
fn finish(s: &Summary, out: &Path, text: &str) -> Result<Ended> {
    let json = serde_json::to_string_pretty(s)? + "\n";
    write(&out.join("summary.json"), json.as_bytes())?;
    write(
        &out.join("junit.xml"),
        s.junit().map_err(Error::Internal)?.as_bytes(),
    )?;
    if let Some(signal) = crate::stop::received() {
        eprintln!("harvemu: interrupted by {}", signal.describe());
    }
    output::stdout(text)?;
    Ok(Ended {
        expectations_failed: !s.failed.is_empty(),
        node_down: false,
    })
}

fn write(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut o = Output::create(path)?;
    o.write_all(bytes)
        .map_err(|e| output::failed("write", o.path(), e))?;
    o.commit()
}

/// `harvemu campaign merge`.
fn merge(dirs: &[PathBuf], out: &Path) -> Result<Ended> {
    let mut parts = Vec::new();
    for d in dirs {
        let path = d.join("summary.json");
        let text = read_summary(&path)?;
        let s: Summary = serde_json::from_str(&text)
            .map_err(|e| Error::BadInput(format!("{}: not a campaign summary: {e}", path.display())))?;
        parts.push((d.display().to_string(), s));
    }
    let merged = super::summary::merge(&parts).map_err(|e| Error::BadInput(format!("cannot merge: {e}")))?;
    let failing = out.join("failing");
    std::fs::create_dir_all(&failing).map_err(|e| output::failed("create", &failing, e))?;
    for (dir, s) in &parts {
        for f in &s.failed {
            let from = Path::new(dir).join(&f.shrunk);
            let to = out.join(&f.shrunk);
            write(&to, moved(&from, &to)?.as_bytes())?;
        }
    }
    let text = summary_lines(&merged, out);
    finish(&merged, out, &text)
}

/// Largest summary read: some two million failing runs.
const MAX_SUMMARY: u64 = 1 << 30;

/// A shard's summary.json as text: at most [`MAX_SUMMARY`] bytes of UTF-8.
fn read_summary(path: &Path) -> Result<String> {
    use std::io::Read;
    let bad = |why: String| Error::BadInput(format!("{}: {why}", path.display()));
    let file = std::fs::File::open(path).map_err(|e| bad(format!("cannot read it: {e}")))?;
    let mut bytes = Vec::new();
    file.take(MAX_SUMMARY + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| bad(format!("cannot read it: {e}")))?;
    if bytes.len() as u64 > MAX_SUMMARY {
        return Err(bad(format!(
            "larger than {MAX_SUMMARY} bytes: not a campaign summary"
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
    fn the_harvester_is_named_from_where_the_shrunk_file_lies() {
        let built_in = Source {
            path: "configs/harvester.ron".into(),
            built_in: true,
        };
        assert_eq!(
            config_field(&built_in, Path::new("/x/out/failing/run-1.ron")),
            "configs/harvester.ron (built in)"
        );
        let absolute = Source::file("/etc/harvemu/./h.ron");
        assert_eq!(
            config_field(&absolute, Path::new("out/failing/run-1.ron")),
            "/etc/harvemu/h.ron"
        );
        // Relative to the working directory, both: up out of out/failing, then down.
        let relative = Source::file("configs/../configs/harvester.ron");
        assert_eq!(
            config_field(&relative, Path::new("out/failing/run-1.ron")),
            "../../configs/harvester.ron"
        );
        assert_eq!(
            relative_to(Path::new("/a/b/c"), Path::new("/a/d/e.ron")),
            Path::new("../../d/e.ron")
        );
    }

    fn relative_to(from: &Path, to: &Path) -> PathBuf {
        relative(&normal(from), &normal(to))
    }

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
