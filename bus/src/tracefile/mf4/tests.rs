use super::read::nanos;
use super::*;
use crate::Error;
use crate::time::Stamp;
use crate::tracefile::test_items::{data, error, item, remote};
use crate::tracefile::{Entry, Item, ItemWriter};
use std::io::Cursor;

/// 2024-01-01T00:00:00.123456789Z.
const START: u64 = 1_704_067_200_123_456_789;

/// Every kind of item, on two interfaces, at nanosecond times (one before the start).
fn sample() -> Vec<Item> {
    vec![
        item(START - 5, "harv0", data(0x7FF, false, &[9])),
        item(START, "harv0", data(0x123, false, &[1, 2, 3])),
        item(START + 1, "harv0", data(0x1ABC_DEF0, true, &[0xFF; 8])),
        item(START + 2, "harv0", data(0x5, true, &[])),
        item(
            START + 999_999,
            "harv0.D2",
            error(0x04, [0, 0x10, 0, 0, 0, 0, 0x60, 0]),
        ),
        item(START + 1_000_001, "harv0", remote(0x7FF, false, 0)),
        item(START + 2_000_000, "harv0", remote(0x1FFF_FFFF, true, 8)),
        item(START + 2_500_000, "harv0.D2", Entry::Error(None)),
        item(START + 3_000_000, "harv0", data(0, false, &[])),
        item(START + 3_000_007, "harv0.D2", error(0, [0; 8])),
        item(
            START + 3_000_008,
            "harv0.D2",
            error(0x1000_0800, [1, 2, 3, 4, 5, 6, 7, 8]),
        ),
        item(START + 60_000_000_003, "harv0", data(0x100, false, &[0xA5; 8])),
        // 97 days less a nanosecond: the last time kept exactly.
        item(
            START + (1 << 23) * 1_000_000_000 - 1,
            "harv0",
            remote(0x42, false, 3),
        ),
    ]
}

fn write(items: &[Item]) -> Vec<u8> {
    let mut w = Mf4Writer::new(Cursor::new(Vec::new()), Stamp(START)).unwrap();
    for i in items {
        w.write(i).unwrap();
    }
    w.finish().unwrap();
    w.into_inner().into_inner()
}

fn read(file: &[u8]) -> Result<Vec<Item>, Error> {
    let reader = Mf4Reader::new(Cursor::new(file))?;
    let mut items = Vec::new();
    for (n, r) in reader.enumerate() {
        let (number, item) = r?;
        assert_eq!(number, n as u64 + 1);
        items.push(item);
    }
    Ok(items)
}

