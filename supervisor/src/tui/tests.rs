//! The view and its rendering, from snapshots built by hand on the sans-IO bus engine.

use super::view::decimals;
use super::*;
use bus::Frame;
use bus::engine::{Bus, BusConfig, ControllerConfig, ControllerCounters, NodeId};
use bus::fault::ErrorState;
use bus::time::BusTime;
use bus_runtime::hub::{NodeSnapshot, Snapshot};
use nodes::monitor::{Alarm, Display};
use nodes::plant::{Plant, PlantConfig};
use protocol::catalogue::by_name;
use protocol::ident::Address;
use ratatui::Terminal;
use ratatui::backend::TestBackend;
use ratatui::buffer::Buffer;
use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyEventKind, KeyModifiers};

/// The screen as lines of text.
fn lines(buffer: &Buffer) -> Vec<String> {
    let width = usize::from(buffer.area.width);
    buffer
        .content()
        .chunks(width.max(1))
        .map(|row| row.iter().map(|c| c.symbol()).collect())
        .collect()
}

fn render(view: &View, width: u16, height: u16) -> Vec<String> {
    let mut terminal = Terminal::new(TestBackend::new(width, height)).unwrap();
    terminal.draw(|f| draw(f, view)).unwrap();
    lines(terminal.backend().buffer())
}

/// The one line that contains `key`.
fn line_with<'a>(screen: &'a [String], key: &str) -> &'a str {
    let found: Vec<&String> = screen.iter().filter(|l| l.contains(key)).collect();
    assert_eq!(found.len(), 1, "one line with {key:?} in:\n{}", screen.join("\n"));
    found[0]
}

/// A bus with a sender and a receiver (someone has to acknowledge).
fn bus_with_sender() -> (Bus, NodeId) {
    let mut bus = Bus::new(BusConfig::default()).unwrap();
    let tx = bus.attach(ControllerConfig::named("tx"));
    bus.attach(ControllerConfig::named("rx"));
    (bus, tx)
}

fn snapshot(bus: &mut Bus, now: BusTime, nodes: Vec<NodeSnapshot>) -> Snapshot {
    bus.advance_stats(now);
    Snapshot {
        now,
        stats: bus.stats().clone(),
        nodes,
        wakes: 0,
        late_submissions: 0,
        overruns: Default::default(),
        trace_error: None,
    }
}

fn node(name: &str, state: ErrorState, tec: u16, rec: u16) -> NodeSnapshot {
    NodeSnapshot {
        name: name.into(),
        tec,
        rec,
        state,
        counters: ControllerCounters::default(),
        handover: Default::default(),
        rx_queued: 0,
        hung: false,
        crashed: None,
    }
}

fn view_of(snapshot: &Snapshot, display: Option<&Display>, rates: &RateMeter) -> View {
    let plant = Plant::new(PlantConfig::default(), 7);
    View::build(&Sources {
        machine: "test",
        clock: Clock::Virtual,
        finished: false,
        snapshot,
        display,
        plant: &plant,
        rates,
        events: &[],
        database: None,
    })
}

#[test]
fn node_states_show_passive_and_bus_off_with_their_counters() {
    let (mut bus, _) = bus_with_sender();
    let mut crashed = node("D3", ErrorState::Active, 0, 0);
    crashed.crashed = Some(bus::node::CrashCause::Panic("panicked".into()));
    let nodes = vec![
        node("F5", ErrorState::Active, 0, 0),
        node("B3", ErrorState::Passive, 136, 9),
        node("D1", ErrorState::BusOff, 256, 0),
        crashed,
    ];
    let snap = snapshot(&mut bus, BusTime::from_millis(100), nodes.clone());
    let view = view_of(&snap, None, &RateMeter::default());
    let screen = render(&view, 160, 30);
    let expect = |n: &NodeSnapshot, state: &str| format!("{} {state} {}/{}", n.name, n.tec, n.rec);
    for (n, state) in nodes.iter().zip(["active", "passive", "bus-off", "active"]) {
        line_with(&screen, &expect(n, state));
    }
    assert!(line_with(&screen, "D3 active").contains("D3 active 0/0 crashed"));
    // Without a monitor, the panel says so and shows only the plant's values.
    line_with(&screen, "no monitor");
    let speed = line_with(&screen, "travel speed");
    let plant = Plant::new(PlantConfig::default(), 7);
    let truth = format!("{:.1}", plant.signal("speed.actual").unwrap());
    assert!(speed.contains(" - ") && speed.contains(&truth), "{speed}");
}

