//! What `harvemu import` writes for a database: the network file, one node script per node
//! (one that sends nothing only listens), and a warning for everything the scripts cannot do as
//! the DBC says. Pure: text in, text out.

use bus::bits::BitRate;
use protocol::database::{Database, Message, Mux, Signal};
use std::fmt::Write as _;

/// The values the generated scripts give signals.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Signals {
    /// Each signal's initial value (`GenSigStartValue`, else raw 0), constant.
    Initial,
    /// A sine across each signal's range.
    Sine,
    /// A sawtooth across each signal's range.
    Ramp,
    /// A random walk within each signal's range.
    Walk,
}

/// The bit rate of a database that gives none, or one the bus cannot run.
pub const DEFAULT_BITRATE: u32 = 250_000;

/// One file to write, relative to the output folder.
pub struct File {
    /// Path inside the folder (`network.ron`, `nodes/engine.ron`).
    pub path: String,
    /// Its text.
    pub text: String,
}

/// The import of one database.
pub struct Plan {
    /// The files, the network file first.
    pub files: Vec<File>,
    /// One line per thing not imported as the DBC says.
    pub warnings: Vec<String>,
    /// Nodes (each has a script, a node that sends nothing one that only listens), messages
    /// sent on their own (periodic or on change), event messages written as `OnRequest`.
    pub counts: (usize, usize, usize),
}

/// Plans the import of `db`, read from the file called `dbc_name` (which the scripts name as
/// `../{dbc_name}` and the network file holds beside it); `stem` names the network when the
/// database does not.
pub fn plan(db: &Database, dbc_name: &str, stem: &str, signals: Signals) -> Plan {
    let mut warnings: Vec<String> = db
        .warnings
        .iter()
        .map(|w| format!("{}: {}", w.at, w.reason))
        .collect();
    let bitrate = match db.bitrate {
        Some(b) if BitRate::for_bus(b).is_some() => b,
        Some(b) => {
            warnings.push(format!(
                "Baudrate {b} bit/s: {}; the network runs at {DEFAULT_BITRATE}",
                BitRate::RULE
            ));
            DEFAULT_BITRATE
        }
        None => DEFAULT_BITRATE,
    };
    let mut files = Vec::new();
    let mut node_files = Vec::new();
    let mut counts = (0, 0, 0);
    let mut taken = std::collections::BTreeSet::new();
    // The nodes of `BU_`, then any transmitter the file does not list there.
    let mut nodes: Vec<&str> = db.nodes.iter().map(String::as_str).collect();
    for m in &db.messages {
        if let Some(t) = m.transmitter.as_deref()
            && !nodes.contains(&t)
        {
            warnings.push(format!(
                "{}: its transmitter {t} is not in BU_: taken as a node",
                shown(m)
            ));
            nodes.push(t);
        }
    }
    for &node in &nodes {
        let sent: Vec<&Message> = db.sent_by(node).collect();
        if sent.is_empty() {
            // It is on the bus all the same: its controller acknowledges every frame, without
            // which a lone sender sees nothing but acknowledgement errors.
            warnings.push(format!(
                "node {node} sends nothing: its script only listens (its controller acknowledges frames)"
            ));
        }
        let mut file = file_name(node);
        while !taken.insert(file.clone()) {
            file = format!("{}_", file.trim_end_matches(".ron")) + ".ron";
        }
        let script = script(db, node, &sent, dbc_name, signals, &mut warnings);
        counts.0 += 1;
        counts.1 += script.1;
        counts.2 += script.2;
        node_files.push(format!("nodes/{file}"));
        files.push(File {
            path: format!("nodes/{file}"),
            text: script.0,
        });
    }
    for m in db.messages.iter().filter(|m| m.transmitter.is_none()) {
        warnings.push(format!("{}: no transmitting node: not sent", shown(m)));
    }
    let name = db.name.clone().unwrap_or_else(|| stem.to_string());
    let mut net = String::new();
    let _ = writeln!(
        net,
        "// {name}, imported from {dbc_name} by `harvemu import`: run it with"
    );
    let _ = writeln!(
        net,
        "// `harvemu run network.ron`. The node scripts are in nodes/."
    );
    let _ = writeln!(net, "Network(");
    let _ = writeln!(net, "    name: {},", ron_string(&name));
    let _ = writeln!(net, "    bitrate: {bitrate},");
    let _ = writeln!(net, "    nodes: [");
    for f in &node_files {
        let _ = writeln!(net, "        {},", ron_string(f));
    }
    let _ = writeln!(net, "    ],");
    let _ = writeln!(net, ")");
    files.insert(
        0,
        File {
            path: "network.ron".into(),
            text: net,
        },
    );
    Plan {
        files,
        warnings,
        counts,
    }
}

