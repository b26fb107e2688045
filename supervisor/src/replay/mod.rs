//! `harvemu replay FILE`: a trace in any format harvemu reads (candump log, Vector ASC, BLF,
//! pcapng or pcap, MF4; [`crate::traces`]) played onto the bus of the emulated harvester.
//!
//! Contract: the whole trace is read and checked before anything starts (a bad line is bad input
//! naming `file:line`, a bad record of a binary trace names its number and byte offset), then
//! read again as it is played, once per pass: it is never held in memory, so memory does not grow
//! with the trace ([`schedule`]), and it must be a file that can be read more than once (not a
//! pipe). A line longer than [`bus::tracefile::MAX_LINE`] is a bad line. The replay is one more controller on the hub, with no receive filter
//! match, so its frames arbitrate with the emulated nodes' and reach them through their filters.
//! Each frame is handed to that controller at the start of the replay plus its offset
//! ([`schedule`]), in virtual time (`--fast`) or in real time; the bus is run up to that moment
//! first, so timing is the same under both clocks. A frame the controller's queue cannot take is
//! counted as refused. After the last frame the bus runs on for [`TAIL`] (or to `--for`), and a
//! summary goes to stderr. With `--iface`, no node is emulated unless `--with-emulated` asks for
//! them ([`for_interface`]): only the trace goes out on the interface.

pub mod schedule;

use crate::Error;
use crate::exit::Ended;
use crate::harvester::{self, Harvester, Running};
use crate::run::parse_duration;
use crate::stop::Stop;
use actix::prelude::*;
use bus::engine::{ControllerConfig, Filter, NodeId};
use bus::time::{BusDuration, BusTime};
use bus::tracefile::{ErrorFrames, Record};
use bus_runtime::hub::{Attach, FlushTrace, GetSnapshot, SubmitAt, runtime};
use protocol::ident::Address;
use schedule::{Passes, Schedule, Source, Survey};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// How long the bus runs on after the last frame: the frame goes out, the nodes answer.
pub const TAIL: Duration = Duration::from_millis(100);

/// Arguments of `harvemu replay`.
#[derive(clap::Args)]
pub struct Args {
    /// The trace: a candump log, Vector ASC or BLF, pcapng (or pcap), or MF4 (the format is read
    /// from the file, and must agree with its name's extension).
    #[arg(value_name = "TRACE")]
    file: PathBuf,
    /// Harvester config: the emulated nodes that run alongside the replay.
    /// The default is read from the working directory when it is there, else built in.
    #[arg(long, value_name = "FILE", default_value = "configs/harvester.ron")]
    config: PathBuf,
    /// Leave a node out of the emulation (repeatable; F5 is the monitor).
    #[arg(long, value_name = "NODE")]
    without: Vec<String>,
    /// Leave out frames whose source address belongs to an emulated node, so that a trace of the
    /// whole machine stands in only for the nodes left out.
    #[arg(long)]
    skip_emulated: bool,
    /// Virtual time, as fast as the machine allows; by default the trace plays in real time.
    #[arg(long)]
    fast: bool,
    /// Play the trace again after its end, for ever or N times in all; each pass is shifted so
    /// that times keep increasing.
    #[arg(long = "loop", value_name = "N", num_args = 0..=1)]
    passes: Option<Option<u32>>,
    /// Stop this long after the replay starts (e.g. 30s, 10m).
    #[arg(long = "for", value_name = "DURATION", value_parser = parse_duration)]
    duration: Option<Duration>,
    /// Record the resulting bus; the format follows the name: .asc Vector ASC, .blf Vector BLF, .pcapng
    /// pcapng (Wireshark), .mf4 MF4 (asammdf), anything else a candump log.
    #[arg(long, value_name = "FILE")]
    record: Option<PathBuf>,
    /// The trace's format whatever its name says: log (candump), asc, blf, pcapng or mf4.
    #[arg(long, value_name = "FORMAT", value_parser = crate::traces::parse_format, requires = "record")]
    format: Option<bus::tracefile::FileFormat>,
    /// Where bus time zero lies in the recorded trace's timestamps: RFC 3339
    /// (2024-01-01T00:00:00Z) or seconds since 1970. Default: the wall clock at the start in
    /// real time, 2024-01-01T00:00:00Z with --fast. The trace replayed plays from its first
    /// record whatever its times.
    #[arg(long, value_name = "TIME", value_parser = crate::record::parse_start_time)]
    start_time: Option<bus::time::Epoch>,
    /// Bridge the bus to this SocketCAN interface. Real time only. Only the trace's frames go
    /// out on it, unless --with-emulated is given.
    #[arg(long, value_name = "IFACE")]
    iface: Option<String>,
    /// With --iface: run the emulated harvester too (as without --iface), so that the trace
    /// stands in only for the nodes left out (--without, --skip-emulated).
    #[arg(long, requires = "iface")]
    with_emulated: bool,
    /// Refuse a trace with a pause between two records longer than this (e.g. 10s, 1h). Without
    /// it, a pause over an hour is only warned about: the replay plays it as bus time, which in
    /// real time means waiting it out.
    #[arg(long, value_name = "DURATION", value_parser = parse_duration)]
    max_gap: Option<Duration>,
}

