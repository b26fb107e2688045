//! The hub actor with node actors, in virtual time (and once in real time).

mod common;

use actix::prelude::*;
use bus::candump::parse_frame;
use bus::engine::{BitPosition, BusConfig, ControllerConfig, Effect, Rule, Schedule, SeenBy, Target};
use bus::node::NodeLogic;
use bus::time::{BusTime, Epoch};
use bus::trace::{CandumpWriter, Sink};
use bus::{Frame, bits};
use bus_runtime::hub::{
    Attach, Control, FlushTrace, GetSnapshot, Hub, HubConfig, RunUntil, SubmitAt, runtime,
};
use bus_runtime::node::NodeActor;
use common::Periodic;
use std::cell::RefCell;
use std::io::Write;
use std::rc::Rc;
use std::time::Duration;

/// Answers every frame it receives with `reply`.
struct Echo {
    reply: Frame,
    owed: usize,
}

impl NodeLogic for Echo {
    fn handle_frame(&mut self, _: BusTime, _: &Frame) {
        self.owed += 1;
    }
    fn handle_timeout(&mut self, _: BusTime) {}
    fn poll_transmit(&mut self) -> Option<Frame> {
        (self.owed > 0).then(|| {
            self.owed -= 1;
            self.reply
        })
    }
    fn poll_timeout(&self) -> Option<BusTime> {
        None
    }
}

/// A Write that tests can read back.
#[derive(Clone, Default)]
struct Shared(Rc<RefCell<Vec<u8>>>);

