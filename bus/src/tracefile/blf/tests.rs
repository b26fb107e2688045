use super::*;
use crate::Error;
use crate::tracefile::test_items::{data, error, item, remote};
use crate::tracefile::{Entry, Item, ItemWriter};
use std::io::{Cursor, Write};

/// 2024-01-01T00:00:00Z, a Monday.
const NEW_YEAR: u64 = 1_704_067_200_000_000_000;

/// Every kind of item on two interfaces, with nanoseconds, from a start 0.123456789 s past a
/// whole second (not on a millisecond).
fn sample(start: u64) -> Vec<Item> {
    vec![
        item(start, "harv0", data(0x123, false, &[1, 2, 3])),
        item(start + 1, "harv0", data(0x1ABC_DEF0, true, &[0xFF; 8])),
        item(
            start + 999_999,
            "harv0.D2",
            error(0x04, [0, 0x10, 0, 0, 0, 0, 0x60, 0]),
        ),
        item(start + 1_000_001, "harv0", remote(0x7FF, false, 0)),
        item(start + 2_000_000, "harv0", remote(0x1FFF_FFFF, true, 8)),
        item(start + 2_500_000, "harv0.D2", Entry::Error(None)),
        item(start + 3_000_000, "harv0", data(0, false, &[])),
        item(start + 3_000_007, "harv0.D2", error(0, [0; 8])),
        item(
            start + 60_000_000_003,
            "harv0",
            data(0x42, true, &[9, 8, 7, 6, 5]),
        ),
    ]
}

fn write_all(start: Stamp, items: &[Item], flush_every: usize) -> Vec<u8> {
    let mut w = BlfWriter::new(Cursor::new(Vec::new()), start).unwrap();
    for (i, it) in items.iter().enumerate() {
        w.write(it).unwrap();
        if flush_every > 0 && (i + 1).is_multiple_of(flush_every) {
            w.flush().unwrap();
        }
    }
    w.finish().unwrap();
    w.into_inner().into_inner()
}

fn read_all(bytes: &[u8]) -> Result<Vec<(u64, Item)>, Error> {
    BlfReader::new(bytes)?.collect()
}

fn items_of(bytes: &[u8]) -> Vec<Item> {
    read_all(bytes).unwrap().into_iter().map(|(_, i)| i).collect()
}

#[test]
fn items_come_back_as_written() {
    let start = NEW_YEAR + 123_456_789;
    let items = sample(start);
    let bytes = write_all(Stamp(start), &items, 0);
    let read = read_all(&bytes).unwrap();
    assert_eq!(read.iter().map(|(_, i)| i.clone()).collect::<Vec<_>>(), items);
    // Numbers count every object: the two channel names come before their first frames.
    let numbers: Vec<u64> = read.iter().map(|(n, _)| *n).collect();
    assert_eq!(numbers, [2, 3, 5, 6, 7, 8, 9, 10, 11]);
    let reader = BlfReader::new(&bytes[..]).unwrap();
    assert_eq!(reader.start(), Stamp(NEW_YEAR + 123_000_000));
}

#[test]
fn many_items_span_containers_and_flushes_change_nothing() {
    let start = NEW_YEAR + 5;
    let mut items = Vec::new();
    for i in 0..12_000u64 {
        let sample = sample(start + i * 1_000_003);
        items.push(sample[(i % 9) as usize].clone());
        items.last_mut().unwrap().at = Stamp(start + i * 1_000_003);
    }
    for flush_every in [0, 1000, 7] {
        let bytes = write_all(Stamp(start), &items, flush_every);
        assert_eq!(items_of(&bytes), items, "flushing every {flush_every}");
    }
}

