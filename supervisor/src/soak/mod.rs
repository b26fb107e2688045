//! `harvemu soak`: a long scenario in virtual time with random faults (by default a day of
//! harvesting, `configs/soak/soak_24h.ron`), reported with its memory over time and the
//! monitor's books.
//!
//! Contract: the run is an ordinary scenario run (same loader, runner and verdicts); this module
//! adds only the sampling of resident memory at the start, at every eighth of the run and at the
//! end, and the report. Exit code 0 when every expectation passed and memory stayed flat, 1
//! otherwise, 2 for bad input.

pub mod memory;

use crate::Error;
use crate::configs;
use crate::exit::Ended;
use crate::harvester::Happened;
use crate::scenario::{self, random};
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Arguments of `harvemu soak`.
#[derive(clap::Args)]
pub struct Args {
    /// The soak scenario (RON, usually with a `random_faults` section), or the name of a built-in
    /// one (`soak_24h` for configs/soak/soak_24h.ron). The default is read from the working
    /// directory when it is there, else built in.
    #[arg(value_name = "SCENARIO", default_value = "configs/soak/soak_24h.ron")]
    scenario: PathBuf,
    /// Virtual hours to run (default: the scenario's duration); the faults are drawn for this length.
    #[arg(long, value_name = "HOURS")]
    hours: Option<f64>,
    /// Seed of the run and of its faults (default: the scenario's, else its config's).
    #[arg(long, value_name = "N")]
    seed: Option<u64>,
    /// Write the trace here; the format follows the name: .asc Vector ASC, .blf Vector BLF, .pcapng
    /// pcapng (Wireshark), .mf4 MF4 (asammdf), anything else a candump log.
    #[arg(long, value_name = "FILE")]
    record: Option<PathBuf>,
    /// The trace's format whatever its name says: log (candump), asc, blf, pcapng or mf4.
    #[arg(long, value_name = "FORMAT", value_parser = crate::traces::parse_format, requires = "record")]
    format: Option<bus::tracefile::FileFormat>,
    /// Where bus time zero lies in the trace's timestamps: RFC 3339 (2024-01-01T00:00:00Z) or
    /// seconds since 1970. Default: 2024-01-01T00:00:00Z (virtual time: a seed gives the same
    /// trace).
    #[arg(long, value_name = "TIME", value_parser = crate::record::parse_start_time)]
    start_time: Option<bus::time::Epoch>,
}

