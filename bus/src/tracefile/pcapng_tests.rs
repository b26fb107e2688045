//! pcapng in: what harvemu writes reads back item for item; captures in the other byte order,
//! with other time resolutions and as classic pcap read as their layouts say; a cut-off or
//! corrupt capture is refused at its block, never a panic.

use super::{Entry, Item, ItemWriter, PcapngReader, PcapngWriter};
use crate::time::{Epoch, Stamp};
use crate::trace::ErrorFrame;
use crate::{Error, Frame};

fn items() -> Vec<Item> {
    let frame = |t: &str| crate::candump::parse_frame(t).unwrap();
    let item = |at: u64, interface: &str, entry| Item {
        at: Stamp(at),
        interface: interface.into(),
        entry,
    };
    vec![
        item(
            1_704_067_200_551_520_123,
            "harv0",
            Entry::Frame(frame("0200F5E0#107800F4010000")),
        ),
        item(1_704_067_200_551_520_123, "harv0", Entry::Frame(frame("123#"))),
        item(1_704_067_200_700_000_000, "harv0", Entry::Frame(frame("7FF#R8"))),
        item(
            1_704_067_200_800_000_000,
            "harv0",
            Entry::Frame(frame("0000ABCD#R")),
        ),
        item(
            1_704_067_201_000_000_001,
            "harv0.D2",
            Entry::Error(Some(ErrorFrame {
                can_id: 0x2000_0088,
                data: [0, 0, 0x80, 0x19, 0, 0, 136, 0],
            })),
        ),
        item(
            1_704_067_202_000_000_000,
            "harv0",
            Entry::Frame(frame("1FFFFFFF#0102030405060708")),
        ),
    ]
}

fn written(items: &[Item]) -> Vec<u8> {
    let mut w = PcapngWriter::new(Vec::new(), Epoch::UNIX).unwrap();
    for i in items {
        ItemWriter::write(&mut w, i).unwrap();
    }
    ItemWriter::finish(&mut w).unwrap();
    w.into_inner()
}

fn read(bytes: &[u8]) -> Result<Vec<Item>, Error> {
    PcapngReader::new(bytes)?.map(|r| r.map(|(_, i)| i)).collect()
}

#[test]
fn what_harvemu_writes_reads_back_item_for_item() {
    let items = items();
    assert_eq!(read(&written(&items)).unwrap(), items);
}

#[test]
fn a_capture_cut_anywhere_reads_up_to_its_last_whole_block_or_names_the_cut_block() {
    let items = items();
    let bytes = written(&items);
    for len in 0..bytes.len() {
        match read(&bytes[..len]) {
            Ok(got) => assert_eq!(got[..], items[..got.len()], "cut at {len}"),
            Err(Error::TraceRecord { record, offset, .. }) => {
                assert!(
                    record >= 1 && offset <= len as u64,
                    "cut at {len}: {record} {offset}"
                )
            }
            Err(e) => panic!("cut at {len}: {e}"),
        }
    }
}

/// Appends a block in big-endian order: type, length, body, length.
fn be_block(out: &mut Vec<u8>, kind: u32, body: &[u8]) {
    let total = (12 + body.len().next_multiple_of(4)) as u32;
    out.extend_from_slice(&kind.to_be_bytes());
    out.extend_from_slice(&total.to_be_bytes());
    out.extend_from_slice(body);
    out.resize(out.len() + body.len().next_multiple_of(4) - body.len(), 0);
    out.extend_from_slice(&total.to_be_bytes());
}