#[test]
fn the_header_is_laid_out_by_hand() {
    let start = Stamp(NEW_YEAR + 123_456_789);
    let stop = NEW_YEAR + 3_723_004_000_000; // 01:02:03.004
    let items = [
        item(start.0, "can0", data(1, false, &[])),
        item(stop, "can0", data(2, false, &[])),
    ];
    let bytes = write_all(start, &items, 0);
    let u16s = |at: usize, n: usize| (0..n).map(|i| u16_at(&bytes, at + 2 * i)).collect::<Vec<_>>();
    assert_eq!(&bytes[..4], b"LOGG");
    assert_eq!(u32_at(&bytes, 4), 144);
    assert_eq!(&bytes[8..16], &[5, 0, 0, 0, 2, 6, 8, 1]);
    assert_eq!(u64_at(&bytes, 16), bytes.len() as u64);
    // Objects: the channel name and two frames; uncompressed: header, container header, the
    // APP_TEXT (32 + 16 + 5 text bytes + 1 padding byte), two CAN_MESSAGEs (48 each).
    assert_eq!(u32_at(&bytes, 32), 3);
    assert_eq!(u64_at(&bytes, 24), 144 + 32 + 54 + 2 * 48);
    // Start and stop: year, month, day of the week (Monday 1), day, hour, minute, second, ms.
    assert_eq!(u16s(40, 8), [2024, 1, 1, 1, 0, 0, 0, 123]);
    assert_eq!(u16s(56, 8), [2024, 1, 1, 1, 1, 2, 3, 4]);
    assert!(bytes[72..144].iter().all(|&b| b == 0));
    // One container: LOBJ, base header size 16, version 1, its size, type 10, zlib, 150 bytes.
    assert_eq!(&bytes[144..148], b"LOBJ");
    assert_eq!(u16s(148, 2), [16, 1]);
    let size = u32_at(&bytes, 152) as usize;
    assert_eq!(u32_at(&bytes, 156), 10);
    assert_eq!(u16_at(&bytes, 160), 2);
    assert_eq!(u32_at(&bytes, 168), 54 + 2 * 48);
    assert_eq!(bytes.len(), 144 + size + size % 4);
    // Inside: the APP_TEXT (source 1; version 1, channel 1, bus CAN; ";can0"), then the frames
    // with times in ns after the millisecond start.
    let mut inner = Vec::new();
    std::io::Read::read_to_end(
        &mut flate2::read::ZlibDecoder::new(&bytes[176..144 + size]),
        &mut inner,
    )
    .unwrap();
    assert_eq!(&inner[..4], b"LOBJ");
    assert_eq!((u32_at(&inner, 8), u32_at(&inner, 12)), (53, 65));
    assert_eq!((u32_at(&inner, 16), u64_at(&inner, 24)), (2, 456_789));
    assert_eq!(
        (u32_at(&inner, 32), u32_at(&inner, 36), u32_at(&inner, 40)),
        (1, 0x0001_0101, 5)
    );
    assert_eq!(&inner[48..54], b";can0\0");
    let frame = &inner[54 + 48..];
    assert_eq!((u32_at(frame, 8), u32_at(frame, 12)), (48, 1));
    assert_eq!(u64_at(frame, 24), stop - (NEW_YEAR + 123_000_000));
    assert_eq!(&frame[32..40], &[1, 0, 0, 0, 2, 0, 0, 0]);
}

#[test]
fn frames_and_error_frames_are_laid_out_as_python_can_has_them() {
    let items = [
        item(NEW_YEAR, "can0", remote(0x1234, true, 3)),
        item(NEW_YEAR, "can0", error(0x24, [1, 2, 3, 4, 5, 6, 7, 8])),
        item(NEW_YEAR, "can0", Entry::Error(None)),
    ];
    let bytes = write_all(Stamp(NEW_YEAR), &items, 0);
    let mut inner = Vec::new();
    std::io::Read::read_to_end(&mut flate2::read::ZlibDecoder::new(&bytes[176..]), &mut inner).unwrap();
    // After the 54-byte APP_TEXT: CAN_MESSAGE channel 1, flags 0x80, DLC 3, id with bit 31.
    let m = &inner[54..];
    assert_eq!(u32_at(m, 12), 1);
    assert_eq!(&m[32..40], &[1, 0, 0x80, 3, 0x34, 0x12, 0, 0x80]);
    assert_eq!(&m[40..48], &[0; 8]);
    // CAN_ERROR_EXT, 64 bytes: channel 1, DLC 8 at 10, classes as the id at 16, data at 24.
    let e = &m[48..];
    assert_eq!((u32_at(e, 8), u32_at(e, 12)), (64, 73));
    assert_eq!((u16_at(e, 32), e[42], u32_at(e, 48)), (1, 8, 0x24));
    assert_eq!(&e[56..64], &[1, 2, 3, 4, 5, 6, 7, 8]);
    let none = &e[64..];
    assert_eq!((none[42], u32_at(none, 48)), (0, 0));
}

