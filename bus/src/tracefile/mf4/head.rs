//! What the writer writes first: the ID, header and file history blocks and the three groups'
//! channels; and the header's comment with the interface names, written last.

use super::*;
use crate::time::Stamp;

/// The largest record: a data or error frame's.
pub(super) const RECORD: usize = 25;

/// One group's members: name, byte offset, bits, data type.
type Member = (&'static str, u32, u32, u8);

/// Data and error frames: `.DataBytes` holds the 8 data bytes or error details.
const FRAME_MEMBERS: [Member; 7] = [
    ("BusChannel", 8, 8, UINT_LE),
    ("ID", 9, 32, UINT_LE),
    ("IDE", 13, 8, UINT_LE),
    ("DLC", 14, 8, UINT_LE),
    ("DataLength", 15, 8, UINT_LE),
    ("DataBytes", 16, 64, BYTE_ARRAY),
    ("Dir", 24, 8, UINT_LE),
];
/// Remote frames carry no data.
const REMOTE_MEMBERS: [Member; 6] = [
    ("BusChannel", 8, 8, UINT_LE),
    ("ID", 9, 32, UINT_LE),
    ("IDE", 13, 8, UINT_LE),
    ("DLC", 14, 8, UINT_LE),
    ("DataLength", 15, 8, UINT_LE),
    ("Dir", 16, 8, UINT_LE),
];

fn members(kind: Kind) -> &'static [Member] {
    match kind {
        Kind::Remote => &REMOTE_MEMBERS,
        _ => &FRAME_MEMBERS,
    }
}

/// Bytes per record of a group.
pub(super) fn record_size(kind: Kind) -> usize {
    match kind {
        Kind::Remote => 17,
        _ => RECORD,
    }
}

/// A block: header, links, data, then zeros up to a multiple of 8 (not counted in its length).
pub(super) fn put(out: &mut Vec<u8>, base: u64, id: &[u8; 2], links: &[u64], data: &[u8]) -> u64 {
    let at = base + out.len() as u64;
    let length = HEADER + 8 * links.len() as u64 + data.len() as u64;
    out.extend_from_slice(b"##");
    out.extend_from_slice(id);
    out.extend_from_slice(&[0; 4]);
    out.extend_from_slice(&length.to_le_bytes());
    out.extend_from_slice(&(links.len() as u64).to_le_bytes());
    for link in links {
        out.extend_from_slice(&link.to_le_bytes());
    }
    out.extend_from_slice(data);
    out.resize(out.len().next_multiple_of(8), 0);
    at
}

/// A TX or MD block's data: the text, zero-terminated, padded to a multiple of 8.
pub(super) fn text(s: &str) -> Vec<u8> {
    let mut data = s.as_bytes().to_vec();
    data.push(0);
    data.resize(data.len().next_multiple_of(8), 0);
    data
}

/// A CN block's data (after its links).
pub(super) fn channel(kind: u8, sync: u8, data_type: u8, byte_offset: u32, bits: u32, flags: u32) -> Vec<u8> {
    let mut d = vec![kind, sync, data_type, 0];
    d.extend_from_slice(&byte_offset.to_le_bytes());
    d.extend_from_slice(&bits.to_le_bytes());
    d.extend_from_slice(&flags.to_le_bytes());
    // Invalidation bit, precision, reserved, attachments, then six f64 ranges and limits.
    d.resize(72, 0);
    d
}

/// `s` with XML's special characters escaped (and control characters, which XML 1.0 cannot
/// hold, as character references).
fn xml(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c if c.is_control() => out.push_str(&format!("&#x{:X};", u32::from(c))),
            c => out.push(c),
        }
    }
    out
}

/// Where the header block's comment link is.
pub(super) const COMMENT_AT: u64 = ID_SIZE + HEADER + 5 * 8;

