//! A CAN database read from a DBC file: the network's nodes, messages and signals, for networks
//! that are not the harvester (`harvemu import`).
//!
//! Contract:
//! - [`Database::parse`] reads DBC text (with the `can-dbc` crate) into owned [`Message`]s and
//!   [`Signal`]s. A file that does not parse is an [`Error::Dbc`] at its line and column; what
//!   parses but cannot be run as given (a signal wider than its message, two signals on one bit,
//!   a message with no cycle time, a float signal) is kept with a [`Warning`] naming the
//!   message and signal, never an error, so that the rest of the network still runs.
//! - Identifiers: a `BO_` id with bit 31 set is extended (its low 29 bits), as DBC marks them;
//!   one without is a base identifier and must fit in 11 bits, else it is an error.
//! - Cycle times and send types come from the attributes `GenMsgCycleTime` and
//!   `GenMsgSendType` (their `BA_DEF_DEF_` defaults where a message has none); start values
//!   from `GenSigStartValue` (raw, as Vector's tools write it).
//! - [`Signal::positions`] places a signal's bits as DBC defines them for both byte orders;
//!   [`Signal::to_raw`] turns a physical value into the raw one the frame carries (limited to
//!   the signal's range and bits); [`Message::encode`] builds a payload from physical values.
//! - [`Database::to_dbc`] writes the database back as DBC text with the cycle times a network
//!   sends; read again, it gives the same messages and signals.
//!   Nothing here does I/O or panics on any input.

mod codec;
mod read;
mod write;

#[cfg(test)]
mod tests;

use crate::Error;
use std::collections::BTreeMap;

pub use codec::PAYLOAD_BITS;
pub use write::Written;

/// A DBC file's bytes as text: UTF-8 when they are, else Windows-1252, the code page DBC
/// editors write.
pub fn text_of(bytes: &[u8]) -> String {
    match std::str::from_utf8(bytes) {
        Ok(t) => t.to_string(),
        Err(_) => can_dbc::encodings::WINDOWS_1252.decode(bytes).0.into_owned(),
    }
}

/// How a signal's bytes are ordered.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum ByteOrder {
    /// `@1`: little-endian, the start bit is the least significant bit.
    Intel,
    /// `@0`: big-endian, the start bit is the most significant bit.
    Motorola,
}

/// A signal's place in multiplexing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mux {
    /// Always in the message.
    Plain,
    /// The multiplexor (`M`): its value says which multiplexed signals the frame holds.
    Multiplexor,
    /// In the message when the multiplexor has this value (`m3`).
    On(u64),
}

/// One signal of a message.
#[derive(Clone, Debug, PartialEq)]
pub struct Signal {
    /// Name, unique within its message.
    pub name: String,
    /// DBC start bit (Intel: least significant bit; Motorola: most significant).
    pub start_bit: u16,
    /// Width, 1 to 64 bits.
    pub bits: u8,
    /// Byte order.
    pub byte_order: ByteOrder,
    /// Two's complement when true.
    pub signed: bool,
    /// physical = raw × factor + offset.
    pub factor: f64,
    /// physical = raw × factor + offset.
    pub offset: f64,
    /// The physical range; `min == max` (often 0 and 0) means none is given.
    pub min: f64,
    /// The physical range's top.
    pub max: f64,
    /// Unit.
    pub unit: String,
    /// Nodes that receive it.
    pub receivers: Vec<String>,
    /// Multiplexing.
    pub mux: Mux,
    /// Names of raw values (`VAL_`).
    pub values: Vec<(i64, String)>,
    /// The raw start value (`GenSigStartValue`), if given.
    pub start_raw: Option<f64>,
    /// `CM_ SG_`.
    pub comment: Option<String>,
}

impl Signal {
    /// The physical value a node sends before anything else is said: the start value, else 0
    /// raw, brought into the range.
    pub fn initial(&self) -> f64 {
        let raw = self.start_raw.unwrap_or(0.0);
        let v = raw * self.factor + self.offset;
        if self.min < self.max {
            v.clamp(self.min, self.max)
        } else {
            v
        }
    }

    /// Whether the signal has a physical range.
    pub fn has_range(&self) -> bool {
        self.min < self.max
    }
}

