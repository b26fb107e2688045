//! `harvemu scenario FILE...` and `harvemu validate FILE...`: a folder stands for the `.ron`
//! files directly in it ([`configs::expand`]).

use crate::configs::{self, Source};
use crate::exit::Ended;
use crate::harvester::Harvester;
use crate::output::Output;
use crate::report;
use crate::scenario::{self, Loaded, junit};
use indicatif::{ProgressBar, ProgressStyle};
use nodes::Error;
use std::fmt::Write as _;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Arguments of `harvemu scenario`.
#[derive(clap::Args)]
pub struct ScenarioArgs {
    /// Scenario files (RON), folders (every .ron file directly in one, sorted by name), or names
    /// of built-in scenarios and folders of them (`bus_off` for configs/scenarios/bus_off.ron,
    /// `conformance` for configs/scenarios/conformance/; `harvemu config list` names them).
    #[arg(required = true, value_name = "SCENARIO")]
    files: Vec<PathBuf>,
    /// Seed for every scenario (default: the scenario's, else its config's).
    #[arg(long, value_name = "N")]
    seed: Option<u64>,
    /// Run every scenario against this harvester config instead of the one it names (e.g.
    /// configs/harvester-firmware-c0.ron, the harvester with C0 as firmware).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Write a JUnit XML report here.
    #[arg(long, value_name = "FILE")]
    junit: Option<PathBuf>,
    /// Write the trace here (with several files, the last one's); the format follows the name: .asc Vector ASC, .blf Vector BLF, .pcapng
    /// pcapng (Wireshark), .mf4 MF4 (asammdf), anything else a candump log.
    #[arg(long, value_name = "FILE")]
    record: Option<PathBuf>,
    /// The trace's format whatever its name says: log (candump), asc, blf, pcapng or mf4.
    #[arg(long, value_name = "FORMAT", value_parser = crate::traces::parse_format, requires = "record")]
    format: Option<bus::tracefile::FileFormat>,
    /// Write an HTML report here: one page, a section per scenario, plots inline (written also
    /// when expectations fail or the run is interrupted).
    #[arg(long, value_name = "FILE")]
    report: Option<PathBuf>,
    /// Where bus time zero lies in the trace's timestamps: RFC 3339 (2024-01-01T00:00:00Z) or
    /// seconds since 1970. Default: 2024-01-01T00:00:00Z (virtual time: a seed gives the same
    /// trace).
    #[arg(long, value_name = "TIME", value_parser = crate::record::parse_start_time)]
    start_time: Option<bus::time::Epoch>,
    /// Write the firmware images' code coverage, merged over every scenario run, to this
    /// folder (docs/FIRMWARE.md, "Coverage"; written also when expectations fail or the run is
    /// interrupted).
    #[arg(long, value_name = "DIR")]
    coverage: Option<PathBuf>,
}

