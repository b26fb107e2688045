//! Finding the bus-logging channel groups and where their fields are in a record.

use super::blocks::{Block, Input};
use super::*;
use crate::Error;
use crate::text::quote;
use std::io::{Read, Seek};

/// Where a value is in a record's data bytes, and how it is stored.
#[derive(Clone, Copy, Debug)]
pub(super) struct Field {
    pub(super) byte: usize,
    pub(super) bit: u8,
    pub(super) bits: u32,
    pub(super) data_type: u8,
}

/// The time master: `offset + factor * raw`, raw being the stored value or (virtual master) the
/// record's index.
#[derive(Clone, Copy, Debug)]
pub(super) struct Master {
    pub(super) field: Option<Field>,
    pub(super) offset: f64,
    pub(super) factor: f64,
}

/// The members of a bus-logging channel read; those absent are zero.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Fields {
    pub(super) bus: Option<Field>,
    pub(super) id: Option<Field>,
    pub(super) ide: Option<Field>,
    pub(super) dlc: Option<Field>,
    pub(super) length: Option<Field>,
    pub(super) bytes: Option<Field>,
    pub(super) edl: Option<Field>,
}

/// How long another channel group's records are, in an unsorted data group.
#[derive(Clone, Copy, Debug)]
pub(super) enum Length {
    Fixed(u64),
    /// Variable-length signal data: a u32 length, then that many bytes.
    Vlsd,
}

/// One bus-logging channel group.
#[derive(Clone, Debug)]
pub(super) struct Layout {
    pub(super) kind: Kind,
    /// `CAN_DataFrame of data group 2`.
    pub(super) what: String,
    /// The data group's data link, and where the DG block is.
    pub(super) data: u64,
    pub(super) dg: u64,
    /// Bytes of record id before each record (0: a sorted data group).
    pub(super) id_size: u8,
    pub(super) record_id: u64,
    /// Every channel group of an unsorted data group, by record id.
    pub(super) others: Vec<(u64, Length)>,
    /// Data and invalidation bytes of a record (without its record id).
    pub(super) size: u64,
    pub(super) cycles: u64,
    pub(super) master: Master,
    pub(super) fields: Fields,
}

/// The largest record read, bytes.
const MAX_RECORD: u64 = 1 << 20;
/// How much of a CN, CG, DG or CC block's data is read: all that is used.
const CN_DATA: u64 = 16;
const CG_DATA: u64 = 32;
const CC_DATA: u64 = 40;

/// Every bus-logging channel group of the file whose header block is `hd`.
pub(super) fn find<R: Read + Seek>(input: &mut Input<R>, hd: &Block) -> Result<Vec<Layout>, Error> {
    let mut found = Vec::new();
    let mut dg_number = 0u64;
    input.list(hd.link(0), hd.offset, b"DG", 8, "a data group", |input, dg| {
        dg_number += 1;
        let id_size = byte(&dg.data, 0);
        if ![0, 1, 2, 4, 8].contains(&id_size) {
            return Err(input.error(
                dg.offset,
                format!("DG block: record ids of {id_size} bytes (0, 1, 2, 4 or 8)"),
            ));
        }
        let mut groups = Vec::new();
        let mut others = Vec::new();
        input.list(
            dg.link(1),
            dg.offset,
            b"CG",
            CG_DATA,
            "a channel group",
            |_, cg| {
                let flags = u16_at(&cg.data, 16);
                let length = if flags & CG_VLSD != 0 {
                    Length::Vlsd
                } else {
                    Length::Fixed(u64::from(u32_at(&cg.data, 24)) + u64::from(u32_at(&cg.data, 28)))
                };
                others.push((u64_at(&cg.data, 0), length));
                if flags & CG_VLSD == 0 {
                    groups.push(cg);
                }
                Ok(())
            },
        )?;
        for cg in groups {
            if let Some(mut layout) = channel_group(input, &cg)? {
                if found.len() == MAX_GROUPS {
                    return Err(input.error(
                        cg.offset,
                        format!("more than {MAX_GROUPS} CAN bus-logging groups"),
                    ));
                }
                layout.what = format!("{} of data group {dg_number}", layout.what);
                layout.data = dg.link(2);
                layout.dg = dg.offset;
                layout.id_size = id_size;
                if id_size != 0 {
                    layout.others = others.clone();
                }
                found.push(layout);
            }
        }
        Ok(())
    })?;
    Ok(found)
}

