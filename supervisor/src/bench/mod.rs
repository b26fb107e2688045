//! `harvemu bench`: how fast the emulator runs, measured, never asserted.
//!
//! Workloads, each on one or many independent buses spread over threads (one actor system per
//! thread):
//! - saturated: 21 nodes that always have a frame pending at 250 kbit/s, each frame addressed to
//!   the next node, so every frame is arbitrated among all pending contenders, bit-timed exactly,
//!   delivered once and answered by a wake of its receiver;
//! - harvester: the harvester of a config (the default one unless told), monitor, plant and
//!   supervision included, in virtual time;
//! - realtime: the same harvester paced by the wall clock, watched from outside the hub.
//! - campaign: runs of the built-in campaign `harvest` (the default harvester for 60 s with random
//!   faults) on every core, as `harvemu campaign` plays them: runs per hour.
//! - python-monitor: the six-sensor monitor written in Python on the python-can interface, in
//!   F5's place, as `python -m harvemu.monitor` measures itself: microseconds per received frame
//!   (only when named in `--only`: it needs the Python package installed).
//!
//! Every workload reports the same figures ([`Measurement`]); the peak RSS is the process's peak
//! since the workload started (the kernel's high-water mark is reset before each one).

use serde::Serialize;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

mod campaign;
mod cpu;
mod harvester;
mod python;
mod realtime;
mod saturated;

pub use realtime::Jitter;

/// Arguments of `harvemu bench`.
#[derive(clap::Args)]
pub struct Args {
    /// Print one JSON object per scenario (JSON lines) instead of a table.
    #[arg(long)]
    json: bool,
    /// Virtual seconds each saturated bus runs.
    #[arg(long, value_name = "SECONDS", default_value_t = 600.0)]
    seconds: f64,
    /// Bus counts for the multi-bus scenario.
    #[arg(long, value_name = "N,...", value_delimiter = ',', default_value = "1,10,100")]
    buses: Vec<usize>,
    /// Threads for the multi-bus scenarios (each runs its own actor system).
    #[arg(long, value_name = "N", default_value_t = 2)]
    threads: usize,
    /// Harvester config of the harvester scenarios.
    /// The default is read from the working directory when it is there, else built in.
    #[arg(long, value_name = "FILE", default_value = "configs/harvester.ron")]
    config: PathBuf,
    /// Virtual seconds of the one-harvester scenario.
    #[arg(long, value_name = "SECONDS", default_value_t = 3600.0)]
    harvester_seconds: f64,
    /// Harvester counts of the many-harvester scenario.
    #[arg(long, value_name = "N,...", value_delimiter = ',', default_value = "100")]
    harvesters: Vec<usize>,
    /// Virtual seconds of each harvester in the many-harvester scenario.
    #[arg(long, value_name = "SECONDS", default_value_t = 120.0)]
    many_seconds: f64,
    /// Machine cycles of the firmware-cpu scenario (an 80C51 busy loop on one core).
    #[arg(long, value_name = "N", default_value_t = 200_000_000)]
    cpu_cycles: u64,
    /// Virtual seconds of the firmware-lab scenario (the seed lab: two 80C51 benches with
    /// SJA1000s, configs/firmware/seed_lab.ron) and of the interrupt-driven lab
    /// (configs/firmware/irq_lab.ron) with and without the skipping of idle loops.
    #[arg(long, value_name = "SECONDS", default_value_t = 600.0)]
    lab_seconds: f64,
    /// Runs of the campaign scenario (the built-in campaign `harvest`: the default harvester for
    /// 60 s with random faults), played on every core.
    #[arg(long, value_name = "N", default_value_t = 40, value_parser = clap::value_parser!(u64).range(1..))]
    campaign_runs: u64,
    /// Run only these scenarios (saturated, saturated-multi, harvester, realtime, firmware-cpu,
    /// firmware-lab, firmware-c0, campaign, python-monitor, python-recv). The Python rows run
    /// only when named here or when --python is given: they need the Python package (pip
    /// install supervisor/python).
    #[arg(long, value_name = "SCENARIO,...", value_delimiter = ',')]
    only: Vec<String>,
    /// The Python with the harvemu package, for the Python rows: a file, or a command on PATH
    /// (python3 when not given). Given without --only, the Python rows run beside the others.
    #[arg(long, value_name = "COMMAND")]
    python: Option<String>,
    /// Frames of the python-recv rows: received by a Python recv loop from harvemu's bus (the
    /// program's controller active, then listen-only) and from python-can's virtual bus.
    #[arg(long, value_name = "N", default_value_t = 200_000, value_parser = clap::value_parser!(u64).range(1..))]
    python_frames: u64,
    /// Bus seconds of the python-monitor scenario.
    #[arg(long, value_name = "SECONDS", default_value_t = 600.0)]
    python_seconds: f64,
    /// Run the harvester in real time for this many seconds and measure period jitter against
    /// the wall clock and losses (the realtime scenario, which only runs when asked; e.g. 600).
    #[arg(long, value_name = "SECONDS")]
    realtime: Option<f64>,
}