/// Every prefix of a written file either reads as a prefix of its items or fails with the
/// object and offset; clean cuts between objects read fine.
#[test]
fn a_file_cut_anywhere_reads_a_prefix_or_says_where() {
    let start = NEW_YEAR + 777;
    let items = sample(start);
    let bytes = write_all(Stamp(start), &items, 2);
    let mut clean = 0;
    for len in 0..=bytes.len() {
        let cut = &bytes[..len];
        let reader = match BlfReader::new(cut) {
            Ok(r) => r,
            Err(Error::TraceRecord { record, offset, .. }) => {
                assert!(len < 144, "header refused at {len}");
                assert_eq!((record, offset), (0, 0));
                continue;
            }
            Err(e) => panic!("{e}"),
        };
        let mut got = Vec::new();
        let mut failed = None;
        for r in reader {
            match r {
                Ok((_, it)) => got.push(it),
                Err(e) => failed = Some(e),
            }
        }
        assert_eq!(got[..], items[..got.len()], "prefix at {len}");
        match failed {
            None => clean += 1,
            Some(Error::TraceRecord {
                record,
                offset,
                reason,
                ..
            }) => {
                assert!(
                    record >= 1 && offset >= 144 && (offset as usize) < len,
                    "{len}: {reason}"
                );
                assert!(reason.contains("ends"), "{len}: {reason}");
            }
            Some(e) => panic!("{e}"),
        }
    }
    // The header alone and the whole file at least (the sample fits one container).
    assert!(clean >= 2, "{clean} clean cuts");
    assert_eq!(items_of(&bytes), items);
}

#[test]
fn a_killed_writer_leaves_a_file_that_reads_up_to_its_last_container() {
    let start = NEW_YEAR;
    let mut w = BlfWriter::new(Cursor::new(Vec::new()), Stamp(start)).unwrap();
    let mut items = Vec::new();
    for i in 0..12_000u64 {
        let mut item = sample(start)[(i % 9) as usize].clone();
        item.at = Stamp(start + i * 1_000_003);
        w.write(&item).unwrap();
        items.push(item);
    }
    // Flushing passes on the file, not the container being filled.
    w.flush().unwrap();
    // Never finished: the header's counts are zero and the last container never left the
    // buffer. The file reads up to the last whole object; the one that goes on in the container
    // never written is named as cut off.
    let bytes = w.into_inner().into_inner();
    assert_eq!((u64_at(&bytes, 16), u32_at(&bytes, 32)), (0, 0));
    let mut got = Vec::new();
    for r in BlfReader::new(&bytes[..]).unwrap() {
        match r {
            Ok((_, item)) => got.push(item),
            Err(Error::TraceRecord { reason, .. }) => assert!(reason.contains("ends"), "{reason}"),
            Err(e) => panic!("{e}"),
        }
    }
    assert!(!got.is_empty() && got.len() < items.len(), "{} items", got.len());
    assert_eq!(got, items[..got.len()]);
}