/// One message (`BO_`).
#[derive(Clone, Debug, PartialEq)]
pub struct Message {
    /// Name.
    pub name: String,
    /// Identifier (29 bits when extended, else 11).
    pub id: u32,
    /// A 29-bit identifier.
    pub extended: bool,
    /// Payload length, 0 to 8 bytes.
    pub dlc: u8,
    /// The node that sends it, if any (`Vector__XXX` is none).
    pub transmitter: Option<String>,
    /// Its signals, in file order.
    pub signals: Vec<Signal>,
    /// `GenMsgCycleTime`, ms (none, or 0, means not cyclic).
    pub cycle_ms: Option<u32>,
    /// `GenMsgSendType`, as its value table names it (`Cyclic`, `Event`, ...), if given.
    pub send_type: Option<String>,
    /// `CM_ BO_`.
    pub comment: Option<String>,
}

impl Message {
    /// The signal called `name`.
    pub fn signal(&self, name: &str) -> Option<&Signal> {
        self.signals.iter().find(|s| s.name == name)
    }

    /// The multiplexor, if the message has one.
    pub fn multiplexor(&self) -> Option<&Signal> {
        self.signals.iter().find(|s| s.mux == Mux::Multiplexor)
    }

    /// The multiplexor values the message's multiplexed signals use, in order.
    pub fn mux_values(&self) -> Vec<u64> {
        let mut v: Vec<u64> = self
            .signals
            .iter()
            .filter_map(|s| match s.mux {
                Mux::On(n) => Some(n),
                _ => None,
            })
            .collect();
        v.sort_unstable();
        v.dedup();
        v
    }

    /// The signals a payload carries (in a multiplexed message, the multiplexor and the signals
    /// of its page), each with its raw value; `None` for one the payload is too short for.
    pub fn decode<'a>(&'a self, data: &[u8]) -> Vec<(&'a Signal, Option<i128>)> {
        let page = self.multiplexor().and_then(|s| s.extract(data));
        self.signals
            .iter()
            .filter(|s| match s.mux {
                Mux::On(n) => page == Some(i128::from(n)),
                _ => true,
            })
            .map(|s| (s, s.extract(data)))
            .collect()
    }

    /// The payload that carries `values` (physical, by signal name; a signal not named sends its
    /// [`Signal::initial`]). In a multiplexed message the multiplexor's value picks which
    /// multiplexed signals are written (the others are left 0). A value that is not a number
    /// is `None`.
    pub fn encode(&self, values: &BTreeMap<String, f64>) -> Option<Vec<u8>> {
        self.encode_with(|i| self.signals.get(i).and_then(|s| values.get(&s.name).copied()))
    }

    /// [`Message::encode`] with the values by signal index (`None`: the signal's initial value).
    pub fn encode_with(&self, value: impl Fn(usize) -> Option<f64>) -> Option<Vec<u8>> {
        let mut data = vec![0u8; usize::from(self.dlc.min(8))];
        let value = |i: usize, s: &Signal| value(i).unwrap_or_else(|| s.initial());
        let mux = match self.signals.iter().position(|s| s.mux == Mux::Multiplexor) {
            Some(i) => Some(self.signals[i].to_raw(value(i, &self.signals[i]))?),
            None => None,
        };
        for (i, s) in self.signals.iter().enumerate() {
            if let Mux::On(n) = s.mux
                && mux != Some(i128::from(n))
            {
                continue;
            }
            s.insert(&mut data, s.to_raw(value(i, s))?);
        }
        Some(data)
    }
}

/// Something in the file that is run otherwise than it says, or not at all.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Warning {
    /// The message (and signal) it is about.
    pub at: String,
    /// What was done.
    pub reason: String,
}

/// A network read from a DBC file.
#[derive(Clone, Debug, PartialEq)]
pub struct Database {
    /// `BU_`, in file order.
    pub nodes: Vec<String>,
    /// `BO_`, in file order.
    pub messages: Vec<Message>,
    /// The `Baudrate` attribute, bit/s, if given.
    pub bitrate: Option<u32>,
    /// The `DBName` attribute, if given.
    pub name: Option<String>,
    /// The file's general comment (`CM_ "..."`), if any.
    pub comment: Option<String>,
    /// What will not run as written.
    pub warnings: Vec<Warning>,
}

impl Database {
    /// Reads DBC text (`file` names it in errors).
    pub fn parse(file: &str, text: &str) -> Result<Database, Error> {
        read::parse(file, text)
    }

    /// The message called `name`.
    pub fn message(&self, name: &str) -> Option<&Message> {
        self.messages.iter().find(|m| m.name == name)
    }

    /// The messages node `node` sends.
    pub fn sent_by<'a>(&'a self, node: &'a str) -> impl Iterator<Item = &'a Message> + 'a {
        self.messages
            .iter()
            .filter(move |m| m.transmitter.as_deref() == Some(node))
    }
}
