//! harvemu's BLF against python-can's `BLFReader` and `BLFWriter`: what one writes, the other
//! reads. The python is `$HARVEMU_PYTHON`, else `python3`; it must have python-can (the tests
//! fail, never skip, without it). Expected values come from the side that wrote the file.

mod python;

use python::{hex, id, json_lines, run_python};

use bus::Frame;
use bus::filter::CAN_ERR_FLAG;
use bus::time::Stamp;
use bus::trace::ErrorFrame;
use bus::tracefile::blf::{BlfReader, BlfWriter};
use bus::tracefile::{Entry, Item, ItemWriter};
use std::path::PathBuf;

fn scratch(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("{name}-{}.blf", std::process::id()))
}

/// A few thousand items of every kind on two interfaces, at whole microseconds and (every
/// third) a few nanoseconds past, over more than one 128 KiB container.
fn items() -> Vec<Item> {
    // 2024-01-01 00:00:00.123456: not on a millisecond.
    let start = 1_704_067_200_123_456_000u64;
    (0..3000u64)
        .map(|i| {
            let at = start + i * 250_000 + if i.is_multiple_of(3) { 1 + i % 997 } else { 0 };
            let n = (i % 9) as usize;
            let bytes: Vec<u8> = (0..n as u64).map(|k| (i * 31 + k) as u8).collect();
            let entry = match i % 7 {
                0 => Entry::Frame(Frame::base((i % 0x800) as u16, &bytes).unwrap()),
                1 => Entry::Frame(Frame::extended((i * 7919) as u32 & 0x1FFF_FFFF, &bytes).unwrap()),
                2 => Entry::Frame(Frame::new_remote(id((i % 0x800) as u32, false), n).unwrap()),
                3 => Entry::Frame(Frame::new_remote(id(i as u32 * 104_729, true), n).unwrap()),
                4 => Entry::Error(Some(ErrorFrame {
                    can_id: CAN_ERR_FLAG | (1 << (i % 9)),
                    data: [0, 0x10, 0, 0, 0, 0, i as u8, (i >> 8) as u8],
                })),
                5 => Entry::Error(None),
                _ => Entry::Frame(Frame::base(0x7FF, &[0xA5; 8]).unwrap()),
            };
            let interface = if matches!(entry, Entry::Error(_)) && i.is_multiple_of(2) {
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

const READ_BLF: &str = r#"
import json, sys, can
for m in can.BLFReader(sys.argv[1]):
    print(json.dumps({
        "t": round(m.timestamp * 1e6), "id": m.arbitration_id, "ext": m.is_extended_id,
        "rtr": m.is_remote_frame, "err": m.is_error_frame, "dlc": m.dlc,
        "data": bytes(m.data).hex(), "ch": m.channel,
    }))
"#;

#[test]
fn python_can_reads_what_harvemu_writes() {
    let items = items();
    let path = scratch("harvemu-written");
    let file = std::fs::File::create(&path).unwrap();
    let mut w = BlfWriter::new(file, items[0].at).unwrap();
    for item in &items {
        w.write(item).unwrap();
    }
    w.finish().unwrap();
    drop(w);
    assert!(std::fs::metadata(&path).unwrap().len() > 144);

    let got = json_lines(&run_python("can", READ_BLF, &[path.to_str().unwrap()]));
    assert_eq!(got.len(), items.len(), "python-can read {} messages", got.len());
    let mut interfaces: Vec<&str> = Vec::new();
    for (i, (item, m)) in items.iter().zip(&got).enumerate() {
        // Channels: numbered by first sight from BLF channel 1, python-can's channel 0.
        let channel = match interfaces.iter().position(|n| *n == item.interface) {
            Some(c) => c,
            None => {
                interfaces.push(&item.interface);
                interfaces.len() - 1
            }
        };
        assert_eq!(m["ch"], channel, "{i}: {m}");
        let us = m["t"].as_i64().unwrap();
        let ns = item.at.0 as i64;
        if ns % 1000 == 0 {
            assert_eq!(us * 1000, ns, "{i}: {m}");
        } else {
            assert!((us * 1000 - ns).abs() < 1000, "{i}: {m} vs {ns} ns");
        }
        match &item.entry {
            Entry::Frame(f) => {
                assert_eq!(m["err"], false, "{i}: {m}");
                assert_eq!(m["id"], f.raw_id(), "{i}: {m}");
                assert_eq!(m["ext"], f.is_extended(), "{i}: {m}");
                assert_eq!(m["rtr"], f.is_remote(), "{i}: {m}");
                assert_eq!(m["dlc"], f.dlc(), "{i}: {m}");
                if !f.is_remote() {
                    assert_eq!(m["data"], hex(f.data()), "{i}: {m}");
                }
            }
            Entry::Error(Some(e)) => {
                // As python-can's socketcan backend gives an error frame.
                assert_eq!(m["err"], true, "{i}: {m}");
                assert_eq!(m["id"], e.can_id & 0x1FFF_FFFF, "{i}: {m}");
                assert_eq!(m["dlc"], 8, "{i}: {m}");
                assert_eq!(m["data"], hex(&e.data), "{i}: {m}");
            }
            Entry::Error(None) => {
                assert_eq!(m["err"], true, "{i}: {m}");
                assert_eq!(
                    (&m["id"], &m["dlc"], &m["data"]),
                    (&0.into(), &0.into(), &"".into()),
                    "{i}: {m}"
                );
            }
        }
    }
    let _ = std::fs::remove_file(&path);
}

const WRITE_BLF: &str = r#"
import json, sys, can
# Small containers, so that many objects go on in the next one.
w = can.BLFWriter(sys.argv[1], max_container_size=1000)
t0 = 1704067200.5
for i in range(600):
    ts = t0 + i * 0.000731 + (i % 10) * 1e-6
    ch = i % 2
    n = i % 9
    kind = i % 5
    if kind == 0:
        m = can.Message(timestamp=ts, arbitration_id=i % 0x800, is_extended_id=False,
                        data=bytes((i + k) % 256 for k in range(n)), channel=ch)
    elif kind == 1:
        m = can.Message(timestamp=ts, arbitration_id=(i * 7919) % 0x20000000, is_extended_id=True,
                        data=bytes((i * 3 + k) % 256 for k in range(8)), channel=ch)
    elif kind == 2:
        m = can.Message(timestamp=ts, arbitration_id=i % 0x800, is_extended_id=False,
                        is_remote_frame=True, dlc=n, channel=ch)
    elif kind == 3:
        m = can.Message(timestamp=ts, arbitration_id=(i * 104729) % 0x20000000, is_extended_id=True,
                        is_remote_frame=True, dlc=n, channel=ch)
    else:
        m = can.Message(timestamp=ts, is_error_frame=True, arbitration_id=0x4 | (i % 3),
                        is_extended_id=False, dlc=8, data=bytes([0, 0x10, 0, 0, 0, 0, i % 256, 0]),
                        channel=ch)
    w.on_message_received(m)
    print(json.dumps({
        "t": round(ts * 1e6), "id": m.arbitration_id, "ext": m.is_extended_id,
        "rtr": m.is_remote_frame, "err": m.is_error_frame, "dlc": m.dlc,
        "data": bytes(m.data).hex(), "ch": ch,
    }))
w.stop()
"#;

#[test]
fn harvemu_reads_what_python_can_writes() {
    let path = scratch("python-written");
    let wrote = json_lines(&run_python("can", WRITE_BLF, &[path.to_str().unwrap()]));
    assert_eq!(wrote.len(), 600);
    let file = std::io::BufReader::new(std::fs::File::open(&path).unwrap());
    let read: Vec<(u64, Item)> = BlfReader::new(file).unwrap().collect::<Result<_, _>>().unwrap();
    assert_eq!(read.len(), wrote.len());
    for (i, (m, (number, item))) in wrote.iter().zip(&read).enumerate() {
        assert_eq!(*number, i as u64 + 1);
        assert_eq!(item.interface, format!("can{}", m["ch"]), "{i}: {m}");
        let us = m["t"].as_i64().unwrap();
        assert!(
            (item.at.0 as i64 - us * 1000).abs() < 1000,
            "{i}: {m} vs {} ns",
            item.at.0
        );
        let raw = m["id"].as_u64().unwrap() as u32;
        let dlc = m["dlc"].as_u64().unwrap() as usize;
        let data: Vec<u8> = (0..m["data"].as_str().unwrap().len() / 2)
            .map(|k| u8::from_str_radix(&m["data"].as_str().unwrap()[2 * k..2 * k + 2], 16).unwrap())
            .collect();
        let expected = if m["err"] == true {
            let mut details = [0u8; 8];
            details.copy_from_slice(&data);
            Entry::Error(Some(ErrorFrame {
                can_id: CAN_ERR_FLAG | raw,
                data: details,
            }))
        } else if m["rtr"] == true {
            Entry::Frame(Frame::new_remote(id(raw, m["ext"] == true), dlc).unwrap())
        } else {
            Entry::Frame(Frame::new_data(id(raw, m["ext"] == true), &data).unwrap())
        };
        assert_eq!(item.entry, expected, "{i}: {m}");
    }
    let _ = std::fs::remove_file(&path);
}
