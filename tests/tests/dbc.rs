//! The DBC export read back by an independent parser (can-dbc): every catalogue message is in it
//! as the catalogue defines it, the cycle times are the node scripts', and a recorded trace decoded
//! through the parsed DBC gives the catalogue decoder's values, frame by frame.

use bus::time::BusTime;
use can_dbc::{AttributeValue, ByteOrder, Dbc, Message, MessageId, MultiplexIndicator, Signal, ValueType};
use harvemu_e2e::{Line, default_harvester, run_virtual};
use nodes::script::When;
use protocol::catalogue::{self, Direction, MESSAGES, MessageDef, dbc};
use protocol::ident::Address;
use std::collections::{BTreeMap, BTreeSet};

/// The DBC of the default harvester, as text and as can-dbc reads it.
fn exported() -> (String, Dbc) {
    let text = dbc::generate(MESSAGES, &supervisor::dbc::network(&default_harvester()));
    let parsed = Dbc::try_from(text.as_str()).unwrap_or_else(|e| panic!("can-dbc rejects the export: {e:?}"));
    (text, parsed)
}

/// The 29-bit identifier of `m` exchanged with `node`, from the protocol's field layout
/// (priority | frame type | destination | source), not from `AppId`.
fn identifier(m: &MessageDef, node: Address) -> u32 {
    let (dst, src) = match m.direction {
        Direction::ToMonitor => (0xF5, node.0),
        Direction::FromMonitor => (node.0, 0xF5),
    };
    (u32::from(m.priority().value()) << 24)
        | (u32::from(u8::from(m.frame_type)) << 16)
        | (u32::from(dst) << 8)
        | u32::from(src)
}

fn message(dbc: &Dbc, id: u32) -> &Message {
    dbc.messages
        .iter()
        .find(|x| x.id == MessageId::Extended(id))
        .unwrap_or_else(|| panic!("no BO_ for {id:08X}"))
}

/// Data0, the message number.
fn data0(m: &Message) -> &Signal {
    let s: Vec<&Signal> = m
        .signals
        .iter()
        .filter(|s| s.start_bit == 0 && s.size == 8)
        .collect();
    assert_eq!(s.len(), 1, "{}: one signal on Data0", m.name);
    s[0]
}

/// The signals present when Data0 is `number` (Data0 itself left out).
fn active(m: &Message, number: u8) -> Vec<&Signal> {
    let d0 = &data0(m).name;
    m.signals
        .iter()
        .filter(|s| &s.name != d0)
        .filter(|s| match s.multiplexer_indicator {
            MultiplexIndicator::Plain => true,
            MultiplexIndicator::MultiplexedSignal(n) => n == u64::from(number),
            other => panic!("{}.{}: unexpected multiplexing {other:?}", m.name, s.name),
        })
        .collect()
}

/// The signal carrying field `field`: its own name, or prefixed with its message's short name
/// where several messages on one identifier use the name.
fn signal_for<'a>(signals: &[&'a Signal], field: &str) -> &'a Signal {
    let suffix = format!("_{field}");
    let found: Vec<&&Signal> = signals
        .iter()
        .filter(|s| s.name == field || s.name.ends_with(&suffix))
        .collect();
    assert_eq!(found.len(), 1, "exactly one signal for {field}: {found:?}");
    found[0]
}

/// Decodes a signal bit by bit from the parsed definition (Intel numbering: bit `i` of the
/// signal is payload bit `start + i`, byte `(start + i) / 8`, bit `(start + i) % 8`).
fn raw_value(data: &[u8], s: &Signal) -> Option<i64> {
    assert_eq!(
        s.byte_order,
        ByteOrder::LittleEndian,
        "{}: the catalogue packs every field low byte first",
        s.name
    );
    let mut v: u64 = 0;
    for i in 0..s.size {
        let pos = s.start_bit + i;
        let byte = *data.get(usize::try_from(pos / 8).ok()?)?;
        v |= u64::from((byte >> (pos % 8)) & 1) << i;
    }
    let negative = s.value_type == ValueType::Signed && (v >> (s.size - 1)) & 1 == 1;
    Some(if negative {
        v as i64 - (1i64 << s.size)
    } else {
        v as i64
    })
}

fn uint(v: Option<&AttributeValue>) -> Option<u64> {
    match v? {
        AttributeValue::Uint(n) => Some(*n),
        AttributeValue::Int(n) => u64::try_from(*n).ok(),
        other => panic!("not an integer attribute: {other:?}"),
    }
}

