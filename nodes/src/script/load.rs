//! Reading scripts and checking them against the catalogue and the plant, reporting every
//! problem at once.

use super::book::Def;
use super::model::*;
use crate::{Error, Problem};
use bus::Frame;
use bus::filter::AcceptanceFilter;
use bus::text::{LIST_CHARS, cut, quote};
use protocol::catalogue::{self, Direction, MessageDef};
use protocol::database::Database;
use protocol::ident::Address;
use std::collections::BTreeSet;
use std::path::Path;
use std::sync::Arc;

/// What a script may read and write in its environment (the plant).
pub trait Signals {
    /// True for a signal a script may read.
    fn is_signal(&self, name: &str) -> bool;
    /// True for a plant input a script may write.
    fn is_input(&self, name: &str) -> bool;
}

/// Parses a script; a syntax error or unknown field comes back with its line and column.
pub fn parse(file: &str, text: &str) -> Result<NodeScript, Error> {
    crate::parse_ron(file, text)
}

/// Reads ([`crate::file::read_text`], so at most [`crate::file::MAX_FILE`] bytes), parses and
/// validates a script file. A file whose top is `Instance(…)` is expanded from its template
/// (read with the same function, see [`super::expand`]); problems of the script it makes name
/// the instance's file.
pub fn load(path: &Path, signals: &dyn Signals) -> Result<NodeScript, Error> {
    let (file, text) = super::disk(path)?;
    from_file_text(&file, path, &text, signals, &super::disk)
}

/// [`load`] with the file already read: `text` is the content of `path`, named `file` in
/// problems, and `read` reads the template of an instance.
pub fn from_file_text(
    file: &str,
    path: &Path,
    text: &str,
    signals: &dyn Signals,
    read: super::Reader,
) -> Result<NodeScript, Error> {
    let mut script = if super::top_name(text) == Some("Instance") {
        super::expand(file, path, text, read)?
    } else {
        parse(file, text)?
    };
    if let Some(rel) = &script.database {
        let at = path.parent().unwrap_or(Path::new("")).join(rel);
        let db = read(&at).and_then(|(name, text)| {
            Database::parse(&name, &text)
                .map_err(|e| Error::Invalid(vec![Problem::at(file, "database", e.to_string())]))
        });
        match db {
            Ok(db) => script.db = Some(Arc::new(db)),
            Err(Error::Invalid(p)) => return Err(Error::Invalid(p)),
            Err(e) => return Err(Error::Invalid(vec![Problem::at(file, "database", e.to_string())])),
        }
    }
    let problems = validate(file, &script, signals);
    if problems.is_empty() {
        Ok(script)
    } else {
        Err(Error::Invalid(problems))
    }
}

/// Parses and validates a script held in memory; `file` names it in problems. [`load`] is this
/// after reading the file.
pub fn from_text(file: &str, text: &str, signals: &dyn Signals) -> Result<NodeScript, Error> {
    let script = parse(file, text)?;
    let problems = validate(file, &script, signals);
    if problems.is_empty() {
        Ok(script)
    } else {
        Err(Error::Invalid(problems))
    }
}

struct Checker<'a> {
    file: &'a str,
    node: String,
    problems: Vec<Problem>,
}

impl Checker<'_> {
    fn problem(&mut self, field: impl Into<String>, message: impl Into<String>) {
        self.problems.push(Problem {
            file: self.file.to_string(),
            position: None,
            node: Some(self.node.clone()),
            field: Some(field.into()),
            message: message.into(),
        });
    }
}