/// A CN block's field, checked to lie inside a record of `size` data bytes.
fn field(input: &Input<impl Read + Seek>, cn: &Block, name: &str, size: u64) -> Result<Field, Error> {
    let d = &cn.data;
    let f = Field {
        byte: u32_at(d, 4) as usize,
        bit: byte(d, 3),
        bits: u32_at(d, 8),
        data_type: byte(d, 2),
    };
    let end = (u64::from(f.bit) + u64::from(f.bits)).div_ceil(8) + u64::from(u32_at(d, 4));
    if f.bit > 7 || f.bits == 0 || end > size {
        return Err(input.error(
            cn.offset,
            format!(
                "channel {}: {} bits at byte {} bit {} do not fit in a {size}-byte record",
                quote(name),
                f.bits,
                f.byte,
                f.bit
            ),
        ));
    }
    Ok(f)
}

/// The layout of channel group `cg` if it is a CAN bus-logging one.
fn channel_group<R: Read + Seek>(input: &mut Input<R>, cg: &Block) -> Result<Option<Layout>, Error> {
    let size = u64::from(u32_at(&cg.data, 24));
    let inval = u64::from(u32_at(&cg.data, 28));
    let mut channels = Vec::new();
    input.list(cg.link(1), cg.offset, b"CN", CN_DATA, "a channel", |input, cn| {
        let name = input.text(cn.link(2), cn.offset, "a channel's name")?;
        channels.push((name, cn));
        Ok(())
    })?;
    let found = channels
        .iter()
        .find_map(|(name, cn)| Kind::ALL.into_iter().find(|k| k.name() == name).map(|k| (k, cn)));
    let Some((kind, composed)) = found else {
        return Ok(None);
    };
    let record = size + inval;
    if record == 0 || record > MAX_RECORD {
        return Err(input.error(
            cg.offset,
            format!("CG block: records of {record} bytes (1 to {MAX_RECORD} are read)"),
        ));
    }
    // The members: the composed channel's, or channels of the group named so.
    let mut members = Vec::new();
    if composed.link(1) != 0 {
        input.list(
            composed.link(1),
            composed.offset,
            b"CN",
            CN_DATA,
            "a member of a composed channel",
            |input, cn| {
                let name = input.text(cn.link(2), cn.offset, "a channel's name")?;
                members.push((name, cn));
                Ok(())
            },
        )?;
    }
    let mut fields = Fields::default();
    let mut master = None;
    for (name, cn) in members.iter().chain(channels.iter()) {
        let d = &cn.data;
        if matches!(byte(d, 0), CN_MASTER | CN_VIRTUAL_MASTER) && byte(d, 1) == SYNC_TIME {
            if master.is_none() {
                master = Some(time(input, cn, name, size)?);
            }
            continue;
        }
        let short = name.strip_prefix(kind.name()).and_then(|n| n.strip_prefix('.'));
        let slot = match short.unwrap_or(name) {
            "BusChannel" => &mut fields.bus,
            "ID" => &mut fields.id,
            "IDE" => &mut fields.ide,
            "DLC" => &mut fields.dlc,
            "DataLength" => &mut fields.length,
            "DataBytes" => &mut fields.bytes,
            "EDL" => &mut fields.edl,
            _ => continue,
        };
        if slot.is_some() {
            continue;
        }
        let f = field(input, cn, name, size)?;
        let integer = matches!(f.data_type, UINT_LE | INT_LE)
            || (matches!(f.data_type, UINT_BE | INT_BE) && f.bit == 0 && f.bits % 8 == 0);
        let ok = if short == Some("DataBytes") || name == "DataBytes" {
            (integer || f.data_type == BYTE_ARRAY) && f.bit == 0 && f.bits % 8 == 0
        } else {
            integer && f.bits <= 64
        };
        if !ok {
            return Err(input.error(
                cn.offset,
                format!(
                    "channel {}: data type {} of {} bits at bit {} is not read",
                    quote(name),
                    f.data_type,
                    f.bits,
                    f.bit
                ),
            ));
        }
        *slot = Some(f);
    }
    let what = kind.name();
    let Some(master) = master else {
        return Err(input.error(cg.offset, format!("CG block of {what}: no time master channel")));
    };
    let needed: &[(&str, Option<Field>)] = match kind {
        Kind::Data => &[("ID", fields.id), ("DataBytes", fields.bytes)],
        Kind::Remote => &[("ID", fields.id)],
        Kind::Error => &[],
    };
    if let Some((missing, _)) = needed.iter().find(|(_, f)| f.is_none()) {
        return Err(input.error(
            cg.offset,
            format!("CG block of {what}: no channel {what}.{missing}"),
        ));
    }
    Ok(Some(Layout {
        kind,
        what: what.to_string(),
        data: 0,
        dg: 0,
        id_size: 0,
        record_id: u64_at(&cg.data, 0),
        others: Vec::new(),
        size: record,
        cycles: u64_at(&cg.data, 8),
        master,
        fields,
    }))
}