/// The file's first blocks, for a writer starting at `start`; and for each group, where its DG
/// block's data link and its CG block's cycle count are.
pub(super) fn head(start: Stamp) -> (Vec<u8>, [(u64, u64); 3]) {
    let mut out = vec![0u8; (ID_SIZE + HEADER + 80) as usize];
    let fh_comment = put(
        &mut out,
        0,
        b"MD",
        &[],
        &text(concat!(
            "<FHcomment>\n<TX>created</TX>\n<tool_id>harvemu</tool_id>\n",
            "<tool_vendor>harvemu</tool_vendor>\n<tool_version>",
            env!("CARGO_PKG_VERSION"),
            "</tool_version>\n</FHcomment>"
        )),
    );
    let mut fh = start.0.to_le_bytes().to_vec();
    fh.resize(16, 0);
    let fh = put(&mut out, 0, b"FH", &[0, fh_comment], &fh);
    let can = put(&mut out, 0, b"TX", &[], &text("CAN"));
    let si = put(
        &mut out,
        0,
        b"SI",
        &[can, 0, 0],
        &[SOURCE_BUS, BUS_TYPE_CAN, 0, 0, 0, 0, 0, 0],
    );
    let t_name = put(&mut out, 0, b"TX", &[], &text("t"));
    let t_unit = put(&mut out, 0, b"TX", &[], &text("s"));
    let mut next_dg = 0;
    let mut places = [(0u64, 0u64); 3];
    for kind in Kind::ALL.into_iter().rev() {
        let size = match kind {
            Kind::Remote => 17u32,
            _ => RECORD as u32,
        };
        let mut next_cn = 0;
        for &(field, byte_offset, bits, data_type) in members(kind).iter().rev() {
            let name = put(
                &mut out,
                0,
                b"TX",
                &[],
                &text(&format!("{}.{field}", kind.name())),
            );
            let data = channel(0, 0, data_type, byte_offset, bits, CN_BUS_EVENT);
            next_cn = put(&mut out, 0, b"CN", &[next_cn, 0, name, 0, 0, 0, 0, 0], &data);
        }
        let name = put(&mut out, 0, b"TX", &[], &text(kind.name()));
        let data = channel(0, 0, BYTE_ARRAY, 8, (size - 8) * 8, CN_BUS_EVENT);
        let composed = put(&mut out, 0, b"CN", &[0, next_cn, name, si, 0, 0, 0, 0], &data);
        let data = channel(CN_MASTER, SYNC_TIME, FLOAT_LE, 0, 64, 0);
        let master = put(
            &mut out,
            0,
            b"CN",
            &[composed, 0, t_name, 0, 0, 0, t_unit, 0],
            &data,
        );
        // Record id 0, cycles (filled in), flags, path separator '.', reserved, data bytes,
        // invalidation bytes.
        let mut cg = vec![0u8; 16];
        cg.extend_from_slice(&(CG_BUS_EVENT | CG_PLAIN_BUS_EVENT).to_le_bytes());
        cg.extend_from_slice(&u16::from(b'.').to_le_bytes());
        cg.extend_from_slice(&[0; 4]);
        cg.extend_from_slice(&size.to_le_bytes());
        cg.extend_from_slice(&0u32.to_le_bytes());
        let cg = put(&mut out, 0, b"CG", &[0, master, can, si, 0, 0], &cg);
        next_dg = put(&mut out, 0, b"DG", &[next_dg, cg, 0, 0], &[0; 8]);
        places[kind as usize] = (next_dg + HEADER + 16, cg + HEADER + 48 + 8);
    }
    // ID: unfinished until `finish`, with custom flag 1 saying why.
    out[..8].copy_from_slice(b"UnFinMF ");
    out[8..16].copy_from_slice(b"4.10    ");
    out[16..24].copy_from_slice(b"harvemu ");
    out[28..30].copy_from_slice(&410u16.to_le_bytes());
    out[62..64].copy_from_slice(&1u16.to_le_bytes());
    // HD: first data group, file history, then the start time in UTC (time flags 0: no
    // zone), the rest (zone, flags, angle, distance) zero. Its comment comes at the end.
    let mut hd = start.0.to_le_bytes().to_vec();
    hd.resize(32, 0);
    let mut block = Vec::new();
    put(&mut block, 0, b"HD", &[next_dg, fh, 0, 0, 0, 0], &hd);
    out[ID_SIZE as usize..][..block.len()].copy_from_slice(&block);
    (out, places)
}

/// The header's comment: the interfaces' names by bus channel.
pub(super) fn comment(names: &[String]) -> String {
    let mut s = format!(
        "<HDcomment>\n<TX>CAN trace written by harvemu</TX>\n<common_properties>\n<tree name=\"{NAMES_TREE}\">\n"
    );
    for (i, name) in names.iter().enumerate() {
        if name.len() <= MAX_NAME {
            s.push_str(&format!(
                "<e name=\"{}\" type=\"string\">{}</e>\n",
                i + 1,
                xml(name)
            ));
        }
    }
    s.push_str("</tree>\n</common_properties>\n</HDcomment>");
    s
}
