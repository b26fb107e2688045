//! The message catalogue: every message of the harvester protocol, in one table.
//!
//! Each [`MessageDef`] says who sends it to whom, its message number (Data0), frame type, DLC,
//! trigger (period or event) and the layout of Data1–Data7 as [`Field`]s with scaling, units and
//! valid ranges. Priority is not stored per message: the protocol ties it to the field node's
//! class ([`NodeKind::priority`]), and [`MessageDef::priority`] derives it from there.
//!
//! Multi-byte fields are little-endian (low byte first), as the flow sensor frames of the source
//! are; bit positions are given the way DBC files give Intel signals (start bit = LSB position,
//! byte × 8 + bit). The decoder, the reference monitor, the behaviour scripts and the DBC export
//! all read this table; `docs/PROTOCOL.md` describes it.

pub mod dbc;
pub mod doc;
mod messages;

use crate::Error;
use crate::ident::{Address, AppId, FrameType, NodeKind, Priority};
use bus::Frame;

pub use messages::MESSAGES;

/// Which field nodes a message belongs to.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Nodes {
    /// Every node of a kind (e.g. all six flow sensors).
    Kind(NodeKind),
    /// One node (e.g. B3, the drum-speed module).
    One(Address),
}

impl Nodes {
    /// True when `address` is one of these nodes.
    pub fn contains(self, address: Address) -> bool {
        match self {
            Nodes::Kind(kind) => address.kind() == Some(kind),
            Nodes::One(one) => one == address,
        }
    }

    /// The kind of node.
    pub fn kind(self) -> NodeKind {
        match self {
            Nodes::Kind(kind) => kind,
            // Every `One` in the table names a harvester address (a test checks it).
            Nodes::One(address) => address.kind().unwrap_or(NodeKind::Monitor),
        }
    }
}

/// Which way a message goes. Every message has the monitor at one end.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Direction {
    /// Field node -> monitor.
    ToMonitor,
    /// Monitor -> field node.
    FromMonitor,
}

/// When a message is sent.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Trigger {
    /// Every `period_ms` milliseconds while the node runs.
    Periodic {
        /// Period in milliseconds.
        period_ms: u32,
    },
    /// When a value changes, and again every `heartbeat_ms` so that silence means a fault.
    OnChange {
        /// Repetition period in milliseconds when nothing changes.
        heartbeat_ms: u32,
    },
    /// Sent when something happens (an operator command, a state change, a reply).
    Event,
    /// Part of a frame group that starts with a marker every `period_ms` milliseconds.
    Group {
        /// Period of the group in milliseconds.
        period_ms: u32,
    },
}

impl Trigger {
    /// The cycle time a DBC or a bus-load estimate should use, if there is one.
    pub fn cycle_ms(self) -> Option<u32> {
        match self {
            Trigger::Periodic { period_ms } | Trigger::Group { period_ms } => Some(period_ms),
            Trigger::OnChange { heartbeat_ms } => Some(heartbeat_ms),
            Trigger::Event => None,
        }
    }
}

/// One field of Data1–Data7.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct Field {
    /// Signal name, unique within the message; behaviour scripts bind plant signals by it.
    pub name: &'static str,
    /// Position of the least significant bit: byte × 8 + bit (Data0 is byte 0).
    pub start_bit: u8,
    /// Width in bits.
    pub bits: u8,
    /// Two's complement when true.
    pub signed: bool,
    /// physical = raw × scale + offset.
    pub scale: f64,
    /// physical = raw × scale + offset.
    pub offset: f64,
    /// Unit of the physical value ("" when it has none).
    pub unit: &'static str,
    /// Lowest valid physical value.
    pub min: f64,
    /// Highest valid physical value.
    pub max: f64,
    /// Names of raw values (states, commands).
    pub values: &'static [(u32, &'static str)],
    /// A value the field always has; the decoder rejects any other.
    pub constant: Option<u32>,
    /// What the field means.
    pub doc: &'static str,
}

