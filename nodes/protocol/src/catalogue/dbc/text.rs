//! The DBC syntax: sections in the order DBC editors write them, numbers and strings in the forms
//! every parser reads.

use super::Network;
use super::layout::{Message, Mux, Signal, node_name};
use crate::ident::Address;
use core::fmt::Write;

/// Bit 31 marks an extended identifier in a DBC.
const EXTENDED: u32 = 0x8000_0000;

/// The symbols a DBC editor declares; tools expect the list even when most are unused.
const NEW_SYMBOLS: &[&str] = &[
    "NS_DESC_",
    "CM_",
    "BA_DEF_",
    "BA_",
    "VAL_",
    "CAT_DEF_",
    "CAT_",
    "FILTER",
    "BA_DEF_DEF_",
    "EV_DATA_",
    "ENVVAR_DATA_",
    "SGTYPE_",
    "SGTYPE_VAL_",
    "BA_DEF_SGTYPE_",
    "BA_SGTYPE_",
    "SIG_TYPE_REF_",
    "VAL_TABLE_",
    "SIG_GROUP_",
    "SIG_VALTYPE_",
    "SIGTYPE_VALTYPE_",
    "BO_TX_BU_",
    "BA_DEF_REL_",
    "BA_REL_",
    "BA_DEF_DEF_REL_",
    "BU_SG_REL_",
    "BU_EV_REL_",
    "BU_BO_REL_",
    "SG_MUL_VAL_",
];

/// A factor or offset: Rust's shortest round-trip form, so that the parsed value is the
/// catalogue's exactly (never an exponent: `{}` on f64 writes plain digits).
pub(super) fn exact(x: f64) -> String {
    if x == 0.0 { "0".to_string() } else { format!("{x}") }
}

/// A range bound: nine decimals at most, so that float noise from scaling
/// (655.3500000000001) does not show.
pub(super) fn bound(x: f64) -> String {
    let s = format!("{x:.9}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".to_string() } else { s.to_string() }
}

/// A DBC string: no double quotes or backslashes inside, and plain ASCII because DBC tools
/// read files as Windows-1252.
pub(super) fn string(text: &str) -> String {
    text.chars()
        .map(|c| match c {
            '"' => '\'',
            '\\' => '/',
            '\u{2013}' | '\u{2014}' => '-',
            '\u{00D7}' => 'x',
            c if c.is_ascii() => c,
            _ => '?',
        })
        .collect()
}

fn mux(m: Mux) -> String {
    match m {
        Mux::Plain => String::new(),
        Mux::Multiplexor => " M".to_string(),
        Mux::On(n) => format!(" m{n}"),
    }
}

fn sg(out: &mut String, s: &Signal, receiver: &str) {
    let _ = writeln!(
        out,
        " SG_ {}{} : {}|{}@1{} ({},{}) [{}|{}] \"{}\" {receiver}",
        s.name,
        mux(s.mux),
        s.start_bit,
        s.bits,
        if s.signed { "-" } else { "+" },
        exact(s.scale),
        exact(s.offset),
        bound(s.min),
        bound(s.max),
        string(s.unit),
    );
}

/// The whole file.
pub(super) fn write(network: &Network, nodes: &[Address], messages: &[Message]) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "VERSION \"\"\n\n");
    let _ = writeln!(out, "NS_ :");
    for s in NEW_SYMBOLS {
        let _ = writeln!(out, "\t{s}");
    }
    let _ = writeln!(out, "\nBS_:\n");
    let names: Vec<String> = nodes.iter().map(|a| node_name(*a)).collect();
    let _ = writeln!(out, "BU_: {}\n", names.join(" "));

    for m in messages {
        let _ = writeln!(
            out,
            "BO_ {} {}: {} {}",
            m.id.raw() | EXTENDED,
            m.name,
            m.dlc,
            node_name(m.id.source)
        );
        let receiver = node_name(m.id.destination);
        for s in &m.signals {
            sg(&mut out, s, &receiver);
        }
        let _ = writeln!(out);
    }

    let _ = writeln!(
        out,
        "CM_ \"{}: the CAN network of the cotton harvester as harvemu emulates it, written from its message catalogue. 29-bit identifiers: priority | frame type | destination | source.\";",
        string(&network.name)
    );
    for a in nodes {
        if let Some(name) = a.name() {
            let _ = writeln!(out, "CM_ BU_ {} \"{}\";", node_name(*a), string(&name));
        }
    }
    for m in messages {
        let id = m.id.raw() | EXTENDED;
        let _ = writeln!(out, "CM_ BO_ {id} \"{}\";", string(&m.comment));
        for s in &m.signals {
            let _ = writeln!(out, "CM_ SG_ {id} {} \"{}\";", s.name, string(&s.comment));
        }
    }

    let _ = writeln!(out, "BA_DEF_  \"BusType\" STRING ;");
    let _ = writeln!(out, "BA_DEF_  \"Baudrate\" INT 0 1000000;");
    let _ = writeln!(out, "BA_DEF_ BO_  \"GenMsgCycleTime\" INT 0 65535;");
    let _ = writeln!(
        out,
        "BA_DEF_ BO_  \"VFrameFormat\" ENUM  \"StandardCAN\",\"ExtendedCAN\",\"reserved\",\"J1939PG\";"
    );
    let _ = writeln!(out, "BA_DEF_ SG_  \"GenSigCycleTime\" INT 0 65535;");
    let _ = writeln!(out, "BA_DEF_DEF_  \"BusType\" \"CAN\";");
    let _ = writeln!(out, "BA_DEF_DEF_  \"Baudrate\" 0;");
    let _ = writeln!(out, "BA_DEF_DEF_  \"GenMsgCycleTime\" 0;");
    let _ = writeln!(out, "BA_DEF_DEF_  \"VFrameFormat\" \"ExtendedCAN\";");
    let _ = writeln!(out, "BA_DEF_DEF_  \"GenSigCycleTime\" 0;");
    let _ = writeln!(out, "BA_ \"BusType\" \"CAN\";");
    let _ = writeln!(out, "BA_ \"Baudrate\" {};", network.bitrate);
    for m in messages {
        let id = m.id.raw() | EXTENDED;
        // Index 1 of the VFrameFormat enum: ExtendedCAN.
        let _ = writeln!(out, "BA_ \"VFrameFormat\" BO_ {id} 1;");
        if let Some(ms) = m.cycle_ms {
            let _ = writeln!(out, "BA_ \"GenMsgCycleTime\" BO_ {id} {ms};");
        }
        for s in &m.signals {
            if let Some(ms) = s.cycle_ms {
                let _ = writeln!(out, "BA_ \"GenSigCycleTime\" SG_ {id} {} {ms};", s.name);
            }
        }
    }

    for m in messages {
        let id = m.id.raw() | EXTENDED;
        for s in m.signals.iter().filter(|s| !s.values.is_empty()) {
            let mut values = s.values.clone();
            values.sort_by_key(|(v, _)| *v);
            let table: Vec<String> = values
                .iter()
                .map(|(v, name)| format!("{v} \"{}\"", string(name)))
                .collect();
            let _ = writeln!(out, "VAL_ {id} {} {} ;", s.name, table.join(" "));
        }
    }
    out
}