/// The time master channel `cn`: a float, or an integer, with a linear conversion or none.
fn time<R: Read + Seek>(input: &mut Input<R>, cn: &Block, name: &str, size: u64) -> Result<Master, Error> {
    let mut master = Master {
        field: None,
        offset: 0.0,
        factor: 1.0,
    };
    if byte(&cn.data, 0) == CN_MASTER {
        let f = field(input, cn, name, size)?;
        let ok = match f.data_type {
            FLOAT_LE | FLOAT_BE => f.bit == 0 && (f.bits == 32 || f.bits == 64),
            UINT_LE | INT_LE => f.bits <= 64,
            UINT_BE | INT_BE => f.bit == 0 && f.bits % 8 == 0 && f.bits <= 64,
            _ => false,
        };
        if !ok {
            return Err(input.error(
                cn.offset,
                format!(
                    "time channel {}: data type {} of {} bits is not read",
                    quote(name),
                    f.data_type,
                    f.bits
                ),
            ));
        }
        master.field = Some(f);
    }
    if cn.link(4) != 0 {
        let cc = input.block(
            cn.link(4),
            cn.offset,
            &[b"CC"],
            CC_DATA,
            "the time channel's conversion",
        )?;
        let values = u16_at(&cc.data, 6);
        match byte(&cc.data, 0) {
            0 => {}
            1 if values >= 2 && cc.data.len() >= 40 => {
                master.offset = f64::from_bits(u64_at(&cc.data, 24));
                master.factor = f64::from_bits(u64_at(&cc.data, 32));
            }
            t => {
                return Err(input.error(
                    cc.offset,
                    format!(
                        "time channel {}: conversion of type {t} (only linear ones are read)",
                        quote(name)
                    ),
                ));
            }
        }
    }
    Ok(master)
}

/// The interface names in the header's comment, by bus channel: `<tree name="bus channels">`
/// of `<e name="N">name</e>`, as [`Mf4Writer`] writes them.
pub(super) fn names(comment: &str) -> Vec<Option<String>> {
    let mut names = vec![None; 256];
    let Some(start) = comment.find(&format!("<tree name=\"{NAMES_TREE}\">")) else {
        return names;
    };
    let tree = &comment[start..];
    let tree = &tree[..tree.find("</tree>").unwrap_or(tree.len())];
    for e in tree.split("<e name=\"").skip(1) {
        let Some((number, rest)) = e.split_once('"') else {
            continue;
        };
        let Some((_, rest)) = rest.split_once('>') else {
            continue;
        };
        let Some((value, _)) = rest.split_once("</e>") else {
            continue;
        };
        let (Ok(n), Some(value)) = (number.parse::<u8>(), unescape(value)) else {
            continue;
        };
        if value.len() <= MAX_NAME
            && let Some(slot) = names.get_mut(usize::from(n))
        {
            *slot = Some(value);
        }
    }
    names
}

/// XML text with its entities and character references replaced; `None` if one is bad.
fn unescape(s: &str) -> Option<String> {
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(i) = rest.find('&') {
        out.push_str(&rest[..i]);
        let (entity, after) = rest[i + 1..].split_once(';')?;
        let c = match entity {
            "amp" => '&',
            "lt" => '<',
            "gt" => '>',
            "quot" => '"',
            "apos" => '\'',
            _ => {
                let code = match entity.strip_prefix("#x").or_else(|| entity.strip_prefix("#X")) {
                    Some(hex) => u32::from_str_radix(hex, 16).ok()?,
                    None => entity.strip_prefix('#')?.parse().ok()?,
                };
                char::from_u32(code)?
            }
        };
        out.push(c);
        rest = after;
    }
    out.push_str(rest);
    Some(out)
}