#[test]
fn finish_is_idempotent_refuses_more_and_works_after_flushes() {
    let mut w = BlfWriter::new(Cursor::new(Vec::new()), Stamp(NEW_YEAR)).unwrap();
    w.finish().unwrap();
    w.finish().unwrap();
    assert!(w.write(&item(NEW_YEAR, "can0", Entry::Error(None))).is_err());
    let bytes = w.into_inner().into_inner();
    assert_eq!(bytes.len(), 144);
    assert_eq!(u64_at(&bytes, 16), 144);
    assert!(items_of(&bytes).is_empty());
    // An item before the start (truncated to the millisecond) is refused.
    let mut w = BlfWriter::new(Cursor::new(Vec::new()), Stamp(NEW_YEAR + 1_500_000)).unwrap();
    assert!(
        w.write(&item(NEW_YEAR + 1_000_000, "can0", Entry::Error(None)))
            .is_ok()
    );
    assert!(
        w.write(&item(NEW_YEAR + 999_999, "can0", Entry::Error(None)))
            .is_err()
    );
}

#[test]
fn the_writer_starts_where_its_output_is() {
    let mut out = Cursor::new(Vec::new());
    out.write_all(b"prefix").unwrap();
    let items = sample(NEW_YEAR);
    let mut w = BlfWriter::new(out, Stamp(NEW_YEAR)).unwrap();
    for it in &items {
        w.write(it).unwrap();
    }
    w.finish().unwrap();
    let bytes = w.into_inner().into_inner();
    assert_eq!(&bytes[..10], b"prefixLOGG");
    assert_eq!(u64_at(&bytes, 6 + 16), bytes.len() as u64 - 6);
    assert_eq!(items_of(&bytes[6..]), items);
}

// Files as other writers make them, object by object.

/// An object with a version 1 header: type, flags, time, body; padded as BLF pads.
fn object(kind: u32, flags: u32, time: u64, body: &[u8]) -> Vec<u8> {
    let size = 32 + body.len();
    let mut o = Vec::new();
    o.extend_from_slice(b"LOBJ");
    o.extend_from_slice(&32u16.to_le_bytes());
    o.extend_from_slice(&1u16.to_le_bytes());
    o.extend_from_slice(&(size as u32).to_le_bytes());
    o.extend_from_slice(&kind.to_le_bytes());
    o.extend_from_slice(&flags.to_le_bytes());
    o.extend_from_slice(&[0; 4]);
    o.extend_from_slice(&time.to_le_bytes());
    o.extend_from_slice(body);
    o.resize(o.len() + size % 4, 0);
    o
}

/// A container of `data`: compressed with zlib, or stored (method 0).
fn container(data: &[u8], zlib: bool, stated: u32) -> Vec<u8> {
    let payload = if zlib {
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(data).unwrap();
        z.finish().unwrap()
    } else {
        data.to_vec()
    };
    let size = 32 + payload.len();
    let mut c = Vec::new();
    c.extend_from_slice(b"LOBJ");
    c.extend_from_slice(&16u16.to_le_bytes());
    c.extend_from_slice(&1u16.to_le_bytes());
    c.extend_from_slice(&(size as u32).to_le_bytes());
    c.extend_from_slice(&10u32.to_le_bytes());
    c.extend_from_slice(&(if zlib { 2u16 } else { 0 }).to_le_bytes());
    c.extend_from_slice(&[0; 6]);
    c.extend_from_slice(&stated.to_le_bytes());
    c.extend_from_slice(&[0; 4]);
    c.extend_from_slice(&payload);
    c.resize(c.len() + size % 4, 0);
    c
}

/// A file header with counts of zero (python-can's before it stops) and a start time.
fn file_header(start: [u16; 8]) -> Vec<u8> {
    let mut h = vec![0u8; 144];
    h[..4].copy_from_slice(b"LOGG");
    h[4..8].copy_from_slice(&144u32.to_le_bytes());
    for (i, w) in start.iter().enumerate() {
        h[40 + 2 * i..42 + 2 * i].copy_from_slice(&w.to_le_bytes());
    }
    h
}

fn can_message(channel: u16, flags: u8, dlc: u8, id: u32, data: [u8; 8]) -> Vec<u8> {
    let mut b = Vec::new();
    b.extend_from_slice(&channel.to_le_bytes());
    b.extend_from_slice(&[flags, dlc]);
    b.extend_from_slice(&id.to_le_bytes());
    b.extend_from_slice(&data);
    b
}