/// Checks a parsed script; returns every problem found (empty when it is good).
pub fn validate(file: &str, s: &NodeScript, signals: &dyn Signals) -> Vec<Problem> {
    let mut c = Checker {
        file,
        node: s.name.clone(),
        problems: Vec::new(),
    };
    let address = Address(s.address);
    let db = s.db.as_ref();
    // A database that could not be had: its messages are not looked for in the catalogue.
    let unread = s.database.is_some() && db.is_none();
    match (&s.database, db) {
        (Some(_), None) => c.problem(
            "database",
            "the database is read when the script is loaded from its file (`harvemu validate FILE`)",
        ),
        (Some(_), Some(_)) if s.address != 0 => c.problem(
            "address",
            "a node of a network from a DBC file has no harvester address: leave `address` and `kind` out",
        ),
        _ => {}
    }
    match address.kind() {
        _ if s.database.is_some() => {}
        None => c.problem(
            "address",
            format!("0x{:02X} is not a harvester address", s.address),
        ),
        Some(k) if k != s.kind => c.problem(
            "kind",
            format!(
                "address {address} belongs to the kind '{}', not '{}'",
                k.name(),
                s.kind.name()
            ),
        ),
        _ => {}
    }
    if s.name.trim().is_empty() {
        c.problem("name", "is empty");
    } else if s.name.chars().any(char::is_whitespace) {
        // Traces name a controller's interface by it (`harv0.D2`), and a candump line is
        // split at spaces.
        c.problem(
            "name",
            format!("{:?} holds a space: traces name the node by it", s.name),
        );
    }
    printable(&mut c, "name", &s.name);
    for (i, d) in s.states.iter().enumerate() {
        printable(&mut c, &format!("states[{i}].name"), &d.name);
    }
    for (i, m) in s.messages.iter().enumerate() {
        printable(&mut c, &format!("messages[{i}].name"), &m.name);
    }
    for (i, t) in s.timers.iter().enumerate() {
        printable(&mut c, &format!("timers[{i}].name"), &t.name);
    }
    for (name, v) in &s.vars {
        printable(&mut c, &format!("vars.{name}"), name);
        finite(&mut c, &format!("vars.{name}"), "the initial value", *v);
    }
    let states: Vec<&str> = s.states.iter().map(|d| d.name.as_str()).collect();
    if states.is_empty() {
        c.problem("states", "a node needs at least one state");
    }
    duplicates(&mut c, "states", states.iter().copied());
    let state_ok = |c: &mut Checker, field: String, name: &str| {
        if !states.contains(&name) {
            c.problem(
                field,
                format!(
                    "unknown state {} (states: {})",
                    quote(name),
                    cut(&states.join(", "), LIST_CHARS)
                ),
            );
        }
    };
    state_ok(&mut c, "initial".into(), &s.initial);
    let sends: Vec<&str> = s.messages.iter().map(|m| m.name.as_str()).collect();
    duplicates(&mut c, "messages", sends.iter().copied());
    let timers: Vec<&str> = s.timers.iter().map(|t| t.name.as_str()).collect();
    duplicates(&mut c, "timers", timers.iter().copied());
    let vars: BTreeSet<&str> = s.vars.keys().map(String::as_str).collect();

    for (i, m) in s.messages.iter().enumerate() {
        let at = format!("messages[{i}] ({})", m.name);
        match m.when {
            When::Periodic { period_ms: 0, .. } => c.problem(format!("{at}.when"), "period 0"),
            When::OnChange { heartbeat_ms: 0, .. } => c.problem(format!("{at}.when"), "heartbeat 0"),
            When::OnChange { check_ms: 0, .. } => c.problem(format!("{at}.when"), "check period 0"),
            _ => {}
        }
        if m.frames.is_empty() {
            c.problem(format!("{at}.frames"), "no frames");
        }
        for st in &m.states {
            state_ok(&mut c, format!("{at}.states"), st);
        }
        if let Some(ack) = &m.ack {
            state_ok(&mut c, format!("{at}.ack.state"), &ack.state);
            if ack.limit == 0 {
                c.problem(format!("{at}.ack.limit"), "limit 0");
            }
            if ack.timeout_ms == 0 {
                c.problem(format!("{at}.ack.timeout_ms"), "timeout 0");
            }
            if let Some(v) = &ack.count_var
                && !vars.contains(v.as_str())
            {
                c.problem(
                    format!("{at}.ack.count_var"),
                    format!("unknown variable {}", quote(v)),
                );
            }
        }
        for (j, f) in m.frames.iter().enumerate() {
            let fat = format!("{at}.frames[{j}]");
            if unread {
                continue;
            }
            if let Some(db) = db {
                let Some(def) = in_database(&mut c, &fat, &f.message, db) else {
                    continue;
                };
                for (name, e) in &f.fields {
                    let at = format!("{fat}.fields.{name}");
                    if def.has_field(name) {
                        expr(&mut c, &at, e, signals, &vars, None);
                    } else {
                        c.problem(at, format!("{} has no signal {}", def.name(), quote(name)));
                    }
                }
                continue;
            }
            let Some(def) = message(&mut c, &fat, &f.message, address, Direction::ToMonitor) else {
                continue;
            };
            for field in def.fields.iter().filter(|fd| fd.constant.is_none()) {
                if !f.fields.contains_key(field.name) {
                    c.problem(
                        format!("{fat}.fields"),
                        format!("no value for field '{}' of {}", field.name, def.name),
                    );
                }
            }
            for (name, e) in &f.fields {
                match def.field(name) {
                    None => c.problem(
                        format!("{fat}.fields.{name}"),
                        format!("{} has no field {}", def.name, quote(name)),
                    ),
                    Some(fd) if fd.constant.is_some() => c.problem(
                        format!("{fat}.fields.{name}"),
                        "is fixed by the protocol: leave it out",
                    ),
                    Some(_) => expr(&mut c, &format!("{fat}.fields.{name}"), e, signals, &vars, None),
                }
            }
        }
    }
    // Two entries that send the same frames in overlapping states would put two streams of one
    // identifier and number on the bus. (Groups may share their data frames: the flow sensor's
    // two groups differ in their markers.)
    for (i, a) in s.messages.iter().enumerate() {
        for b in &s.messages[i + 1..] {
            let scheduled = |m: &SendDef| m.enabled && !matches!(m.when, When::OnRequest);
            let overlap =
                a.states.is_empty() || b.states.is_empty() || a.states.iter().any(|st| b.states.contains(st));
            let same = a.frames.len() == b.frames.len()
                && a.frames
                    .iter()
                    .zip(&b.frames)
                    .all(|(x, y)| x.message == y.message);
            if same && scheduled(a) && scheduled(b) && overlap {
                c.problem(
                    format!("messages ({} and {})", a.name, b.name),
                    format!(
                        "duplicate message {}: both send it in the same states",
                        a.frames[0].message
                    ),
                );
            }
        }
    }
    for (i, r) in s.reactions.iter().enumerate() {
        let at = format!("reactions[{i}] ({})", r.message);
        let def = match db {
            _ if unread => None,
            Some(db) => in_database(&mut c, &at, &r.message, db),
            None => message(&mut c, &at, &r.message, address, Direction::FromMonitor).map(Def::Catalogue),
        };
        for st in &r.states {
            state_ok(&mut c, format!("{at}.states"), st);
        }
        for (name, v) in &r.when {
            finite(&mut c, &format!("{at}.when.{name}"), "the value to match", *v);
        }
        if let Some(def) = &def {
            for name in r.when.keys() {
                if !def.has_field(name) {
                    c.problem(
                        format!("{at}.when.{name}"),
                        format!("{} has no field {}", def.name(), quote(name)),
                    );
                }
            }
        }
        actions(
            &mut c,
            &at,
            &r.actions,
            &states,
            &sends,
            &timers,
            &vars,
            signals,
            def.as_ref(),
        );
    }
    for (i, t) in s.timers.iter().enumerate() {
        let at = format!("timers[{i}] ({})", t.name);
        if t.after_ms == 0 {
            c.problem(format!("{at}.after_ms"), "delay 0");
        }
        for st in &t.states {
            state_ok(&mut c, format!("{at}.states"), st);
        }
        actions(
            &mut c, &at, &t.actions, &states, &sends, &timers, &vars, signals, None,
        );
    }
    filter(&mut c, s, address);
    for (i, f) in s.faults.iter().enumerate() {
        if !signals.is_signal(&f.signal) {
            c.problem(
                format!("faults[{i}].signal"),
                format!("unknown plant signal {}", quote(&f.signal)),
            );
        }
        if let Some(m) = f.fault.problem() {
            c.problem(format!("faults[{i}].fault"), m);
        }
    }
    c.problems
}