/// One measured scenario.
#[derive(Serialize, Debug, Clone)]
pub struct Measurement {
    /// Scenario name.
    pub scenario: String,
    /// Independent buses.
    pub buses: usize,
    /// Threads used.
    pub threads: usize,
    /// Virtual seconds per bus.
    pub virtual_seconds: f64,
    /// Wall-clock seconds.
    pub wall_seconds: f64,
    /// Frames arbitrated and delivered, all buses.
    pub frames: u64,
    /// Frames per wall second.
    pub frames_per_second: f64,
    /// Frames placed in receive FIFOs, all buses.
    pub deliveries: u64,
    /// Deliveries per wall second.
    pub deliveries_per_second: f64,
    /// Node wakes, all buses.
    pub wakes: u64,
    /// Bus load of the first bus, 0..=1.
    pub bus_load: f64,
    /// Peak resident set size of the process while the scenario ran.
    pub peak_rss_bytes: u64,
    /// Virtual seconds per wall second, per bus.
    pub speedup: f64,
    /// Real-time scenario only: period jitter against the wall clock, and losses.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub jitter: Option<Jitter>,
}

/// What one thread's share of buses did.
pub struct Totals {
    frames: u64,
    deliveries: u64,
    wakes: u64,
    load: f64,
}

/// What the hubs of one thread did; the load is the first one's.
async fn totals(hubs: &[actix::Addr<bus_runtime::hub::Hub>]) -> Result<Totals, String> {
    let mut totals = Totals {
        frames: 0,
        deliveries: 0,
        wakes: 0,
        load: 0.0,
    };
    for (i, hub) in hubs.iter().enumerate() {
        let snap = hub
            .send(bus_runtime::hub::GetSnapshot)
            .await
            .map_err(|e| e.to_string())?;
        totals.frames += snap.stats.frames;
        totals.deliveries += snap.stats.deliveries;
        totals.wakes += snap.wakes;
        if i == 0 {
            totals.load = snap.stats.total_load();
        }
    }
    Ok(totals)
}

/// A workload: builds and runs some buses on the calling thread.
#[derive(Clone)]
pub enum Workload {
    /// The saturated bus.
    Saturated,
    /// The harvester of a config.
    Harvester(Arc<crate::harvester::Harvester>),
}

impl Workload {
    fn run_on_this_thread(&self, buses: usize, first: u64, seconds: f64) -> Result<Totals, String> {
        match self {
            Workload::Saturated => saturated::run_on_this_thread(buses, first, seconds),
            Workload::Harvester(h) => harvester::run_on_this_thread(h, buses, first, seconds),
        }
    }
}

/// Peak resident set size (VmHWM) of this process, 0 where /proc is not there.
pub fn peak_rss_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kb| kb.parse::<u64>().ok())
        })
        .map_or(0, |kb| kb * 1024)
}