#[test]
fn rates_are_measured_over_the_last_second_of_bus_time() {
    let (mut bus, tx) = bus_with_sender();
    let frame = Frame::extended(0x0500F5B1, &[0x21, 0x10, 0x08]).unwrap();
    let mut rates = RateMeter::default();
    let mut seen = Vec::new();
    // 100 frames/s for 2 s, then 20 frames/s for 2 s; a snapshot every 250 ms.
    for ms in (0..4000u64).step_by(10) {
        let period = if ms < 2000 { 10 } else { 50 };
        if ms % period == 0 {
            bus.submit(tx, frame, BusTime::from_millis(ms)).unwrap();
        }
        bus.run_until(BusTime::from_millis(ms + 10));
        bus.take_events().for_each(drop);
        if (ms + 10) % 250 == 0 {
            let snap = snapshot(&mut bus, BusTime::from_millis(ms + 10), Vec::new());
            rates.update(&snap);
            let id = &snap.stats.per_id[&(0x0500F5B1 | bus::filter::CAN_EFF_FLAG)];
            seen.push((ms + 10, rates.rate(0x0500F5B1 | bus::filter::CAN_EFF_FLAG, id)));
        }
    }
    let at = |t: u64| seen.iter().find(|(ms, _)| *ms == t).unwrap().1;
    // Before a second has passed, the window is as long as the run so far.
    assert!((at(250) - 100.0).abs() < 1e-9, "{}", at(250));
    assert!((at(2000) - 100.0).abs() < 1e-9, "{}", at(2000));
    assert!((at(4000) - 20.0).abs() < 1e-9, "{}", at(4000));
    // Half a second into the slow part, the last second holds 50 fast and 10 slow frames.
    assert!((at(2500) - 60.0).abs() < 1e-9, "{}", at(2500));
}

#[test]
fn a_single_snapshot_falls_back_to_the_mean_period() {
    let (mut bus, tx) = bus_with_sender();
    let frame = Frame::extended(0x0500F5B1, &[0x21, 0x10, 0x08]).unwrap();
    for k in 0..5u64 {
        bus.submit(tx, frame, BusTime::from_millis(k * 40)).unwrap();
        bus.run_until(BusTime::from_millis(k * 40 + 10));
    }
    let snap = snapshot(&mut bus, BusTime::from_millis(200), Vec::new());
    let mut rates = RateMeter::default();
    rates.update(&snap);
    let view = view_of(&snap, None, &rates);
    assert!(
        (view.bus.ids[0].rate - 25.0).abs() < 1e-6,
        "{}",
        view.bus.ids[0].rate
    );
}

/// E0's speed.status with `actual` km/h, set-point 8 km/h, cruise.
fn speed_status(actual: f64) -> Frame {
    by_name("speed.status")
        .unwrap()
        .encode(Address::SPEED_CONTROL, |f| match f {
            "actual" => Some(actual),
            "setpoint" => Some(8.0),
            "mode" => Some(1.0),
            _ => Some(0.0),
        })
        .unwrap()
}

