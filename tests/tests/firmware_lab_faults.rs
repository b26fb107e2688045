//! Faults reaching the seed lab's firmware (`configs/firmware/seed_lab.ron`, run as harvemu runs
//! it) through its SJA1000's registers: the receiver unplugged, then the whole lab switched off
//! and on. The scenarios `lab_disconnect.ron` and `lab_ack_failure.ron` check the error states
//! over time; these check what the firmware would read.
//!
//! Expectations: ISO 11898-1 fault confinement, the SJA1000 data sheet's register map (SR at 2,
//! RXERR at 14, TXERR at 15; SR bit 7 bus status, 6 error status, 2 transmit buffer status),
//! and the listing's cycle counts as worked out in `firmware_seed_lab.rs`.

use bus::node::HardwareState;
use bus::time::{BusDuration, BusTime};
use bus_runtime::hub::Control;
use harvemu_e2e::{drive, iram, parse_trace, root};
use supervisor::harvester::{Harvester, Running};

const DATA: [u8; 8] = [0xAA, 0xBB, 0xCC, 0xD4, 0xE5, 0xF6, 0x97, 0x18];
/// Reset to the end of the write that takes the sender's chip out of reset mode, machine cycles
/// of 1 µs (`firmware_seed_lab.rs` counts them from the listing).
const SENDER_JOINS: u64 = 93;
/// Bits from the sender's first start of frame to the end of its first frame: the first attempt,
/// which the receiver (still integrating) does not acknowledge, and the second, acknowledged
/// (`firmware_seed_lab.rs` works them out).
const FIRST_FRAME_BITS: u64 = 119 + FRAME_BITS;
/// The lab frame from start of frame to the end of end of frame, stuff bits counted by hand
/// (`firmware_seed_lab.rs`).
const FRAME_BITS: u64 = 110;

fn lab() -> Harvester {
    Harvester::load(&root().join("configs/firmware/seed_lab.ron")).expect("the seed lab loads")
}

/// One bit at 30 kbit/s: 3.456e12 / 30 000 bus-clock ticks.
fn bit() -> BusDuration {
    BusDuration::from_ticks(3_456_000_000_000 / 30_000)
}

/// The hardware of the node called `name`.
async fn hardware(running: &Running, name: &str, at: BusTime) -> HardwareState {
    let all = running.hardware(at).await;
    let (_, hw) = all.into_iter().find(|(n, _)| n == name).expect("the node");
    hw
}

/// Register `r` of the node's SJA1000, as the CPU would read it.
fn register(hw: &HardwareState, r: usize) -> u8 {
    let text = &hw.controllers[0].registers;
    u8::from_str_radix(&text[2 * r..2 * r + 2], 16).expect("hex")
}

