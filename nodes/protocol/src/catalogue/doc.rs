//! The catalogue written out as Markdown tables, so that `docs/PROTOCOL.md` can carry the table
//! itself rather than a copy that drifts (a test compares the two).

use super::{Direction, MESSAGES, MessageDef, Nodes, Trigger};
use crate::ident::Address;
use core::fmt::Write;

/// Marks the start of the generated part of `docs/PROTOCOL.md`.
pub const BEGIN: &str = "<!-- BEGIN GENERATED CATALOGUE -->";
/// Marks its end.
pub const END: &str = "<!-- END GENERATED CATALOGUE -->";

fn nodes(n: Nodes) -> String {
    match n {
        Nodes::Kind(kind) => kind.name().to_string(),
        Nodes::One(address) => address.to_string(),
    }
}

pub(super) fn trigger(t: Trigger) -> String {
    match t {
        Trigger::Periodic { period_ms } => format!("every {period_ms} ms"),
        Trigger::OnChange { heartbeat_ms } => format!("on change, at least every {heartbeat_ms} ms"),
        Trigger::Event => "event".to_string(),
        Trigger::Group { period_ms } => format!("group, every {period_ms} ms"),
    }
}

fn number(x: f64) -> String {
    // Trim float noise such as 0.30000000000000004 without losing real digits.
    let s = format!("{:.6}", x);
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".to_string() } else { s.to_string() }
}

fn message(out: &mut String, m: &MessageDef) {
    let (from, to) = match m.direction {
        Direction::ToMonitor => (nodes(m.nodes), "monitor F5".to_string()),
        Direction::FromMonitor => ("monitor F5".to_string(), nodes(m.nodes)),
    };
    let example = Address::all()
        .find(|a| m.nodes.contains(*a))
        .map(|a| m.app_id(a).raw())
        .unwrap_or(0);
    let _ = writeln!(out, "### `{}`\n", m.name);
    let _ = writeln!(out, "{}\n", m.doc);
    let selector = m
        .selector
        .map(|(byte, v)| format!(", Data{byte} = 0x{v:02X}"))
        .unwrap_or_default();
    let _ = writeln!(
        out,
        "Data0 = 0x{:02X}{selector} · {from} -> {to} · priority {} ({}) · {} · DLC {} · {} · e.g. `{example:08X}`\n",
        m.number,
        m.priority().value(),
        m.priority().class_name(),
        m.frame_type,
        m.dlc,
        trigger(m.trigger),
    );
    let _ = writeln!(
        out,
        "| field | bytes (bits) | type | scale | offset | unit | range | values |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|");
    for f in m.fields {
        let first = f.start_bit / 8;
        let last = (f.start_bit + f.bits - 1) / 8;
        let place = if f.bits % 8 == 0 && f.start_bit % 8 == 0 {
            if first == last {
                format!("Data{first}")
            } else {
                format!("Data{first}–Data{last} (LE)")
            }
        } else {
            format!(
                "Data{first} bit {}{}",
                f.start_bit % 8,
                if f.bits > 1 {
                    format!("+{}", f.bits)
                } else {
                    String::new()
                }
            )
        };
        let ty = format!("{}{}", if f.signed { "i" } else { "u" }, f.bits);
        let range = match f.constant {
            Some(c) => format!("fixed 0x{c:X}"),
            None => format!("{} to {}", number(f.min), number(f.max)),
        };
        let values = f
            .values
            .iter()
            .map(|(v, n)| format!("{v}={n}"))
            .collect::<Vec<_>>()
            .join(", ");
        let _ = writeln!(
            out,
            "| `{}` | {place} | {ty} | {} | {} | {} | {range} | {values} |",
            f.name,
            number(f.scale),
            number(f.offset),
            f.unit,
        );
    }
    let _ = writeln!(out);
}

/// The generated part of `docs/PROTOCOL.md`, markers included.
pub fn markdown() -> String {
    let mut out = String::new();
    let _ = writeln!(out, "{BEGIN}\n");
    for m in MESSAGES {
        message(&mut out, m);
    }
    let _ = write!(out, "{END}");
    out
}