impl Write for Shared {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.borrow_mut().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

fn in_virtual_time<F: Future>(f: F) -> F::Output {
    System::with_tokio_rt(|| runtime(true).unwrap()).block_on(f)
}

async fn attach(
    hub: &Addr<Hub>,
    name: &str,
    logic: Box<dyn NodeLogic>,
    reaction_us: u64,
) -> bus::engine::NodeId {
    let node = NodeActor::new(name, logic).start();
    hub.send(Attach {
        controller: ControllerConfig::named(name),
        node: Some(node.recipient()),
        reaction: Duration::from_micros(reaction_us),
    })
    .await
    .unwrap()
}

/// A virtual-time hub writes its trace from 2024-01-01T00:00:00Z: 54 years of 365 days and the
/// 13 leap days 1972..=2020, in nanoseconds.
const NEW_YEAR_2024_NS: u64 = (54 * 365 + 13) * 86_400 * 1_000_000_000;

/// The time a virtual-time trace writes for bus time `ns`.
fn stamp(ns: u64) -> bus::time::Stamp {
    bus::time::Stamp(NEW_YEAR_2024_NS + ns)
}

/// The hub's trace as a candump log into `t` (these hubs run in virtual time: the fixed epoch).
fn candump(t: Shared) -> Vec<Box<dyn Sink>> {
    vec![Box::new(CandumpWriter::new(t, Epoch::FIXED))]
}

fn lines(trace: &Shared) -> Vec<String> {
    String::from_utf8(trace.0.borrow().clone())
        .unwrap()
        .lines()
        .map(str::to_string)
        .collect()
}

#[test]
fn periodic_frames_start_exactly_on_their_deadlines() {
    let trace = Shared::default();
    let t = trace.clone();
    in_virtual_time(async move {
        let hub = Hub::new(HubConfig::new(false), candump(t)).unwrap().start();
        attach(
            &hub,
            "a",
            Box::new(Periodic::new("0601F5D0#200D0002FFBFFF00", 100, 250)),
            0,
        )
        .await;
        attach(
            &hub,
            "monitor",
            Box::new(Echo {
                reply: parse_frame("0601D0F5#210D01").unwrap(),
                owed: 0,
            }),
            0,
        )
        .await;
        hub.send(RunUntil(BusTime::from_millis(1000)))
            .await
            .unwrap()
            .unwrap();
    });
    let marker = bits::frame_bits(&parse_frame("0601F5D0#200D0002FFBFFF00").unwrap()) as u64;
    let ack = bits::frame_bits(&parse_frame("0601D0F5#210D01").unwrap()) as u64;
    let mut expected = Vec::new();
    for k in 0..10u64 {
        // SOF at 250 us + k x 100 ms; the candump time is the end of frame.
        let sof = 250_000 + k * 100_000_000;
        let end = sof + (marker - 3) * 4000;
        expected.push(format!("({}) harv0 0601F5D0#200D0002FFBFFF00", stamp(end)));
        // The monitor answers at once (reaction 0): its reply starts when the bus is idle.
        let reply_end = sof + marker * 4000 + (ack - 3) * 4000;
        expected.push(format!("({}) harv0 0601D0F5#210D01", stamp(reply_end)));
    }
    assert_eq!(lines(&trace), expected);
}

#[test]
fn reaction_time_delays_the_reply() {
    let trace = Shared::default();
    let t = trace.clone();
    in_virtual_time(async move {
        let hub = Hub::new(HubConfig::new(false), candump(t)).unwrap().start();
        attach(&hub, "a", Box::new(Periodic::new("123#01", 10, 0)), 0).await;
        attach(
            &hub,
            "b",
            Box::new(Echo {
                reply: parse_frame("456#02").unwrap(),
                owed: 0,
            }),
            700,
        )
        .await;
        hub.send(RunUntil(BusTime::from_millis(10)))
            .await
            .unwrap()
            .unwrap();
    });
    let first = bits::frame_bits(&parse_frame("123#01").unwrap()) as u64;
    let reply = bits::frame_bits(&parse_frame("456#02").unwrap()) as u64;
    let eof = (first - 3) * 4000;
    let reply_end = eof + 700_000 + (reply - 3) * 4000;
    assert_eq!(
        lines(&trace),
        [
            format!("({}) harv0 123#01", stamp(eof)),
            format!("({}) harv0 456#02", stamp(reply_end))
        ]
    );
}

#[test]
fn a_hung_node_overruns_and_resumes() {
    let snap = in_virtual_time(async move {
        let hub = Hub::new(HubConfig::new(false), Vec::new()).unwrap().start();
        attach(
            &hub,
            "a",
            Box::new(Periodic::new("0601F5D0#0101341EEA2BEF2C", 1, 0)),
            0,
        )
        .await;
        let b = attach(
            &hub,
            "b",
            Box::new(Echo {
                reply: parse_frame("0601D0F5#21").unwrap(),
                owed: 0,
            }),
            50,
        )
        .await;
        hub.send(RunUntil(BusTime::from_millis(5)))
            .await
            .unwrap()
            .unwrap();
        hub.send(Control::SetHung(b, true)).await.unwrap().unwrap();
        hub.send(RunUntil(BusTime::from_millis(20)))
            .await
            .unwrap()
            .unwrap();
        hub.send(Control::SetHung(b, false)).await.unwrap().unwrap();
        hub.send(RunUntil(BusTime::from_millis(30)))
            .await
            .unwrap()
            .unwrap();
        hub.send(GetSnapshot).await.unwrap()
    });
    let b = &snap.nodes[1];
    // 15 frames arrive while hung; four fit the 64-byte FIFO (13 bytes each), the rest overrun.
    assert_eq!(b.counters.rx_overruns, 11);
    assert!(snap.stats.overruns == 11);
    // b answered every frame it got: 5 before, 4 from the FIFO, 10 after.
    assert_eq!(b.counters.tx_frames, 5 + 4 + 10);
}

fn run_with_faults(seed: u64) -> Vec<u8> {
    run_with(
        seed,
        vec![Rule::bit_errors(
            Target::Any,
            Schedule::BitErrorRate(2e-4),
            BitPosition::Random,
        )],
    )
}

fn run_with(seed: u64, rules: Vec<Rule>) -> Vec<u8> {
    let trace = Shared::default();
    let t = trace.clone();
    in_virtual_time(async move {
        let config = HubConfig {
            bus: BusConfig {
                seed,
                ..BusConfig::default()
            },
            ..HubConfig::new(false)
        };
        let hub = Hub::new(config, candump(t)).unwrap().start();
        for (i, period) in [(0u8, 10u64), (1, 20), (2, 50), (3, 7)] {
            let text = format!("06{:02X}F5D{i}#0102030405060708", i);
            attach(
                &hub,
                &format!("n{i}"),
                Box::new(Periodic::new(&text, period, 100 * u64::from(i))),
                0,
            )
            .await;
        }
        attach(
            &hub,
            "m",
            Box::new(Echo {
                reply: parse_frame("0601D0F5#21").unwrap(),
                owed: 0,
            }),
            200,
        )
        .await;
        for rule in rules {
            hub.send(Control::AddRule(rule)).await.unwrap().unwrap();
        }
        hub.send(RunUntil(BusTime::from_millis(3000)))
            .await
            .unwrap()
            .unwrap();
    });
    trace.0.take()
}

/// Every kind of injected fault, bus off and recovery included: the trace's times never go
/// backwards, and every controller's error lines carry its own name.
#[test]
fn trace_time_never_goes_backwards() {
    let every = |effect, schedule| Rule {
        target: Target::Any,
        schedule,
        bit: BitPosition::Random,
        effect,
        seen_by: SeenBy::All,
    };
    let rules = vec![
        every(Effect::Bit, Schedule::EveryNth(7)),
        every(Effect::Stuff, Schedule::EveryNth(11)),
        every(Effect::Crc, Schedule::EveryNth(13)),
        every(Effect::Form, Schedule::EveryNth(17)),
        every(Effect::Overload(2), Schedule::EveryNth(5)),
        // n2 is corrupted until it goes bus off, again and again.
        Rule::bit_errors(
            Target::Node(bus::engine::NodeId(2)),
            Schedule::Always,
            BitPosition::Random,
        ),
    ];
    let text = String::from_utf8(run_with(4, rules)).unwrap();
    let mut last = 0.0f64;
    let mut bus_off = 0;
    let mut kinds = std::collections::BTreeSet::new();
    for line in text.lines() {
        let (time, rest) = line.strip_prefix('(').unwrap().split_once(") ").unwrap();
        let t: f64 = time.parse().unwrap();
        assert!(t >= last, "{line} after {last}");
        last = t;
        let (iface, frame) = rest.split_once(' ').unwrap();
        if let Some(node) = iface.strip_prefix("harv0.") {
            assert!(["n0", "n1", "n2", "n3", "m"].contains(&node), "{line}");
            let id = u32::from_str_radix(frame.split_once('#').unwrap().0, 16).unwrap();
            assert_ne!(id & 0x2000_0000, 0, "an error frame: {line}");
            if id & 0x40 != 0 {
                bus_off += 1;
            }
            if id & 0x88 == 0x88 {
                kinds.insert(&frame[frame.len() - 12..frame.len() - 10]);
            }
        } else {
            assert_eq!(iface, "harv0", "{line}");
        }
    }
    assert!(bus_off >= 2, "n2 went bus off {bus_off} times");
    // Bit (0x01), form (0x02) and stuff (0x04) errors, with or without CAN_ERR_PROT_TX, and
    // CRC errors (no type).
    for kind in ["81", "02", "04", "00"] {
        assert!(kinds.contains(kind), "type {kind} in {kinds:?}");
    }
}

#[test]
fn same_seed_same_trace_byte_for_byte() {
    let (a, b, c) = (run_with_faults(9), run_with_faults(9), run_with_faults(10));
    assert_eq!(a, b);
    assert_ne!(a, c);
    let text = String::from_utf8(a).unwrap();
    assert!(text.lines().count() > 1000);
    // SocketCAN error frames: CAN_ERR_FLAG | PROT | BUSERROR | CNT.
    assert!(
        text.lines()
            .any(|l| l.contains(" harv0.") && l.contains(" 20000288#")),
        "bit errors are in the trace, on the controllers' interfaces"
    );
}

#[test]
fn real_time_paces_the_bus() {
    let started = std::time::Instant::now();
    let snap = System::with_tokio_rt(|| runtime(false).unwrap()).block_on(async {
        let hub = Hub::new(HubConfig::new(true), Vec::new()).unwrap().start();
        attach(&hub, "a", Box::new(Periodic::new("123#01", 20, 0)), 0).await;
        attach(
            &hub,
            "b",
            Box::new(Echo {
                reply: parse_frame("456#02").unwrap(),
                owed: 0,
            }),
            0,
        )
        .await;
        hub.send(RunUntil(BusTime::from_millis(200)))
            .await
            .unwrap()
            .unwrap();
        hub.send(GetSnapshot).await.unwrap()
    });
    // Bus time never runs ahead of the wall clock by more than the slack.
    assert!(started.elapsed() >= Duration::from_millis(199));
    assert_eq!(snap.stats.frames, 20, "10 periodic frames and 10 replies");
}

/// The pairing `runtime` does not make by itself: a paced hub on a paused-clock runtime keeps
/// to the wall clock (it waits on its own wall timer), and an unpaced hub on a normal runtime
/// runs ahead of it.
#[test]
fn pacing_follows_the_config_not_the_runtime() {
    // The unpaced run covers 60 s of bus time, so that it ends long before a paced one could
    // (a paced run never ends before its bus time has passed on the wall clock) even on a loaded
    // machine; the paced one covers 300 ms.
    for (virtual_runtime, paced, until) in [
        (true, true, BusTime::from_millis(300)),
        (false, false, BusTime::from_secs(60)),
    ] {
        let started = std::time::Instant::now();
        let snap = System::with_tokio_rt(move || runtime(virtual_runtime).unwrap()).block_on(async move {
            let hub = Hub::new(HubConfig::new(paced), Vec::new()).unwrap().start();
            attach(&hub, "a", Box::new(Periodic::new("123#01", 20, 0)), 0).await;
            hub.send(RunUntil(until)).await.unwrap().unwrap();
            hub.send(GetSnapshot).await.unwrap()
        });
        let wall = started.elapsed();
        if paced {
            assert!(
                wall >= Duration::from_millis(299),
                "paced on a paused runtime: {wall:?}"
            );
        } else {
            assert!(
                wall < Duration::from_secs(30),
                "unpaced on a normal runtime: {wall:?} for 60 s of bus time"
            );
        }
        // Either way the run reached the time asked for.
        assert!(snap.now >= until, "{paced}: {:?}", snap.now);
    }
}

/// Freezes the hub's thread once, at `at`, as a process that is not scheduled would be.
struct Stall {
    at: BusTime,
    done: bool,
}

impl NodeLogic for Stall {
    fn handle_frame(&mut self, _: BusTime, _: &Frame) {}
    fn handle_timeout(&mut self, _: BusTime) {
        std::thread::sleep(Duration::from_millis(250));
        self.done = true;
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        None
    }
    fn poll_timeout(&self) -> Option<BusTime> {
        (!self.done).then_some(self.at)
    }
}

/// After a 250 ms stall, bus time goes on from where it stopped (the run takes 250 ms longer)
/// instead of sending the overdue frames back to back, and the overrun is counted.
#[test]
fn a_stall_slips_bus_time_instead_of_bursting() {
    let started = std::time::Instant::now();
    let snap = System::with_tokio_rt(|| runtime(false).unwrap()).block_on(async {
        let hub = Hub::new(HubConfig::new(true), Vec::new()).unwrap().start();
        attach(&hub, "a", Box::new(Periodic::new("123#01", 10, 0)), 0).await;
        let stall = Stall {
            at: BusTime::from_millis(100),
            done: false,
        };
        attach(&hub, "stall", Box::new(stall), 0).await;
        hub.send(RunUntil(BusTime::from_millis(500)))
            .await
            .unwrap()
            .unwrap();
        hub.send(GetSnapshot).await.unwrap()
    });
    let took = started.elapsed();
    assert!(
        took >= Duration::from_millis(740),
        "took {took:?}: the stall was caught up in a burst"
    );
    assert_eq!(snap.stats.frames, 50, "every periodic frame, none lost");
    let o = snap.overruns;
    assert!(o.count >= 1, "{o:?}");
    assert!(o.longest_ns >= 240_000_000, "{o:?}");
    assert!(o.slipped_ns >= o.longest_ns, "{o:?}");
}

#[test]
fn three_nodes_contend_and_win_in_identifier_order() {
    let trace = Shared::default();
    let t = trace.clone();
    in_virtual_time(async move {
        let hub = Hub::new(HubConfig::new(false), candump(t)).unwrap().start();
        // All three deadlines at 1 ms: frame lengths 151, 142 and 74 bits (docs/CAN.md, test vectors).
        attach(
            &hub,
            "x",
            Box::new(Periodic::new("1FFFFFFF#0000000000000000", 1000, 1000)),
            0,
        )
        .await;
        attach(
            &hub,
            "y",
            Box::new(Periodic::new("0300A0F5#0102030405060708", 1000, 1000)),
            0,
        )
        .await;
        attach(&hub, "z", Box::new(Periodic::new("00000000#", 1000, 1000)), 0).await;
        hub.send(RunUntil(BusTime::from_millis(10)))
            .await
            .unwrap()
            .unwrap();
    });
    let at = |bits_before: u64, bits: u64| stamp(1_000_000 + (bits_before + bits - 3) * 4000);
    assert_eq!(
        lines(&trace),
        [
            format!("({}) harv0 00000000#", at(0, 74)),
            format!("({}) harv0 0300A0F5#0102030405060708", at(74, 142)),
            format!("({}) harv0 1FFFFFFF#0000000000000000", at(74 + 142, 151)),
        ]
    );
}

/// Keeps the times of the frames it receives and asks the run to stop at each.
struct Waiter {
    got: Rc<RefCell<Vec<BusTime>>>,
    stop: bool,
}

impl NodeLogic for Waiter {
    fn handle_frame(&mut self, now: BusTime, _: &Frame) {
        self.got.borrow_mut().push(now);
        self.stop = true;
    }
    fn handle_timeout(&mut self, _: BusTime) {}
    fn poll_transmit(&mut self) -> Option<Frame> {
        None
    }
    fn poll_timeout(&self) -> Option<BusTime> {
        None
    }
    fn stop_here(&mut self) -> bool {
        std::mem::take(&mut self.stop)
    }
}

#[test]
fn a_node_that_asks_stops_the_run_where_it_received_a_frame() {
    let got = Rc::new(RefCell::new(Vec::new()));
    let g = got.clone();
    in_virtual_time(async move {
        let hub = Hub::new(HubConfig::new(false), Vec::new()).unwrap().start();
        // A frame every 100 ms from 250 µs on; the waiter reacts at once.
        attach(
            &hub,
            "a",
            Box::new(Periodic::new("0601F5D0#200D0002FFBFFF00", 100, 250)),
            0,
        )
        .await;
        attach(&hub, "waiter", Box::new(Waiter { got: g, stop: false }), 0).await;
        let far = BusTime::from_secs(10);
        let first = hub.send(RunUntil(far)).await.unwrap().unwrap();
        let second = hub.send(RunUntil(far)).await.unwrap().unwrap();
        let times = got.borrow().clone();
        // Each run ends at the end of the frame the waiter was handed, not at 10 s.
        assert_eq!(times.len(), 2, "{times:?}");
        assert_eq!((first, second), (times[0], times[1]));
        // The second frame is the next period's: 100 ms later, to the nanosecond.
        assert_eq!((second - first).as_nanos(), 100_000_000);
        // The frame began at 250 µs and lasts less than 160 bits of 4 µs.
        assert!(first > BusTime::from_micros(250) && first < BusTime::from_micros(250 + 640));
        // The hub waits where the second run ended.
        let snap = hub.send(GetSnapshot).await.unwrap();
        assert_eq!(snap.now, second);
    });
}

/// Attaches a controller with no logic behind it (driven from outside, or silent).
async fn attach_bare(hub: &Addr<Hub>, name: &str) -> bus::engine::NodeId {
    hub.send(Attach {
        controller: ControllerConfig::named(name),
        node: None,
        reaction: Duration::ZERO,
    })
    .await
    .unwrap()
}

/// The engine commits a frame whole at its start; a controller reset at the hub's present,
/// while that frame is still on the bus, is written before the frame's end (docs/TRACES.md,
/// "Time order"), and the trace never goes back.
#[test]
fn a_reset_while_a_frame_is_on_the_bus_is_written_before_that_frame_ends() {
    let marker = "0601F5D0#200D0002FFBFFF00";
    let trace = Shared::default();
    let t = trace.clone();
    in_virtual_time(async move {
        let hub = Hub::new(HubConfig::new(false), candump(t)).unwrap().start();
        attach(&hub, "a", Box::new(Periodic::new(marker, 100, 250)), 0).await;
        let b = attach_bare(&hub, "b").await;
        // a's first frame starts at 250 µs and ends after 500 µs: the engine has it already.
        hub.send(RunUntil(BusTime::from_micros(500)))
            .await
            .unwrap()
            .unwrap();
        hub.send(Control::Reset(b)).await.unwrap().unwrap();
        hub.send(RunUntil(BusTime::from_millis(250)))
            .await
            .unwrap()
            .unwrap();
        hub.send(FlushTrace).await.unwrap().unwrap();
    });
    let end = 250_000 + (bits::frame_bits(&parse_frame(marker).unwrap()) as u64 - 3) * 4000;
    assert!(end > 500_000);
    let lines = lines(&trace);
    assert_eq!(
        lines[..2],
        [
            format!("({}) harv0.b 20000304#0040000000000000", stamp(500_000)),
            format!("({}) harv0 {marker}", stamp(end)),
        ]
    );
    // Three frames (at 0.25, 100.25 and 200.25 ms), each written once.
    assert_eq!(lines.len(), 4, "{lines:#?}");
    let time = |l: &String| l.split(')').next().unwrap().to_string();
    assert!(lines.windows(2).all(|w| time(&w[0]) <= time(&w[1])), "{lines:#?}");
}

/// A record that comes later than the reorder window allows (here: a frame submitted in the
/// past of a hub that already wrote a later record, which [`SubmitAt`]'s sender must never do)
/// is not written out of order: the run answers with the error, and the trace stays in order.
#[test]
fn a_record_later_than_the_window_is_an_error_never_a_line_out_of_order() {
    let trace = Shared::default();
    let t = trace.clone();
    in_virtual_time(async move {
        let hub = Hub::new(HubConfig::new(false), candump(t)).unwrap().start();
        let x = attach_bare(&hub, "x").await;
        let b = attach_bare(&hub, "b").await;
        hub.send(RunUntil(BusTime::from_millis(1)))
            .await
            .unwrap()
            .unwrap();
        hub.send(Control::Reset(b)).await.unwrap().unwrap();
        hub.send(RunUntil(BusTime::from_millis(100)))
            .await
            .unwrap()
            .unwrap();
        // 100 ms is more than the window (80 ms at 250 kbit/s) past 1 ms: that reset is written.
        hub.send(Control::Reset(b)).await.unwrap().unwrap();
        let frame = parse_frame("123#01").unwrap();
        let at = BusTime::from_micros(500);
        assert!(hub.send(SubmitAt { node: x, frame, at }).await.unwrap().unwrap());
        let e = hub
            .send(RunUntil(BusTime::from_millis(200)))
            .await
            .unwrap()
            .unwrap_err();
        assert!(
            matches!(
                e,
                bus_runtime::Error::Bus(bus::Error::TraceOrder { released, .. })
                    if released == BusTime::from_millis(1)
            ),
            "{e}"
        );
        assert!(e.to_string().contains("internal error"), "{e}");
        assert!(hub.send(FlushTrace).await.unwrap().is_err());
    });
    assert_eq!(
        lines(&trace),
        [
            format!("({}) harv0.b 20000304#0040000000000000", stamp(1_000_000)),
            format!("({}) harv0.b 20000304#0040000000000000", stamp(100_000_000)),
        ]
    );
}