/// The declared acceptance filter: its registers must read, and it must pass every frame the
/// script reacts to, or the node would never see them.
fn filter(c: &mut Checker, s: &NodeScript, node: Address) {
    let filter = match s.filter.to_filter() {
        Ok(f) => f,
        Err(problems) => {
            for p in problems {
                c.problem(format!("filter{}", p.field), p.message);
            }
            return;
        }
    };
    let mut checked = BTreeSet::new();
    for (i, r) in s.reactions.iter().enumerate() {
        if let Some(db) = &s.db {
            // The database's frame with this identifier; an unknown message is reported with
            // the reaction.
            let frame = db.message(&r.message).and_then(|m| {
                Frame::new_data(super::book::dbc_id(m)?, &vec![0; usize::from(m.dlc.min(8))]).ok()
            });
            if let Some(frame) = frame
                && checked.insert(frame.raw_id())
                && !filter.accepts(&frame)
            {
                c.problem(
                    "filter",
                    format!(
                        "rejects {} (identifier {:X}), which reactions[{i}] answers",
                        r.message,
                        frame.raw_id()
                    ),
                );
            }
            continue;
        }
        // Unknown messages, and messages of other nodes or going the other way, are reported
        // with the reaction.
        let Some(def) = catalogue::by_name(&r.message) else {
            continue;
        };
        if !def.nodes.contains(node) || def.direction != Direction::FromMonitor {
            continue;
        }
        let Some(frame) = example_frame(def, node, r) else {
            continue;
        };
        if checked.insert(frame.raw_id()) && !filter.accepts(&frame) {
            c.problem(
                "filter",
                format!(
                    "rejects {} (identifier {:08X}), which reactions[{i}] answers",
                    def.name,
                    frame.raw_id()
                ),
            );
        }
    }
}

