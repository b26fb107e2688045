//! harvemu's MF4 against asammdf and python-can: asammdf opens what harvemu writes and decodes
//! its frames with a DBC, python-can's `MF4Reader` reads it, and harvemu reads what python-can's
//! `MF4Writer` writes (uncompressed, deflated and transposed, over several data blocks). The
//! python is `$HARVEMU_PYTHON`, else `python3`; it must have python-can and asammdf (the tests
//! fail, never skip, without them). Expected values come from the side that wrote the file.

mod python;

use python::{hex, id, json_lines, run_python};

use bus::Frame;
use bus::filter::CAN_ERR_FLAG;
use bus::time::Stamp;
use bus::trace::ErrorFrame;
use bus::tracefile::mf4::{Mf4Reader, Mf4Writer};
use bus::tracefile::{Entry, Item, ItemWriter};
use std::fs::File;
use std::io::BufWriter;
use std::path::PathBuf;

fn scratch(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("{name}-{}.mf4", std::process::id()))
}

/// 2024-01-01 00:00:00.123456, on a microsecond.
const START: u64 = 1_704_067_200_123_456_000;

fn write_mf4(path: &PathBuf, items: &[Item]) {
    let mut w = Mf4Writer::new(BufWriter::new(File::create(path).unwrap()), Stamp(START)).unwrap();
    for i in items {
        w.write(i).unwrap();
    }
    w.finish().unwrap();
}

/// Items of every kind on two interfaces, a few nanoseconds past whole microseconds.
fn items() -> Vec<Item> {
    // Enough for two data blocks of data frames (1 MiB of 25-byte records each).
    const ITEMS: u64 = 120_000;
    (0..ITEMS)
        .map(|i| {
            let at = START + i * 250_000 + (i % 3) * 97;
            let n = (i % 9) as usize;
            let bytes: Vec<u8> = (0..n as u64).map(|k| (i * 31 + k) as u8).collect();
            let entry = match i % 7 {
                0 => Entry::Frame(Frame::base((i % 0x800) as u16, &bytes).unwrap()),
                1 => Entry::Frame(Frame::extended((i * 7919) as u32 & 0x1FFF_FFFF, &bytes).unwrap()),
                2 => Entry::Frame(Frame::new_remote(id((i % 0x800) as u32, false), n).unwrap()),
                3 => {
                    Entry::Frame(Frame::new_remote(id((i * 104_729) as u32 & 0x1FFF_FFFF, true), n).unwrap())
                }
                4 => Entry::Error(Some(ErrorFrame {
                    can_id: CAN_ERR_FLAG | (1 << (i % 9)),
                    data: [0, 0x10, 0, 0, 0, 0, i as u8, (i >> 8) as u8],
                })),
                5 => Entry::Error(None),
                _ => Entry::Frame(Frame::base(0x7FF, &[0xA5; 8]).unwrap()),
            };
            let interface = if matches!(entry, Entry::Error(_)) && i % 2 == 0 {
                "harv0.D2"
            } else {
                "harv0"
            };
            Item {
                at: Stamp(at),
                interface: interface.to_string(),
                entry,
            }
        })
        .collect()
}

const READ_MF4: &str = r#"
import json, sys, asammdf, can
mdf = asammdf.MDF(sys.argv[1])
groups = {}
for g in mdf.groups:
    names = [c.name for c in g.channels]
    cg = g.channel_group
    groups[names[1]] = {"channels": names, "cycles": cg.cycles_nr, "bus_event": bool(cg.flags & 2),
                        "can": cg.acq_source.bus_type == asammdf.Source.BUS_TYPE_CAN}
print(json.dumps({"groups": groups, "names": mdf.header._common_properties.get("bus channels"),
                  "start": round(mdf.header.start_time.timestamp() * 1e6)}))
mdf.close()
for m in can.MF4Reader(sys.argv[1]):
    print(json.dumps({
        "t": round(m.timestamp * 1e6), "id": m.arbitration_id, "ext": m.is_extended_id,
        "rtr": m.is_remote_frame, "err": m.is_error_frame, "dlc": m.dlc,
        "data": bytes(m.data).hex(), "ch": m.channel,
    }))
"#;

