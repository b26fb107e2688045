//! DBC text to a [`Database`], through `can-dbc`'s parser.

use super::{ByteOrder, Database, Message, Mux, Signal, Warning};
use crate::Error;
use can_dbc::{
    AttributeDefinition, AttributeValue, AttributeValueType, Comment, Dbc, DbcError, MessageId,
    MultiplexIndicator, NumericValue, SignalExtendedValueType, ValueDescription, ValueType,
};
use std::collections::BTreeMap;

pub(super) fn parse(file: &str, text: &str) -> Result<Database, Error> {
    let dbc = Dbc::try_from(text).map_err(|e| error(file, text, &e))?;
    let attrs = Attributes::of(&dbc);
    let mut warnings = Vec::new();
    let mut messages = Vec::with_capacity(dbc.messages.len());
    for m in &dbc.messages {
        let (id, extended) = match m.id {
            MessageId::Standard(id) => (u32::from(id), false),
            MessageId::Extended(id) => (id, true),
        };
        let shown = format!("{} (0x{id:X})", m.name);
        if !extended && id > 0x7FF {
            let (line, column) = locate(text, &format!("BO_ {id} ")).unwrap_or((0, 0));
            return Err(Error::Dbc {
                file: file.to_string(),
                line,
                column,
                reason: format!(
                    "message {}: identifier {id} is over 0x7FF but not marked extended (bit 31, +2147483648)",
                    m.name
                ),
            });
        }
        let dlc = match u8::try_from(m.size) {
            Ok(n) if n <= 8 => n,
            _ => {
                warnings.push(Warning {
                    at: shown,
                    reason: format!(
                        "{} bytes: a CAN FD message; harvemu is CAN 2.0, so it is left out",
                        m.size
                    ),
                });
                continue;
            }
        };
        let mut signals = Vec::with_capacity(m.signals.len());
        for s in &m.signals {
            let at = format!("{shown} signal {}", s.name);
            let bits = match u8::try_from(s.size) {
                Ok(n @ 1..=64) => n,
                _ => {
                    warnings.push(Warning {
                        at,
                        reason: format!("{} bits: a signal has 1 to 64; it is left out", s.size),
                    });
                    continue;
                }
            };
            let start_bit = u16::try_from(s.start_bit).unwrap_or(u16::MAX);
            let mux = match s.multiplexer_indicator {
                MultiplexIndicator::Plain => Mux::Plain,
                MultiplexIndicator::Multiplexor => Mux::Multiplexor,
                MultiplexIndicator::MultiplexedSignal(n) => Mux::On(n),
                MultiplexIndicator::MultiplexorAndMultiplexedSignal(n) => {
                    warnings.push(Warning {
                        at: at.clone(),
                        reason: "a multiplexor that is itself multiplexed (extended multiplexing): \
                                 only one level is run, this one as a signal multiplexed on its own value"
                            .into(),
                    });
                    Mux::On(n)
                }
            };
            let key = (mid(&m.id), s.name.clone());
            // Literals past f64's range read as infinities; a factor of 0 inverts to nothing.
            let (mut min, mut max) = (number(&s.min), number(&s.max));
            let mut offset = s.offset;
            if !(min.is_finite() && max.is_finite()) {
                warnings.push(Warning {
                    at: at.clone(),
                    reason: format!("range [{min}|{max}] is not finite: taken as no range"),
                });
                (min, max) = (0.0, 0.0);
            }
            if !offset.is_finite() {
                warnings.push(Warning {
                    at: at.clone(),
                    reason: format!("offset {offset} is not finite: taken as 0"),
                });
                offset = 0.0;
            }
            if s.factor == 0.0 || !s.factor.is_finite() {
                warnings.push(Warning {
                    at: at.clone(),
                    reason: format!(
                        "factor {}: no raw value stands for a chosen physical one; raw 0 is sent",
                        s.factor
                    ),
                });
            }
            if let Some(kind) = attrs.float.get(&key) {
                warnings.push(Warning {
                    at: at.clone(),
                    reason: format!("an IEEE {kind} signal: sent as the integer of its bits"),
                });
            }
            signals.push(Signal {
                name: s.name.clone(),
                start_bit,
                bits,
                byte_order: match s.byte_order {
                    can_dbc::ByteOrder::LittleEndian => ByteOrder::Intel,
                    can_dbc::ByteOrder::BigEndian => ByteOrder::Motorola,
                },
                signed: s.value_type == ValueType::Signed,
                factor: s.factor,
                offset,
                min,
                max,
                unit: s.unit.clone(),
                receivers: s
                    .receivers
                    .iter()
                    .filter(|r| r.as_str() != "Vector__XXX")
                    .cloned()
                    .collect(),
                mux,
                values: attrs.values.get(&key).cloned().unwrap_or_default(),
                start_raw: attrs.signal_number(mid(&m.id), &s.name, "GenSigStartValue"),
                comment: attrs.signal_comments.get(&key).cloned(),
            });
        }
        let message = Message {
            name: m.name.clone(),
            id,
            extended,
            dlc,
            transmitter: m
                .transmitter
                .clone()
                .filter(|t| t != "Vector__XXX" && !t.is_empty()),
            cycle_ms: attrs
                .message_number(mid(&m.id), "GenMsgCycleTime")
                .filter(|&v| v >= 1.0 && v <= f64::from(u32::MAX))
                .map(|v| v.round() as u32),
            send_type: attrs.message_enum(mid(&m.id), "GenMsgSendType"),
            comment: attrs.message_comments.get(&mid(&m.id)).cloned(),
            signals,
        };
        check_layout(&message, &shown, &mut warnings);
        messages.push(message);
    }
    Ok(Database {
        nodes: dbc.nodes.iter().map(|n| n.0.clone()).collect(),
        messages,
        bitrate: attrs
            .database_number("Baudrate")
            .filter(|&v| v >= 1.0 && v <= f64::from(u32::MAX))
            .map(|v| v.round() as u32),
        name: match attrs.database.get("DBName") {
            Some(AttributeValue::String(s)) => Some(s.clone()),
            _ => None,
        },
        comment: dbc.comments.iter().find_map(|c| match c {
            Comment::Plain { comment } => Some(comment.clone()),
            _ => None,
        }),
        warnings,
    })
}

