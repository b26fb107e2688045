//! A [`Database`] written out as DBC text again, with the cycle times a network really sends.

use super::{ByteOrder, Database, Message, Mux};
use std::collections::BTreeMap;
use std::fmt::Write as _;

/// What a DBC written from a running network says beyond the database.
pub struct Written<'a> {
    /// The network's name (`DBName`).
    pub name: &'a str,
    /// Its bit rate (`Baudrate`).
    pub bitrate: u32,
    /// The cycle time of each message a node sends on its own, ms, by message name; a message
    /// not here gets none.
    pub cycles: &'a BTreeMap<String, u32>,
}

/// A DBC string literal's content: DBC strings cannot hold `"`, and are one line.
fn text(s: &str) -> String {
    s.replace('"', "'").replace(['\r', '\n'], " ")
}

/// A number as DBC tools read it: the shortest decimal that reads back as the same f64.
fn num(v: f64) -> String {
    if v.is_finite() { format!("{v}") } else { "0".into() }
}

/// A `BO_` identifier: bit 31 marks an extended one.
fn bo_id(m: &Message) -> u64 {
    u64::from(m.id) | if m.extended { 0x8000_0000 } else { 0 }
}

impl Database {
    /// The database as DBC text, its messages in order, with the cycle times of `w`.
    pub fn to_dbc(&self, w: &Written) -> String {
        let mut t = String::new();
        let _ = writeln!(
            t,
            "VERSION \"\"\n\nNS_ :\n\tCM_\n\tBA_DEF_\n\tBA_\n\tVAL_\n\tBA_DEF_DEF_\n\nBS_:\n"
        );
        let _ = writeln!(t, "BU_: {}\n", self.nodes.join(" "));
        for m in &self.messages {
            let from = m.transmitter.as_deref().unwrap_or("Vector__XXX");
            let _ = writeln!(t, "BO_ {} {}: {} {from}", bo_id(m), m.name, m.dlc);
            for s in &m.signals {
                let mux = match s.mux {
                    Mux::Plain => String::new(),
                    Mux::Multiplexor => " M".into(),
                    Mux::On(n) => format!(" m{n}"),
                };
                let order = match s.byte_order {
                    ByteOrder::Intel => 1,
                    ByteOrder::Motorola => 0,
                };
                let sign = if s.signed { '-' } else { '+' };
                let to = if s.receivers.is_empty() {
                    "Vector__XXX".to_string()
                } else {
                    s.receivers.join(",")
                };
                let _ = writeln!(
                    t,
                    " SG_ {}{mux} : {}|{}@{order}{sign} ({},{}) [{}|{}] \"{}\" {to}",
                    s.name,
                    s.start_bit,
                    s.bits,
                    num(s.factor),
                    num(s.offset),
                    num(s.min),
                    num(s.max),
                    text(&s.unit)
                );
            }
            let _ = writeln!(t);
        }
        if let Some(c) = &self.comment {
            let _ = writeln!(t, "CM_ \"{}\";", text(c));
        }
        for m in &self.messages {
            if let Some(c) = &m.comment {
                let _ = writeln!(t, "CM_ BO_ {} \"{}\";", bo_id(m), text(c));
            }
            for s in &m.signals {
                if let Some(c) = &s.comment {
                    let _ = writeln!(t, "CM_ SG_ {} {} \"{}\";", bo_id(m), s.name, text(c));
                }
            }
        }
        // The send types the messages have, in order of first use, as an enumeration.
        let mut send_types: Vec<&str> = Vec::new();
        for m in &self.messages {
            if let Some(st) = m.send_type.as_deref()
                && !send_types.contains(&st)
            {
                send_types.push(st);
            }
        }
        let _ = writeln!(t, "BA_DEF_ BO_ \"GenMsgCycleTime\" INT 0 65535;");
        if !send_types.is_empty() {
            let names: Vec<String> = send_types.iter().map(|s| format!("\"{}\"", text(s))).collect();
            let _ = writeln!(t, "BA_DEF_ BO_ \"GenMsgSendType\" ENUM {};", names.join(","));
        }
        let _ = writeln!(t, "BA_DEF_ SG_ \"GenSigStartValue\" INT -2147483648 2147483647;");
        let _ = writeln!(t, "BA_DEF_ \"Baudrate\" INT 0 1000000;");
        let _ = writeln!(t, "BA_DEF_ \"DBName\" STRING;");
        let _ = writeln!(t, "BA_DEF_ \"BusType\" STRING;");
        let _ = writeln!(t, "BA_DEF_DEF_ \"GenMsgCycleTime\" 0;");
        if let Some(first) = send_types.first() {
            let _ = writeln!(t, "BA_DEF_DEF_ \"GenMsgSendType\" \"{}\";", text(first));
        }
        let _ = writeln!(t, "BA_DEF_DEF_ \"GenSigStartValue\" 0;");
        let _ = writeln!(t, "BA_DEF_DEF_ \"Baudrate\" 500000;");
        let _ = writeln!(t, "BA_DEF_DEF_ \"DBName\" \"\";");
        let _ = writeln!(t, "BA_DEF_DEF_ \"BusType\" \"CAN\";");
        let _ = writeln!(t, "BA_ \"DBName\" \"{}\";", text(w.name));
        let _ = writeln!(t, "BA_ \"Baudrate\" {};", w.bitrate);
        let _ = writeln!(t, "BA_ \"BusType\" \"CAN\";");
        for m in &self.messages {
            if let Some(c) = w.cycles.get(&m.name) {
                let _ = writeln!(t, "BA_ \"GenMsgCycleTime\" BO_ {} {c};", bo_id(m));
            }
            if let Some(i) = m
                .send_type
                .as_deref()
                .and_then(|st| send_types.iter().position(|x| *x == st))
            {
                let _ = writeln!(t, "BA_ \"GenMsgSendType\" BO_ {} {i};", bo_id(m));
            }
            for s in &m.signals {
                if let Some(v) = s.start_raw {
                    let _ = writeln!(
                        t,
                        "BA_ \"GenSigStartValue\" SG_ {} {} {};",
                        bo_id(m),
                        s.name,
                        num(v)
                    );
                }
            }
        }
        for m in &self.messages {
            for s in m.signals.iter().filter(|s| !s.values.is_empty()) {
                let list: Vec<String> = s
                    .values
                    .iter()
                    .map(|(v, name)| format!("{v} \"{}\"", text(name)))
                    .collect();
                let _ = writeln!(t, "VAL_ {} {} {} ;", bo_id(m), s.name, list.join(" "));
            }
        }
        t
    }
}
