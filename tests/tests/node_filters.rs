//! The shipped nodes' acceptance filters, read from their scripts: each takes what the node must
//! hear and nothing else the harvester puts on the bus, by the chips' register semantics
//! computed here bit by bit; and the running harvester uses them.

use bus::Frame;
use bus::filter::{AcceptanceFilter, Sja1000Mode};
use bus::time::BusTime;
use harvemu_e2e::{default_harvester, run_virtual};
use nodes::script::{FilterDef, NodeScript, SocketCanDef};
use protocol::catalogue::{Direction, MESSAGES};
use protocol::ident::{Address, NodeKind};
use supervisor::harvester::Harvester;

/// The identifier of the monitor's frames to `node` (docs/PROTOCOL.md: priority of the node's
/// class, point-to-point for flow sensors and broadcast otherwise, destination, source F5).
fn from_monitor(node: Address) -> u32 {
    let (priority, frame_type) = match node.kind() {
        Some(NodeKind::SpeedControl) => (0b00010, 0),
        Some(NodeKind::RowAlignment) => (0b00011, 0),
        Some(NodeKind::Alarm) => (0b00100, 0),
        Some(NodeKind::Parameter) => (0b00101, 0),
        Some(NodeKind::FlowSensor) => (0b00110, 1),
        other => panic!("{node} is not a field node: {other:?}"),
    };
    (priority << 24) | (frame_type << 16) | (u32::from(node.0) << 8) | 0xF5
}

/// Four register bytes from a script's text: hex, `0x` prefixes and spaces ignored.
fn regs(text: &str) -> [u8; 4] {
    let hex: String = text
        .split_whitespace()
        .map(|t| t.trim_start_matches("0x"))
        .collect();
    assert_eq!(hex.len(), 8, "{text}");
    let byte = |i: usize| u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).unwrap();
    [byte(0), byte(1), byte(2), byte(3)]
}

/// Bit `p` of four registers, counted from bit 7 of the first register (p = 0) to bit 0 of the
/// last (p = 31): the order in which the data sheets draw them.
fn reg_bit(r: [u8; 4], p: usize) -> bool {
    r[p / 8] >> (7 - p % 8) & 1 == 1
}

/// The message bits of an extended frame in register positions: ID28 at p = 0 down to ID0 at
/// p = 28, RTR at p = 29 (AT89C51CC03 CANIDT1..4; SJA1000 ACR0..3 in single-filter mode).
fn extended_layout(frame: &Frame) -> Vec<(usize, bool)> {
    let id = frame.raw_id();
    let mut bits: Vec<(usize, bool)> = (0..29).map(|p| (p, id >> (28 - p) & 1 == 1)).collect();
    bits.push((29, frame.is_remote()));
    bits
}

/// What the data sheets say the declared registers do with an extended frame.
fn reference(filter: &FilterDef, frame: &Frame) -> bool {
    assert!(frame.is_extended(), "the harvester sends extended frames only");
    match filter {
        FilterDef::Atmel { canidt, canidm, ide } => {
            // CANIDM bit 1 = compare; IDEMSK (CANIDM4 bit 0) compares the format with IDE.
            let (t, m) = (regs(canidt), regs(canidm));
            let format_ok = !reg_bit(m, 31) || *ide;
            format_ok
                && extended_layout(frame)
                    .into_iter()
                    .all(|(p, bit)| !reg_bit(m, p) || bit == reg_bit(t, p))
        }
        FilterDef::Sja1000 { mode, acr, amr } => {
            // AMR bit 1 = don't care.
            let (c, m) = (regs(acr), regs(amr));
            let passes =
                |bits: &[(usize, bool)]| bits.iter().all(|&(p, bit)| reg_bit(m, p) || bit == reg_bit(c, p));
            match mode {
                Sja1000Mode::Single => passes(&extended_layout(frame)),
                Sja1000Mode::Dual => {
                    // ID28..13 against ACR0:ACR1 (filter 1) or ACR2:ACR3 (filter 2).
                    let high: Vec<(usize, bool)> = extended_layout(frame).into_iter().take(16).collect();
                    let second: Vec<(usize, bool)> = high.iter().map(|&(p, b)| (p + 16, b)).collect();
                    passes(&high) || passes(&second)
                }
            }
        }
        FilterDef::SocketCan(list) => {
            let rx = frame.raw_id() | 1 << 31 | u32::from(frame.is_remote()) << 30;
            list.iter().any(|SocketCanDef { can_id, can_mask }| {
                let id = u32::from_str_radix(can_id.trim_start_matches("0x"), 16).unwrap();
                let mask = u32::from_str_radix(can_mask.trim_start_matches("0x"), 16).unwrap();
                assert_eq!((id | mask) & 0x2000_0000, 0, "no inverted or error filters here");
                (rx ^ id) & mask == 0
            })
        }
    }
}

/// Every identifier the harvester's addressing can produce (32 priorities, both frame types,
/// each of the 21 addresses as destination and as source), as data frames, plus the remote
/// frames of the identifiers the node listens for.
fn sample(listens: &[u32]) -> Vec<Frame> {
    let mut frames = Vec::new();
    for priority in 0..32u32 {
        for frame_type in 0..2u32 {
            for dst in Address::all() {
                for src in Address::all() {
                    let id = priority << 24 | frame_type << 16 | u32::from(dst.0) << 8 | u32::from(src.0);
                    frames.push(Frame::extended(id, &[0x01, 0x01]).unwrap());
                }
            }
        }
    }
    for &id in listens {
        frames.push(Frame::new_remote(bus::ExtendedId::new(id).unwrap(), 2).unwrap());
    }
    frames
}