/// `EEC1 (0x0CF00400)`.
fn shown(m: &Message) -> String {
    format!("{} (0x{:X})", m.name, m.id)
}

/// A node's script file name: its name in lower case, other characters than letters, digits,
/// `-` and `_` as `_`.
fn file_name(node: &str) -> String {
    let stem: String = node
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c.to_ascii_lowercase()
            } else {
                '_'
            }
        })
        .collect();
    format!("{}.ron", if stem.is_empty() { "node" } else { &stem })
}

/// A RON string literal.
fn ron_string(s: &str) -> String {
    format!("{s:?}")
}

/// A number as RON writes a float (`1.0`, `0.125`, `-40.0`).
fn num(v: f64) -> String {
    let s = format!("{v:?}");
    if s.contains(['.', 'e', 'E']) || s.contains("inf") || s.contains("NaN") {
        s
    } else {
        format!("{s}.0")
    }
}

/// When a message goes out: `Periodic`, `OnChange` for a cyclic message also sent on change,
/// or `None` for an event message.
fn when(m: &Message, phase: u32) -> Option<String> {
    let cycle = m.cycle_ms.filter(|&c| c > 0)?;
    let send = m.send_type.as_deref().unwrap_or("").to_ascii_lowercase();
    let spontaneous = send.contains("spontan") || send.contains("onchange") || send.contains("onwrite");
    if spontaneous && send.contains("cyclic") {
        Some(format!(
            "OnChange(heartbeat_ms: {cycle}, check_ms: {})",
            cycle.min(10)
        ))
    } else {
        Some(format!(
            "Periodic(period_ms: {cycle}, phase_ms: {})",
            phase % cycle
        ))
    }
}

/// The physical span a generator may use: the signal's range, else what its bits hold.
fn span(s: &Signal) -> (f64, f64) {
    if s.has_range() {
        return (s.min, s.max);
    }
    let (lo, hi) = s.raw_range();
    let (a, b) = (s.physical(lo), s.physical(hi));
    (a.min(b), a.max(b))
}

/// The generator of one signal; `Const` of its initial value (or 0) where another would need a
/// number that is not finite (a range wider than f64 spans).
fn generator(s: &Signal, m: &Message, signals: Signals) -> String {
    let (lo, hi) = span(s);
    if (hi - lo).is_finite() {
        moving(s, m, signals)
    } else if s.initial().is_finite() {
        format!("Const({})", num(s.initial()))
    } else {
        "Const(0.0)".into()
    }
}

fn moving(s: &Signal, m: &Message, signals: Signals) -> String {
    let (lo, hi) = span(s);
    if s.mux == Mux::Multiplexor {
        // Every page in turn.
        let pages: Vec<String> = m
            .mux_values()
            .iter()
            .map(|&v| num(s.physical(i128::from(v))))
            .collect();
        if !pages.is_empty() {
            return format!("Cycle([{}])", pages.join(", "));
        }
    }
    if signals == Signals::Initial {
        return format!("Const({})", num(s.initial()));
    }
    if !s.values.is_empty() {
        let named: Vec<String> = s
            .values
            .iter()
            .map(|(raw, _)| num(s.physical(i128::from(*raw))))
            .collect();
        return format!("Cycle([{}])", named.join(", "));
    }
    match signals {
        Signals::Initial => format!("Const({})", num(s.initial())),
        Signals::Sine => format!(
            "Sine(mean: {}, amplitude: {}, period_s: 60.0)",
            num((lo + hi) / 2.0),
            num((hi - lo) / 2.0)
        ),
        Signals::Ramp => format!("Ramp(from: {}, to: {}, period_s: 60.0)", num(lo), num(hi)),
        Signals::Walk => format!(
            "RandomWalk(start: {}, step: {}, min: {}, max: {})",
            num(s.initial().clamp(lo, hi)),
            num((hi - lo) / 100.0),
            num(lo),
            num(hi)
        ),
    }
}

/// The SocketCAN filter entry that takes exactly message `m`'s data frames.
fn filter_entry(m: &Message) -> String {
    if m.extended {
        format!(
            "(can_id: \"0x{:08X}\", can_mask: \"0xDFFFFFFF\")",
            m.id | 0x8000_0000
        )
    } else {
        format!("(can_id: \"0x{:03X}\", can_mask: \"0xC00007FF\")", m.id)
    }
}