#[test]
fn an_identifier_row_shows_its_last_payload_decoded() {
    let (mut bus, tx) = bus_with_sender();
    let speeds = [3.5, 7.25];
    for (k, speed) in speeds.iter().enumerate() {
        bus.submit(tx, speed_status(*speed), BusTime::from_millis(k as u64 * 50))
            .unwrap();
    }
    // A frame whose identifier and Data0 name a message but whose length breaks it.
    let broken = Frame::extended(0x0500F5B1, &[0x21]).unwrap();
    bus.submit(tx, broken, BusTime::from_millis(120)).unwrap();
    bus.run_until(BusTime::from_millis(200));
    let last = speed_status(7.25);
    let snap = snapshot(&mut bus, BusTime::from_millis(200), Vec::new());
    let view = view_of(&snap, None, &RateMeter::default());
    let screen = render(&view, 200, 30);
    let row = line_with(&screen, "0200F5E0");
    let hex: Vec<String> = last.data().iter().map(|b| format!("{b:02X}")).collect();
    for part in [
        "speed.status",
        "E0>F5",
        &hex.join(" "),
        "actual=7.25 km/h",
        "setpoint=8.00 km/h",
    ] {
        assert!(row.contains(part), "{part:?} in {row}");
    }
    // Arbitration order: 0200F5E0 (priority 2) above 0500F5B1 (priority 5).
    let broken_row = line_with(&screen, "0500F5B1");
    assert!(
        broken_row.contains("param.engine") && broken_row.contains("DLC"),
        "{broken_row}"
    );
    let pos = |key: &str| screen.iter().position(|l| l.contains(key)).unwrap();
    assert!(pos("0200F5E0") < pos("0500F5B1"));
}

/// A view with far more than any screen holds.
fn crowded_view() -> View {
    let (mut bus, _) = bus_with_sender();
    bus.attach(ControllerConfig {
        tx_queue_len: 300,
        ..ControllerConfig::named("many")
    });
    let many = NodeId(2);
    for k in 0..300u32 {
        let frame = Frame::extended(0x1000_0000 + k, &[k as u8, 1, 2, 3, 4, 5, 6, 7]).unwrap();
        bus.submit(many, frame, BusTime::from_nanos(u64::from(k)))
            .unwrap();
    }
    bus.run_until(BusTime::from_millis(1000));
    let nodes = (0..40)
        .map(|i| node(&format!("N{i}"), ErrorState::Passive, 128 + i, i))
        .collect();
    let snap = snapshot(&mut bus, BusTime::from_millis(1000), nodes);
    let display = Display {
        phase: "running".into(),
        alarms: (0..40)
            .map(|i| Alarm {
                name: format!("alarm{i}"),
                node: "C0".into(),
                raised: BusTime::from_millis(100 * i),
                cleared: None,
            })
            .collect(),
        ..Display::default()
    };
    view_of(&snap, Some(&display), &RateMeter::default())
}

#[test]
fn long_tables_are_cut_to_the_area() {
    let view = crowded_view();
    assert_eq!(view.bus.ids.len(), 300);
    let screen = render(&view, 100, 24);
    assert_eq!(screen.len(), 24);
    // The first identifiers are shown, the last not; the borders close the panels.
    assert!(screen.iter().any(|l| l.contains("10000000")));
    assert!(!screen.iter().any(|l| l.contains("1000012B")));
    assert!(
        screen[23].starts_with('└') && screen[23].ends_with('┘'),
        "{}",
        screen[23]
    );
    // Six alarm lines at most: five alarms and a count of the rest.
    assert!(screen.iter().any(|l| l.contains("ALARM C0 alarm4 since 0.4 s")));
    assert!(!screen.iter().any(|l| l.contains("alarm5 ")));
    line_with(&screen, &format!("... {} more alarms", 40 - 5));
}

#[test]
fn any_size_renders_without_panicking() {
    let view = crowded_view();
    for (w, h) in [(0, 0), (1, 1), (20, 5), (5, 20), (80, 24), (400, 200), (1000, 3)] {
        let screen = render(&view, w, h);
        assert_eq!(screen.len(), if w == 0 { 0 } else { usize::from(h) });
        assert!(screen.iter().all(|l| l.chars().count() == usize::from(w)));
    }
    // At 20x5 the title is cut, not wrapped.
    let screen = render(&view, 20, 5);
    assert_eq!(screen[0], "harvemu test        ");
}