#[test]
fn every_catalogue_message_is_in_the_dbc_as_the_catalogue_defines_it() {
    let (text, dbc) = exported();
    let nodes: Vec<&str> = dbc.nodes.iter().map(|n| n.0.as_str()).collect();
    for a in Address::all() {
        assert!(nodes.contains(&a.to_string().as_str()), "BU_ lists {a}");
    }
    let mut ids = BTreeSet::new();
    let mut checked = 0;
    for m in MESSAGES {
        for node in Address::all().filter(|a| m.nodes.contains(*a)) {
            let id = identifier(m, node);
            ids.insert(id);
            assert!(
                text.contains(&format!("BO_ {} ", id | 0x8000_0000)),
                "{} {node}: BO_ with bit 31 set",
                m.name
            );
            let bo = message(&dbc, id);
            assert_eq!(bo.id.raw(), id | 0x8000_0000);
            assert!(bo.size >= u64::from(m.dlc), "{}: DLC", bo.name);
            let source = if m.direction == Direction::ToMonitor {
                node
            } else {
                Address::MONITOR
            };
            assert_eq!(bo.transmitter.as_deref(), Some(source.to_string().as_str()));
            assert_eq!(
                uint(dbc.resolved_message_attribute(bo.id, "VFrameFormat")),
                Some(1),
                "{}: ExtendedCAN",
                bo.name
            );
            let signals = active(bo, m.number);
            assert_eq!(
                signals.len(),
                m.fields.len(),
                "{} {node}: one signal per field",
                m.name
            );
            for f in m.fields {
                let s = signal_for(&signals, f.name);
                let what = format!("{} {node} {}", m.name, f.name);
                assert_eq!(
                    (s.start_bit, s.size),
                    (u64::from(f.start_bit), u64::from(f.bits)),
                    "{what}"
                );
                assert_eq!(s.value_type == ValueType::Signed, f.signed, "{what}");
                assert_eq!(
                    (s.factor, s.offset, s.unit.as_str()),
                    (f.scale, f.offset, f.unit),
                    "{what}"
                );
                let table = dbc.value_descriptions_for_signal(bo.id, &s.name).unwrap_or(&[]);
                for (v, label) in f.values {
                    assert!(
                        table
                            .iter()
                            .any(|d| d.id == i64::from(*v) && d.description == *label),
                        "{what}: VAL_ {v} \"{label}\""
                    );
                }
                let receiver = if m.direction == Direction::ToMonitor {
                    Address::MONITOR
                } else {
                    node
                };
                assert_eq!(s.receivers, [receiver.to_string()], "{what}");
                checked += 1;
            }
            // Data0 names the message.
            let d0 = data0(bo);
            let labels = dbc.value_descriptions_for_signal(bo.id, &d0.name).unwrap_or(&[]);
            assert!(
                labels
                    .iter()
                    .any(|d| d.id == i64::from(m.number) && d.description.contains(m.name)),
                "{}: Data0 table names it",
                m.name
            );
        }
    }
    assert_eq!(dbc.messages.len(), ids.len(), "one BO_ per identifier, no more");
    // Two each for E0 and A0 (to and from the monitor), one for each B and C module, two for
    // each of the six flow sensors.
    assert_eq!(ids.len(), 2 + 2 + 8 + 4 + 2 * 6);
    assert!(checked > 200, "{checked} signals checked");
    let names: BTreeSet<&str> = dbc.messages.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names.len(), dbc.messages.len(), "message names are unique");
}

#[test]
fn cycle_times_are_the_node_scripts() {
    let (_, dbc) = exported();
    let h = default_harvester();
    // Expected cycle of every (identifier, message number): the scripts for what field nodes
    // send, the catalogue for what the monitor sends.
    let mut expected: BTreeMap<u32, BTreeMap<u8, u64>> = BTreeMap::new();
    let mut keep = |id: u32, number: u8, ms: u64| {
        let e = expected.entry(id).or_default().entry(number).or_insert(ms);
        *e = (*e).min(ms);
    };
    for script in &h.scripts {
        for send in &script.messages {
            let ms = match send.when {
                When::Periodic { period_ms, .. } => period_ms,
                When::OnChange { heartbeat_ms, .. } => heartbeat_ms,
                When::OnRequest => continue,
            };
            for frame in &send.frames {
                let m = catalogue::by_name(&frame.message).expect("scripts name catalogue messages");
                keep(identifier(m, Address(script.address)), m.number, ms);
            }
        }
    }
    for m in MESSAGES.iter().filter(|m| m.direction == Direction::FromMonitor) {
        if let Some(ms) = m.trigger.cycle_ms() {
            for node in Address::all().filter(|a| m.nodes.contains(*a)) {
                keep(identifier(m, node), m.number, u64::from(ms));
            }
        }
    }
    // Fixed points read off configs/nodes: E0's status every 50 ms, D0's groups every 100 ms and
    // its status at least every 250 ms.
    assert_eq!(expected[&0x0200F5E0][&0x10], 50);
    assert_eq!(expected[&0x0601F5D0][&0x01], 100);
    assert_eq!(expected[&0x0601F5D0][&0x30], 250);

    for bo in &dbc.messages {
        let MessageId::Extended(id) = bo.id else {
            panic!("{}: a base identifier", bo.name)
        };
        let cycles = expected.get(&id);
        let shortest = cycles.and_then(|c| c.values().min().copied());
        assert_eq!(
            uint(dbc.message_attribute(bo.id, "GenMsgCycleTime")),
            shortest,
            "{} GenMsgCycleTime",
            bo.name
        );
        for s in &bo.signals {
            let own = match s.multiplexer_indicator {
                MultiplexIndicator::MultiplexedSignal(n) => cycles.and_then(|c| c.get(&(n as u8)).copied()),
                _ => None,
            };
            assert_eq!(
                uint(dbc.signal_attribute(bo.id, &s.name, "GenSigCycleTime")),
                own,
                "{}.{} GenSigCycleTime",
                bo.name,
                s.name
            );
        }
    }
}