#[test]
fn asammdf_and_python_can_read_what_harvemu_writes() {
    let items = items();
    let path = scratch("harvemu-written");
    write_mf4(&path, &items);
    let file = std::fs::read(&path).unwrap();
    let dz = file.chunks(8).filter(|c| c.starts_with(b"##DZ")).count();
    assert!(dz >= 4, "{dz} data blocks");
    let out = run_python("can, asammdf", READ_MF4, &[path.to_str().unwrap()]);
    let lines = json_lines(&out);
    let (head, messages) = lines.split_first().expect("a first line");
    assert_eq!(head["start"], START / 1000);
    let count = |f: fn(&Entry) -> bool| items.iter().filter(|i| f(&i.entry)).count();
    let kinds = [
        (
            "CAN_DataFrame",
            count(|e| matches!(e, Entry::Frame(f) if !f.is_remote())),
        ),
        ("CAN_ErrorFrame", count(|e| matches!(e, Entry::Error(_)))),
        (
            "CAN_RemoteFrame",
            count(|e| matches!(e, Entry::Frame(f) if f.is_remote())),
        ),
    ];
    for (name, n) in kinds {
        let g = &head["groups"][name];
        assert_eq!(g["cycles"], n as u64, "{name}: {g}");
        assert_eq!(g["bus_event"], true, "{name}");
        assert_eq!(g["can"], true, "{name}");
        for member in ["BusChannel", "ID", "IDE", "DLC", "DataLength", "Dir"] {
            let full = format!("{name}.{member}");
            assert!(
                g["channels"].as_array().unwrap().iter().any(|c| c == &full),
                "{full}"
            );
        }
    }
    assert_eq!(head["names"], serde_json::json!({"1": "harv0", "2": "harv0.D2"}));
    assert_eq!(messages.len(), items.len());
    for (item, m) in items.iter().zip(messages) {
        let at = item.at.as_nanos();
        assert_eq!(m["t"], (at + 500) / 1000, "{m} for {item:?}");
        let ch = if item.interface == "harv0" { 1 } else { 2 };
        assert_eq!(m["ch"], ch, "{m}");
        let (raw, ext, rtr, err, dlc, data) = match &item.entry {
            Entry::Frame(f) => (
                f.raw_id(),
                f.is_extended(),
                f.is_remote(),
                false,
                f.dlc(),
                hex(f.data()),
            ),
            Entry::Error(Some(e)) => (e.can_id & 0x1FFF_FFFF, false, false, true, 8, hex(&e.data)),
            Entry::Error(None) => (0, false, false, true, 0, String::new()),
        };
        assert_eq!(
            (&m["id"], &m["ext"], &m["rtr"], &m["err"], &m["dlc"], &m["data"]),
            (
                &raw.into(),
                &ext.into(),
                &rtr.into(),
                &err.into(),
                &dlc.into(),
                &data.into()
            ),
            "{m} for {item:?}"
        );
    }
    std::fs::remove_file(&path).unwrap();
}

/// The DBC's message and signals: id 0x101 extended, an unsigned 16-bit and a signed 8-bit
/// signal with their factor and offset.
const SPEED: (f64, f64) = (0.5, -10.0);
const TEMP: (f64, f64) = (2.0, 5.0);

fn dbc() -> String {
    format!(
        "VERSION \"\"\n\nNS_ :\n\nBS_:\n\nBU_: N\n\n\
         BO_ 2147483905 M: 8 N\n \
         SG_ Speed : 0|16@1+ ({}, {}) [-100|1000] \"km/h\" N\n \
         SG_ Temp : 16|8@1- ({}, {}) [-300|300] \"C\" N\n\n",
        SPEED.0, SPEED.1, TEMP.0, TEMP.1
    )
}

const EXTRACT: &str = r#"
import json, sys, asammdf
mdf = asammdf.MDF(sys.argv[1])
out = mdf.extract_bus_logging({"CAN": [(sys.argv[2], 0)]})
for name in ("Speed", "Temp"):
    # One channel group per bus: "CAN1 message ID=0x101 EXT=True".
    samples = []
    for group, index in out.channels_db[name]:
        bus = int(out.groups[group].channel_group.acq_name.split()[0][3:])
        s = out.get(name, group=group, index=index)
        samples += [(round(t * 1e6), bus, v) for t, v in zip(s.timestamps, s.samples.tolist())]
    samples.sort()
    print(json.dumps({"name": name, "samples": samples}))
"#;

#[test]
fn asammdf_decodes_harvemu_frames_with_a_dbc() {
    let mut items = Vec::new();
    let mut expected = Vec::new();
    for i in 0..300u64 {
        let at = START + i * 1_000_000 + 3;
        let speed = 1000 + 7 * i as u16;
        let temp = (i % 100) as i8 - 50;
        let mut data = [0u8; 8];
        data[..2].copy_from_slice(&speed.to_le_bytes());
        data[2] = temp as u8;
        let frame = match i % 3 {
            0 => {
                // Bus channels: harv0 is 1, harv1 2 (first seen first).
                expected.push((i * 1000, 1 + i % 2, speed, temp));
                Frame::extended(0x101, &data).unwrap()
            }
            // The same number as a base id, and another id: not the DBC's message.
            1 => Frame::base(0x101, &data).unwrap(),
            _ => Frame::extended(0x102, &data).unwrap(),
        };
        let interface = if i % 2 == 0 { "harv0" } else { "harv1" };
        items.push(Item {
            at: Stamp(at),
            interface: interface.into(),
            entry: Entry::Frame(frame),
        });
    }
    let path = scratch("dbc");
    let dbc_path = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("mf4-{}.dbc", std::process::id()));
    std::fs::write(&dbc_path, dbc()).unwrap();
    write_mf4(&path, &items);
    let out = run_python(
        "can, asammdf",
        EXTRACT,
        &[path.to_str().unwrap(), dbc_path.to_str().unwrap()],
    );
    let signals = json_lines(&out);
    assert_eq!(signals.len(), 2);
    for s in &signals {
        let samples = s["samples"].as_array().unwrap();
        assert_eq!(samples.len(), expected.len(), "{}", s["name"]);
        for ((us, bus, speed, temp), sample) in expected.iter().zip(samples) {
            assert_eq!(
                (&sample[0], &sample[1]),
                (&(*us).into(), &(*bus).into()),
                "{}",
                s["name"]
            );
            let want = if s["name"] == "Speed" {
                f64::from(*speed) * SPEED.0 + SPEED.1
            } else {
                f64::from(*temp) * TEMP.0 + TEMP.1
            };
            assert_eq!(sample[2].as_f64().unwrap(), want, "{} at {us} µs", s["name"]);
        }
    }
    std::fs::remove_file(&path).unwrap();
    std::fs::remove_file(&dbc_path).unwrap();
}