#[test]
fn quit_keys() {
    let key = |code, modifiers| KeyEvent::new(code, modifiers);
    assert!(quits(&key(KeyCode::Char('q'), KeyModifiers::NONE)));
    assert!(quits(&key(KeyCode::Esc, KeyModifiers::NONE)));
    assert!(quits(&key(KeyCode::Char('c'), KeyModifiers::CONTROL)));
    assert!(!quits(&key(KeyCode::Char('c'), KeyModifiers::NONE)));
    assert!(!quits(&key(KeyCode::Char('x'), KeyModifiers::NONE)));
    let mut release = key(KeyCode::Char('q'), KeyModifiers::NONE);
    release.kind = KeyEventKind::Release;
    assert!(!quits(&release));
}

#[test]
fn decimals_follow_the_scaling() {
    assert_eq!(decimals(1.0), 0);
    assert_eq!(decimals(0.01), 2);
    assert_eq!(decimals(0.5), 1);
    assert_eq!(decimals(0.125), 3);
    assert_eq!(decimals(1e-5), 4);
    assert_eq!(decimals(-0.1), 1);
}

/// A monitor showing values whose cut forms ("3.7", ".62", "62") would look like numbers.
fn display_with_numbers() -> Display {
    Display {
        phase: "running".into(),
        total_kg: 13.7,
        feed_kg_s: 2.62,
        area_ha: 0.125,
        kg_per_ha: Some(109.6),
        speed_kmh: Some(5.4),
        engine_rpm: Some(2150.0),
        basket_fill_pct: Some(37.5),
        rows: (0..6)
            .map(|r| nodes::monitor::RowYield {
                kg: 2.0 + f64::from(r),
                flow_g_s: 1234.0,
                sensor_state: "running".into(),
                calibrated: true,
            })
            .collect(),
        ..Display::default()
    }
}

/// The tokens after the label of the monitor panel's row that starts with `label`.
fn row_tokens(screen: &[String], label: &str) -> Vec<String> {
    let start = format!("│{label} ");
    let line = screen
        .iter()
        .find(|l| l.starts_with(&start))
        .unwrap_or_else(|| panic!("no row {label:?} in:\n{}", screen.join("\n")));
    // The monitor panel's part of the line: up to its right border.
    let panel: String = line.chars().skip(1).take_while(|c| *c != '│').collect();
    panel
        .split_whitespace()
        .skip(label.split_whitespace().count())
        .map(str::to_owned)
        .collect()
}

#[test]
fn numbers_are_shown_whole_at_every_width() {
    let (mut bus, _) = bus_with_sender();
    let snap = snapshot(
        &mut bus,
        BusTime::from_millis(13_700),
        vec![node("D0", ErrorState::Active, 0, 0)],
    );
    let display = display_with_numbers();
    let view = view_of(&snap, Some(&display), &RateMeter::default());
    // The expected texts, from the values fed in and the plant's signals (not from the view).
    let plant = Plant::new(PlantConfig::default(), 7);
    let truth = |name: &str, decimals: usize| format!("{:.decimals$}", plant.signal(name).unwrap());
    let expected = [
        ("harvested", "13.7".to_string(), truth("harvested.total", 1)),
        ("feed", "2.62".to_string(), "-".to_string()),
        ("area", "0.125".to_string(), "-".to_string()),
        ("travel speed", "5.4".to_string(), truth("speed.actual", 1)),
        ("engine", "2150".to_string(), truth("engine.rpm", 0)),
        ("basket", "37.5".to_string(), truth("basket.fill", 1)),
        ("row 3", "4.0".to_string(), truth("row3.harvested", 1)),
    ];
    for width in [60, 64, 72, 80, 100, 120, 160, 200] {
        let screen = render(&view, width, 60);
        for (label, shown, plant_value) in &expected {
            let tokens = row_tokens(&screen, label);
            let numbers: Vec<&String> = tokens
                .iter()
                .filter(|t| t.starts_with(|c: char| c.is_ascii_digit() || c == '-' || c == '#'))
                .collect();
            assert!(
                numbers.len() >= 2,
                "{width}: {label}: {tokens:?}\n{}",
                screen.join("\n")
            );
            assert_eq!(numbers[0], shown, "{width}: {label} on the monitor: {tokens:?}");
            assert_eq!(
                numbers[1], plant_value,
                "{width}: {label} in the plant: {tokens:?}"
            );
        }
        // Nowhere a cut form of a number shown.
        for l in &screen {
            for t in l.split(|c: char| c.is_whitespace() || c == '│') {
                assert!(
                    ![".62", "3.7", "62", ".7", "150"].contains(&t),
                    "{width}: {t:?} in {l}"
                );
            }
        }
        // The title's time is whole.
        assert!(screen[0].contains(" t 13.7 s"), "{width}: {}", screen[0]);
    }
    // A wide terminal shows every flow sensor's state whole.
    let screen = render(&view, 200, 60);
    for r in 1..=6 {
        let row = line_with(&screen, &format!("row {r} "));
        assert!(row.contains("1234 g/s running│"), "{row}");
    }
}

