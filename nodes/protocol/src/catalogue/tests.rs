use super::*;
use bus::bits::{BitRate, worst_case_bits};
use bus::candump::parse_frame;
use proptest::prelude::*;

/// The six frames of a flow group worked through in the harvester's source documents, as printed there.
const SEED_D0: [&str; 6] = [
    "200D0002FFBFFF00",
    "0101000000000000",
    "0200000000906EFF",
    "200E0002FFBEFF00",
    "0101341EEA2BEF2C",
    "028921982C44D46E",
];

fn seed_frame(i: usize) -> Frame {
    parse_frame(&format!("0601F5D0#{}", SEED_D0[i])).unwrap()
}

/// Unit values read straight from the seed's byte positions (1-based bytes 3–4, 5–6, 7–8 of the
/// second frame, 2–3, 4–5 of the third), low byte first.
fn seed_units(part1: &[u8], part2: &[u8]) -> [i64; 5] {
    let le = |d: &[u8], one_based: usize| i64::from(d[one_based - 1]) | i64::from(d[one_based]) << 8;
    [
        le(part1, 3),
        le(part1, 5),
        le(part1, 7),
        le(part2, 2),
        le(part2, 4),
    ]
}

#[test]
fn seed_frames_decode() {
    let names: Vec<&str> = (0..6)
        .map(|i| decode(&seed_frame(i)).unwrap().unwrap().message.name)
        .collect();
    assert_eq!(
        names,
        [
            "flow.marker_flow",
            "flow.part1",
            "flow.part2",
            "flow.marker_reference",
            "flow.part1",
            "flow.part2"
        ]
    );
    let (p1, p2) = (
        decode(&seed_frame(4)).unwrap().unwrap(),
        decode(&seed_frame(5)).unwrap().unwrap(),
    );
    assert_eq!(p1.node, Address::flow_sensor(0));
    let got = [
        p1.get("unit1").unwrap().raw,
        p1.get("unit2").unwrap().raw,
        p1.get("unit3").unwrap().raw,
        p2.get("unit4").unwrap().raw,
        p2.get("unit5").unwrap().raw,
    ];
    assert_eq!(got, seed_units(seed_frame(4).data(), seed_frame(5).data()));
    // The values the source documents state for frames 5–6.
    assert_eq!(got, [0x1E34, 0x2BEA, 0x2CEF, 0x2189, 0x2C98]);
    let flow = decode(&seed_frame(1)).unwrap().unwrap();
    assert!(
        flow.values[1..].iter().all(|v| v.raw == 0),
        "no cotton in the seed's flow group"
    );
}

#[test]
fn seed_frames_encode_byte_for_byte() {
    let d0 = Address::flow_sensor(0);
    let encode = |name: &str, values: &[(&str, f64)]| {
        by_name(name)
            .unwrap()
            .encode(d0, |f| values.iter().find(|(n, _)| *n == f).map(|(_, v)| *v))
            .unwrap()
    };
    let units = |u: [i64; 5], aux: u32| {
        let p1 = encode(
            "flow.part1",
            &[
                ("status", 1.0),
                ("unit1", u[0] as f64),
                ("unit2", u[1] as f64),
                ("unit3", u[2] as f64),
            ],
        );
        let p2 = encode(
            "flow.part2",
            &[
                ("unit4", u[3] as f64),
                ("unit5", u[4] as f64),
                ("aux", f64::from(aux)),
            ],
        );
        (p1, p2)
    };
    assert_eq!(encode("flow.marker_flow", &[]), seed_frame(0));
    assert_eq!(encode("flow.marker_reference", &[]), seed_frame(3));
    let (p1, p2) = units([0; 5], 0xFF6E90);
    assert_eq!((p1, p2), (seed_frame(1), seed_frame(2)));
    let (p1, p2) = units(seed_units(seed_frame(4).data(), seed_frame(5).data()), 0x6ED444);
    assert_eq!((p1, p2), (seed_frame(4), seed_frame(5)));
}