/// Warnings for signals that reach past the message or share a bit with another signal that is
/// in the same frames.
fn check_layout(m: &Message, shown: &str, warnings: &mut Vec<Warning>) {
    let size = u16::from(m.dlc) * 8;
    let mut owner: BTreeMap<(Option<u64>, u16), &str> = BTreeMap::new();
    for s in &m.signals {
        let at = format!("{shown} signal {}", s.name);
        let Some(bits) = s.positions().filter(|p| p.iter().all(|&b| b < size)) else {
            warnings.push(Warning {
                at,
                reason: format!(
                    "{} bits from bit {} do not fit in the message's {} bytes: the bits past its end are not sent",
                    s.bits, s.start_bit, m.dlc
                ),
            });
            continue;
        };
        let group = match s.mux {
            Mux::On(n) => Some(n),
            _ => None,
        };
        for b in bits {
            // A plain signal is in every frame: it clashes with a multiplexed one of any value.
            let clash = match group {
                None => owner.iter().find(|((_, bit), _)| *bit == b).map(|(_, n)| *n),
                Some(_) => owner.get(&(group, b)).or_else(|| owner.get(&(None, b))).copied(),
            };
            if let Some(other) = clash {
                warnings.push(Warning {
                    at,
                    reason: format!("shares bit {b} with signal {other}: the later signal's bits win"),
                });
                break;
            }
            owner.insert((group, b), &s.name);
        }
    }
}

/// A message identifier as a map key: extended, and the id.
type Mid = (bool, u32);

fn mid(id: &MessageId) -> Mid {
    match *id {
        MessageId::Standard(n) => (false, u32::from(n)),
        MessageId::Extended(n) => (true, n),
    }
}

fn number(v: &NumericValue) -> f64 {
    match *v {
        NumericValue::Uint(n) => n as f64,
        NumericValue::Int(n) => n as f64,
        NumericValue::Double(n) => n,
    }
}

fn attribute_number(v: &AttributeValue) -> Option<f64> {
    match v {
        AttributeValue::Uint(n) => Some(*n as f64),
        AttributeValue::Int(n) => Some(*n as f64),
        AttributeValue::Double(n) => Some(*n),
        AttributeValue::String(s) => s.trim().parse().ok(),
    }
}

/// The attributes, comments, value tables and value types, by what they are about.
struct Attributes {
    defaults: BTreeMap<String, AttributeValue>,
    enums: BTreeMap<String, Vec<String>>,
    database: BTreeMap<String, AttributeValue>,
    messages: BTreeMap<(Mid, String), AttributeValue>,
    signals: BTreeMap<(Mid, String, String), AttributeValue>,
    message_comments: BTreeMap<Mid, String>,
    signal_comments: BTreeMap<(Mid, String), String>,
    values: BTreeMap<(Mid, String), Vec<(i64, String)>>,
    float: BTreeMap<(Mid, String), &'static str>,
}