/// The longest pause between two records replayed without a word: one hour.
pub const GAP_WARNING: Duration = Duration::from_secs(3600);

/// `d` in the largest unit that keeps it readable: 3.2 years, 5.0 days, 2.5 h, 12 min, 30 s.
fn readable(d: Duration) -> String {
    let s = d.as_secs_f64();
    const DAY: f64 = 86_400.0;
    match s {
        s if s >= 365.25 * DAY => format!("{:.1} years", s / (365.25 * DAY)),
        s if s >= DAY => format!("{:.1} days", s / DAY),
        s if s >= 3600.0 => format!("{:.1} h", s / 3600.0),
        s if s >= 60.0 => format!("{:.1} min", s / 60.0),
        s => format!("{s:.3} s"),
    }
}

/// Says what a long pause in the trace means: with `--max-gap`, bad input at its line; without
/// it, a warning (once) past [`GAP_WARNING`].
fn check_gap(path: &Path, survey: &Survey, max_gap: Option<Duration>) -> crate::Result<()> {
    let Some(gap) = survey.long_gap() else {
        return Ok(());
    };
    let length = readable(Duration::from_nanos(gap.nanos));
    match max_gap {
        Some(limit) => Err(Error::BadInput(format!(
            "{}:{}: {length} after the record before, longer than --max-gap {}",
            path.display(),
            gap.line,
            readable(limit)
        ))),
        None => {
            crate::say!(
                "harvemu: warning: {}:{}: {length} after the record before; the replay plays                  it as bus time (in real time it waits it out). --max-gap refuses such a trace",
                path.display(),
                gap.line
            );
            Ok(())
        }
    }
}

/// What a replay did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Played {
    /// Frames handed to the replay's controller.
    pub replayed: u64,
    /// Frames its full transmit queue refused.
    pub refused: u64,
}

/// The records of a trace file, read as they are taken; a bad line is bad input naming
/// `file:line`, a file that cannot be opened is bad input too.
pub fn records(path: &Path) -> Box<dyn Iterator<Item = crate::Result<Record>>> {
    Box::new(numbered(path).map(|r| r.map(|(_, record)| record)))
}

/// [`records`], each with its number: its line in a text trace, its record in a binary one.
pub fn numbered(path: &Path) -> Box<dyn Iterator<Item = crate::Result<(u64, Record)>>> {
    match crate::traces::open(path, ErrorFrames::Keep) {
        Ok((_, items)) => Box::new(items.map(|r| {
            r.map(|(number, item)| {
                let line = usize::try_from(number).unwrap_or(usize::MAX);
                (
                    number,
                    Record {
                        at: item.at,
                        line,
                        entry: item.entry,
                    },
                )
            })
        })),
        Err(e) => Box::new(std::iter::once(Err(e))),
    }
}

