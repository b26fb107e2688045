//! `harvemu bench`: how fast the emulator runs, measured, never asserted.
//!
//! Saturated bus: 21 nodes that always have a frame pending at 250 kbit/s, each frame addressed
//! to the next node (whose acceptance filter takes it), so every frame is arbitrated among all
//! pending contenders, bit-timed exactly, delivered once and answered by a wake of its receiver.

use actix::prelude::*;
use bus::engine::{ControllerConfig, Filter, NodeId};
use bus::filter::{CAN_EFF_FLAG, SocketCanFilter, SocketCanFilterSet};
use bus::hub::{Attach, GetSnapshot, Hub, HubConfig, RunUntil, runtime};
use bus::ident::{Address, AppId, FrameType, Priority};
use bus::node::{ControllerEvent, NodeActor, NodeLogic};
use bus::time::BusTime;
use bus::{Frame, engine::BusConfig};
use futures_util::future::join_all;
use serde::Serialize;
use std::time::{Duration, Instant};

/// Arguments of `harvemu bench`.
#[derive(clap::Args)]
pub struct Args {
    /// Print one JSON object per scenario (JSON lines) instead of a table.
    #[arg(long)]
    json: bool,
    /// Virtual seconds each bus runs.
    #[arg(long, default_value_t = 600.0)]
    seconds: f64,
    /// Bus counts for the multi-bus scenario.
    #[arg(long, value_delimiter = ',', default_value = "1,10,100")]
    buses: Vec<usize>,
    /// Threads for the multi-bus scenario (each runs its own actor system).
    #[arg(long, default_value_t = 2)]
    threads: usize,
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
    /// Peak resident set size of the process so far.
    pub peak_rss_bytes: u64,
    /// Virtual seconds per wall second, per bus.
    pub speedup: f64,
}

/// Keeps `DEPTH` frames in its controller's queue: it refills whenever it is woken.
struct Saturator {
    me: Address,
    to: Address,
    priority: Priority,
    in_flight: usize,
    sequence: u64,
    owed: usize,
}

const DEPTH: usize = 8;

impl NodeLogic for Saturator {
    fn handle_frame(&mut self, _: BusTime, _: &Frame) {}
    fn handle_timeout(&mut self, _: BusTime) {}
    fn handle_event(&mut self, _: BusTime, event: ControllerEvent) {
        if let ControllerEvent::Sent(_) | ControllerEvent::Aborted(_) | ControllerEvent::Refused(_) = event {
            self.in_flight = self.in_flight.saturating_sub(1);
        }
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        if self.owed == 0 {
            self.owed = DEPTH - self.in_flight;
        }
        if self.owed == 0 || self.in_flight >= DEPTH {
            self.owed = 0;
            return None;
        }
        self.owed -= 1;
        self.in_flight += 1;
        self.sequence += 1;
        let id = AppId::new(self.priority, FrameType::PointToPoint, self.to, self.me);
        Frame::new_data(id.emit(), &self.sequence.to_le_bytes()).ok()
    }
    fn poll_timeout(&self) -> Option<BusTime> {
        None
    }
}

/// Builds one saturated bus and returns its hub.
async fn saturated_bus(seed: u64) -> Result<Addr<Hub>, bus::Error> {
    let config = HubConfig {
        bus: BusConfig {
            seed,
            ..BusConfig::default()
        },
        ..HubConfig::default()
    };
    let hub = Hub::new(config, None)?.start();
    let addresses: Vec<Address> = Address::all().collect();
    for (i, &me) in addresses.iter().enumerate() {
        let to = addresses[(i + 1) % addresses.len()];
        let logic = Saturator {
            me,
            to,
            priority: Priority::new(2 + (i % 5) as u8)?,
            in_flight: 0,
            sequence: 0,
            owed: 0,
        };
        // Take only frames addressed to this node: ID15..8 = own address.
        let filter = SocketCanFilterSet(vec![SocketCanFilter::new(
            CAN_EFF_FLAG | (u32::from(me.0) << 8),
            CAN_EFF_FLAG | 0xFF00,
        )]);
        let node = NodeActor::new(me.to_string(), Box::new(logic)).start();
        let controller = ControllerConfig {
            tx_queue_len: DEPTH,
            ..ControllerConfig::named(me.to_string())
        }
        .with_filter(Filter::SocketCan(filter));
        let _: NodeId = hub
            .send(Attach {
                controller,
                node: Some(node.recipient()),
                reaction: Duration::from_micros(50),
            })
            .await
            .map_err(|e| bus::Error::Syntax(e.to_string()))?;
    }
    Ok(hub)
}

