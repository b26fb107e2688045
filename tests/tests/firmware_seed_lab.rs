//! The lab program of `configs/firmware/` on two emulated benches, each an 80C51 at 12 MHz with
//! one SJA1000 (6 MHz crystal, 30 kbit/s): the sender's chip at D300h, the receiver's at D400h.
//! Driven through the hub as harvemu drives every node, in virtual time.
//!
//! Expectations come from the program listing and the data sheets, worked by hand (and with s51
//! for the loop's length): the receiver stores the frame's eight data bytes at 30H–37H; the
//! sender sends one frame per pass of its loop, 99 916 machine cycles (µs at 12 MHz), each 113
//! bit times long at 30 kbit/s; a receiver whose acceptance code is AAh instead of BBh never
//! stores it.

use actix::prelude::*;
use bus::bits::BitRate;
use bus::engine::{BusConfig, ControllerConfig, Filter, Recovery};
use bus::node::HardwareState;
use bus::time::{BusDuration, BusTime, Epoch};
use bus::trace::CandumpWriter;
use bus_runtime::hub::{Attach, Hub, HubConfig, RunUntil, runtime};
use bus_runtime::node::{Apply, NodeActor};
use harvemu_e2e::{Shared, parse_trace, root};
use nodes::firmware::{FirmwareNode, FirmwareSpec};
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

const LOOP_CYCLES: u64 = 99_916;
const DATA: [u8; 8] = [0xAA, 0xBB, 0xCC, 0xD4, 0xE5, 0xF6, 0x97, 0x18];

/// A bench running `hex` with its SJA1000 at `base`, on a crystal of `xtal_hz`.
fn bench(name: &str, hex: &str, base: u16, xtal_hz: u32) -> Arc<FirmwareSpec> {
    let text = format!(
        "Firmware(name: \"{name}\", image: \"lab.hex\", entry: Some(0x4000), \
         cpu: I80C51(clock_hz: 12000000), \
         controllers: [Sja1000(base: {base}, xtal_hz: {xtal_hz}, irq: None)])"
    );
    let hex = hex.to_string();
    let read = move |_: &Path| Ok(("lab.hex".to_string(), hex.clone()));
    Arc::new(nodes::firmware::load("bench.ron", Path::new("bench.ron"), &text, &read).expect("bench"))
}

/// Runs the two benches for `seconds` of bus time: the trace, and each bench's hardware then.
fn run_lab(sender_hex: &str, receiver_hex: &str, seconds: u64) -> (String, Vec<HardwareState>) {
    run_benches(
        [
            bench("SENDER", sender_hex, 0xD300, 6_000_000),
            bench("RECEIVER", receiver_hex, 0xD400, 6_000_000),
        ],
        seconds,
    )
}

/// Runs `benches` for `seconds` of bus time at 30 kbit/s.
fn run_benches(benches: [Arc<FirmwareSpec>; 2], seconds: u64) -> (String, Vec<HardwareState>) {
    let trace = Shared::default();
    let t = trace.clone();
    let states = System::with_tokio_rt(|| runtime(true).expect("runtime")).block_on(async move {
        let config = HubConfig {
            bus: BusConfig {
                bitrate: BitRate::new(30_000).expect("30 kbit/s"),
                ..BusConfig::default()
            },
            ..HubConfig::new(false)
        };
        let sink = Box::new(CandumpWriter::new(t, Epoch::FIXED));
        let hub = Hub::new(config, vec![sink]).expect("hub").start();
        let mut actors = Vec::new();
        for spec in benches {
            let logic = FirmwareNode::new(spec.clone(), BusTime::ZERO, 30_000.0);
            let actor = NodeActor::new(spec.name.clone(), Box::new(logic)).start();
            let controller = ControllerConfig {
                recovery: Recovery::OnRequest,
                ..ControllerConfig::named(spec.name.clone()).with_filter(Filter::All)
            };
            hub.send(Attach {
                controller,
                node: Some(actor.clone().recipient()),
                reaction: Duration::ZERO,
            })
            .await
            .expect("attach");
            actors.push(actor);
        }
        let end = BusTime::from_secs(seconds);
        hub.send(RunUntil(end)).await.expect("hub").expect("run");
        let mut states = Vec::new();
        for a in actors {
            let (tx, rx) = std::sync::mpsc::channel();
            a.send(Apply(Box::new(move |logic| {
                let _ = tx.send(logic.hardware(end));
            })))
            .await
            .expect("apply");
            states.push(rx.recv().expect("state").expect("a firmware node has hardware"));
        }
        states
    });
    (String::from_utf8(trace.0.take()).expect("utf-8"), states)
}

fn shipped_hex() -> String {
    std::fs::read_to_string(root().join("configs/firmware/can_seed.hex")).expect("the shipped HEX")
}

/// Internal RAM bytes `from..from + n` of a dump.
fn iram(state: &HardwareState, from: usize, n: usize) -> Vec<u8> {
    (from..from + n)
        .map(|i| u8::from_str_radix(&state.cpu.iram[2 * i..2 * i + 2], 16).expect("hex"))
        .collect()
}