#[test]
fn seed_row_alignment_command() {
    let m = by_name("row.command").unwrap();
    assert_eq!(m.app_id(Address::ROW_ALIGNMENT).raw(), 0x0300A0F5);
    assert_eq!(
        by_name("row.status")
            .unwrap()
            .app_id(Address::ROW_ALIGNMENT)
            .raw(),
        0x0300F5A0
    );
    let f = parse_frame("0300A0F5#0101").unwrap();
    let d = decode(&f).unwrap().unwrap();
    assert_eq!(
        (d.message.name, d.values[0].label()),
        ("row.command", Some("start auto alignment"))
    );
}

#[test]
fn payload_errors_are_named() {
    let short = parse_frame("0601F5D0#200D0002FFBFFF").unwrap();
    let err = decode(&short).unwrap_err();
    assert!(
        err.to_string().contains("flow.marker_flow") && err.to_string().contains("DLC"),
        "{err}"
    );
    let bent = parse_frame("0601F5D0#200D0003FFBFFF00").unwrap();
    assert!(
        decode(&bent)
            .unwrap_err()
            .to_string()
            .contains("frames_following")
    );
    // Not harvester traffic at all: no message, no error.
    assert_eq!(decode(&parse_frame("123#0102").unwrap()), Ok(None));
    assert_eq!(decode(&parse_frame("0601F5D0#7F").unwrap()), Ok(None));
    // Out of range values are refused on encode.
    let e = by_name("speed.setpoint")
        .unwrap()
        .encode(Address::SPEED_CONTROL, |_| Some(13.0));
    assert!(e.unwrap_err().to_string().contains("setpoint = 13"));
    let e = by_name("speed.setpoint")
        .unwrap()
        .encode(Address::flow_sensor(1), |_| Some(1.0));
    assert!(e.is_err(), "D1 does not take speed set-points");
}

#[test]
fn table_is_consistent() {
    let mut names: Vec<&str> = MESSAGES.iter().map(|m| m.name).collect();
    names.sort();
    names.dedup();
    assert_eq!(names.len(), MESSAGES.len(), "message names are unique");
    for m in MESSAGES {
        assert!((1..=8).contains(&m.dlc), "{}", m.name);
        if let Nodes::One(a) = m.nodes {
            assert!(a.kind().is_some(), "{} names unknown node {a}", m.name);
        }
        assert_eq!(Some(m.priority()), m.nodes.kind().priority(), "{}", m.name);
        let expected_type = if m.nodes.kind() == NodeKind::FlowSensor {
            FrameType::PointToPoint
        } else {
            FrameType::Broadcast
        };
        assert_eq!(
            m.frame_type, expected_type,
            "{}: only flow sensor traffic is point-to-point",
            m.name
        );
        let mut used = [false; 64];
        used[..8].fill(true); // Data0
        let mut fnames = Vec::new();
        for f in m.fields {
            assert!(f.start_bit >= 8, "{}.{} overlaps Data0", m.name, f.name);
            for bit in f.start_bit..f.start_bit + f.bits {
                assert!(
                    usize::from(bit) < 8 * usize::from(m.dlc),
                    "{}.{} is past the DLC",
                    m.name,
                    f.name
                );
                assert!(
                    !used[usize::from(bit)],
                    "{}.{} overlaps another field",
                    m.name,
                    f.name
                );
                used[usize::from(bit)] = true;
            }
            assert!(f.min <= f.max, "{}.{}", m.name, f.name);
            if f.constant.is_none() {
                assert!(
                    f.to_raw(f.min).is_some() && f.to_raw(f.max).is_some(),
                    "{}.{} range not representable",
                    m.name,
                    f.name
                );
            }
            fnames.push(f.name);
        }
        let n = fnames.len();
        fnames.sort();
        fnames.dedup();
        assert_eq!(fnames.len(), n, "{}: field names are unique", m.name);
    }
}

fn mid_values(m: &MessageDef) -> impl Fn(&str) -> Option<f64> + '_ {
    move |name| {
        m.field(name)
            .map(|f| f.physical(f.to_raw((f.min + f.max) / 2.0).unwrap_or(0)))
    }
}