/// Runs `harvemu scenario`: exit code 0 only when every expectation of every scenario passed.
/// The JUnit XML and the HTML report are written whole at the end, also when an expectation
/// failed or a stop signal ended the batch (they then say so).
pub fn run(args: &ScenarioArgs) -> crate::Result<Ended> {
    let mut inputs: Vec<(&str, &Path)> = args.files.iter().map(|f| ("SCENARIO", f.as_path())).collect();
    if let Some(c) = &args.config {
        inputs.push(("--config", c));
    }
    crate::output::distinct(
        &[
            ("--junit", args.junit.as_deref()),
            ("--record", args.record.as_deref()),
            ("--report", args.report.as_deref()),
            ("--coverage", args.coverage.as_deref()),
        ],
        &inputs,
    )?;
    // Load everything first: a bad file stops the whole batch before anything runs.
    let mut loaded = Vec::new();
    let mut problems = Vec::new();
    let epoch = crate::record::epoch(args.start_time, false);
    for f in &expand(&args.files)? {
        match scenario::load_with(
            &configs::by_name(f, "scenarios"),
            args.seed,
            None,
            args.config.as_deref(),
        ) {
            Ok(mut l) => {
                l.harvester.epoch = Some(epoch);
                l.harvester.coverage = args.coverage.is_some();
                loaded.push(l)
            }
            Err(Error::Invalid(p)) => problems.extend(p),
            Err(e) => return Err(e.into()),
        }
    }
    if !problems.is_empty() {
        return Err(Error::Invalid(problems).into());
    }
    // Started before anything runs: a bad path should not cost a whole run.
    let report = args.report.as_deref().map(Output::create).transpose()?;
    let junit = args.junit.as_deref().map(Output::create).transpose()?;
    if let Some(dir) = &args.coverage {
        for l in &loaded {
            crate::coverage::check(&l.harvester)?;
        }
        crate::coverage::prepare(dir)?;
    }
    let mut outcomes = Vec::new();
    let mut failure = None;
    for l in &loaded {
        if crate::stop::received().is_some() {
            break;
        }
        let outcome = match run_one(l, args.record.as_ref(), args.format) {
            Ok(outcome) => outcome,
            Err(e) => {
                // A trace that could not be written ends the batch; what ran before it is still
                // reported, and the error decides the exit code.
                failure = Some(e);
                break;
            }
        };
        let interrupted = outcome.interrupted;
        outcomes.push(outcome);
        if interrupted {
            // A stop signal stops the batch: what ran is reported below.
            break;
        }
    }
    if let Some(signal) = crate::stop::received() {
        crate::say!("harvemu: interrupted by {}", signal.describe());
    }
    let mut out = String::new();
    let mut all_passed = true;
    for (l, o) in loaded.iter().zip(&outcomes) {
        let against = args
            .config
            .as_ref()
            .map(|c| format!(", against {}", c.display()))
            .unwrap_or_default();
        let _ = writeln!(
            out,
            "{} ({}{against}, seed {}, {:.1} s wall)",
            l.scenario.name, l.source, o.seed, o.wall_seconds
        );
        // The path alone, which finds the same file again (a built-in one too).
        let file = l.source.path.display();
        for e in &o.events {
            let _ = writeln!(out, "  event {} {} {}", e.at, e.node, e.what);
        }
        for line in o.disturbances() {
            let _ = writeln!(out, "  {line}");
        }
        for v in &o.verdicts {
            let at = v.at.map_or("-".to_string(), |t| format!("{t}"));
            let _ = writeln!(
                out,
                "  {} {}  [{at}] {}",
                if v.passed { "pass" } else { "FAIL" },
                v.expectation,
                v.observed
            );
        }
        if !o.passed() {
            all_passed = false;
            let _ = writeln!(
                out,
                "  failed: seed {}; reproduce with: harvemu scenario {file} --seed {}{}",
                o.seed,
                o.seed,
                args.config
                    .as_ref()
                    .map(|c| format!(" --config {}", c.display()))
                    .unwrap_or_default()
            );
        }
    }
    let passed: usize = outcomes
        .iter()
        .map(|o| o.verdicts.iter().filter(|v| v.passed).count())
        .sum();
    let failed: usize = outcomes
        .iter()
        .map(|o| o.verdicts.iter().filter(|v| !v.passed).count())
        .sum();
    let _ = writeln!(out, "{passed} passed, {failed} failed");
    let shown = crate::output::stdout(&out);
    let runs: Vec<(String, &scenario::Scenario, &scenario::Outcome)> = loaded
        .iter()
        .zip(&outcomes)
        .map(|(l, o)| (l.source.path.display().to_string(), &l.scenario, o))
        .collect();
    let mut node_down = false;
    for o in &outcomes {
        for name in &o.down {
            node_down = true;
            crate::say!(
                "harvemu: node {name} crashed more often than the restart policy allows and stays down"
            );
        }
    }
    if let Some(out) = junit {
        write(out, junit::xml(&runs).as_bytes())?;
    }
    if let Some(out) = report {
        write(out, report::html(&runs).as_bytes())?;
    }
    if let Some(dir) = &args.coverage {
        let mut merged = crate::coverage::Coverage::default();
        for c in outcomes.iter().filter_map(|o| o.coverage.as_ref()) {
            merged.merge(c).map_err(crate::Error::Internal)?;
        }
        crate::coverage::report(dir, &merged)?;
    }
    if let Some(e) = failure {
        return Err(e);
    }
    shown?;
    Ok(Ended {
        expectations_failed: !all_passed,
        node_down,
    })
}