#[test]
fn the_receiver_stores_the_senders_frame_at_30h() {
    let hex = shipped_hex();
    let (trace, states) = run_lab(&hex, &hex, 1);
    assert_eq!(iram(&states[1], 0x30, 8), DATA, "receiver 30H-37H");
    // The sender's own copy of the data, made at start-up, is at 20H-27H on both benches.
    assert_eq!(iram(&states[0], 0x20, 8), DATA, "sender 20H-27H");
    let frames = parse_trace(&trace);
    assert!(frames.len() >= 9, "{} frames in a second: {trace}", frames.len());
    for f in &frames {
        assert_eq!(f.frame.raw_id(), 0x5DF);
        assert!(!f.frame.is_extended() && !f.frame.is_remote());
        assert_eq!(f.frame.data(), DATA);
    }
    // One frame per pass of the loop: the bus is idle when each request comes, so the frames
    // end exactly one loop apart.
    let period = BusDuration::from_micros(LOOP_CYCLES);
    for pair in frames.windows(2) {
        assert_eq!(pair[1].at.since(pair[0].at), period, "{trace}");
    }
    // Both chips ended error active with clean counters, in PeliCAN mode.
    for s in &states {
        let c = &s.controllers[0];
        assert_eq!(
            (c.mode.as_str(), c.tec, c.rec, c.state.as_str()),
            ("PeliCAN", 0, 0, "active")
        );
    }
}

#[test]
fn a_receiver_with_acceptance_code_aah_keeps_30h_untouched() {
    let source = std::fs::read_to_string(root().join("configs/firmware/can_seed.asm")).expect("asm");
    let patched = source.replacen("#0BBH", "#0AAH", 1);
    assert_ne!(
        patched, source,
        "the receiver's acceptance code BBh is in the source"
    );
    let hex = harvemu_e2e::assemble(&patched);
    let (trace, states) = run_lab(&shipped_hex(), &hex, 1);
    assert!(!parse_trace(&trace).is_empty(), "the sender still sends");
    assert_eq!(iram(&states[1], 0x30, 8), [0; 8], "receiver 30H-37H");
}

/// The lab notes' first cause of failed communication: bus timing registers set wrong, or a
/// crystal that drifted. A receiver off the bus's bit rate by more than its bit timing
/// tolerates cannot sample the sender's frames: while error active it destroys each with an
/// active error flag, which the sender reads as a bit error (TEC + 8) one bit before its own flag
/// begins, so the receiver sees a dominant bit after its flag (REC + 1 + 8). After 15 attempts
/// its REC (135) makes it error passive and its flags no longer destroy anything, but it
/// acknowledges nothing it could not read: the 16th attempt is an ACK error (TEC 120 + 8 = 128,
/// error passive), and from then on an error-passive sender's ACK errors leave TEC at 128
/// (ISO 11898-1, fault confinement, exception to rule 3). No frame ever gets through.
fn assert_communication_fails(trace: &str, states: &[HardwareState]) {
    let frames = parse_trace(trace);
    assert!(frames.is_empty(), "no frame completes: {trace}");
    assert_eq!(iram(&states[1], 0x30, 8), [0; 8], "receiver 30H-37H");
    let sender = &states[0].controllers[0];
    assert_eq!((sender.tec, sender.state.as_str()), (128, "passive"), "sender");
    let receiver = &states[1].controllers[0];
    assert_eq!(receiver.state, "passive", "receiver REC {}", receiver.rec);
}

#[test]
fn wrong_bus_timing_registers_stop_communication() {
    let source = std::fs::read_to_string(root().join("configs/firmware/can_seed.asm")).expect("asm");
    // BTR0 = 01h: BRP 1 instead of 3, twice the bit rate (60 kbit/s).
    let patched = source.replacen("MOV     A, #03H", "MOV     A, #01H", 1);
    assert_ne!(patched, source, "BTR0's value is in the source");
    let (trace, states) = run_lab(&shipped_hex(), &harvemu_e2e::assemble(&patched), 1);
    assert_communication_fails(&trace, &states);
}

#[test]
fn a_drifted_crystal_stops_communication_and_a_good_one_does_not() {
    let hex = shipped_hex();
    // 1 % off: the bit timing of BTR0 03h, BTR1 FFh tolerates 0.2 % (SJW 1 of 25 quanta:
    // 1 / (20 * 25)).
    let drifted = [
        bench("SENDER", &hex, 0xD300, 6_000_000),
        bench("RECEIVER", &hex, 0xD400, 6_060_000),
    ];
    let (trace, states) = run_benches(drifted, 1);
    assert_communication_fails(&trace, &states);
    // 0.1 % off is within the tolerance.
    let close = [
        bench("SENDER", &hex, 0xD300, 6_000_000),
        bench("RECEIVER", &hex, 0xD400, 6_006_000),
    ];
    let (_, states) = run_benches(close, 1);
    assert_eq!(iram(&states[1], 0x30, 8), DATA, "receiver 30H-37H");
}