/// The frame the monitor sends to `node` for reaction `r`: the fields `r` matches on at those
/// values, the others at their lowest valid value.
fn example_frame(def: &MessageDef, node: Address, r: &Reaction) -> Option<Frame> {
    let value = |name: &str| {
        let field = def.field(name)?;
        let raw = r.when.get(name).map(|&raw| field.physical(raw as i64));
        Some(raw.unwrap_or(field.min))
    };
    def.encode(node, value)
        .or_else(|_| Frame::new_data(def.app_id(node).emit(), &[def.number]))
        .ok()
}

fn duplicates<'a>(c: &mut Checker, field: &str, names: impl Iterator<Item = &'a str>) {
    let mut seen = BTreeSet::new();
    for n in names {
        if !seen.insert(n) {
            c.problem(field, format!("{} is defined twice", quote(n)));
        }
    }
}

fn message(
    c: &mut Checker,
    at: &str,
    name: &str,
    node: Address,
    way: Direction,
) -> Option<&'static MessageDef> {
    let Some(def) = catalogue::by_name(name) else {
        c.problem(
            format!("{at}.message"),
            format!("{} is not in the message catalogue", quote(name)),
        );
        return None;
    };
    if !def.nodes.contains(node) {
        c.problem(
            format!("{at}.message"),
            format!("{name} is not a message of node {node}"),
        );
        return None;
    }
    if def.direction != way {
        let what = if way == Direction::ToMonitor {
            "sends"
        } else {
            "receives"
        };
        c.problem(
            format!("{at}.message"),
            format!("{name} goes the other way: this node never {what} it"),
        );
        return None;
    }
    Some(def)
}

/// The database's message called `name`, or a problem.
fn in_database(c: &mut Checker, at: &str, name: &str, db: &Arc<Database>) -> Option<Def> {
    let def = Def::find(Some(db), name);
    if def.is_none() {
        c.problem(
            format!("{at}.message"),
            format!("{} is not a message of the database", quote(name)),
        );
    }
    def
}