impl Field {
    const fn raw(name: &'static str, start_bit: u8, bits: u8, signed: bool, doc: &'static str) -> Field {
        let (min, max) = if signed {
            (-((1u64 << (bits - 1)) as f64), ((1u64 << (bits - 1)) - 1) as f64)
        } else {
            (0.0, ((1u64 << bits) - 1) as f64)
        };
        Field {
            name,
            start_bit,
            bits,
            signed,
            scale: 1.0,
            offset: 0.0,
            unit: "",
            min,
            max,
            values: &[],
            constant: None,
            doc,
        }
    }
    /// An unsigned byte at `byte`.
    pub const fn u8(name: &'static str, byte: u8, doc: &'static str) -> Field {
        Field::raw(name, byte * 8, 8, false, doc)
    }
    /// A signed byte at `byte`.
    pub const fn i8(name: &'static str, byte: u8, doc: &'static str) -> Field {
        Field::raw(name, byte * 8, 8, true, doc)
    }
    /// An unsigned little-endian 16-bit value at `byte`, `byte + 1`.
    pub const fn u16(name: &'static str, byte: u8, doc: &'static str) -> Field {
        Field::raw(name, byte * 8, 16, false, doc)
    }
    /// A signed little-endian 16-bit value at `byte`, `byte + 1`.
    pub const fn i16(name: &'static str, byte: u8, doc: &'static str) -> Field {
        Field::raw(name, byte * 8, 16, true, doc)
    }
    /// An unsigned little-endian 24-bit value at `byte`..`byte + 2`.
    pub const fn u24(name: &'static str, byte: u8, doc: &'static str) -> Field {
        Field::raw(name, byte * 8, 24, false, doc)
    }
    /// One bit (`bit` 0 = least significant) of `byte`.
    pub const fn flag(name: &'static str, byte: u8, bit: u8, doc: &'static str) -> Field {
        Field::raw(name, byte * 8 + bit, 1, false, doc).values(&[(0, "off"), (1, "on")])
    }
    /// Sets scale, offset and unit; the valid range follows the raw range unless set after.
    pub const fn scaled(mut self, scale: f64, offset: f64, unit: &'static str) -> Field {
        self.scale = scale;
        self.offset = offset;
        self.unit = unit;
        self.min = self.min * scale + offset;
        self.max = self.max * scale + offset;
        self
    }
    /// Sets the valid physical range.
    pub const fn range(mut self, min: f64, max: f64) -> Field {
        self.min = min;
        self.max = max;
        self
    }
    /// Names raw values; the valid range becomes the named values' span.
    pub const fn values(mut self, values: &'static [(u32, &'static str)]) -> Field {
        self.values = values;
        self
    }
    /// Fixes the raw value.
    pub const fn constant(mut self, raw: u32) -> Field {
        self.constant = Some(raw);
        self.min = raw as f64;
        self.max = raw as f64;
        self
    }

    /// Reads the raw value from a payload (`None` if the payload is too short).
    pub fn extract(&self, data: &[u8]) -> Option<i64> {
        let last_byte = usize::from((self.start_bit + self.bits - 1) / 8);
        if last_byte >= data.len() {
            return None;
        }
        let mut word: u64 = 0;
        for (i, &b) in data.iter().enumerate().take(last_byte + 1) {
            word |= u64::from(b) << (8 * i);
        }
        let mask = (1u64 << self.bits) - 1;
        let raw = (word >> self.start_bit) & mask;
        Some(if self.signed && raw >> (self.bits - 1) & 1 == 1 {
            raw as i64 - (1i64 << self.bits)
        } else {
            raw as i64
        })
    }

    /// Writes a raw value into a payload; the caller has checked the range.
    fn insert(&self, data: &mut [u8], raw: i64) {
        // The payload as one little-endian word (bit n of the payload is bit n of the word);
        // bits past its end are dropped.
        let n = data.len().min(8);
        let mut word = [0u8; 8];
        word[..n].copy_from_slice(&data[..n]);
        let mut word = u64::from_le_bytes(word);
        let shift = u32::from(self.start_bit);
        let mask = ((1u64 << self.bits) - 1).checked_shl(shift).unwrap_or(0);
        let value = ((raw as u64) << shift.min(63)) & mask;
        word = (word & !mask) | value;
        data[..n].copy_from_slice(&word.to_le_bytes()[..n]);
    }

    /// The physical value of a raw value.
    pub fn physical(&self, raw: i64) -> f64 {
        raw as f64 * self.scale + self.offset
    }

    /// The raw value nearest a physical one, if it is valid and representable.
    pub fn to_raw(&self, physical: f64) -> Option<i64> {
        if !physical.is_finite() {
            return None;
        }
        // A small tolerance so that a value at the edge of the range survives the scaling.
        let tolerance = self.scale.abs() / 2.0;
        if physical < self.min - tolerance || physical > self.max + tolerance {
            return None;
        }
        let raw = ((physical - self.offset) / self.scale).round() as i64;
        let (lo, hi) = if self.signed {
            (-(1i64 << (self.bits - 1)), (1i64 << (self.bits - 1)) - 1)
        } else {
            (0, (1i64 << self.bits) - 1)
        };
        (lo..=hi).contains(&raw).then_some(raw)
    }

    /// The name of a raw value, if the field names it.
    pub fn label(&self, raw: i64) -> Option<&'static str> {
        self.values
            .iter()
            .find(|(v, _)| i64::from(*v) == raw)
            .map(|(_, name)| *name)
    }
}