fn fd_message(channel: u16, dlc: u8, id: u32, fd_flags: u8, valid: u8) -> Vec<u8> {
    let mut b = Vec::new();
    b.extend_from_slice(&channel.to_le_bytes());
    b.extend_from_slice(&[0, dlc]);
    b.extend_from_slice(&id.to_le_bytes());
    b.extend_from_slice(&[0; 4]);
    b.extend_from_slice(&[0, fd_flags, valid, 0, 0, 0, 0, 0]);
    let mut data = [0u8; 64];
    for (i, d) in data.iter_mut().enumerate() {
        *d = i as u8 + 1;
    }
    b.extend_from_slice(&data);
    b
}

fn fd64_message(channel: u8, dlc: u8, valid: u8, id: u32, flags: u32, data: &[u8]) -> Vec<u8> {
    let mut b = vec![channel, dlc, valid, 0];
    b.extend_from_slice(&id.to_le_bytes());
    b.extend_from_slice(&[0; 4]);
    b.extend_from_slice(&flags.to_le_bytes());
    b.extend_from_slice(&[0; 24]);
    b.extend_from_slice(data);
    b
}

#[test]
fn other_writers_objects_are_read_and_unknown_ones_skipped() {
    // 2024-01-01 00:00:01.250, a header whose counts were never filled in.
    let mut inner = Vec::new();
    // 10 µs units: 3 → 30 µs.
    inner.extend(object(
        1,
        1,
        3,
        &can_message(1, 0, 2, 0x100, [7, 8, 0, 0, 0, 0, 0, 0]),
    ));
    // CAN_MESSAGE2 (with its extra fields), DLC 12: 8 bytes; extended; channel 2 → can1.
    let mut m2 = can_message(2, 0, 12, 0x8000_0001, [1, 2, 3, 4, 5, 6, 7, 8]);
    m2.extend_from_slice(&[0; 8]);
    inner.extend(object(86, 2, 1_000, &m2));
    // A GLOBAL_MARKER: skipped, but counted.
    inner.extend(object(96, 2, 1_000, &[0; 40]));
    // CAN_ERROR: an error frame without details.
    inner.extend(object(2, 2, 2_000, &[1, 0, 0, 0, 0, 0, 0, 0]));
    // CAN_FD_MESSAGE of a classic frame, and CAN_FD_MESSAGE_64 of a classic remote frame.
    inner.extend(object(100, 2, 3_000, &fd_message(1, 3, 0x7FF, 0, 3)));
    inner.extend(object(
        101,
        2,
        4_000,
        &fd64_message(1, 4, 0, 0x8000_0100, 0x10, &[]),
    ));
    // An APP_TEXT naming a database, not a channel: skipped.
    let mut text = Vec::new();
    text.extend_from_slice(&1u32.to_le_bytes());
    text.extend_from_slice(&0x0001_0101u32.to_le_bytes());
    text.extend_from_slice(&8u32.to_le_bytes());
    text.extend_from_slice(&[0; 4]);
    text.extend_from_slice(b"a.dbc;PT");
    inner.extend(object(65, 2, 0, &text));
    inner.extend(object(1, 2, 5_000, &can_message(1, 0x80, 2, 0x555, [0; 8])));
    let mut file = file_header([2024, 1, 1, 1, 0, 0, 1, 250]);
    // Two containers, the second stored uncompressed, cut in the middle of an object; and an
    // object outside any container at the end.
    let (a, b) = inner.split_at(100);
    file.extend(container(a, true, 100));
    file.extend(container(b, false, b.len() as u32));
    file.extend(object(73, 2, 6_000, &{
        let mut e = vec![2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 8, 0];
        e.extend_from_slice(&[0; 4]);
        e.extend_from_slice(&0x10u32.to_le_bytes());
        e.extend_from_slice(&[0; 4]);
        e.extend_from_slice(&[1, 2, 3, 4, 5, 6, 7, 8]);
        e
    }));
    let t0 = NEW_YEAR + 1_250_000_000;
    let read = read_all(&file).unwrap();
    let numbers: Vec<u64> = read.iter().map(|(n, _)| *n).collect();
    assert_eq!(numbers, [1, 2, 4, 5, 6, 8, 9]);
    let items: Vec<Item> = read.into_iter().map(|(_, i)| i).collect();
    assert_eq!(
        items,
        [
            item(t0 + 30_000, "can0", data(0x100, false, &[7, 8])),
            item(t0 + 1_000, "can1", data(1, true, &[1, 2, 3, 4, 5, 6, 7, 8])),
            item(t0 + 2_000, "can0", Entry::Error(None)),
            item(t0 + 3_000, "can0", data(0x7FF, false, &[1, 2, 3])),
            item(t0 + 4_000, "can0", remote(0x100, true, 4)),
            item(t0 + 5_000, "can0", remote(0x555, false, 2)),
            item(t0 + 6_000, "can1", error(0x10, [1, 2, 3, 4, 5, 6, 7, 8])),
        ]
    );
}