#[test]
fn a_big_endian_section_with_microsecond_times_and_no_names_reads_as_its_layout_says() {
    // Section Header Block (big-endian magic), version 1.0, unknown length.
    let mut b = Vec::new();
    let mut shb = vec![0x1A, 0x2B, 0x3C, 0x4D, 0, 1, 0, 0];
    shb.extend_from_slice(&u64::MAX.to_be_bytes());
    be_block(&mut b, 0x0A0D_0D0A, &shb);
    // Interface Description Block: link type 227, no options (microseconds, no name).
    be_block(&mut b, 1, &[0, 227, 0, 0, 0, 0, 0, 0]);
    // Enhanced Packet Block: interface 0, 1,704,067,200.000042 s in microseconds.
    let us: u64 = 1_704_067_200_000_042;
    let mut epb = Vec::new();
    epb.extend_from_slice(&0u32.to_be_bytes());
    epb.extend_from_slice(&((us >> 32) as u32).to_be_bytes());
    epb.extend_from_slice(&(us as u32).to_be_bytes());
    epb.extend_from_slice(&16u32.to_be_bytes());
    epb.extend_from_slice(&16u32.to_be_bytes());
    // can_id 0x8CF004FE (extended), length 3, data.
    epb.extend_from_slice(&[
        0x8C, 0xF0, 0x04, 0xFE, 3, 0, 0, 0, 0xAA, 0xBB, 0xCC, 0, 0, 0, 0, 0,
    ]);
    be_block(&mut b, 6, &epb);
    // A name resolution block is skipped.
    be_block(&mut b, 4, &[0, 0, 0, 0]);
    let got = read(&b).unwrap();
    assert_eq!(
        got,
        vec![Item {
            at: Stamp(1_704_067_200_000_042_000),
            interface: "can0".into(),
            entry: Entry::Frame(Frame::extended(0x0CF0_04FE, &[0xAA, 0xBB, 0xCC]).unwrap()),
        }]
    );
}

#[test]
fn a_classic_pcap_with_nanosecond_magic_reads_on_can0() {
    let mut b = Vec::new();
    b.extend_from_slice(&0xA1B2_3C4Du32.to_le_bytes());
    b.extend_from_slice(&[2, 0, 4, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
    b.extend_from_slice(&65535u32.to_le_bytes());
    b.extend_from_slice(&227u32.to_le_bytes());
    // Packet: 5 s and 7 ns, 16 bytes: a base frame 0x123 with 1 byte; its id big-endian.
    b.extend_from_slice(&5u32.to_le_bytes());
    b.extend_from_slice(&7u32.to_le_bytes());
    b.extend_from_slice(&16u32.to_le_bytes());
    b.extend_from_slice(&16u32.to_le_bytes());
    b.extend_from_slice(&[0, 0, 0x01, 0x23, 1, 0, 0, 0, 0x42, 0, 0, 0, 0, 0, 0, 0]);
    let got = read(&b).unwrap();
    assert_eq!(got[0].at, Stamp(5_000_000_007));
    assert_eq!(got[0].interface, "can0");
    assert_eq!(got[0].entry, Entry::Frame(Frame::base(0x123, &[0x42]).unwrap()));
}

#[test]
fn corrupt_captures_are_refused_at_their_block() {
    let bytes = written(&items());
    let shb = u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]) as usize;
    let idb = u32::from_le_bytes([bytes[shb + 4], bytes[shb + 5], bytes[shb + 6], bytes[shb + 7]]) as usize;
    let epb = shb + idb;
    let cases: Vec<(Vec<u8>, u64, &str)> = vec![
        // The first packet's trailing length does not match its leading one.
        (
            {
                let mut b = bytes.clone();
                b[epb + 47] ^= 1;
                b
            },
            3,
            "at its end",
        ),
        // A block length of 3 GB.
        (
            {
                let mut b = bytes.clone();
                b[epb + 7] = 0xC0;
                b
            },
            3,
            "longest block",
        ),
        // The interface's link type is Ethernet.
        (
            {
                let mut b = bytes.clone();
                b[shb + 8] = 1;
                b[shb + 9] = 0;
                b
            },
            3,
            "link type 1",
        ),
        // A CAN FD length.
        (
            {
                let mut b = bytes.clone();
                b[epb + 32] = 12;
                b
            },
            3,
            "CAN FD",
        ),
    ];
    for (bytes, at, says) in cases {
        match read(&bytes) {
            Err(Error::TraceRecord { record, reason, .. }) => {
                assert_eq!(record, at, "{reason}");
                assert!(reason.contains(says), "{reason}");
            }
            other => panic!("{says}: {other:?}"),
        }
    }
}