#[test]
fn every_message_is_found_again_for_every_node() {
    for m in MESSAGES {
        for node in Address::all().filter(|a| m.nodes.contains(*a)) {
            let frame = m.encode(node, mid_values(m)).unwrap();
            let d = decode(&frame)
                .unwrap()
                .unwrap_or_else(|| panic!("{} from {node} not found", m.name));
            assert_eq!((d.message.name, d.node), (m.name, node));
            assert!(d.values.iter().all(|v| v.in_range()), "{}", m.name);
            // `Values` holds this many inline: decoding the catalogue does not allocate.
            assert!(!d.values.spilled(), "{} has {} fields", m.name, d.values.len());
        }
    }
}

#[test]
fn nominal_bus_load_is_under_half() {
    // Worst-case frame lengths of all periodic traffic, plus one acknowledgement per group.
    let mut bits_per_second = 0.0;
    for m in MESSAGES {
        let Some(period) = m.trigger.cycle_ms() else {
            continue;
        };
        for node in Address::all().filter(|a| m.nodes.contains(*a)) {
            let frame = m.encode(node, mid_values(m)).unwrap();
            bits_per_second += f64::from(worst_case_bits(&frame)) * 1000.0 / f64::from(period);
        }
    }
    let ack = by_name("flow.ack")
        .unwrap()
        .encode(Address::flow_sensor(0), |_| Some(13.0))
        .unwrap();
    bits_per_second += 6.0 * 2.0 * 10.0 * f64::from(worst_case_bits(&ack));
    let load = bits_per_second / f64::from(BitRate::K250.bits_per_second());
    assert!(load < 0.5, "nominal load {load}");
}

#[test]
fn protocol_doc_names_every_message() {
    let doc = include_str!("../../../../docs/PROTOCOL.md");
    let generated = super::doc::markdown();
    assert!(
        doc.contains(&generated),
        "the catalogue section of docs/PROTOCOL.md is stale: regenerate it with `cargo run -- protocol --markdown`"
    );
    for m in MESSAGES {
        assert!(
            doc.contains(&format!("`{}`", m.name)),
            "docs/PROTOCOL.md lacks {}",
            m.name
        );
        for f in m.fields {
            assert!(
                doc.contains(f.name),
                "docs/PROTOCOL.md lacks {}.{}",
                m.name,
                f.name
            );
        }
    }
}

proptest! {
    #[test]
    fn fields_round_trip(index in 0..MESSAGES.len(), node_pick in 0usize..8, seed in any::<[u64; 8]>()) {
        let m = &MESSAGES[index];
        let nodes: Vec<Address> = Address::all().filter(|a| m.nodes.contains(*a)).collect();
        let node = nodes[node_pick % nodes.len()];
        // A random valid raw value per field, chosen within the field's valid range.
        let raws: Vec<i64> = m.fields.iter().enumerate().map(|(i, f)| {
            let lo = f.to_raw(f.min).unwrap_or(0);
            let hi = f.to_raw(f.max).unwrap_or(lo);
            lo + (seed[i % 8] % (hi - lo + 1) as u64) as i64
        }).collect();
        let frame = m.encode(node, |name| {
            m.fields.iter().position(|f| f.name == name).map(|i| m.fields[i].physical(raws[i]))
        }).unwrap();
        let d = decode(&frame).unwrap().unwrap();
        let got: Vec<i64> = d.values.iter().map(|v| v.raw).collect();
        prop_assert_eq!(got, raws);
        // And the raw bits are where the table says, read with an independent little-endian read.
        for (f, v) in m.fields.iter().zip(&d.values) {
            let mut word = 0u64;
            for (i, b) in frame.data().iter().enumerate() { word |= u64::from(*b) << (8 * i); }
            let bits = (word >> f.start_bit) & ((1 << f.bits) - 1);
            prop_assert_eq!(bits, (v.raw as u64) & ((1 << f.bits) - 1));
        }
    }
}