struct Totals {
    frames: u64,
    deliveries: u64,
    wakes: u64,
    load: f64,
}

/// Runs `buses` saturated buses on this thread for `seconds` of virtual time.
fn run_on_this_thread(buses: usize, first_seed: u64, seconds: f64) -> Result<Totals, String> {
    let system = System::with_tokio_rt(|| runtime(true).expect("a tokio runtime"));
    system.block_on(async move {
        let mut hubs = Vec::new();
        for b in 0..buses {
            hubs.push(
                saturated_bus(first_seed + b as u64)
                    .await
                    .map_err(|e| e.to_string())?,
            );
        }
        let until = BusTime((seconds * 1e9) as u64);
        for r in join_all(hubs.iter().map(|h| h.send(RunUntil(until)))).await {
            r.map_err(|e| e.to_string())?.map_err(|e| e.to_string())?;
        }
        let mut totals = Totals {
            frames: 0,
            deliveries: 0,
            wakes: 0,
            load: 0.0,
        };
        for (i, hub) in hubs.iter().enumerate() {
            let snap = hub.send(GetSnapshot).await.map_err(|e| e.to_string())?;
            totals.frames += snap.stats.frames;
            totals.deliveries += snap.stats.deliveries;
            totals.wakes += snap.wakes;
            if i == 0 {
                totals.load = snap.stats.total_load();
            }
        }
        Ok(totals)
    })
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

/// Measures `buses` saturated buses spread over `threads` threads.
pub fn measure(scenario: &str, buses: usize, threads: usize, seconds: f64) -> Result<Measurement, String> {
    let threads = threads.clamp(1, buses.max(1));
    let started = Instant::now();
    let handles: Vec<_> = (0..threads)
        .map(|t| {
            let share = buses / threads + usize::from(t < buses % threads);
            let first_seed = (t * buses) as u64;
            std::thread::spawn(move || run_on_this_thread(share, first_seed, seconds))
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
    })
}

/// Runs `harvemu bench`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    if !(args.seconds > 0.0 && args.seconds.is_finite()) {
        return Err(crate::BadInput(format!("--seconds {} must be a positive number", args.seconds)).into());
    }
    let mut plan = vec![("saturated", 1usize, 1usize)];
    plan.extend(args.buses.iter().map(|&n| ("saturated-multi", n, args.threads)));
    if !args.json {
        println!(
            "{:<16} {:>5} {:>7} {:>8} {:>8} {:>11} {:>12} {:>12} {:>6} {:>9}",
            "scenario",
            "buses",
            "threads",
            "virt s",
            "wall s",
            "frames",
            "frames/s",
            "deliver/s",
            "load",
            "peak RSS"
        );
    }
    for (name, buses, threads) in plan {
        let threads = threads.clamp(1, buses.max(1));
        eprintln!(
            "bench: {name}, {buses} bus(es) on {threads} thread(s), {} s of virtual time ...",
            args.seconds
        );
        let m = measure(name, buses, threads, args.seconds).map_err(anyhow::Error::msg)?;
        if args.json {
            println!("{}", serde_json::to_string(&m)?);
        } else {
            println!(
                "{:<16} {:>5} {:>7} {:>8.0} {:>8.2} {:>11} {:>12.0} {:>12.0} {:>5.1}% {:>6} MiB",
                m.scenario,
                m.buses,
                m.threads,
                m.virtual_seconds,
                m.wall_seconds,
                m.frames,
                m.frames_per_second,
                m.deliveries_per_second,
                m.bus_load * 100.0,
                m.peak_rss_bytes / (1024 * 1024)
            );
        }
    }
    Ok(())
}
