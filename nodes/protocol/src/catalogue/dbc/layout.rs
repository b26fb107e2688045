//! From the message table to DBC messages and signals: which catalogue messages share an
//! identifier, how their fields become signals, and what DBC leaves unsaid.

use super::Network;
use crate::catalogue::{Field, MessageDef, doc};
use crate::ident::{Address, AppId};
use std::collections::BTreeMap;

/// The multiplexing role of a signal.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum Mux {
    /// Always present.
    Plain,
    /// Data0, when it tells several messages apart (`M`).
    Multiplexor,
    /// Present when Data0 has this value (`m<n>`).
    On(u8),
}

/// One `SG_`.
#[derive(Clone, PartialEq, Debug)]
pub(super) struct Signal {
    pub name: String,
    pub mux: Mux,
    pub start_bit: u8,
    pub bits: u8,
    pub signed: bool,
    pub scale: f64,
    pub offset: f64,
    pub unit: &'static str,
    pub min: f64,
    pub max: f64,
    pub comment: String,
    pub values: Vec<(u32, String)>,
    /// The cycle of the signal's own message, written only for multiplexed signals.
    pub cycle_ms: Option<u32>,
    /// Short name of the message it belongs to, used to tell same-named fields apart.
    owner: &'static str,
}

/// One `BO_`: every catalogue message on one 29-bit identifier.
#[derive(Clone, PartialEq, Debug)]
pub(super) struct Message {
    pub id: AppId,
    pub name: String,
    pub dlc: u8,
    /// Shortest cycle of the messages on this identifier.
    pub cycle_ms: Option<u32>,
    pub comment: String,
    pub signals: Vec<Signal>,
}

/// The name of a node in `BU_`, transmitters and receivers: its address in hex, made a valid
/// DBC identifier when it starts with a digit.
pub(super) fn node_name(a: Address) -> String {
    let hex = a.to_string();
    if hex.starts_with(|c: char| c.is_ascii_digit()) {
        format!("N{hex}")
    } else {
        hex
    }
}

/// `text` as a DBC identifier: letters, digits and underscores, not starting with a digit.
fn identifier(text: &str) -> String {
    let mut s: String = text
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    if !s.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_') {
        s.insert(0, '_');
    }
    s
}

/// `flow.part1` -> `part1`.
fn short(m: &MessageDef) -> &'static str {
    m.name.split_once('.').map_or(m.name, |(_, what)| what)
}

fn same_layout(a: &MessageDef, b: &MessageDef) -> bool {
    a.fields.len() == b.fields.len()
        && a.fields.iter().zip(b.fields).all(|(x, y)| {
            (x.name, x.start_bit, x.bits, x.signed, x.unit) == (y.name, y.start_bit, y.bits, y.signed, y.unit)
                && x.scale == y.scale
                && x.offset == y.offset
        })
}