#[test]
fn a_number_without_room_is_hashes_not_digits() {
    let (mut bus, _) = bus_with_sender();
    let snap = snapshot(&mut bus, BusTime::from_millis(1000), vec![]);
    let display = display_with_numbers();
    let view = view_of(&snap, Some(&display), &RateMeter::default());
    for width in 1..60 {
        let screen = render(&view, width, 40);
        for l in &screen {
            for t in l.split(|c: char| c.is_whitespace() || c == '│') {
                assert!(
                    ![".62", "3.7", "62", ".7", "150", "15", "50"].contains(&t),
                    "{width}: {t:?} in {l}"
                );
            }
        }
    }
}

/// The harvester's 21 controllers, as the live view names them.
const HARVESTER: [&str; 21] = [
    "F5", "E0", "A0", "B0", "B1", "B2", "B3", "B4", "B5", "B6", "B7", "C0", "C1", "C2", "C3", "D0", "D1",
    "D2", "D3", "D4", "D5",
];

#[test]
fn at_80_by_24_every_node_shows_and_the_decoded_column_is_filled_or_left_out() {
    let (mut bus, tx) = bus_with_sender();
    bus.submit(tx, speed_status(7.25), BusTime::from_millis(0))
        .unwrap();
    bus.run_until(BusTime::from_millis(100));
    let nodes: Vec<NodeSnapshot> = HARVESTER
        .iter()
        .map(|name| match *name {
            "B3" => node(name, ErrorState::Passive, 136, 0),
            "D1" => node(name, ErrorState::BusOff, 256, 0),
            _ => node(name, ErrorState::Active, 0, 0),
        })
        .collect();
    let snap = snapshot(&mut bus, BusTime::from_millis(100), nodes);
    let view = view_of(&snap, None, &RateMeter::default());
    let screen = render(&view, 80, 24);
    let text = screen.join("\n");
    let tokens: Vec<&str> = text
        .split(|c: char| c.is_whitespace() || "│┌┐└┘─".contains(c))
        .collect();
    for name in HARVESTER {
        let shown = match name {
            "B3" => "B3:P".to_string(),
            "D1" => "D1:OFF".to_string(),
            _ => name.to_string(),
        };
        assert!(tokens.contains(&shown.as_str()), "{shown} on\n{text}");
    }
    // At 80 columns the bus panel has no room for decoded fields: the column is left out
    // rather than shown empty. From 100 columns it is there, its first field whole and the
    // rest marked as left out, never cut.
    let header = line_with(&screen, "fr/s");
    assert!(!header.contains("decoded"), "{header}");
    for w in [100u16, 140] {
        let wide = render(&view, w, 24);
        assert!(line_with(&wide, "fr/s").contains("decoded"));
        let row = line_with(&wide, "0200F5E0");
        assert!(row.contains("actual=7.25 km/h …"), "{row}");
    }
    let wide = render(&view, 200, 24);
    let row = line_with(&wide, "0200F5E0");
    assert!(row.contains("actual=7.25 km/h setpoint=8.00 km/h"), "{row}");
}