/// One message of the protocol.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct MessageDef {
    /// Unique name, `kind.what` (e.g. `flow.marker_flow`).
    pub name: &'static str,
    /// The message number in Data0.
    pub number: u8,
    /// For messages that share a number: (byte, value) that tells them apart.
    pub selector: Option<(u8, u8)>,
    /// Which field nodes send or receive it.
    pub nodes: Nodes,
    /// Which way it goes.
    pub direction: Direction,
    /// Frame-type field of the identifier.
    pub frame_type: FrameType,
    /// Data length code (Data0 included).
    pub dlc: u8,
    /// When it is sent.
    pub trigger: Trigger,
    /// Data1–Data7 layout.
    pub fields: &'static [Field],
    /// What it is for.
    pub doc: &'static str,
}

impl MessageDef {
    /// Priority of the field node's class.
    pub fn priority(&self) -> Priority {
        self.nodes.kind().priority().unwrap_or(Priority::FLOW_SENSOR)
    }

    /// The identifier this message has when exchanged with field node `node`.
    pub fn app_id(&self, node: Address) -> AppId {
        let (destination, source) = match self.direction {
            Direction::ToMonitor => (Address::MONITOR, node),
            Direction::FromMonitor => (node, Address::MONITOR),
        };
        AppId::new(self.priority(), self.frame_type, destination, source)
    }

    /// The field named `name`.
    pub fn field(&self, name: &str) -> Option<&'static Field> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// The position of the field named `name` in `fields`.
    pub fn field_index(&self, name: &str) -> Option<usize> {
        self.fields.iter().position(|f| f.name == name)
    }

    /// Decodes a payload of this message.
    pub fn decode(&'static self, data: &[u8]) -> Result<Values, Error> {
        if data.len() != usize::from(self.dlc) {
            return Err(self.error(format!("DLC is {}, expected {}", data.len(), self.dlc)));
        }
        self.fields
            .iter()
            .map(|field| {
                let raw = field
                    .extract(data)
                    .ok_or_else(|| self.error(format!("{} is past the payload", field.name)))?;
                if let Some(c) = field.constant.filter(|&c| i64::from(c) != raw) {
                    return Err(self.error(format!(
                        "{} is {raw:#X}, the protocol fixes it at {c:#X}",
                        field.name
                    )));
                }
                Ok(Value {
                    field,
                    raw,
                    physical: field.physical(raw),
                })
            })
            .collect()
    }

    /// Encodes a frame from node `node` (or to it), asking `value` for each field's physical
    /// value by name. Constant fields need no value; every other field must have a valid one.
    pub fn encode(&self, node: Address, value: impl Fn(&str) -> Option<f64>) -> Result<Frame, Error> {
        self.encode_indexed(node, |i| self.fields.get(i).and_then(|f| value(f.name)))
    }

