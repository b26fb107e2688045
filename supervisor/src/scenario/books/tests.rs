use super::*;

/// 1000 frames to the monitor: 8 missed while it was away, 2 lost to an error only it flagged,
/// 5 overruns, 985 stored; of those 3
/// cleared at a restart, 2 still in the FIFO, 980 read; of those 4 in a crashed wake, 6 dropped at
/// the replacement, 1 held, 969 handled; of those 7 did not fit, 950 processed, 2 queued, 10
/// dropped with a replaced logic.
fn balanced() -> MonitorBooks {
    MonitorBooks {
        on_bus: 1000,
        untracked: 0,
        in_trace: Some(1000),
        controller: ControllerCounters {
            rx_missed: 8,
            rx_errored: 2,
            rx_overruns: 5,
            rx_frames: 985,
            rx_cleared: 3,
            rx_read: 980,
            rx_filtered: 123_456,
            ..ControllerCounters::default()
        },
        in_fifo: 2,
        handover: Handover {
            handled: 969,
            crashed: 4,
            dropped_at_replace: 6,
            held: 1,
            in_flight: 0,
        },
        tally: FrameTally {
            received: 969,
            queue_full: 7,
            processed: 950,
            queued: 2,
            dropped_at_restart: 10,
        },
    }
}

#[test]
fn balanced_books_sum_to_the_frames_on_the_bus_in_every_layer() {
    let b = balanced();
    assert_eq!(b.accounted(), 1000);
    assert!(b.balance(), "{}", b.table());
    // Frames addressed to others (filtered) are nobody's loss.
    assert!(!b.reasons().iter().any(|(_, n)| *n == 123_456));
    assert!(b.table().starts_with("        1000  frames addressed to F5"));
}

#[test]
fn a_frame_lost_to_an_error_only_the_monitor_flagged_is_a_reason() {
    let b = balanced();
    assert!(
        b.reasons()
            .contains(&("lost: an error only the monitor flagged (error passive)", 2))
    );
    // Without that counter the controller's identity no longer holds.
    let mut b = balanced();
    b.controller.rx_errored = 0;
    let failed: Vec<&str> = b
        .checks()
        .into_iter()
        .filter(|c| !c.holds())
        .map(|c| c.what)
        .collect();
    assert_eq!(
        failed,
        [
            "on the bus = accounted for",
            "on the bus = own + missed + overrun + errored + stored (controller)"
        ]
    );
}

#[test]
fn a_frame_gone_missing_is_caught_in_its_layer() {
    // The hub loses one frame without saying so: read no longer matches what it did.
    let mut b = balanced();
    b.handover.handled -= 1;
    b.tally.received -= 1;
    b.tally.processed -= 1;
    let failed: Vec<&str> = b
        .checks()
        .into_iter()
        .filter(|c| !c.holds())
        .map(|c| c.what)
        .collect();
    assert_eq!(
        failed,
        [
            "on the bus = accounted for",
            "read = handled + crashed + dropped + held + in a wake (hub)"
        ]
    );
    assert_eq!(b.accounted(), 999);
    assert!(b.table().contains("FAIL read ="), "{}", b.table());
}

#[test]
fn the_trace_count_and_untracked_identifiers_are_checked_too() {
    let mut b = balanced();
    b.in_trace = Some(1001);
    b.untracked = 0;
    assert!(!b.balance());
    b.in_trace = None;
    assert!(b.balance());
    b.untracked = 3;
    assert!(!b.balance());
}

#[test]
fn destinations_are_read_from_the_identifier() {
    // priority | type | destination | source, with the kernel's extended flag.
    assert!(to_monitor(0x8000_0000 | 0x0601_F5D0));
    assert!(to_monitor(0x8000_0000 | 0x0000_F5EE));
    assert!(!to_monitor(0x8000_0000 | 0x0500_A0F5), "from the monitor");
    assert!(!to_monitor(0x0000_00F5), "base identifier");
    assert!(!to_monitor(0x0000_F500), "no extended flag");
}

#[test]
fn trace_records_are_told_apart() {
    use bus::trace::{ErrorFrame, Kind, Record, Source};
    let frame = |text: &str| Kind::Frame(bus::candump::parse_frame(text).unwrap());
    let mut t = TraceTally::default();
    for kind in [
        frame("0601F5D0#200D0002FFBFFF00"),
        frame("0601A0D0#"),
        frame("123#DEADBEEF"),
        // A remote frame to the monitor still counts as one to it.
        frame("0000F5EE#R"),
        // A base identifier has no destination byte, whatever its bits.
        frame("0F5#01"),
        Kind::Error(ErrorFrame {
            can_id: 0x2000_0088,
            data: [0, 0, 0x80, 0, 0, 0, 8, 0],
        }),
    ] {
        t.record(&Record {
            at: bus::time::BusTime::ZERO,
            bus: "harv0",
            source: Source::Bus,
            kind,
        });
    }
    assert_eq!(
        t,
        TraceTally {
            frames: 5,
            to_monitor: 2,
            error_frames: 1,
        }
    );
}