/// Writes with python-can's MF4Writer at each compression level, small data blocks so that
/// there are several; prints every message as written.
const WRITE_MF4: &str = r#"
import json, sys, asammdf, can
from can.util import channel2int
asammdf.set_global_option("write_fragment_size", 16384)
messages = []
for i in range(1500):
    t = 1700000000.0 + i * 0.00025
    ch = [0, 1, "can2"][i % 3]
    n = i % 9
    data = bytes((i * 13 + k) % 256 for k in range(n))
    kind = i % 6
    if kind == 0:
        m = can.Message(timestamp=t, arbitration_id=i % 0x800, is_extended_id=False, data=data, channel=ch)
    elif kind == 1:
        m = can.Message(timestamp=t, arbitration_id=(i * 7919) % 0x20000000, is_extended_id=True, data=data, channel=ch)
    elif kind == 2:
        m = can.Message(timestamp=t, arbitration_id=i % 0x800, is_extended_id=False, is_remote_frame=True, dlc=n, channel=ch)
    elif kind == 3:
        m = can.Message(timestamp=t, arbitration_id=i * 3, is_extended_id=True, is_remote_frame=True, dlc=n, channel=ch)
    elif kind == 4:
        m = can.Message(timestamp=t, arbitration_id=1 << (i % 9), is_extended_id=False, is_error_frame=True,
                        data=bytes([0, 0x10, 0, 0, 0, 0, i % 256, 7]), channel=ch)
    else:
        m = can.Message(timestamp=t, arbitration_id=0, is_extended_id=False, is_error_frame=True, channel=ch)
    messages.append(m)
for level in range(3):
    w = can.MF4Writer(sys.argv[1] + str(level), compression_level=level)
    for m in messages:
        w.on_message_received(m)
    w.stop()
for m in messages:
    print(json.dumps({
        "t": round(m.timestamp * 1e6), "id": m.arbitration_id, "ext": m.is_extended_id,
        "rtr": m.is_remote_frame, "err": m.is_error_frame, "dlc": m.dlc,
        "data": bytes(m.data).hex(), "ch": channel2int(m.channel),
    }))
"#;

#[test]
fn harvemu_reads_what_python_can_writes() {
    let path = scratch("python-can-written");
    let out = run_python("can, asammdf", WRITE_MF4, &[path.to_str().unwrap()]);
    let written = json_lines(&out);
    assert_eq!(written.len(), 1500);
    for level in 0..3 {
        let file = PathBuf::from(format!("{}{level}", path.display()));
        let reader = Mf4Reader::new(File::open(&file).unwrap()).unwrap();
        let read: Vec<Item> = reader.map(|r| r.unwrap().1).collect();
        assert_eq!(read.len(), written.len(), "compression level {level}");
        for (m, item) in written.iter().zip(&read) {
            let at = item.at.as_nanos();
            assert_eq!(m["t"], (at + 500) / 1000, "level {level}: {m} read as {item:?}");
            assert_eq!(item.interface, format!("can{}", m["ch"]), "{m}");
            let id = m["id"].as_u64().unwrap() as u32;
            let data = m["data"].as_str().unwrap();
            match &item.entry {
                Entry::Frame(f) => {
                    assert_eq!(m["err"], false, "{m} read as {item:?}");
                    assert_eq!(
                        (
                            f.raw_id(),
                            f.is_extended(),
                            f.is_remote(),
                            u64::from(f.dlc()),
                            hex(f.data())
                        ),
                        (
                            id,
                            m["ext"].as_bool().unwrap(),
                            m["rtr"].as_bool().unwrap(),
                            m["dlc"].as_u64().unwrap(),
                            data.to_string()
                        ),
                        "{m} read as {item:?}"
                    );
                }
                Entry::Error(Some(e)) => {
                    assert_eq!(m["err"], true, "{m}");
                    assert_eq!(
                        (e.can_id, hex(&e.data)),
                        (CAN_ERR_FLAG | id, data.to_string()),
                        "{m}"
                    );
                }
                Entry::Error(None) => {
                    assert_eq!((&m["err"], id, data), (&true.into(), 0, ""), "{m}");
                }
            }
        }
        std::fs::remove_file(&file).unwrap();
    }
}