fn reason_of(bytes: &[u8]) -> (u64, u64, String) {
    let failed = match BlfReader::new(bytes) {
        Err(e) => e,
        Ok(r) => r.filter_map(Result::err).next().expect("an error"),
    };
    match failed {
        Error::TraceRecord {
            format,
            record,
            offset,
            reason,
        } => {
            assert_eq!(format, "BLF");
            (record, offset, reason)
        }
        e => panic!("{e}"),
    }
}

#[test]
fn bad_files_are_refused_with_the_object_and_its_offset() {
    let zero = [0u16; 8];
    let frame = object(1, 2, 0, &can_message(1, 0, 0, 1, [0; 8]));
    let check = |bytes: &[u8], record: u64, offset: u64, says: &str| {
        let (r, o, reason) = reason_of(bytes);
        assert_eq!((r, o), (record, offset), "{reason}");
        assert!(reason.contains(says), "{reason:?} does not say {says:?}");
    };
    check(b"", 0, 0, "empty");
    check(b"LOGX", 0, 0, "not a BLF file");
    check(b"LOGG\x90\0\0\0", 0, 0, "ends 8 bytes into its 144-byte header");
    let mut h = file_header(zero);
    h[4] = 16;
    check(&h, 0, 0, "header size 16");
    let mut h = file_header([2024, 13, 0, 1, 0, 0, 0, 0]);
    check(&h, 0, 0, "2024-13-01");
    h = file_header(zero);
    let mut f = h.clone();
    f.extend_from_slice(b"LOBX");
    f.extend_from_slice(&[0; 12]);
    check(&f, 1, 144, "LOBJ");
    // Sizes: an object, a container's uncompressed data, more data than stated.
    let mut f = h.clone();
    let mut big = container(&frame, true, 48);
    big[8..12].copy_from_slice(&(MAX_OBJECT as u32 + 1).to_le_bytes());
    f.extend(&big);
    check(&f, 1, 144, "above");
    let mut f = h.clone();
    f.extend(container(&frame, true, MAX_OBJECT as u32 + 1));
    check(&f, 1, 144, "above");
    let mut f = h.clone();
    f.extend(container(&[frame.clone(), frame.clone()].concat(), true, 48));
    check(&f, 1, 144, "more than the 48 bytes");
    let mut f = h.clone();
    f.extend(container(&[0x55; 20], false, 20));
    check(&f, 1, 144, "not the signature LOBJ");
    let mut f = h.clone();
    let mut c = container(&frame, true, 48);
    c[40] ^= 0xFF;
    f.extend(c);
    check(&f, 1, 144, "does not inflate");
    // The second object of a container, with a base id too large.
    let mut f = h.clone();
    let wide = object(1, 2, 0, &can_message(1, 0, 0, 0x800, [0; 8]));
    f.extend(container(&[frame.clone(), wide].concat(), true, 96));
    check(&f, 2, 144, "does not fit in 11 bits");
    // A real CAN FD frame.
    let mut f = h.clone();
    f.extend(frame.clone());
    f.extend(object(100, 2, 0, &fd_message(1, 9, 1, 1, 12)));
    check(&f, 2, 192, "CAN FD");
    let mut f = h.clone();
    f.extend(object(101, 2, 0, &fd64_message(1, 8, 8, 1, 0x1000, &[0; 8])));
    check(&f, 1, 144, "CAN FD");
    // Cut: in a container, and in an object spanning two containers.
    let mut f = h.clone();
    f.extend(container(&frame, true, 48));
    check(&f[..144 + 40], 1, 144, "ends 40 bytes into a");
    let mut f = h.clone();
    f.extend(container(&frame[..20], false, 20));
    check(&f, 1, 144, "ends 20 bytes into a 48-byte object");
    // A short CAN_MESSAGE.
    let mut f = h.clone();
    f.extend(object(1, 2, 0, &[0; 10]));
    check(&f, 1, 144, "10 bytes after the object header, 16 needed");
}