fn reason(e: Error) -> String {
    match e {
        Error::TraceRecord { format, reason, .. } => {
            assert_eq!(format, "MF4");
            reason
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn what_is_written_reads_back_the_same() {
    let items = sample();
    let file = write(&items);
    assert!(file.starts_with(b"MDF     4.10    harvemu "));
    assert_eq!(read(&file).unwrap(), items);
}

#[test]
fn many_items_cross_data_blocks() {
    let items: Vec<Item> = (0..200_000u64)
        .map(|i| {
            let at = START + i * 137_001 + i % 7;
            let n = (i % 9) as usize;
            let bytes: Vec<u8> = (0..n as u64).map(|k| (i * 31 + k) as u8).collect();
            let entry = match i % 5 {
                0 | 1 => data((i % 0x800) as u32, false, &bytes),
                2 => data((i * 7919) as u32 & 0x1FFF_FFFF, true, &bytes),
                3 => remote((i % 0x800) as u32, false, n),
                _ => error(1 << (i % 9), [i as u8; 8]),
            };
            item(at, if i % 3 == 0 { "harv1" } else { "harv0" }, entry)
        })
        .collect();
    let file = write(&items);
    let dz = file.chunks(8).filter(|c| c.starts_with(b"##DZ")).count();
    assert!(dz >= 5, "{dz} data blocks");
    assert_eq!(read(&file).unwrap(), items);
}

#[test]
fn an_empty_file_reads_as_no_items() {
    assert_eq!(read(&write(&[])).unwrap(), vec![]);
}

#[test]
fn equal_times_come_data_error_remote() {
    let at = START + 10;
    let items = vec![
        item(at, "b", remote(1, false, 1)),
        item(at, "a", Entry::Error(None)),
        item(at, "a", data(2, false, &[1])),
        item(at, "a", data(3, false, &[2])),
    ];
    let back = read(&write(&items)).unwrap();
    assert_eq!(
        back,
        [&items[2], &items[3], &items[1], &items[0]].map(Clone::clone)
    );
}

#[test]
fn finish_twice_is_once_and_items_after_it_are_refused() {
    let mut w = Mf4Writer::new(Cursor::new(Vec::new()), Stamp(START)).unwrap();
    w.write(&sample()[1]).unwrap();
    w.finish().unwrap();
    let once = w.into_inner().into_inner();
    let mut w = Mf4Writer::new(Cursor::new(Vec::new()), Stamp(START)).unwrap();
    w.write(&sample()[1]).unwrap();
    w.finish().unwrap();
    w.finish().unwrap();
    assert!(w.write(&sample()[1]).is_err());
    assert_eq!(w.into_inner().into_inner(), once);
}

#[test]
fn an_unfinished_file_is_refused() {
    let mut w = Mf4Writer::new(Cursor::new(Vec::new()), Stamp(START)).unwrap();
    for i in sample() {
        w.write(&i).unwrap();
    }
    w.flush().unwrap();
    let file = w.into_inner().into_inner();
    assert!(file.starts_with(b"UnFinMF "));
    assert!(reason(read(&file).unwrap_err()).contains("not finalised"));
}

#[test]
fn a_cut_file_is_an_error_at_every_length_never_a_panic() {
    let file = write(&sample());
    for len in 0..file.len() {
        let cut = &file[..len];
        match read(cut) {
            Err(Error::TraceRecord { offset, .. }) => assert!(offset <= len as u64),
            other => panic!("cut at {len}: {other:?}"),
        }
    }
}

/// What reads whole from `file`, in time order, is written again and reads back the same
/// (unless it is `known`, which does).
fn reads_back_the_same(file: &[u8], known: &[Item]) {
    let Ok(items) = read(file) else { return };
    if items == known || items.windows(2).any(|w| w[1].at < w[0].at) {
        return;
    }
    let start = items.first().map_or(Stamp(0), |i| i.at);
    let mut w = Mf4Writer::new(Cursor::new(Vec::new()), start).unwrap();
    for i in &items {
        w.write(i).unwrap();
    }
    w.finish().unwrap();
    let again = w.into_inner().into_inner();
    let span = items.last().map_or(0, |l| l.at.0 - start.0);
    if span < 1 << 52 {
        assert_eq!(read(&again).unwrap(), items);
    }
}

#[test]
fn damaged_bytes_never_panic() {
    let sample = sample();
    let file = write(&sample);
    for at in 0..file.len() {
        for value in [0x00, file[at] ^ 0x01, 0xFF] {
            let mut bad = file.clone();
            bad[at] = value;
            if let Err(Error::TraceRecord { offset, reason, .. }) = read(&bad) {
                assert!(
                    offset <= bad.len() as u64 && reason.len() < 250 && !reason.contains('\n'),
                    "{reason}"
                );
            }
            reads_back_the_same(&bad, &sample);
        }
    }
}

/// The offset of the first block with id `id` (blocks are 8-byte aligned).
fn find(file: &[u8], id: &[u8; 4]) -> usize {
    (0..file.len())
        .step_by(8)
        .find(|&i| file[i..].starts_with(id))
        .unwrap()
}

fn put_u64(file: &mut [u8], at: usize, value: u64) {
    file[at..at + 8].copy_from_slice(&value.to_le_bytes());
}

#[test]
fn a_loop_in_a_list_is_refused() {
    let mut file = write(&sample());
    let cn = find(&file, b"##CN");
    put_u64(&mut file, cn + 24, cn as u64);
    assert!(reason(read(&file).unwrap_err()).contains("a loop"));
}

#[test]
fn a_data_block_inflating_past_the_limit_is_refused() {
    let mut file = write(&sample());
    let dz = find(&file, b"##DZ");
    put_u64(&mut file, dz + 32, MAX_BLOCK + 1);
    let e = read(&file).unwrap_err();
    assert!(reason(e).contains("limit"));
}

#[test]
fn a_link_outside_the_file_is_refused() {
    let mut file = write(&sample());
    let dg = find(&file, b"##DG");
    put_u64(&mut file, dg + 24 + 8, 1 << 40);
    assert!(reason(read(&file).unwrap_err()).contains("outside the file"));
}

#[test]
fn a_can_fd_frame_is_refused() {
    let mut file = write(&[item(START, "harv0", data(1, false, &[1]))]);
    // Its DataLength, in the inflated record: write the record as a DT block instead.
    let dz = find(&file, b"##DZ");
    let record = {
        let mut r = vec![0u8; 25];
        r[15] = 12;
        r
    };
    let mut dt = b"##DT\0\0\0\0".to_vec();
    dt.extend_from_slice(&(24u64 + 25).to_le_bytes());
    dt.extend_from_slice(&0u64.to_le_bytes());
    dt.extend_from_slice(&record);
    file[dz..dz + dt.len()].copy_from_slice(&dt);
    let e = reason(read(&file).unwrap_err());
    assert!(
        e.contains("a CAN FD frame") && e.contains("harvemu is CAN 2.0"),
        "{e}"
    );
}

#[test]
fn seconds_to_nanoseconds_is_exact_for_97_days() {
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    for _ in 0..100_000 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let ns = x % ((1 << 23) * 1_000_000_000);
        let t = ns as f64 / 1e9;
        assert_eq!(nanos(t), Some(i128::from(ns)), "{ns}");
        assert_eq!(nanos(-t), Some(-i128::from(ns)), "-{ns}");
    }
    assert_eq!(nanos(0.0), Some(0));
    assert_eq!(nanos(f64::NAN), None);
    assert_eq!(nanos(1e300), None);
    assert_eq!(nanos(5e-324), Some(0));
}

/// An unsorted data group (one-byte record ids) of a CAN_DataFrame group without bus channel,
/// another group and a VLSD group, its data in two DT blocks of a DL block, split inside a
/// record.
fn unsorted() -> Vec<u8> {
    use super::head::{channel, put, text};
    let mut out = vec![0u8; 64 + 104];
    let name = |out: &mut Vec<u8>, s: &str| put(out, 0, b"TX", &[], &text(s));
    let t = name(&mut out, "time");
    // CAN_DataFrame: t, then ID (u32 at 8), DataLength (u8 at 12), DataBytes (8 at 13).
    let mut next = 0;
    for (member, byte, bits, data_type) in [
        ("DataBytes", 13, 64, BYTE_ARRAY),
        ("DataLength", 12, 8, 0),
        ("ID", 8, 32, 0),
    ] {
        let n = name(&mut out, &format!("CAN_DataFrame.{member}"));
        next = put(
            &mut out,
            0,
            b"CN",
            &[next, 0, n, 0, 0, 0, 0, 0],
            &channel(0, 0, data_type, byte, bits, 0),
        );
    }
    let n = name(&mut out, "CAN_DataFrame");
    let composed = put(
        &mut out,
        0,
        b"CN",
        &[0, next, n, 0, 0, 0, 0, 0],
        &channel(0, 0, BYTE_ARRAY, 8, 13 * 8, 0),
    );
    let master = put(
        &mut out,
        0,
        b"CN",
        &[composed, 0, t, 0, 0, 0, 0, 0],
        &channel(2, 1, FLOAT_LE, 0, 64, 0),
    );
    let cg = |record_id: u64, cycles: u64, flags: u16, bytes: u32| {
        let mut d = record_id.to_le_bytes().to_vec();
        d.extend_from_slice(&cycles.to_le_bytes());
        d.extend_from_slice(&flags.to_le_bytes());
        d.extend_from_slice(&[0; 6]);
        d.extend_from_slice(&bytes.to_le_bytes());
        d.extend_from_slice(&0u32.to_le_bytes());
        d
    };
    let vlsd = put(&mut out, 0, b"CG", &[0, 0, 0, 0, 0, 0], &cg(3, 1, 1, 0));
    let x = name(&mut out, "x");
    let x = put(
        &mut out,
        0,
        b"CN",
        &[0, 0, x, 0, 0, 0, 0, 0],
        &channel(0, 0, 0, 0, 16, 0),
    );
    let other = put(&mut out, 0, b"CG", &[vlsd, x, 0, 0, 0, 0], &cg(2, 1, 0, 2));
    let can = put(&mut out, 0, b"CG", &[other, master, 0, 0, 0, 0], &cg(1, 2, 0, 21));
    let mut records = vec![1u8];
    records.extend_from_slice(&0.5f64.to_le_bytes());
    records.extend_from_slice(&0x123u32.to_le_bytes());
    records.extend_from_slice(&[2, 0xAA, 0xBB, 0, 0, 0, 0, 0, 0]);
    records.extend_from_slice(&[2, 7, 7, 3, 3, 0, 0, 0, b'a', b'b', b'c']);
    records.push(1);
    records.extend_from_slice(&0.75f64.to_le_bytes());
    records.extend_from_slice(&0x8000_0456u32.to_le_bytes());
    records.extend_from_slice(&[1, 0xCC, 0, 0, 0, 0, 0, 0, 0]);
    let (a, b) = records.split_at(40);
    let a = put(&mut out, 0, b"DT", &[], a);
    let b = put(&mut out, 0, b"DT", &[], b);
    let mut dl = vec![0u8; 8];
    dl[4] = 2;
    let dl = put(&mut out, 0, b"DL", &[0, a, b], &dl);
    let dg = put(&mut out, 0, b"DG", &[0, can, dl, 0], &[1, 0, 0, 0, 0, 0, 0, 0]);
    out[..16].copy_from_slice(b"MDF     4.10    ");
    let mut hd = Vec::new();
    put(&mut hd, 0, b"HD", &[dg, 0, 0, 0, 0, 0], &[0; 32]);
    hd[24 + 48..24 + 56].copy_from_slice(&START.to_le_bytes());
    out[64..64 + 104].copy_from_slice(&hd);
    out
}

#[test]
fn an_unsorted_data_group_split_over_blocks_reads() {
    let file = unsorted();
    assert_eq!(
        read(&file).unwrap(),
        vec![
            item(START + 500_000_000, "can0", data(0x123, false, &[0xAA, 0xBB])),
            item(START + 750_000_000, "can0", data(0x456, true, &[0xCC])),
        ]
    );
    // Cut anywhere, it is an error, never a panic.
    for len in 0..file.len() {
        assert!(read(&file[..len]).is_err(), "{len}");
    }
}

/// A record layout of `kind` with a DataLength byte at 0 and 16 DataBytes at 1, no time channel.
fn wide_layout(kind: Kind) -> super::groups::Layout {
    use super::groups::{Field, Fields, Layout, Master};
    let field = |byte, bits, data_type| {
        Some(Field {
            byte,
            bit: 0,
            bits,
            data_type,
        })
    };
    Layout {
        kind,
        what: format!("{} of data group 1", kind.name()),
        data: 0,
        dg: 0,
        id_size: 0,
        record_id: 0,
        others: Vec::new(),
        size: 17,
        cycles: 1,
        master: Master {
            field: None,
            offset: 0.0,
            factor: 1.0,
        },
        fields: Fields {
            length: field(0, 8, UINT_LE),
            bytes: field(1, 128, BYTE_ARRAY),
            ..Fields::default()
        },
    }
}

#[test]
fn a_long_data_length_with_wide_data_bytes_is_refused_or_ignored_never_a_panic() {
    use super::read::decode;
    let mut record = [0x5Au8; 17];
    record[0] = 12;
    // A remote frame's DataLength is its DLC; 12 is no CAN 2.0 DLC, and its bytes are not read.
    let e = decode(&wide_layout(Kind::Remote), &record, 0, Stamp(START), &[]).unwrap_err();
    assert!(e.contains("remote frame"), "{e}");
    record[0] = 3;
    let item = decode(&wide_layout(Kind::Remote), &record, 0, Stamp(START), &[]).unwrap();
    assert_eq!(item.entry, remote(0, false, 3));
    for kind in [Kind::Data, Kind::Error] {
        record[0] = 12;
        let e = decode(&wide_layout(kind), &record, 0, Stamp(START), &[]).unwrap_err();
        assert!(e.contains("a CAN FD frame (12 bytes)"), "{e}");
    }
}