/// Runs `harvemu soak`: expectations failed unless every expectation passed and memory stayed
/// flat.
pub fn run(args: &Args) -> crate::Result<Ended> {
    crate::output::distinct(
        &[("--record", args.record.as_deref())],
        &[("SCENARIO", &args.scenario)],
    )?;
    let duration = match args.hours {
        Some(h) if h.is_finite() && h > 0.0 => Some(h * 3600.0),
        Some(h) => {
            return Err(Error::BadInput(format!(
                "--hours {h}: must be a positive number of hours"
            )));
        }
        None => None,
    };
    let before = memory::vm_rss_kib();
    let mut loaded = scenario::load_with(
        &configs::by_name(&args.scenario, "soak"),
        args.seed,
        duration,
        None,
    )?;
    let epoch = crate::record::epoch(args.start_time, false);
    loaded.harvester.epoch = Some(epoch);
    let (trace, recording) = crate::record::create_opt(args.record.as_ref(), args.format, epoch)?;
    let s = &loaded.scenario;
    let mut rss = memory::Samples {
        duration_s: s.duration_s,
        points: before.map(|k| (0.0, k)).into_iter().collect(),
    };
    let bar = ProgressBar::new(s.duration_s.ceil() as u64);
    bar.set_style(
        ProgressStyle::with_template("{msg:24} {bar:30} {pos}/{len} s virtual, {elapsed} wall, eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_message(s.name.clone());
    let step = s.duration_s / 8.0;
    let mut next_sample = step;
    let outcome = scenario::run(&loaded, trace, |t| {
        bar.set_position(t as u64);
        if t >= next_sample {
            if let Some(k) = memory::vm_rss_kib() {
                rss.points.push((t, k));
                bar.set_message(format!("{} {:.1} MiB", s.name, k as f64 / 1024.0));
            }
            next_sample += step;
        }
    });
    bar.finish_and_clear();
    // The trace is ended whatever happened: a failed run still leaves what it recorded.
    let finished = recording.map_or(Ok(()), |r| r.finish(crate::stop::received()));
    let outcome = outcome?;
    finished?;
    if let Some(signal) = crate::stop::received() {
        crate::say!("harvemu: interrupted by {}", signal.describe());
    }
    if let Some(k) = memory::vm_rss_kib() {
        let end = outcome
            .snapshot
            .as_ref()
            .map_or(s.duration_s, |n| n.now.as_secs_f64());
        rss.points.push((end, k));
    }
    crate::output::stdout(&report(&loaded, &outcome, &rss, args.hours))?;
    let flat = rss.verdict().is_none_or(|(flat, _)| flat);
    for name in &outcome.down {
        crate::say!("harvemu: node {name} crashed more often than the restart policy allows and stays down");
    }
    Ok(Ended {
        expectations_failed: !(outcome.passed() && flat),
        node_down: !outcome.down.is_empty(),
    })
}

/// The soak's report, as printed.
fn report(l: &scenario::Loaded, o: &scenario::Outcome, rss: &memory::Samples, hours: Option<f64>) -> String {
    let s = &l.scenario;
    let mut out = format!(
        "{} ({}), seed {}, {:.2} h virtual\n",
        s.name,
        l.source,
        o.seed,
        s.duration_s / 3600.0
    );
    let mut drawn: BTreeMap<String, usize> = BTreeMap::new();
    for step in &s.timeline {
        if let Some(k) = random::kind_of(&step.action) {
            *drawn.entry(format!("{k:?}")).or_insert(0) += 1;
        }
    }
    let total: usize = drawn.values().sum();
    let kinds: Vec<String> = drawn.iter().map(|(k, n)| format!("{k} {n}")).collect();
    let applied: u64 = o.applied.values().sum();
    out += &format!(
        "faults: {total} ({}); {applied} timeline actions carried out\n",
        kinds.join(", ")
    );
    let count = |which: fn(&Happened) -> bool| o.events.iter().filter(|e| which(&e.what)).count();
    out += &format!(
        "supervisor: {}, {}, {} gave up\n",
        bus::text::count(
            count(|h| matches!(h, Happened::Crashed(_))) as u64,
            "crash",
            "crashes"
        ),
        bus::text::count(count(|h| *h == Happened::Restarted) as u64, "restart", "restarts"),
        count(|h| matches!(h, Happened::GaveUp { .. }))
    );
    let virtual_s = o.snapshot.as_ref().map_or(0.0, |n| n.now.as_secs_f64());
    out += &format!(
        "wall: {:.1} s ({:.0}x real time)\n",
        o.wall_seconds,
        virtual_s / o.wall_seconds.max(1e-9)
    );
    out += &rss.line();
    out.push('\n');
    let b = &o.books;
    out += &format!("bus: {} frames, {} error frames", b.frames, b.error_frames);
    if let Some(t) = b.trace {
        out += &format!("; trace: {} frames, {} error frames", t.frames, t.error_frames);
    }
    out.push('\n');
    if let Some(m) = &b.monitor {
        out += "books of the monitor (F5):\n";
        out += &m.table();
    }
    for v in &o.verdicts {
        out += &format!(
            "{} {}  {}\n",
            if v.passed { "pass" } else { "FAIL" },
            v.expectation,
            v.observed
        );
    }
    if !o.passed() {
        out += &format!(
            "failed: reproduce with: harvemu soak {} --seed {}{}\n",
            l.source.path.display(),
            o.seed,
            hours.map(|h| format!(" --hours {h}")).unwrap_or_default()
        );
    }
    out
}