/// What decoding a trace through a DBC gave: frames and signals compared, frames per message,
/// and every signal whose value differs from the catalogue decoder's.
#[derive(Default)]
struct Comparison {
    frames: usize,
    signals: usize,
    kinds: BTreeMap<&'static str, usize>,
    differences: Vec<String>,
}

fn compare(dbc: &Dbc, trace: &[Line]) -> Comparison {
    let mut c = Comparison::default();
    for line in trace {
        let frame = &line.frame;
        let decoded = catalogue::decode(frame)
            .expect("the harvester sends well-formed payloads")
            .unwrap_or_else(|| panic!("{frame:?} is not a catalogue message"));
        let bo = message(dbc, frame.raw_id());
        let data = frame.data();
        let number = raw_value(data, data0(bo)).expect("Data0");
        assert_eq!(number, i64::from(decoded.message.number), "{}: Data0", bo.name);
        let active = active(bo, decoded.message.number);
        assert_eq!(
            active.len(),
            decoded.values.len(),
            "{}: signal count",
            decoded.message.name
        );
        for v in &decoded.values {
            let s = signal_for(&active, v.field.name);
            let raw = raw_value(data, s).unwrap_or_else(|| panic!("{}.{} past the payload", bo.name, s.name));
            let physical = raw as f64 * s.factor + s.offset;
            if raw != v.raw || (physical - v.physical).abs() > 1e-9 * v.physical.abs().max(1.0) {
                c.differences.push(format!(
                    "{} {}: DBC {raw} = {physical}, catalogue {} = {}",
                    decoded.message.name, s.name, v.raw, v.physical
                ));
            }
            c.signals += 1;
        }
        *c.kinds.entry(decoded.message.name).or_default() += 1;
        c.frames += 1;
    }
    c
}

#[test]
fn a_recorded_trace_decodes_through_the_dbc_as_through_the_catalogue() {
    let (text, dbc) = exported();
    let (trace, ()) = run_virtual(
        default_harvester(),
        BusTime::from_millis(60_000),
        |_| {},
        |_, _| (),
    );
    let c = compare(&dbc, &trace);
    assert_eq!(c.differences, Vec::<String>::new());
    assert_eq!(c.frames, trace.len(), "every frame of the trace was compared");
    assert!(c.frames > 20_000, "{} frames", c.frames);
    assert!(c.signals > 3 * c.frames, "{} signals", c.signals);
    // A minute of the default harvester sends every message but the unload command: the
    // periodic traffic, the calibration exchange, acknowledgements and the cruise start at 20 s.
    let missing: Vec<&str> = MESSAGES
        .iter()
        .map(|m| m.name)
        .filter(|n| !c.kinds.contains_key(n))
        .collect();
    assert_eq!(missing, ["speed.unload"], "seen: {:?}", c.kinds);

    // The comparison notices a wrong scale and a wrong sign.
    let wrong = text
        .replace(
            "oil_temperature : 8|16@1- (0.1,0)",
            "oil_temperature : 8|16@1- (0.2,0)",
        )
        .replace("offset : 16|16@1- (1,0)", "offset : 16|16@1+ (1,0)");
    assert_ne!(wrong, text);
    let wrong = compare(&Dbc::try_from(wrong.as_str()).expect("still parses"), &trace);
    let wrong_signals: BTreeSet<&str> = wrong
        .differences
        .iter()
        .filter_map(|d| d.split(':').next()?.split(' ').nth(1))
        .collect();
    assert_eq!(wrong_signals, BTreeSet::from(["oil_temperature", "offset"]));
}