/// Resets the peak RSS to the present RSS, so that the next reading is one workload's peak.
fn reset_peak_rss() {
    // "5" resets the high-water mark (Linux 4.0 and later); where it cannot, the peak reported is
    // the process's.
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// Measures `buses` buses of a workload spread over `threads` threads.
pub fn measure(
    scenario: &str,
    workload: &Workload,
    buses: usize,
    threads: usize,
    seconds: f64,
) -> Result<Measurement, String> {
    let threads = threads.clamp(1, buses.max(1));
    reset_peak_rss();
    let started = Instant::now();
    let handles: Vec<_> = (0..threads)
        .map(|t| {
            let share = buses / threads + usize::from(t < buses % threads);
            let first = (t * buses) as u64;
            let workload = workload.clone();
            std::thread::spawn(move || workload.run_on_this_thread(share, first, seconds))
        })
        .collect();
    let mut frames = 0;
    let mut deliveries = 0;
    let mut wakes = 0;
    let mut load = 0.0;
    for (i, h) in handles.into_iter().enumerate() {
        let t = h.join().map_err(|_| "a bench thread panicked".to_string())??;
        frames += t.frames;
        deliveries += t.deliveries;
        wakes += t.wakes;
        if i == 0 {
            load = t.load;
        }
    }
    let wall = started.elapsed().as_secs_f64();
    Ok(Measurement {
        scenario: scenario.to_string(),
        buses,
        threads,
        virtual_seconds: seconds,
        wall_seconds: wall,
        frames,
        frames_per_second: frames as f64 / wall,
        deliveries,
        deliveries_per_second: deliveries as f64 / wall,
        wakes,
        bus_load: load,
        peak_rss_bytes: peak_rss_bytes(),
        speedup: seconds / wall,
        jitter: None,
    })
}

const SCENARIOS: [&str; 10] = [
    "saturated",
    "saturated-multi",
    "harvester",
    "realtime",
    "firmware-cpu",
    "firmware-lab",
    "firmware-c0",
    "campaign",
    "python-monitor",
    "python-recv",
];

/// Runs `harvemu bench`.
pub fn run(args: &Args) -> crate::Result<()> {
    for (flag, v) in [
        ("--seconds", args.seconds),
        ("--harvester-seconds", args.harvester_seconds),
        ("--many-seconds", args.many_seconds),
        ("--lab-seconds", args.lab_seconds),
        ("--python-seconds", args.python_seconds),
        ("--realtime", args.realtime.unwrap_or(1.0)),
    ] {
        if !(v > 0.0 && v.is_finite()) {
            return Err(crate::Error::BadInput(format!(
                "{flag} {v} must be a positive number"
            )));
        }
    }
    if let Some(bad) = args.only.iter().find(|n| !SCENARIOS.contains(&n.as_str())) {
        return Err(crate::Error::BadInput(format!(
            "--only {bad}: the scenarios are {}",
            SCENARIOS.join(", ")
        )));
    }
    let wanted = |n: &str| args.only.is_empty() || args.only.iter().any(|o| o == n);
    let mut plan: Vec<(&str, Workload, usize, usize, f64)> = Vec::new();
    if wanted("saturated") {
        plan.push(("saturated", Workload::Saturated, 1, 1, args.seconds));
    }
    if wanted("saturated-multi") {
        for &n in &args.buses {
            plan.push((
                "saturated-multi",
                Workload::Saturated,
                n,
                args.threads,
                args.seconds,
            ));
        }
    }
    let realtime = args.realtime.filter(|_| wanted("realtime"));
    let harvester = if wanted("harvester") || realtime.is_some() {
        let h = crate::harvester::Harvester::load(&args.config)?;
        Some(Arc::new(h))
    } else {
        None
    };
    if let (true, Some(h)) = (wanted("harvester"), &harvester) {
        let w = Workload::Harvester(h.clone());
        plan.push(("harvester", w.clone(), 1, 1, args.harvester_seconds));
        for &n in &args.harvesters {
            plan.push(("harvester", w.clone(), n, args.threads, args.many_seconds));
        }
    }
    if wanted("firmware-lab") {
        let lab = crate::harvester::Harvester::load(std::path::Path::new("configs/firmware/seed_lab.ron"))?;
        plan.push((
            "firmware-lab",
            Workload::Harvester(Arc::new(lab)),
            1,
            1,
            args.lab_seconds,
        ));
        // The sender with a receiver that idles in `SJMP $` between interrupts: with and
        // without the skipping of loops that change nothing.
        let irq = crate::harvester::Harvester::load(std::path::Path::new("configs/firmware/irq_lab.ron"))?;
        let mut stepped = irq.clone();
        for f in &mut stepped.firmware {
            Arc::make_mut(f).skip_idle_loops = false;
        }
        for (name, h) in [("firmware-irq", irq), ("firmware-irq-noskip", stepped)] {
            plan.push((name, Workload::Harvester(Arc::new(h)), 1, 1, args.lab_seconds));
        }
    }
    if wanted("firmware-c0") {
        // The default harvester with C0 as its C firmware, and with every field node as
        // firmware, against the same harvester all scripts, for the same virtual time.
        let load = |p: &str| crate::harvester::Harvester::load(std::path::Path::new(p));
        let scripts = load("configs/harvester.ron")?;
        let c0 = load("configs/harvester-firmware-c0.ron")?;
        let all = load("configs/harvester-firmware.ron")?;
        // The same with code coverage counted (and left unwritten): what counting costs.
        let covered = |h: &crate::harvester::Harvester| crate::harvester::Harvester {
            coverage: true,
            ..h.clone()
        };
        let (c0_cov, all_cov) = (covered(&c0), covered(&all));
        for (name, h) in [
            ("harvester-scripts", scripts),
            ("harvester-c0-fw", c0),
            ("harvester-c0-fw-cov", c0_cov),
            ("harvester-all-fw", all),
            ("harvester-all-fw-cov", all_cov),
        ] {
            plan.push((
                name,
                Workload::Harvester(Arc::new(h)),
                1,
                1,
                args.harvester_seconds,
            ));
        }
    }
    if !args.json && !plan.is_empty() {
        crate::output::stdout(&format!(
            "{:<20} {:>5} {:>7} {:>8} {:>8} {:>11} {:>12} {:>9} {:>6} {:>9}\n",
            "scenario",
            "buses",
            "threads",
            "virt s",
            "wall s",
            "frames",
            "frames/s",
            "speedup",
            "load",
            "peak RSS"
        ))?;
    }
    let print = |m: &Measurement| -> crate::Result<()> {
        if args.json {
            crate::output::stdout(&format!("{}\n", serde_json::to_string(m)?))?;
        } else {
            crate::output::stdout(&format!(
                "{:<20} {:>5} {:>7} {:>8.0} {:>8.2} {:>11} {:>12.0} {:>8.1}x {:>5.1}% {:>5.1} MiB\n",
                m.scenario,
                m.buses,
                m.threads,
                m.virtual_seconds,
                m.wall_seconds,
                m.frames,
                m.frames_per_second,
                m.speedup,
                m.bus_load * 100.0,
                m.peak_rss_bytes as f64 / (1024.0 * 1024.0)
            ))?;
            if let Some(j) = &m.jitter {
                crate::output::stdout(&format!("{}\n", j.summary()))?;
            }
        }
        Ok(())
    };
    for (name, workload, buses, threads, seconds) in plan {
        let threads = threads.clamp(1, buses.max(1));
        crate::say!(
            "bench: {name}, {} on {}, {seconds} s of virtual time ...",
            bus::text::count(buses as u64, "bus", "buses"),
            bus::text::count(threads as u64, "thread", "threads")
        );
        print(&measure(name, &workload, buses, threads, seconds).map_err(crate::Error::Internal)?)?;
    }
    if wanted("firmware-cpu") {
        crate::say!(
            "bench: firmware-cpu, {} machine cycles of an 80C51 busy loop ...",
            args.cpu_cycles
        );
        let m = cpu::measure(args.cpu_cycles).map_err(crate::Error::Internal)?;
        if args.json {
            crate::output::stdout(&format!("{}\n", serde_json::to_string(&m)?))?;
        } else {
            crate::output::stdout(&format!(
                "firmware-cpu: {:.1} million 80C51 machine cycles per second on one core, busy \
                 ({} cycles in {:.2} s): {:.0} chips at 12 MHz\n",
                m.cycles_per_second / 1e6,
                m.cycles,
                m.wall_seconds,
                m.chips_at_12_mhz
            ))?;
        }
    }
    if wanted("campaign") {
        let jobs = std::thread::available_parallelism().map_or(1, |n| n.get());
        crate::say!(
            "bench: campaign, {} runs of the built-in campaign harvest on {} ...",
            args.campaign_runs,
            bus::text::count(jobs as u64, "job", "jobs")
        );
        let m = campaign::measure(args.campaign_runs, jobs)?;
        if args.json {
            crate::output::stdout(&format!("{}\n", serde_json::to_string(&m)?))?;
        } else {
            crate::output::stdout(&format!(
                "campaign: {:.0} runs per hour on {} ({} runs of {:.0} s with {} random \
                 faults in all, {} failed, in {:.2} s)\n",
                m.runs_per_hour,
                bus::text::count(m.jobs as u64, "job", "jobs"),
                m.runs,
                m.virtual_seconds,
                m.faults,
                m.failed,
                m.wall_seconds
            ))?;
        }
    }
    let python = args.python.as_deref().unwrap_or("python3");
    let python_row =
        |n: &str| args.only.iter().any(|o| o == n) || (args.only.is_empty() && args.python.is_some());
    if python_row("python-monitor") {
        crate::say!(
            "bench: python-monitor, {} s of bus time with {python} -m harvemu.monitor ...",
            args.python_seconds,
        );
        let m = python::measure(python, args.python_seconds)?;
        if args.json {
            crate::output::stdout(&format!("{}\n", serde_json::to_string(&m)?))?;
        } else {
            crate::output::stdout(&format!(
                "python-monitor: {:.1} µs per received frame, Python included: {:.0} times real \
                 time ({} frames in {:.0} s of bus time, {:.2} s; digest {})\n",
                m.us_per_frame, m.speedup, m.frames, m.virtual_seconds, m.wall_seconds, m.digest
            ))?;
        }
    }
    if python_row("python-recv") {
        crate::say!(
            "bench: python-recv, {} frames into a Python recv loop with {python} -m harvemu.throughput \
             (python-can's virtual bus, then harvemu's) ...",
            args.python_frames,
        );
        for row in python::throughput(python, args.python_frames)? {
            if args.json {
                crate::output::stdout(&format!("{}\n", serde_json::to_string(&row)?))?;
            } else {
                crate::output::stdout(&format!("{}\n", row.line()))?;
            }
        }
    }
    if let (Some(seconds), Some(h)) = (realtime, &harvester) {
        crate::say!("bench: realtime, the harvester for {seconds} s of wall-clock time ...");
        print(&realtime::measure(h, seconds).map_err(crate::Error::Internal)?)?;
    }
    Ok(())
}
