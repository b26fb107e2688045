//! `harvemu run`: the emulated harvester on the virtual hub, in real time or as fast as possible.

mod console;
pub mod cpu_trace;
pub mod summary;

pub use console::{PLAIN_EVERY, PLAIN_LINES, plain_period};
pub use summary::Summary;

use crate::Error;
use crate::exit::Ended;
use crate::harvester::{self, Harvester};
use crate::stop::Stop;
use actix::prelude::*;
use bus::time::{BusDuration, BusTime};
use bus_runtime::hub::{FlushTrace, GetSnapshot, Snapshot, runtime};
use console::Console;
use std::path::PathBuf;
use std::time::Duration;

/// Arguments of `harvemu run`.
#[derive(clap::Args)]
pub struct Args {
    /// Harvester config. The default is read from the working directory when it is there, else
    /// built in.
    #[arg(value_name = "CONFIG", default_value = "configs/harvester.ron")]
    config: PathBuf,
    /// Run in virtual time, as fast as the machine allows (needs --for).
    #[arg(long)]
    fast: bool,
    /// Stop after this much emulated time (e.g. 120s, 10m, 1h, 500ms).
    #[arg(long = "for", value_name = "DURATION", value_parser = parse_duration)]
    duration: Option<Duration>,
    /// Write every frame on the bus to this file; the format follows the name: .asc Vector ASC, .blf Vector BLF, .pcapng
    /// pcapng (Wireshark), .mf4 MF4 (asammdf), anything else a candump log.
    #[arg(long, value_name = "FILE")]
    record: Option<PathBuf>,
    /// The trace's format whatever its name says: log (candump), asc, blf, pcapng or mf4.
    #[arg(long, value_name = "FORMAT", value_parser = crate::traces::parse_format, requires = "record")]
    format: Option<bus::tracefile::FileFormat>,
    /// Serve the bus to socketcand clients (python-can's `socketcand` interface, ...) on this
    /// address; loopback port 29536 when no address is given. The bus is called `harv0`.
    #[arg(long, num_args = 0..=1, default_missing_value = "127.0.0.1:29536", value_name = "ADDR")]
    socketcand: Option<std::net::SocketAddr>,
    /// Put the emulated nodes on this SocketCAN interface (vcan0, can0) as well: their frames go
    /// out on it, frames of real devices on it reach them. Real time only.
    #[arg(long, value_name = "IFACE")]
    iface: Option<String>,
    /// Leave a node out, so that a real device on the interface takes its place (repeatable;
    /// F5 is the monitor).
    #[arg(long, value_name = "NODE")]
    without: Vec<String>,
    /// Show the cab monitor and the bus live in the terminal (q, Esc or Ctrl-C quits).
    #[arg(long)]
    tui: bool,
    /// The run's seed (the plant's randomness, each node's), instead of the config's.
    #[arg(long, value_name = "N")]
    seed: Option<u64>,
    /// Real-time scheduling for a bench: SCHED_FIFO priority 40 and locked memory (mlockall), so
    /// that the machine's other work does not stall the bus. Needs root or CAP_SYS_NICE and
    /// CAP_IPC_LOCK; without them a warning says so and the run goes on. Real time only.
    #[arg(long)]
    realtime: bool,
    /// Where bus time zero lies in the trace's timestamps and the socketcand frames: RFC 3339
    /// (2024-01-01T00:00:00Z) or seconds since 1970. Default: the wall clock at the start in
    /// real time, 2024-01-01T00:00:00Z with --fast (so a seed gives the same trace).
    #[arg(long, value_name = "TIME", value_parser = crate::record::parse_start_time)]
    start_time: Option<bus::time::Epoch>,
    /// At the end of the run, write each firmware node's state (CPU, internal RAM, SFRs, CAN
    /// controllers) to this JSON file (docs/FIRMWARE.md).
    #[arg(long, value_name = "FILE")]
    dump_state: Option<PathBuf>,
    /// Write the instructions a firmware node executes to standard output: bus time, machine
    /// cycles since reset, address, bytes, instruction and its cycles, one line each.
    #[arg(long, value_name = "NODE")]
    trace_cpu: Option<String>,
    /// The stretch of bus time --trace-cpu covers (default: the whole run), e.g. 0.5s..600ms.
    #[arg(long, value_name = "FROM..TO", value_parser = cpu_trace::parse_window, requires = "trace_cpu")]
    trace_cpu_window: Option<(BusTime, BusTime)>,
    /// Write each firmware image's code coverage to this folder: lcov .info where its debug
    /// files lie beside it, a listing of every instruction, and a record `coverage merge` reads
    /// (docs/FIRMWARE.md, "Coverage").
    #[arg(long, value_name = "DIR")]
    coverage: Option<PathBuf>,
}