/// One signal for field `i` of messages laid out alike (usually just one message): the widest
/// range, every named value, and the constants each message fixes.
fn signal(messages: &[&'static MessageDef], i: usize, mux: Mux, cycle_ms: Option<u32>) -> Option<Signal> {
    let fields: Vec<(&str, &Field)> = messages
        .iter()
        .filter_map(|m| m.fields.get(i).map(|f| (m.name, f)))
        .collect();
    let (_, first) = *fields.first()?;
    let mut docs: Vec<&str> = Vec::new();
    let mut values: Vec<(u32, String)> = Vec::new();
    let mut constants: Vec<(&str, u32)> = Vec::new();
    for (message, f) in &fields {
        if !docs.contains(&f.doc) {
            docs.push(f.doc);
        }
        for (v, n) in f.values {
            if !values.iter().any(|(x, _)| x == v) {
                values.push((*v, n.to_string()));
            }
        }
        if let Some(c) = f.constant {
            constants.push((message, c));
        }
    }
    let mut comment = docs.join(" / ");
    if let [(_, c), rest @ ..] = constants.as_slice()
        && constants.len() == fields.len()
        && rest.iter().all(|(_, x)| x == c)
    {
        comment.push_str(&format!(" (always 0x{c:02X})"));
    } else if !constants.is_empty() {
        let each: Vec<String> = constants
            .iter()
            .map(|(m, c)| format!("0x{c:02X} in {m}"))
            .collect();
        comment.push_str(&format!(" ({})", each.join(", ")));
    }
    Some(Signal {
        name: first.name.to_string(),
        mux,
        start_bit: first.start_bit,
        bits: first.bits,
        signed: first.signed,
        scale: first.scale,
        offset: first.offset,
        unit: first.unit,
        min: fields.iter().map(|(_, f)| f.min).fold(f64::INFINITY, f64::min),
        max: fields
            .iter()
            .map(|(_, f)| f.max)
            .fold(f64::NEG_INFINITY, f64::max),
        comment,
        values,
        cycle_ms: if mux == Mux::Plain { None } else { cycle_ms },
        owner: messages.first().map_or("", |m| short(m)),
    })
}

/// Messages on one identifier that share a Data0 value.
struct Group {
    number: u8,
    messages: Vec<&'static MessageDef>,
}

/// Every identifier the catalogue gives `nodes`, in identifier order, with its messages.
pub(super) fn frames(messages: &'static [MessageDef], network: &Network, nodes: &[Address]) -> Vec<Message> {
    let mut by_id: BTreeMap<u32, (AppId, Address, Vec<Group>)> = BTreeMap::new();
    for m in messages {
        for &node in nodes.iter().filter(|a| m.nodes.contains(**a)) {
            let id = m.app_id(node);
            let (_, _, groups) = by_id.entry(id.raw()).or_insert((id, node, Vec::new()));
            match groups.iter_mut().find(|g| g.number == m.number) {
                Some(g) => g.messages.push(m),
                None => groups.push(Group {
                    number: m.number,
                    messages: vec![m],
                }),
            }
        }
    }
    by_id
        .into_values()
        .map(|(id, node, groups)| message(id, node, &groups, network))
        .collect()
}

fn message(id: AppId, node: Address, groups: &[Group], network: &Network) -> Message {
    let multiplexed = groups.len() > 1;
    let all: Vec<&'static MessageDef> = groups.iter().flat_map(|g| g.messages.iter().copied()).collect();
    let numbers = || groups.iter().map(|g| f64::from(g.number));
    let mut signals = vec![Signal {
        name: "message_number".to_string(),
        mux: if multiplexed { Mux::Multiplexor } else { Mux::Plain },
        start_bit: 0,
        bits: 8,
        signed: false,
        scale: 1.0,
        offset: 0.0,
        unit: "",
        min: numbers().fold(f64::INFINITY, f64::min),
        max: numbers().fold(f64::NEG_INFINITY, f64::max),
        comment: "Data0: the message number, which says how Data1-Data7 are laid out.".to_string(),
        values: groups
            .iter()
            .map(|g| {
                let names: Vec<&str> = g.messages.iter().map(|m| m.name).collect();
                (u32::from(g.number), names.join(", "))
            })
            .collect(),
        cycle_ms: None,
        owner: "",
    }];
    let mut notes = Vec::new();
    for g in groups {
        let cycle = g
            .messages
            .iter()
            .filter_map(|m| network.trigger(m, node).cycle_ms())
            .min();
        let mux = if multiplexed {
            Mux::On(g.number)
        } else {
            Mux::Plain
        };
        let Some((&base, rest)) = g.messages.split_first() else {
            continue;
        };
        let mut alike = vec![base];
        for m in rest {
            if same_layout(base, m) {
                alike.push(m);
            } else {
                notes.push(format!(
                    "{} shares Data0 = 0x{:02X} with {} but lays out its fields differently; DBC multiplexing on Data0 cannot tell them apart, so its fields are not given here.",
                    m.name, g.number, base.name
                ));
            }
        }
        let first = signals.len();
        signals.extend((0..base.fields.len()).filter_map(|i| signal(&alike, i, mux, cycle)));
        // Messages that share a Data0 value are told apart by a selector byte: name them in
        // the value table of the signal on that byte.
        if g.messages.len() > 1 {
            for m in &g.messages {
                let Some((byte, value)) = m.selector else { continue };
                if let Some(s) = signals[first..]
                    .iter_mut()
                    .find(|s| u16::from(s.start_bit) == u16::from(byte) * 8 && s.bits == 8)
                    && !s.values.iter().any(|(v, _)| *v == u32::from(value))
                {
                    s.values.push((u32::from(value), m.name.to_string()));
                }
            }
        }
    }
    // One line per message (the truth DBC has no place for: own DLC, trigger), then the notes.
    let mut lines: Vec<String> = all
        .iter()
        .map(|m| {
            let selector = m
                .selector
                .map(|(byte, v)| format!(", Data{byte} = 0x{v:02X}"))
                .unwrap_or_default();
            format!(
                "{} (Data0 = 0x{:02X}{selector}, DLC {}, {}): {}",
                m.name,
                m.number,
                m.dlc,
                doc::trigger(network.trigger(m, node)),
                m.doc
            )
        })
        .collect();
    lines.append(&mut notes);
    unique_names(&mut signals);
    let name = match all.as_slice() {
        [one] => format!("{}_{}", identifier(one.name), node_name(node)),
        _ => {
            let kind = all[0].name.split('.').next().unwrap_or("messages");
            let kind = if all.iter().all(|m| m.name.split('.').next() == Some(kind)) {
                kind
            } else {
                "messages"
            };
            format!(
                "{}_{}_to_{}",
                identifier(kind),
                node_name(id.source),
                node_name(id.destination)
            )
        }
    };
    Message {
        id,
        name,
        dlc: all.iter().map(|m| m.dlc).max().unwrap_or(8),
        cycle_ms: groups
            .iter()
            .flat_map(|g| &g.messages)
            .filter_map(|m| network.trigger(m, node).cycle_ms())
            .min(),
        comment: lines.join("\n"),
        signals,
    }
}

/// Signal names are unique within a `BO_`: a field name that several messages on one identifier
/// use is prefixed with its message's short name (`status_state`).
fn unique_names(signals: &mut [Signal]) {
    let mut count: BTreeMap<String, usize> = BTreeMap::new();
    for s in signals.iter() {
        *count.entry(s.name.clone()).or_default() += 1;
    }
    for s in signals.iter_mut() {
        if count.get(&s.name).copied().unwrap_or(0) > 1 && !s.owner.is_empty() {
            s.name = format!("{}_{}", s.owner, s.name);
        }
        s.name = identifier(&s.name);
    }
    // Whatever still clashes (a prefixed name equal to another field's) gets a number.
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    for s in signals.iter_mut() {
        let n = seen.entry(s.name.clone()).or_default();
        *n += 1;
        if *n > 1 {
            s.name = format!("{}_{}", s.name, n);
        }
    }
}