/// Checks one script's filter: it takes every catalogue message to the node that its script
/// reacts to, and of everything else only data frames on the identifier those messages use.
fn check(script: &NodeScript) {
    let node = Address(script.address);
    let filter = script
        .filter
        .to_filter()
        .unwrap_or_else(|p| panic!("{}: {p:?}", script.name));
    let own = from_monitor(node);
    // The catalogue's messages to this node, all on one identifier, and all handled.
    let to_node: Vec<_> = MESSAGES
        .iter()
        .filter(|m| m.direction == Direction::FromMonitor && m.nodes.contains(node))
        .collect();
    for m in &to_node {
        assert_eq!(m.app_id(node).raw(), own, "{} to {node}", m.name);
        assert!(
            script.reactions.iter().any(|r| r.message == m.name),
            "{} does not react to {}",
            script.name,
            m.name
        );
        let frame = Frame::extended(own, &[m.number]).unwrap();
        assert!(filter.accepts(&frame), "{} drops {}", script.name, m.name);
        assert!(
            reference(&script.filter, &frame),
            "{}: reference drops {}",
            script.name,
            m.name
        );
    }
    let mut taken = 0;
    for frame in sample(&[own]) {
        let expected = frame.raw_id() == own && !frame.is_remote();
        assert_eq!(
            reference(&script.filter, &frame),
            expected,
            "{}: data sheet semantics for {:08X} (remote {})",
            script.name,
            frame.raw_id(),
            frame.is_remote()
        );
        assert_eq!(
            filter.accepts(&frame),
            expected,
            "{}: controller filter for {:08X} (remote {})",
            script.name,
            frame.raw_id(),
            frame.is_remote()
        );
        taken += usize::from(expected);
    }
    assert_eq!(taken, 1, "{}", script.name);
}

#[test]
fn every_shipped_filter_takes_its_nodes_frames_and_no_other() {
    let h = default_harvester();
    assert_eq!(h.scripts.len(), 20);
    for script in &h.scripts {
        // The source's field nodes are AT89C51-family modules with on-chip CAN.
        assert!(
            matches!(script.filter, FilterDef::Atmel { .. }),
            "{}: {:?}",
            script.name,
            script.filter
        );
        check(script);
    }
    // The source gives A0's registers.
    let a0 = h.scripts.iter().find(|s| s.name == "A0").unwrap();
    let FilterDef::Atmel { canidt, .. } = &a0.filter else {
        panic!("A0 is an AT89C51CC03");
    };
    assert_eq!(regs(canidt), [0x18, 0x05, 0x07, 0xA8]);
}

/// The same check for the other two kinds, with exact filters for D0 (SJA1000) and D1
/// (SocketCAN); and the harvester runs with them: every sensor is calibrated and streams.
#[test]
fn the_harvester_runs_with_each_kind_of_filter() {
    let mut h = default_harvester();
    for s in &mut h.scripts {
        match s.name.as_str() {
            "D0" => {
                s.filter = FilterDef::Sja1000 {
                    mode: Sja1000Mode::Single,
                    acr: "30 0E 87 A8".into(),
                    amr: "00 00 00 03".into(),
                }
            }
            "D1" => {
                s.filter = FilterDef::SocketCan(vec![SocketCanDef {
                    can_id: "0x8601D1F5".into(),
                    can_mask: "0xDFFFFFFF".into(),
                }])
            }
            _ => continue,
        }
        check(s);
    }
    let running = sensors_running(h);
    assert_eq!(running, [true; 6]);
}

/// A node whose filter drops its commands never hears them: D2 with A0's registers is never
/// calibrated, while the others are.
#[test]
fn the_running_nodes_use_their_scripts_filters() {
    let mut h = default_harvester();
    let a0 = h.scripts.iter().find(|s| s.name == "A0").unwrap().filter.clone();
    let d2 = h.scripts.iter_mut().find(|s| s.name == "D2").unwrap();
    d2.filter = a0;
    assert_eq!(sensors_running(h), [true, true, false, true, true, true]);
}

/// Runs `h` for 5 s; for each flow sensor, whether its last `flow.status` says "running" and it
/// sent flow groups.
fn sensors_running(h: Harvester) -> [bool; 6] {
    let (lines, _) = run_virtual(h, BusTime::from_secs(5), |_| {}, |_, _| ());
    let decoded: Vec<_> = lines
        .iter()
        .filter_map(|l| protocol::catalogue::decode(&l.frame).ok().flatten())
        .collect();
    std::array::from_fn(|n| {
        let d = Address::flow_sensor(n as u8);
        let last = decoded
            .iter()
            .rev()
            .find(|x| x.node == d && x.message.name == "flow.status");
        let state = last.and_then(|x| x.get("state")).and_then(|v| v.label());
        let groups = decoded
            .iter()
            .filter(|x| x.node == d && x.message.name == "flow.marker_flow")
            .count();
        state == Some("running") && groups > 0
    })
}