/// The script of `node`, which sends `sent`: its text, the messages it sends on its own and the
/// event messages it holds for actions.
fn script(
    db: &Database,
    node: &str,
    sent: &[&Message],
    dbc_name: &str,
    signals: Signals,
    warnings: &mut Vec<String>,
) -> (String, usize, usize) {
    let mut own = Vec::new();
    let mut events = Vec::new();
    for m in sent {
        if m.cycle_ms.is_some_and(|c| c > 0) {
            own.push(*m);
        } else {
            events.push(*m);
            let send = m
                .send_type
                .as_deref()
                .map_or(String::new(), |t| format!(" (send type {t})"));
            warnings.push(format!(
                "{}: no cycle time{send}: an event message, written with `when: OnRequest` (an action's Send(\"{}\") sends it)",
                shown(m),
                m.name
            ));
        }
    }
    let received: Vec<&Message> = db
        .messages
        .iter()
        .filter(|m| m.transmitter.as_deref() != Some(node))
        .filter(|m| m.signals.iter().any(|s| s.receivers.iter().any(|r| r == node)))
        .collect();
    let mut t = String::new();
    let _ = writeln!(t, "// {node}, imported from {dbc_name} by `harvemu import`.");
    let cyc: Vec<String> = own
        .iter()
        .map(|m| format!("{} ({} ms)", m.name, m.cycle_ms.unwrap_or(0)))
        .collect();
    if !cyc.is_empty() {
        let _ = writeln!(t, "// Sends on its own: {}.", cyc.join(", "));
    }
    if !events.is_empty() {
        let names: Vec<&str> = events.iter().map(|m| m.name.as_str()).collect();
        let _ = writeln!(
            t,
            "// Not generated (event messages, no cycle time): {}. Each is here as `OnRequest`: a",
            names.join(", ")
        );
        let _ = writeln!(t, "// reaction's Send(\"NAME\") sends it.");
    }
    for w in db
        .warnings
        .iter()
        .filter(|w| sent.iter().any(|m| w.at.starts_with(&format!("{} ", m.name))))
    {
        let _ = writeln!(t, "// Warning: {}: {}", w.at, w.reason);
    }
    let _ = writeln!(t, "NodeScript(");
    let _ = writeln!(t, "    name: {},", ron_string(node));
    let _ = writeln!(
        t,
        "    database: Some({}),",
        ron_string(&format!("../{dbc_name}"))
    );
    if received.is_empty() {
        let _ = writeln!(
            t,
            "    // Receives no message of the database: its controller takes every frame, and no"
        );
        let _ = writeln!(t, "    // reaction answers any.");
        let _ = writeln!(
            t,
            "    filter: SocketCan([(can_id: \"0x0\", can_mask: \"0x0\")]),"
        );
    } else {
        let _ = writeln!(t, "    // Its controller takes the messages it receives.");
        let _ = writeln!(t, "    filter: SocketCan([");
        for m in &received {
            let _ = writeln!(t, "        {}, // {}", filter_entry(m), m.name);
        }
        let _ = writeln!(t, "    ]),");
    }
    let _ = writeln!(t, "    states: [(name: \"running\", code: 1)],");
    let _ = writeln!(t, "    initial: \"running\",");
    if own.is_empty() && events.is_empty() {
        let _ = writeln!(
            t,
            "    // Sends nothing of the database: on the bus to listen and acknowledge."
        );
    }
    let _ = writeln!(t, "    messages: [");
    for (i, m) in own.iter().chain(events.iter()).enumerate() {
        let when = when(m, (i as u32).saturating_mul(7)).unwrap_or_else(|| "OnRequest".into());
        let _ = writeln!(
            t,
            "        (name: {}, frames: [(message: {}, fields: {{",
            ron_string(&m.name),
            ron_string(&m.name)
        );
        for s in &m.signals {
            let unit = if s.unit.is_empty() {
                String::new()
            } else {
                format!(" // {}", s.unit)
            };
            let _ = writeln!(
                t,
                "            {}: {},{unit}",
                ron_string(&s.name),
                generator(s, m, signals)
            );
        }
        let _ = writeln!(t, "        }})], when: {when}),");
    }
    let _ = writeln!(t, "    ],");
    let _ = writeln!(t, ")");
    (t, own.len(), events.len())
}