/// The trace file at `path` read again for each pass.
pub fn source(path: &Path) -> Source {
    let path = path.to_path_buf();
    Box::new(move || records(&path))
}

/// The addresses of the nodes the harvester emulates.
pub fn emulated(h: &Harvester) -> BTreeSet<Address> {
    let mut set: BTreeSet<Address> = h.scripts.iter().map(|s| Address(s.address)).collect();
    if h.config.monitor.enabled {
        set.insert(Address::MONITOR);
    }
    set
}

/// Sets up the harvester for a replay onto an interface: without `with_emulated`, no node is
/// emulated and the trace starts at once, so that the interface carries only what the trace
/// holds (a whole machine's trace next to the emulated machine would put every node on the bus
/// twice).
pub fn for_interface(h: &mut Harvester, with_emulated: bool) {
    if !with_emulated {
        h.scripts.clear();
        h.config.monitor.enabled = false;
        h.config.time_relay_ms = 0;
    }
}

/// Attaches the replay's controller to the hub of `running`.
pub async fn attach(running: &Running) -> crate::Result<NodeId> {
    let controller = ControllerConfig {
        tx_queue_len: 256,
        ..ControllerConfig::named("replay")
    }
    .with_filter(Filter::Nothing);
    Ok(running
        .hub
        .send(Attach {
            controller,
            node: None,
            reaction: Duration::ZERO,
        })
        .await?)
}

/// Sends the frames of `schedule` from `node`, the replay starting at bus time `start`, until
/// the schedule ends or `end`. Counts go to `played` as they happen, so an interrupted replay
/// still reports them.
pub async fn play(
    running: &mut Running,
    node: NodeId,
    schedule: &mut Schedule,
    start: BusTime,
    end: Option<BusTime>,
    played: &mut Played,
) -> crate::Result<()> {
    for due in schedule.by_ref() {
        let due = due?;
        let at = start + BusDuration::from_nanos(due.offset);
        if end.is_some_and(|e| at >= e) {
            break;
        }
        running.run_until(at).await?;
        let queued = running
            .hub
            .send(SubmitAt {
                node,
                frame: due.frame,
                at,
            })
            .await??;
        if queued {
            played.replayed += 1;
        } else {
            played.refused += 1;
        }
    }
    Ok(())
}

/// Refuses a trace that cannot be read twice (a pipe, a FIFO, a terminal): the check before
/// the run would drain it, and the replay would then find it empty and send nothing.
fn readable_twice(path: &Path) -> crate::Result<()> {
    match std::fs::metadata(path) {
        Ok(m) if !m.is_file() => Err(Error::BadInput(format!(
            "{}: not a regular file (a pipe, a FIFO or a device): replay reads its trace twice, \
             once to check it and once as it plays, so save it to a file first",
            path.display()
        ))),
        // A missing file is reported by the reader, with the reason.
        _ => Ok(()),
    }
}