/// The files the arguments stand for, in their order, each folder expanded
/// ([`configs::expand`]); the first argument that stands for nothing usable is the error.
fn expand(args: &[PathBuf]) -> crate::Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for a in args {
        files.extend(configs::expand(a, "scenarios")?);
    }
    Ok(files)
}

/// Writes a whole output and puts it in place.
fn write(mut out: Output, bytes: &[u8]) -> crate::Result<()> {
    out.write_all(bytes)
        .map_err(|e| crate::output::failed("write", out.path(), e))?;
    out.commit()?;
    Ok(())
}

fn run_one(
    l: &Loaded,
    record: Option<&PathBuf>,
    format: Option<bus::tracefile::FileFormat>,
) -> crate::Result<scenario::Outcome> {
    let epoch = l.harvester.epoch.unwrap_or(bus::time::Epoch::FIXED);
    let (trace, recording) = crate::record::create_opt(record, format, epoch)?;
    let bar = ProgressBar::new(l.scenario.duration_s.ceil() as u64);
    bar.set_style(
        ProgressStyle::with_template("{msg:30} {bar:30} {pos}/{len} s virtual time")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_message(l.scenario.name.clone());
    let outcome = scenario::run(l, trace, |t| bar.set_position(t as u64));
    bar.finish_and_clear();
    // The trace is ended whatever happened: a failed run still leaves what it recorded.
    let finished = recording.map_or(Ok(()), |r| r.finish(crate::stop::received()));
    let outcome = outcome?;
    finished?;
    Ok(outcome)
}

/// Arguments of `harvemu validate`.
#[derive(clap::Args)]
pub struct ValidateArgs {
    /// Harvester configs, node scripts, templates or scenarios (RON), or folders of them (every
    /// .ron file directly in one; `conformance` is configs/scenarios/conformance/, on disk or
    /// built in); the kind is read from the file.
    #[arg(required = true, value_name = "FILE")]
    files: Vec<PathBuf>,
}

/// Runs `harvemu validate`: every problem of every file, exit code 2 when there is any.
pub fn validate(args: &ValidateArgs) -> crate::Result<()> {
    let mut problems = Vec::new();
    for f in &expand(&args.files)? {
        let (source, text) = Source::file(f).read()?;
        // The struct name at the top of the file says what it is.
        let signals = nodes::environment::PlantSignals;
        let name = source.to_string();
        let result = match nodes::script::top_name(&text) {
            Some("Scenario") => scenario::load(f, None).map(|_| "scenario"),
            Some("NodeScript") => {
                nodes::script::from_file_text(&name, &source.path, &text, &signals, &source.reader())
                    .map(|_| "node script")
            }
            Some("Instance") => {
                nodes::script::from_file_text(&name, &source.path, &text, &signals, &source.reader())
                    .map(|_| "node script from a template")
            }
            Some("Template") => nodes::script::check_template(&name, &text).map(|_| "node script template"),
            Some("Firmware") => {
                nodes::firmware::load(&name, &source.path, &text, &source.reader()).map(|_| "firmware node")
            }
            Some("Network") => Harvester::open(&source).map(|_| "network config"),
            _ => Harvester::open(&source).map(|_| "harvester config"),
        };
        match result {
            Ok(kind) => crate::output::stdout(&format!("{source}: ok ({kind})\n"))?,
            Err(Error::Invalid(p)) => problems.extend(p),
            Err(e) => problems.push(nodes::Problem {
                file: source.to_string(),
                position: None,
                node: None,
                field: None,
                message: e.to_string(),
            }),
        }
    }
    if problems.is_empty() {
        Ok(())
    } else {
        Err(Error::Invalid(problems).into())
    }
}
