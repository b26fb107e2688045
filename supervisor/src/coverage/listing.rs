//! The plain listing of an image's coverage: every instruction the image holds, with how often
//! it ran and, for a conditional jump, which way.
//!
//! Instructions are found by decoding each range the image writes from its start, one after
//! another; where an address that ran lies inside what that decoding took for one instruction
//! (data in the code, a table), the bytes before it are listed as data and decoding starts
//! again there.

use super::record::ImageCoverage;
use nodes::firmware::coverage::Counts;
use std::fmt::Write as _;

/// An instruction (or, when `data`, bytes taken as data) at `address`, `len` bytes long.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Item {
    /// Its address.
    pub address: u16,
    /// Its length.
    pub len: u16,
    /// Its text (`DJNZ R7, 0032H`), or `DB` for data.
    pub text: String,
    /// Bytes that are not an instruction.
    pub data: bool,
    /// A conditional jump (JB, JNB, JBC, JC, JNC, JZ, JNZ, CJNE, DJNZ) whose target is not the
    /// next instruction.
    pub branches: bool,
}

const CONDITIONAL: [&str; 9] = ["JB", "JNB", "JBC", "JC", "JNC", "JZ", "JNZ", "CJNE", "DJNZ"];

/// The instructions of `code` in `written` (see the module docs).
pub fn items(code: &[u8], written: &[(u32, u32)], counts: &Counts) -> Vec<Item> {
    let mut out = Vec::new();
    for &(start, end) in written {
        let end = end.min(code.len() as u32);
        let mut pc = start;
        while pc < end {
            let address = pc as u16;
            let (text, len) = mcs51::disasm(code, address);
            let len = u32::from(len.max(1)).min(end - pc);
            // An address that ran, inside this decoding: data up to it.
            if let Some(inner) = (pc + 1..pc + len).find(|&a| counts.get(a as u16).runs > 0) {
                out.push(Item {
                    address,
                    len: (inner - pc) as u16,
                    text: "DB".into(),
                    data: true,
                    branches: false,
                });
                pc = inner;
                continue;
            }
            let mnemonic = text.split_whitespace().next().unwrap_or("");
            // Every conditional jump ends in its relative offset; one of 0 goes on to the next
            // instruction either way (SDCC compares with `CJNE R7,#0FH,$+3` to set the carry):
            // no branch.
            let offset = code.get((pc + len - 1) as usize).copied().unwrap_or(0);
            out.push(Item {
                address,
                len: len as u16,
                branches: CONDITIONAL.contains(&mnemonic) && offset != 0,
                text,
                data: false,
            });
            pc += len;
        }
    }
    out
}

/// Totals of a listing: instructions and branch directions, all and covered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Totals {
    /// Instructions.
    pub instructions: u64,
    /// Of them, run at least once.
    pub run: u64,
    /// Branch directions (two per conditional jump).
    pub directions: u64,
    /// Of them, taken at least once.
    pub taken: u64,
}

/// The totals of `items` under `counts`.
pub fn totals(items: &[Item], counts: &Counts) -> Totals {
    let mut t = Totals::default();
    for i in items.iter().filter(|i| !i.data) {
        let c = counts.get(i.address);
        t.instructions += 1;
        t.run += u64::from(c.runs > 0);
        if i.branches {
            t.directions += 2;
            t.taken += u64::from(c.taken > 0) + u64::from(c.not_taken > 0);
        }
    }
    t
}

/// "412 of 530 instructions (77.7 %), 60 of 98 branch directions (61.2 %)".
pub fn describe(t: &Totals) -> String {
    let pct = |a: u64, b: u64| if b == 0 { 0.0 } else { 100.0 * a as f64 / b as f64 };
    format!(
        "{} of {} instructions ({:.1} %), {} of {} branch directions ({:.1} %)",
        t.run,
        t.instructions,
        pct(t.run, t.instructions),
        t.taken,
        t.directions,
        pct(t.taken, t.directions)
    )
}

/// The listing's text: `image`, its code, counts and instructions ([`items`]).
pub fn text(image: &ImageCoverage, code: &[u8], counts: &Counts, items: &[Item]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "; harvemu coverage of {} (SHA-256 {}), nodes {}, {}",
        image.image,
        image.sha256,
        image.nodes.join(" "),
        bus::text::count(image.runs, "run", "runs")
    );
    let _ = writeln!(out, "; {}", describe(&totals(items, counts)));
    let _ = writeln!(
        out,
        "; address  bytes      instruction               runs      jumped  fell through"
    );
    for i in items {
        let bytes: Vec<String> = (0..i.len)
            .take(if i.data { 8 } else { 3 })
            .map(|k| {
                format!(
                    "{:02X}",
                    code.get(usize::from(i.address) + usize::from(k))
                        .copied()
                        .unwrap_or(0xFF)
                )
            })
            .collect();
        let more = if i.data && i.len > 8 { " .." } else { "" };
        let c = counts.get(i.address);
        let text = if i.data {
            format!("DB ({} bytes)", i.len)
        } else {
            i.text.clone()
        };
        let _ = write!(
            out,
            "{:04X}       {:<10} {:<24}",
            i.address,
            format!("{}{more}", bytes.join(" ")),
            text
        );
        if i.data {
            let _ = writeln!(out);
        } else if i.branches {
            let _ = writeln!(out, " {:>10} {:>10} {:>10}", c.runs, c.taken, c.not_taken);
        } else {
            let _ = writeln!(out, " {:>10}", c.runs);
        }
    }
    out
}