/// Runs `harvemu replay`. A stop signal ends it at any moment; the trace is finished in every
/// case.
pub fn run(args: &Args) -> crate::Result<Ended> {
    crate::output::distinct(
        &[("--record", args.record.as_deref())],
        &[("TRACE", &args.file), ("--config", &args.config)],
    )?;
    let mut h = Harvester::load(&args.config)?;
    h.without(&args.without)?;
    let passes = match args.passes {
        None => Passes::Times(1),
        Some(None) => Passes::Forever,
        Some(Some(0)) => {
            return Err(Error::BadInput(
                "--loop N: N is the number of passes, at least 1".into(),
            ));
        }
        Some(Some(n)) => Passes::Times(n),
    };
    if args.fast && args.iface.is_some() {
        return Err(Error::BadInput(
            "--iface runs in real time: leave out --fast".into(),
        ));
    }
    if args.fast && passes == Passes::Forever && args.duration.is_none() {
        return Err(Error::BadInput(
            "--fast --loop needs --for: virtual time would otherwise run for ever".into(),
        ));
    }
    if let Some(name) = &args.iface {
        bus_runtime::backend::socketcan::check(name).map_err(Error::Interface)?;
        for_interface(&mut h, args.with_emulated);
    }
    let skip = if args.skip_emulated {
        emulated(&h)
    } else {
        BTreeSet::new()
    };
    readable_twice(&args.file)?;
    let limit = args.max_gap.unwrap_or(GAP_WARNING);
    let limit_ns = u64::try_from(limit.as_nanos()).unwrap_or(u64::MAX);
    let survey = Survey::numbered(numbered(&args.file), &skip, limit_ns)?;
    check_gap(&args.file, &survey, args.max_gap)?;
    if survey.counts().read == 0 {
        return Err(Error::BadInput(format!(
            "{}: no frames in this trace",
            args.file.display()
        )));
    }
    let mut schedule = Schedule::new(survey, skip, passes, source(&args.file));
    let counts = schedule.counts();
    let epoch = crate::record::epoch(args.start_time, !args.fast);
    h.epoch = Some(epoch);
    let (trace, recording) = crate::record::create_opt(args.record.as_ref(), args.format, epoch)?;
    crate::say!(
        "harvemu: replaying {} ({} records, {} to send per pass) onto {} from {}, {}",
        args.file.display(),
        counts.read,
        counts.per_pass,
        h.config.network.name,
        h.source,
        if args.fast {
            "virtual time"
        } else {
            "real time (Ctrl-C stops)"
        }
    );
    let fast = args.fast;
    let iface = args.iface.clone();
    let duration = args.duration;
    let relay = h.relay();
    let system = System::with_tokio_rt(move || runtime(fast).expect("a tokio runtime"));
    let result = system.block_on(async move {
        let mut stop = Stop::new().map_err(Error::System)?;
        let mut running = harvester::begin(&h, !fast, trace.into_iter().collect()).await?;
        let _bridge = match &iface {
            Some(name) => Some(
                bus_runtime::backend::socketcan::bridge(running.hub.clone(), name)
                    .await
                    .map_err(Error::Interface)?,
            ),
            None => None,
        };
        let mut interrupted = None;
        // Start-up first: the trace is played once the field nodes are there.
        tokio::select! {
            r = running.run_until(relay) => r?,
            s = stop.wait() => interrupted = Some(s),
        }
        let node = attach(&running).await?;
        let start = running.now();
        let end = duration.map(|d| start.after(d));
        let mut played = Played::default();
        if interrupted.is_none() {
            tokio::select! {
                r = play(&mut running, node, &mut schedule, start, end, &mut played) => r?,
                s = stop.wait() => interrupted = Some(s),
            }
        }
        if interrupted.is_none() {
            let last = schedule.end().map_or(start, |e| start + BusDuration::from_nanos(e));
            let until = end.unwrap_or(last.after(TAIL));
            tokio::select! {
                r = running.run_until(until) => r?,
                s = stop.wait() => interrupted = Some(s),
            }
        }
        if let Some(s) = interrupted {
            crate::say!("\nharvemu: interrupted by {}", s.describe());
        }
        running.hub.send(FlushTrace).await??;
        let snap = running.hub.send(GetSnapshot).await?;
        crate::say!("{}", crate::run::summary(&snap, &running));
        crate::say!(
            "harvemu: replay: {} records read, {} error frames (not replayable), {} frames skipped (emulated sources), {} replayed, {} refused (queue full), {}",
            counts.read,
            counts.error_frames,
            counts.skipped,
            played.replayed,
            played.refused,
            bus::text::count(u64::from(schedule.passes_begun()), "pass", "passes")
        );
        if let Some(line) = crate::realtime::overruns_line(&snap) {
            crate::say!("{line}");
        }
        Ok::<_, Error>(Ended {
            expectations_failed: false,
            node_down: crate::run::report_down(&running),
        })
    });
    // The trace is ended whatever happened: a failed run still leaves what it recorded.
    let finished = recording.map_or(Ok(()), |r| r.finish(crate::stop::received()));
    let ended = result?;
    finished?;
    Ok(ended)
}