/// Flipping any byte of a file (stored uncompressed, so that the flips reach the objects)
/// never panics; what still reads whole, in time order, is written and read back the same.
#[test]
fn damaged_files_never_panic() {
    let items = sample(NEW_YEAR);
    let mut inner = Vec::new();
    for (i, it) in items.iter().enumerate() {
        let Entry::Frame(f) = it.entry else { continue };
        let mut d = [0u8; 8];
        d[..f.data().len()].copy_from_slice(f.data());
        inner.extend(object(1, 2, i as u64, &can_message(1, 0, f.dlc(), f.raw_id(), d)));
    }
    let mut file = file_header([2024, 1, 1, 1, 0, 0, 0, 0]);
    let (a, b) = inner.split_at(70);
    file.extend(container(a, false, 0));
    file.extend(container(b, false, 0));
    file.extend(container(&inner, true, inner.len() as u32));
    for at in 0..file.len() {
        for flip in [0xFF, 0x01, 0x80] {
            let mut bad = file.clone();
            bad[at] ^= flip;
            let Ok(read) = read_all(&bad) else { continue };
            let got: Vec<Item> = read.into_iter().map(|(_, i)| i).collect();
            if got.windows(2).any(|w| w[1].at < w[0].at) {
                continue;
            }
            let start = got.first().map_or(Stamp(0), |i| i.at);
            assert_eq!(items_of(&write_all(start, &got, 0)), got, "byte {at} ^ {flip:#X}");
        }
    }
}

proptest::proptest! {
    /// Objects of any type, size and content, stored or compressed, never panic the reader,
    /// and an error names an offset inside the file.
    #[test]
    fn any_objects_never_panic(
        objects in proptest::collection::vec(
            (0u32..110, 0u32..3, proptest::collection::vec(proptest::prelude::any::<u8>(), 0..90)),
            0..8,
        ),
        split in 0usize..400,
        zlib in proptest::prelude::any::<bool>(),
        size_fuzz in proptest::prelude::any::<u32>(),
    ) {
        let mut inner = Vec::new();
        for (kind, flags, body) in &objects {
            inner.extend(object(*kind, *flags, 7, body));
        }
        if let Some(b) = inner.get_mut(8) {
            // Sometimes a wrong size in the first object's header.
            if size_fuzz.is_multiple_of(4) {
                *b = size_fuzz as u8;
            }
        }
        let split = split.min(inner.len());
        let mut file = file_header([2024, 1, 1, 1, 0, 0, 0, 0]);
        file.extend(container(&inner[..split], zlib, split as u32));
        file.extend(container(&inner[split..], zlib, (inner.len() - split) as u32));
        match read_all(&file) {
            Ok(_) => {}
            Err(Error::TraceRecord { offset, .. }) => proptest::prop_assert!(offset < file.len() as u64),
            Err(e) => proptest::prop_assert!(false, "{e}"),
        }
    }
}
