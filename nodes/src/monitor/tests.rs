use super::*;
use bus::candump::parse_frame;

fn monitor(capacity: usize) -> Monitor {
    Monitor::new(MonitorConfig {
        queue_capacity: capacity,
        ..MonitorConfig::default()
    })
}

#[test]
fn the_producer_counts_what_does_not_fit_and_the_consumer_catches_up() {
    let mut m = monitor(4);
    let f = parse_frame("0500F5B1#218C08").unwrap(); // param.engine 2188 rpm
    for k in 0..6 {
        m.handle_frame(BusTime::from_micros(k), &f);
    }
    assert_eq!(m.display().borrow().lost, 2);
    m.handle_timeout(BusTime::from_millis(10));
    let d = m.display();
    assert_eq!((d.borrow().frames, d.borrow().engine_rpm), (4, Some(2188.0)));
    assert_eq!(m.poll_timeout(), Some(BusTime::from_millis(20)));
}

#[test]
fn alarm_switches_raise_and_clear_with_their_frame_times() {
    let mut m = monitor(16);
    // C0: door 3 open (bit 2 of Data1), then closed again.
    m.handle_frame(
        BusTime::from_millis(5),
        &parse_frame("0400F5C0#3004AC0D").unwrap(),
    );
    m.handle_frame(
        BusTime::from_millis(7),
        &parse_frame("0400F5C0#3000AC0D").unwrap(),
    );
    m.handle_timeout(BusTime::from_millis(10));
    let d = m.display();
    let d = d.borrow();
    assert_eq!(d.alarms.len(), 1);
    let a = &d.alarms[0];
    assert_eq!((a.name.as_str(), a.node.as_str()), ("door3_open", "C0"));
    assert_eq!(
        (a.raised, a.cleared),
        (BusTime::from_millis(5), Some(BusTime::from_millis(7)))
    );
}

#[test]
fn a_silent_node_raises_an_alarm_that_its_next_frame_clears() {
    let mut m = monitor(16);
    m.handle_frame(BusTime::from_millis(1), &parse_frame("0500F5B1#218C08").unwrap());
    m.handle_timeout(BusTime::from_millis(10));
    m.handle_timeout(BusTime::from_millis(3010));
    assert_eq!(m.display().borrow().active_alarms().count(), 1);
    m.handle_frame(
        BusTime::from_millis(3015),
        &parse_frame("0500F5B1#218C08").unwrap(),
    );
    m.handle_timeout(BusTime::from_millis(3020));
    let d = m.display();
    let d = d.borrow();
    assert_eq!(d.active_alarms().count(), 0);
    assert_eq!(d.alarms[0].name, "silent");
}

#[test]
fn flow_groups_become_yield_through_the_references() {
    let mut m = monitor(64);
    let t = |ms| BusTime::from_millis(ms);
    // D0 reference group (references 10000 each = 0x2710), then a flow group of 40 counts each:
    // flow = (40 / 10000) / 0.004 = 1 g/s.
    let frames = [
        "0601F5D0#200E0002FFBEFF00",
        "0601F5D0#0101102710271027",
        "0601F5D0#0210271027000000",
        "0601F5D0#200D0002FFBFFF00",
        "0601F5D0#0101280028002800",
        "0601F5D0#0228002800000000",
    ];
    for (k, f) in frames.iter().enumerate() {
        m.handle_frame(t(k as u64), &parse_frame(f).unwrap());
    }
    m.handle_timeout(t(10));
    let acks: Vec<Frame> = std::iter::from_fn(|| m.poll_transmit()).collect();
    assert_eq!(acks.len(), 2, "one acknowledgement per group");
    assert_eq!(bus::candump::format_frame(&acks[0]), "0601D0F5#210E01");
    let d = m.display();
    let d = d.borrow();
    assert!((d.rows[0].flow_g_s - 1.0).abs() < 1e-9);
    // The first group stands for one nominal period of 100 ms: 0.1 g.
    assert!((d.rows[0].kg - 0.0001).abs() < 1e-12);
}

#[test]
fn the_tally_places_every_frame_and_survives_a_restart() {
    let mut m = Monitor::new(MonitorConfig {
        queue_capacity: 4,
        consume_per_tick: 3,
        ..MonitorConfig::default()
    });
    let f = parse_frame("0500F5B1#218C08").unwrap();
    for k in 0..6 {
        m.handle_frame(BusTime::from_micros(k), &f);
    }
    // 4 queued, 2 did not fit; the main loop takes 3 of the 4.
    m.handle_timeout(BusTime::from_millis(10));
    let display = m.display();
    let t = display.borrow().tally;
    assert_eq!(
        (
            t.received,
            t.queue_full,
            t.processed,
            t.queued,
            t.dropped_at_restart
        ),
        (6, 2, 3, 1, 0)
    );
    assert!(t.balances());
    // A new logic on the same screen: the frame the old one still held is lost with it.
    let mut again = Monitor::with_display(MonitorConfig::default(), display.clone(), BusTime::from_secs(1));
    again.handle_frame(BusTime::from_millis(1001), &f);
    let t = display.borrow().tally;
    assert_eq!(
        (
            t.received,
            t.queue_full,
            t.processed,
            t.queued,
            t.dropped_at_restart
        ),
        (7, 2, 3, 1, 1)
    );
    assert!(t.balances());
    // The rest of the screen is blanked as before.
    assert_eq!(display.borrow().lost, 0);
}

#[test]
fn an_expected_node_never_heard_is_missing_after_its_start_up_and_the_silence_time() {
    let t = BusTime::from_millis;
    // B1 ends its start-up at 0.585 s, B2 at 0.590 s; silence_ms is 3000 by default.
    let mut m = monitor(16).expecting([(Address(0xB1), t(585)), (Address(0xB2), t(590))]);
    // B1 is heard in time; B2 never.
    m.handle_frame(t(3000), &parse_frame("0500F5B1#218C08").unwrap());
    for ms in (0..=3590).step_by(10) {
        m.handle_timeout(t(ms));
    }
    // At 3.590 s exactly B2 is not late yet: "past" is strictly after.
    assert_eq!(m.display().borrow().active_alarms().count(), 0);
    m.handle_timeout(t(3600));
    {
        let d = m.display();
        let d = d.borrow();
        let a: Vec<(&str, &str, BusTime)> = d
            .alarms
            .iter()
            .map(|a| (a.name.as_str(), a.node.as_str(), a.raised))
            .collect();
        assert_eq!(a, [("missing", "B2", t(3600))]);
    }
    // Its first frame clears it; from then on the silence alarm watches it.
    m.handle_frame(t(4000), &parse_frame("0500F5B2#22480D").unwrap());
    m.handle_timeout(t(4010));
    assert_eq!(m.display().borrow().alarms[0].cleared, Some(t(4000)));
    m.handle_timeout(t(7010));
    let d = m.display();
    let active: Vec<(String, String)> = d
        .borrow()
        .active_alarms()
        .map(|a| (a.name.clone(), a.node.clone()))
        .collect();
    assert_eq!(
        active,
        [("silent".into(), "B1".into()), ("silent".into(), "B2".into())]
    );
}