/// Parses `120s`, `10m`, `1h`, `500ms`, `250us` or a plain number of seconds.
pub fn parse_duration(text: &str) -> Result<Duration, String> {
    let t = text.trim();
    let (number, scale) = if let Some(n) = t.strip_suffix("ms") {
        (n, 1e-3)
    } else if let Some(n) = t.strip_suffix("us").or_else(|| t.strip_suffix("µs")) {
        (n, 1e-6)
    } else if let Some(n) = t.strip_suffix('s') {
        (n, 1.0)
    } else if let Some(n) = t.strip_suffix('m') {
        (n, 60.0)
    } else if let Some(n) = t.strip_suffix('h') {
        (n, 3600.0)
    } else {
        (t, 1.0)
    };
    match number.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 && v * scale < 1e9 => Ok(Duration::from_secs_f64(v * scale)),
        _ => Err(format!(
            "'{text}' is not a duration (use e.g. 120s, 10m, 1h, 500ms)"
        )),
    }
}

/// One line about the running harvester: the bus, the plant's truth and, when there is one, what
/// the monitor shows.
pub fn summary(s: &Snapshot, running: &harvester::Running) -> String {
    Summary::of(s, running).to_string()
}

/// Runs `harvemu run`. It stops at `--for`, at a stop signal (at any moment, start-up included)
/// or, with the terminal display, at a quit key; the trace is finished in every case.
pub fn run(args: &Args) -> crate::Result<Ended> {
    crate::output::distinct(
        &[
            ("--record", args.record.as_deref()),
            ("--dump-state", args.dump_state.as_deref()),
            ("--coverage", args.coverage.as_deref()),
        ],
        &[("CONFIG", &args.config)],
    )?;
    if args.tui {
        crate::tui::require_terminal()?;
    }
    let mut h = Harvester::load(&args.config)?;
    if let Some(seed) = args.seed {
        h.config.network.seed = seed;
    }
    h.without(&args.without)?;
    if args.fast && args.iface.is_some() {
        return Err(Error::BadInput(
            "--iface runs in real time: leave out --fast".into(),
        ));
    }
    if args.fast && args.realtime {
        return Err(Error::BadInput(
            "--realtime is for real-time runs: leave out --fast".into(),
        ));
    }
    let iface = args.iface.clone();
    if let Some(name) = &iface {
        bus_runtime::backend::socketcan::check(name).map_err(Error::Interface)?;
    }
    if args.fast && args.duration.is_none() {
        return Err(Error::BadInput(
            "--fast needs --for: virtual time would otherwise run for ever".into(),
        ));
    }
    let cpu_trace = match &args.trace_cpu {
        Some(node) => {
            let window = args.trace_cpu_window.unwrap_or((BusTime::ZERO, BusTime::NEVER));
            Some(cpu_trace::request(&h, node, window)?)
        }
        None => None,
    };
    let cpu_trace_out = cpu_trace.as_ref().map(|(_, out)| out.clone());
    if let Some(dir) = &args.coverage {
        crate::coverage::check(&h)?;
        crate::coverage::prepare(dir)?;
    }
    h.coverage = args.coverage.is_some();
    let epoch = crate::record::epoch(args.start_time, !args.fast);
    h.epoch = Some(epoch);
    let (trace, recording) = crate::record::create_opt(args.record.as_ref(), args.format, epoch)?;
    let end = args.duration.map(BusTime::from_duration);
    // Two lines, so that the default config's fits 80 columns.
    crate::say!(
        "harvemu: {} ({} nodes) from {}, seed {}",
        h.config.network.name,
        h.scripts.len() + h.firmware.len() + usize::from(h.config.monitor.enabled),
        h.source,
        h.config.network.seed
    );
    crate::say!(
        "harvemu: {}",
        if args.fast {
            "virtual time, as fast as the machine allows"
        } else {
            "real time (Ctrl-C stops)"
        }
    );
    let fast = args.fast;
    let dump_state = args.dump_state.clone();
    let (tui, machine) = (args.tui, h.config.network.name.clone());
    let socketcand = args.socketcand;
    if fast && socketcand.is_some() {
        crate::say!(
            "harvemu: note: with --fast the bus runs in virtual time, far faster than clients can follow"
        );
    }
    if args.realtime {
        for line in crate::realtime::enter() {
            crate::say!("{line}");
        }
    }
    let system = System::with_tokio_rt(move || runtime(fast).expect("a tokio runtime"));
    let result = system.block_on(async move {
        let mut stop = Stop::new().map_err(Error::System)?;
        let mut running = harvester::begin(&h, !fast, trace.into_iter().collect()).await?;
        running.cpu_trace = cpu_trace.map(|(request, _)| request);
        let mut reported = 0;
        let bridge = match &iface {
            Some(name) => {
                let b = bus_runtime::backend::socketcan::bridge(running.hub.clone(), name)
                    .await
                    .map_err(Error::Interface)?;
                crate::say!("harvemu: bridged to CAN interface {name}");
                Some(b)
            }
            None => None,
        };
        let _gateway = match socketcand {
            Some(addr) => {
                let gw = bus_runtime::gateway::Gateway::start(running.hub.clone(), addr, Default::default()).await?;
                crate::say!("harvemu: socketcand gateway on {}, bus harv0", gw.addr);
                Some(gw)
            }
            None => None,
        };
        // Progress, the live summary and Ctrl-C are looked at once a second of bus time.
        let step = BusDuration::from_secs(1);
        if tui {
            crate::tui::live(&mut running, &machine, fast, end).await?;
            for e in &running.events {
                crate::say!("harvemu: {} {} {}", e.at, e.node, e.what);
            }
        }
        let mut console = Console::stderr(fast, end);
        let mut t = running.now();
        let mut interrupted = None;
        // The live display had its own loop; this one shows the summary instead.
        if !tui {
            loop {
                let next = t.next_multiple_of(step);
                let next = end.map_or(next, |e| next.min(e));
                tokio::select! {
                    r = running.run_until(next) => { r?; t = running.now(); }
                    s = stop.wait() => {
                        interrupted = Some(s);
                        break;
                    }
                }
                for e in &running.events[reported..] {
                    console.event(&format!("harvemu: {} {} {}", e.at, e.node, e.what));
                }
                reported = running.events.len();
                let snap = running.hub.send(GetSnapshot).await?;
                console.update(&Summary::of(&snap, &running));
                if end.is_some_and(|e| t >= e) {
                    break;
                }
            }
        }
        let interrupted = interrupted.or(crate::stop::received());
        running.end_cpu_trace(running.now()).await;
        let coverage = running.end_coverage(running.now()).await;
        running.hub.send(FlushTrace).await??;
        let snap = running.hub.send(GetSnapshot).await?;
        console.finish(&Summary::of(&snap, &running), interrupted);
        if let Some(b) = &bridge {
            let s = b.stats();
            crate::say!(
                "harvemu: interface: {} frames in ({} with kernel timestamps, longest wait {} us), {} out, {} error frames, {} write errors",
                s.received, s.kernel_stamped, s.max_wait_us, s.sent, s.error_frames, s.write_errors
            );
        }
        if let Some(line) = crate::realtime::overruns_line(&snap) {
            crate::say!("{line}");
        }
        if let Some(path) = &dump_state {
            let nodes: serde_json::Map<String, serde_json::Value> = running
                .hardware(running.now())
                .await
                .into_iter()
                .map(|(name, state)| (name, serde_json::json!(state)))
                .collect();
            let text = serde_json::to_string_pretty(&serde_json::json!({ "nodes": nodes }))
                ?;
            crate::output::write_whole(path, format!("{text}\n").as_bytes())?;
        }
        Ok::<_, Error>((
            Ended {
                expectations_failed: false,
                node_down: report_down(&running),
            },
            coverage,
        ))
    });
    // The trace is ended whatever happened: a failed run still leaves what it recorded.
    let finished = recording.map_or(Ok(()), |r| r.finish(crate::stop::received()));
    let traced = cpu_trace_out.map_or(Ok(()), |out| out.borrow_mut().finish());
    let (ended, coverage) = result?;
    finished?;
    traced?;
    if let (Some(dir), Some(coverage)) = (&args.coverage, coverage) {
        crate::coverage::report(dir, &coverage)?;
    }
    Ok(ended)
}

/// Says on stderr which nodes crashed beyond the restart policy and stay down; true when any.
pub fn report_down(running: &harvester::Running) -> bool {
    let down = running.down_by_themselves();
    for name in &down {
        crate::say!("harvemu: node {name} crashed more often than the restart policy allows and stays down");
    }
    !down.is_empty()
}