impl Attributes {
    fn of(dbc: &Dbc) -> Attributes {
        let mut a = Attributes {
            defaults: dbc
                .attribute_defaults
                .iter()
                .map(|d| (d.name.clone(), d.value.clone()))
                .collect(),
            enums: BTreeMap::new(),
            database: dbc
                .attribute_values_database
                .iter()
                .map(|v| (v.name.clone(), v.value.clone()))
                .collect(),
            messages: dbc
                .attribute_values_message
                .iter()
                .map(|v| ((mid(&v.message_id), v.name.clone()), v.value.clone()))
                .collect(),
            signals: dbc
                .attribute_values_signal
                .iter()
                .map(|v| {
                    (
                        (mid(&v.message_id), v.signal_name.clone(), v.name.clone()),
                        v.value.clone(),
                    )
                })
                .collect(),
            message_comments: BTreeMap::new(),
            signal_comments: BTreeMap::new(),
            values: BTreeMap::new(),
            float: BTreeMap::new(),
        };
        for d in &dbc.attribute_definitions {
            if let AttributeDefinition::Message(name, AttributeValueType::Enum(values))
            | AttributeDefinition::Signal(name, AttributeValueType::Enum(values))
            | AttributeDefinition::Plain(name, AttributeValueType::Enum(values)) = d
            {
                a.enums.insert(name.clone(), values.clone());
            }
        }
        for c in &dbc.comments {
            match c {
                Comment::Message { id, comment } => {
                    a.message_comments.insert(mid(id), comment.clone());
                }
                Comment::Signal {
                    message_id,
                    name,
                    comment,
                } => {
                    a.signal_comments
                        .insert((mid(message_id), name.clone()), comment.clone());
                }
                _ => {}
            }
        }
        for v in &dbc.value_descriptions {
            if let ValueDescription::Signal {
                message_id,
                name,
                value_descriptions,
            } = v
            {
                let list = value_descriptions
                    .iter()
                    .map(|d| (d.id, d.description.clone()))
                    .collect();
                a.values.insert((mid(message_id), name.clone()), list);
            }
        }
        for t in &dbc.signal_extended_value_type_list {
            let kind = match t.signal_extended_value_type {
                SignalExtendedValueType::SignedOrUnsignedInteger => continue,
                SignalExtendedValueType::IEEEfloat32Bit => "float32",
                SignalExtendedValueType::IEEEdouble64bit => "float64",
            };
            a.float.insert((mid(&t.message_id), t.signal_name.clone()), kind);
        }
        a
    }

    fn message_number(&self, id: Mid, name: &str) -> Option<f64> {
        self.messages
            .get(&(id, name.to_string()))
            .or_else(|| self.defaults.get(name))
            .and_then(attribute_number)
    }

    /// An enum attribute of a message as the name its index stands for.
    fn message_enum(&self, id: Mid, name: &str) -> Option<String> {
        let v = self
            .messages
            .get(&(id, name.to_string()))
            .or_else(|| self.defaults.get(name))?;
        let names = self.enums.get(name);
        match v {
            AttributeValue::String(s) => Some(s.clone()),
            other => {
                let i = attribute_number(other)?;
                let i = usize::try_from(i as i64).ok()?;
                names.and_then(|n| n.get(i)).cloned()
            }
        }
    }

    fn signal_number(&self, id: Mid, signal: &str, name: &str) -> Option<f64> {
        self.signals
            .get(&(id, signal.to_string(), name.to_string()))
            .and_then(attribute_number)
    }

    fn database_number(&self, name: &str) -> Option<f64> {
        self.database
            .get(name)
            .or_else(|| self.defaults.get(name))
            .and_then(attribute_number)
    }
}

/// The 1-based line and column of the first occurrence of `needle` in `text`.
fn locate(text: &str, needle: &str) -> Option<(usize, usize)> {
    let at = text.find(needle)?;
    Some(line_col(text, at))
}

fn line_col(text: &str, at: usize) -> (usize, usize) {
    let before = &text[..at];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// `can-dbc`'s refusal as an error at a line and column: the parser's own position for a
/// syntax error; for a value it could not take, the first place the value is written.
fn error(file: &str, text: &str, e: &DbcError) -> Error {
    let (line, column, reason) = match e {
        DbcError::Pest(p) => {
            let (line, column) = match p.line_col {
                pest::error::LineColLocation::Pos(lc) => lc,
                pest::error::LineColLocation::Span(lc, _) => lc,
            };
            let reason = p.variant.message().replace('_', " ");
            (line, column, reason)
        }
        other => {
            let token = match other {
                DbcError::InvalidFloat(s)
                | DbcError::InvalidInt(s)
                | DbcError::InvalidUint(s)
                | DbcError::InvalidNumericValue(s)
                | DbcError::UnknownMultiplexIndicator(s) => Some(s.clone()),
                DbcError::MessageIdOutOfRange(n) => Some(n.to_string()),
                _ => None,
            };
            let (line, column) = token.and_then(|t| locate(text, &t)).unwrap_or((0, 0));
            (line, column, other.to_string())
        }
    };
    Error::Dbc {
        file: file.to_string(),
        line,
        column,
        reason,
    }
}