fn expr(
    c: &mut Checker,
    at: &str,
    e: &Expr,
    signals: &dyn Signals,
    vars: &BTreeSet<&str>,
    frame: Option<&Def>,
) {
    match e {
        Expr::Const(v) => finite(c, at, "Const", *v),
        Expr::Signal(s) if !signals.is_signal(s) => {
            c.problem(at, format!("unknown plant signal {}", quote(s)))
        }
        Expr::Var(v) if !vars.contains(v.as_str()) => c.problem(at, format!("unknown variable {}", quote(v))),
        Expr::Field(f) => match frame {
            None => c.problem(at, format!("Field(\"{f}\") only has a meaning in a reaction")),
            Some(def) if !def.has_field(f) => {
                c.problem(at, format!("{} has no field {}", def.name(), quote(f)))
            }
            _ => {}
        },
        Expr::Scaled(inner, gain, offset) => {
            finite(c, at, "Scaled gain", *gain);
            finite(c, at, "Scaled offset", *offset);
            expr(c, at, inner, signals, vars, frame)
        }
        Expr::Clamp(inner, min, max) => {
            finite(c, at, "Clamp min", *min);
            finite(c, at, "Clamp max", *max);
            if min > max {
                c.problem(at, format!("Clamp min {min} is above its max {max}"));
            }
            expr(c, at, inner, signals, vars, frame)
        }
        Expr::Quantize(inner, step) => {
            if !(step.is_finite() && *step > 0.0) {
                c.problem(
                    at,
                    format!("Quantize step {step} is not a positive finite number"),
                );
            }
            expr(c, at, inner, signals, vars, frame)
        }
        Expr::Ramp { from, to, period_s } => {
            finite(c, at, "Ramp from", *from);
            finite(c, at, "Ramp to", *to);
            positive(c, at, "Ramp period_s", *period_s);
        }
        Expr::Sine {
            mean,
            amplitude,
            period_s,
        } => {
            finite(c, at, "Sine mean", *mean);
            finite(c, at, "Sine amplitude", *amplitude);
            positive(c, at, "Sine period_s", *period_s);
        }
        Expr::RandomWalk {
            start,
            step,
            min,
            max,
        } => {
            finite(c, at, "RandomWalk start", *start);
            finite(c, at, "RandomWalk min", *min);
            finite(c, at, "RandomWalk max", *max);
            if !(step.is_finite() && *step >= 0.0) {
                c.problem(at, format!("RandomWalk step {step} is not a finite number >= 0"));
            }
            if min > max {
                c.problem(at, format!("RandomWalk min {min} is above its max {max}"));
            }
        }
        Expr::Counter { from, to, step } => {
            finite(c, at, "Counter from", *from);
            finite(c, at, "Counter to", *to);
            finite(c, at, "Counter step", *step);
            if *step == 0.0 || (to - from) * step < 0.0 {
                c.problem(at, format!("Counter step {step} never takes {from} to {to}"));
            }
        }
        Expr::Cycle(values) => {
            if values.is_empty() {
                c.problem(at, "Cycle of no values");
            }
            for v in values {
                finite(c, at, "a Cycle value", *v);
            }
        }
        _ => {}
    }
}

fn positive(c: &mut Checker, at: &str, what: &str, v: f64) {
    if !(v.is_finite() && v > 0.0) {
        c.problem(at, format!("{what} is {v}, not a positive finite number"));
    }
}

/// Every number of a script is finite: a NaN or an infinity would make what the node sends
/// undefined (a NaN gain turns every value into NaN, which no field can carry).
fn finite(c: &mut Checker, at: &str, what: &str, v: f64) {
    if !v.is_finite() {
        c.problem(at, format!("{what} is {v}, not a finite number"));
    }
}

/// A name may not hold control characters (a NUL, a newline, an escape): names go into traces,
/// reports and terminal lines, which such characters would break or garble.
fn printable(c: &mut Checker, at: &str, name: &str) {
    if let Some(ch) = name.chars().find(|ch| ch.is_control()) {
        c.problem(at, format!("{name:?} holds the control character {:?}", ch));
    }
}

#[allow(clippy::too_many_arguments)]
fn actions(
    c: &mut Checker,
    at: &str,
    list: &[Action],
    states: &[&str],
    sends: &[&str],
    timers: &[&str],
    vars: &BTreeSet<&str>,
    signals: &dyn Signals,
    frame: Option<&Def>,
) {
    for (k, a) in list.iter().enumerate() {
        let here = format!("{at}.actions[{k}]");
        match a {
            Action::SetState(s) if !states.contains(&s.as_str()) => {
                c.problem(here, format!("unknown state {}", quote(s)))
            }
            Action::Start(m) | Action::Stop(m) | Action::Send(m) if !sends.contains(&m.as_str()) => {
                c.problem(here, format!("unknown message {}", quote(m)))
            }
            Action::Restart(t) if !timers.contains(&t.as_str()) => {
                c.problem(here, format!("unknown timer {}", quote(t)))
            }
            Action::Write(s, e) => {
                if !signals.is_input(s) {
                    c.problem(here.clone(), format!("{} is not a plant input", quote(s)));
                }
                expr(c, &here, e, signals, vars, frame);
            }
            Action::Set(v, e) => {
                if !vars.contains(v.as_str()) {
                    c.problem(here.clone(), format!("unknown variable {}", quote(v)));
                }
                expr(c, &here, e, signals, vars, frame);
            }
            _ => {}
        }
    }
}