/// With the receiver unplugged the sender is alone: every attempt is an ACK error, TEC + 8,
/// until error passive; an error-passive transmitter's ACK errors do not count (exception to
/// rule 3), so TXERR stays where it is however long it lasts, the chip is not bus off and its
/// transmit buffer stays locked on the frame it retries. Its TXERR was 2 at 0.55 s: 8 for the
/// ACK error of its very first attempt (the receiver still integrating), less one for each of
/// the six frames sent by then. 15 errors take it to 122, the 16th to 130, error passive.
/// Once the receiver is back each frame that gets through takes one off TXERR (rule 7).
#[test]
fn an_unacknowledged_sender_reads_txerr_128_then_counts_down_frame_by_frame() {
    let unplug = BusTime::from_millis(550);
    let plug = BusTime::from_millis(1500);
    let end = BusTime::from_millis(2500);
    let (trace, (alone, after)) = drive(lab(), async move |running| {
        let receiver = running.node("RECEIVER").expect("RECEIVER");
        running.run_until(unplug).await.expect("run");
        running
            .hub
            .send(Control::SetConnected(receiver, false))
            .await
            .expect("hub")
            .expect("unplug");
        running.run_until(plug).await.expect("run");
        let alone = hardware(running, "SENDER", plug).await;
        running
            .hub
            .send(Control::SetConnected(receiver, true))
            .await
            .expect("hub")
            .expect("plug");
        running.run_until(end).await.expect("run");
        (alone, hardware(running, "SENDER", end).await)
    });
    assert_eq!(
        (register(&alone, 15), register(&alone, 14)),
        (130, 0),
        "TXERR, RXERR"
    );
    let sr = register(&alone, 2);
    assert_eq!(sr & 0x80, 0, "SR {sr:02X}h: not bus off");
    assert_eq!(sr & 0x40, 0x40, "SR {sr:02X}h: error status (TXERR at least 96)");
    assert_eq!(sr & 0x04, 0, "SR {sr:02X}h: transmit buffer locked");
    let frames = parse_trace(&trace);
    let before = frames.iter().filter(|f| f.at <= unplug).count();
    // Frames end at 8.093 ms (after the failed first attempt) and 4.0037 ms + k × 99.916 ms from
    // the second on: six by 0.55 s, none while unplugged.
    assert_eq!(before, 6, "{trace}");
    // The hub commits whole frames: the last in the trace may end after `end`.
    let through = frames.iter().filter(|f| f.at <= end).count() - before;
    assert!(through >= 2, "{trace}");
    assert!(frames[before..].iter().all(|f| f.at > plug), "{trace}");
    assert_eq!(
        register(&after, 15) as usize,
        130 - through,
        "TXERR after {through} frames"
    );
    // Error active again from the third frame through (TXERR 127).
    assert!(through >= 3, "{trace}");
    assert_eq!(after.controllers[0].state, "active");
}

/// The lab switched off and on at 0.55 s: both benches start again from reset. The receiver
/// runs its initialisation again (its chip, reset with the power, would otherwise stay in reset
/// mode and acknowledge nothing), the sender's first frame after the cycle ends as long after
/// the cycle as after the first power-on (its first attempt unacknowledged, the receiver still
/// integrating: `firmware_seed_lab.rs`), and the receiver stores it at
/// 30H–37H at its next poll, once its 99.8 ms delay is over.
#[test]
fn after_a_power_cycle_the_receiver_initialises_again_and_receives_again() {
    let cycle = BusTime::from_millis(550);
    let early = cycle + BusDuration::from_millis(50);
    let late = cycle + BusDuration::from_millis(150);
    let (trace, (before, soon, after)) = drive(lab(), async move |running| {
        running.run_until(cycle).await.expect("run");
        let before = hardware(running, "RECEIVER", cycle).await;
        running.power_cycle().await.expect("power cycle");
        running.run_until(early).await.expect("run");
        let soon = hardware(running, "RECEIVER", early).await;
        running.run_until(late).await.expect("run");
        (before, soon, hardware(running, "RECEIVER", late).await)
    });
    assert_eq!(iram(&before, 0x30, 8), DATA, "before the cycle");
    // 50 ms after power-on: 50 000 machine cycles at 1 µs each, from reset.
    assert_eq!(soon.cpu.cycles, 50_000);
    // The model powers internal RAM up as 00h: the frame is in the chip but not read yet.
    assert_eq!(iram(&soon, 0x30, 8), [0; 8], "50 ms after the cycle");
    assert_eq!(iram(&after, 0x30, 8), DATA, "150 ms after the cycle");
    let ends: Vec<BusTime> = parse_trace(&trace).iter().map(|f| f.at).collect();
    let first = cycle + BusDuration::from_micros(SENDER_JOINS) + bit() * (11 + FIRST_FRAME_BITS);
    // The candump trace has microseconds: the frame ends at 0.558093 s, truncated.
    let after_cycle: Vec<&BusTime> = ends.iter().filter(|t| **t > cycle).collect();
    assert_eq!(after_cycle.len(), 2, "{trace}");
    assert_eq!(after_cycle[0].as_micros(), first.as_micros(), "{trace}");
    for hw in [&soon, &after] {
        assert_eq!((hw.controllers[0].tec, hw.controllers[0].rec), (0, 0));
    }
}