    /// As [`MessageDef::encode`], asking `value` by the field's position in `fields`: for callers
    /// that resolved their names once and encode often.
    pub fn encode_indexed(
        &self,
        node: Address,
        value: impl Fn(usize) -> Option<f64>,
    ) -> Result<Frame, Error> {
        if !self.nodes.contains(node) {
            return Err(self.error(format!("node {node} does not send or receive this message")));
        }
        let mut data = [0u8; 8];
        data[0] = self.number;
        for (i, field) in self.fields.iter().enumerate() {
            let raw = match field.constant {
                Some(c) => i64::from(c),
                None => {
                    let v = value(i).ok_or_else(|| self.error(format!("no value for {}", field.name)))?;
                    field.to_raw(v).ok_or_else(|| {
                        self.error(format!(
                            "{} = {v} is outside {}..={} {}",
                            field.name, field.min, field.max, field.unit
                        ))
                    })?
                }
            };
            field.insert(&mut data, raw);
        }
        Ok(Frame::new_data(
            self.app_id(node).emit(),
            &data[..usize::from(self.dlc)],
        )?)
    }

    fn error(&self, reason: String) -> Error {
        Error::Payload {
            message: self.name,
            reason,
        }
    }

    fn matches(&self, id: &AppId, data: &[u8]) -> Option<Address> {
        let node = match self.direction {
            Direction::ToMonitor if id.destination == Address::MONITOR => id.source,
            Direction::FromMonitor if id.source == Address::MONITOR => id.destination,
            _ => return None,
        };
        let selected = match self.selector {
            Some((byte, value)) => data.get(usize::from(byte)) == Some(&value),
            None => true,
        };
        (self.nodes.contains(node)
            && id.priority == self.priority()
            && id.frame_type == self.frame_type
            && data.first() == Some(&self.number)
            && selected)
            .then_some(node)
    }
}

/// A decoded payload's fields, in order. Up to eight are held inline, so decoding a message of
/// the catalogue allocates nothing (none has more; a test checks it).
pub type Values = smallvec::SmallVec<[Value; 8]>;

/// A decoded field.
#[derive(Clone, Copy, PartialEq, Debug)]
pub struct Value {
    /// Its definition.
    pub field: &'static Field,
    /// The raw value.
    pub raw: i64,
    /// raw × scale + offset.
    pub physical: f64,
}

impl Value {
    /// True when the value lies in the field's valid range.
    pub fn in_range(&self) -> bool {
        self.physical >= self.field.min && self.physical <= self.field.max
    }
    /// The name of the value, if the field names it.
    pub fn label(&self) -> Option<&'static str> {
        self.field.label(self.raw)
    }
}

/// A frame decoded through the catalogue.
#[derive(Clone, PartialEq, Debug)]
pub struct Decoded {
    /// The message.
    pub message: &'static MessageDef,
    /// The field node at the other end from the monitor.
    pub node: Address,
    /// Data1–Data7, field by field.
    pub values: Values,
}

impl Decoded {
    /// The value of the field named `name`.
    pub fn get(&self, name: &str) -> Option<&Value> {
        self.values.iter().find(|v| v.field.name == name)
    }
}

/// The message a frame with this identifier and payload is, and the field node involved.
pub fn lookup(id: &AppId, data: &[u8]) -> Option<(&'static MessageDef, Address)> {
    MESSAGES
        .iter()
        .find_map(|m| m.matches(id, data).map(|node| (m, node)))
}

/// The message called `name`.
pub fn by_name(name: &str) -> Option<&'static MessageDef> {
    MESSAGES.iter().find(|m| m.name == name)
}

/// Decodes a frame: `Ok(None)` when it is not a catalogue message, an error when it is one but
/// its payload breaks the layout.
pub fn decode(frame: &Frame) -> Result<Option<Decoded>, Error> {
    if frame.is_remote() {
        return Ok(None);
    }
    let Ok(id) = AppId::from_id(frame.id()) else {
        return Ok(None);
    };
    let Some((message, node)) = lookup(&id, frame.data()) else {
        return Ok(None);
    };
    Ok(Some(Decoded {
        message,
        node,
        values: message.decode(frame.data())?,
    }))
}

#[cfg(test)]
mod tests;
