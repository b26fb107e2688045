//! The acceptance filter a script declares: register values as the node's firmware writes them,
//! read into the bus's filter types (`bus::filter`), which hold the chips' semantics.
//!
//! Register values are text so that a typo is reported with the script's file, node and field
//! instead of as a syntax error: four-byte register images as `"18 05 07 A8"` (or `"180507A8"`,
//! or with `0x` before each byte), SocketCAN words as `"0x8601D0F5"`.

use super::model::{FilterDef, SocketCanDef};
use bus::engine::Filter;
use bus::filter::{AtmelFilter, Sja1000Filter, SocketCanFilter, SocketCanFilterSet};
use bus::text::quote;

/// What is wrong with one field of a filter declaration.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FilterProblem {
    /// The field, as a path below the filter (`.canidt`, `[1].can_mask`; empty for the filter
    /// itself).
    pub field: String,
    /// What is wrong.
    pub message: String,
}

impl FilterProblem {
    fn new(field: impl Into<String>, message: impl Into<String>) -> FilterProblem {
        FilterProblem {
            field: field.into(),
            message: message.into(),
        }
    }
}

impl FilterDef {
    /// The controller filter these registers set up, or every problem with them.
    pub fn to_filter(&self) -> Result<Filter, Vec<FilterProblem>> {
        let mut problems = Vec::new();
        let mut regs = |field: &str, text: &str| {
            register_image(text).map_err(|m| problems.push(FilterProblem::new(field, m)))
        };
        let filter = match self {
            FilterDef::Atmel { canidt, canidm, ide } => {
                let (idt, idm) = (regs(".canidt", canidt), regs(".canidm", canidm));
                match (idt, idm) {
                    (Ok(idt), Ok(idm)) => Some(Filter::Atmel(AtmelFilter {
                        idt,
                        idm,
                        ide: *ide,
                        // The chip keeps IDEMSK in CANIDM4 bit 0; the bus model reads it from
                        // here.
                        ide_mask: idm[3] & AtmelFilter::IDEMSK != 0,
                    })),
                    _ => None,
                }
            }
            FilterDef::Sja1000 { mode, acr, amr } => {
                let (acr, amr) = (regs(".acr", acr), regs(".amr", amr));
                match (acr, amr) {
                    (Ok(acr), Ok(amr)) => Some(Filter::Sja1000(Sja1000Filter {
                        mode: *mode,
                        acr,
                        amr,
                    })),
                    _ => None,
                }
            }
            FilterDef::SocketCan(list) => {
                if list.is_empty() {
                    problems.push(FilterProblem::new(
                        "",
                        "an empty filter list receives nothing: list at least one filter",
                    ));
                }
                let mut set = Vec::new();
                for (i, SocketCanDef { can_id, can_mask }) in list.iter().enumerate() {
                    let id = word(can_id)
                        .map_err(|m| problems.push(FilterProblem::new(format!("[{i}].can_id"), m)));
                    let mask = word(can_mask)
                        .map_err(|m| problems.push(FilterProblem::new(format!("[{i}].can_mask"), m)));
                    if let (Ok(id), Ok(mask)) = (id, mask) {
                        set.push(SocketCanFilter::new(id, mask));
                    }
                }
                Some(Filter::SocketCan(SocketCanFilterSet(set)))
            }
        };
        match filter {
            Some(f) if problems.is_empty() => Ok(f),
            _ => Err(problems),
        }
    }
}

/// Reads a four-register image (CANIDT1..4, CANIDM1..4, ACR0..3, AMR0..3), first register
/// first: four hex bytes apart (`18 05 07 A8`, `0x18 0x05 0x07 0xA8`) or eight hex digits
/// together (`180507A8`).
pub(super) fn register_image(text: &str) -> Result<[u8; 4], String> {
    let tokens: Vec<&str> = text.split_whitespace().collect();
    let digits: Vec<&str> = match tokens.as_slice() {
        [one] => {
            let one = strip_0x(one);
            if one.len() != 8 {
                return Err(format!(
                    "{} is not four register bytes: write them as \"18 05 07 A8\"",
                    quote(text)
                ));
            }
            (0..4).filter_map(|i| one.get(2 * i..2 * i + 2)).collect()
        }
        bytes if bytes.len() == 4 => bytes.iter().map(|b| strip_0x(b)).collect(),
        bytes => {
            return Err(format!(
                "{} has {} bytes: the filter has four registers",
                quote(text),
                bytes.len()
            ));
        }
    };
    if digits.len() != 4 {
        return Err(format!("{} is not four register bytes", quote(text)));
    }
    let mut image = [0u8; 4];
    for (slot, byte) in image.iter_mut().zip(&digits) {
        let bad = || format!("{}: {} is not a hex byte", quote(text), quote(byte));
        if byte.len() != 2 || !byte.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(bad());
        }
        *slot = u8::from_str_radix(byte, 16).map_err(|_| bad())?;
    }
    Ok(image)
}

/// Reads a 32-bit `can_id` or `can_mask`: one to eight hex digits, `0x` in front optional.
pub(super) fn word(text: &str) -> Result<u32, String> {
    let digits = strip_0x(text.trim());
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(format!("{} is not a hex number", quote(text)));
    }
    if digits.len() > 8 {
        return Err(format!("{} is wider than the 32 bits of a can_id", quote(text)));
    }
    u32::from_str_radix(digits, 16).map_err(|_| format!("{} is not a hex number", quote(text)))
}

fn strip_0x(s: &str) -> &str {
    s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")).unwrap_or(s)
}
