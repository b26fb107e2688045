//! The catalogue written out as a DBC file, for CAN tools (CANdb++, cantools, SavvyCAN,
//! BusMaster, python-can) that read one.
//!
//! Contract: [`generate`] is a pure function of a message table and a [`Network`]; the same input
//! gives the same text, byte for byte. The DBC holds:
//! - `BU_`: every node the catalogue knows (F5, A0, B0–B7, C0–C3, D0–D5, E0), plus any other
//!   address the network's scripts name;
//! - one `BO_` per concrete 29-bit identifier, written with bit 31 set (the DBC mark of an
//!   extended identifier), transmitted by the identifier's source node;
//! - Data0 (the message number) as signal `message_number`. Messages that share an identifier
//!   (the flow sensor's markers, parts and status all use 0x0601F5Dn) are told apart by Data0, so
//!   there it is the multiplexor (`M`) and each message's fields are multiplexed on its number;
//! - every field as an Intel (`@1`) signal, as the catalogue packs them (low byte first), with
//!   its sign, scale, offset, valid range, unit and the receiving node;
//! - `CM_` comments from the catalogue's docs, `VAL_` tables for named values;
//! - `GenMsgCycleTime` for identifiers with cyclic traffic (the shortest cycle of the messages on
//!   it), `GenSigCycleTime` on multiplexed signals (the cycle of their own message), and
//!   `VFrameFormat` = `ExtendedCAN` on every message.
//!
//! Cycle times come from [`Network`]: for a field node that runs a behaviour script, what the
//! script sends and how often; otherwise, and for the monitor's messages, the catalogue.
//!
//! What DBC cannot say is said in comments rather than hidden: the DLC of a multiplexed `BO_` is
//! the longest of its messages (each message's own DLC is in the comment), and two messages that
//! share both identifier and Data0 (told apart by a selector byte) are written as one set of
//! signals when their layouts agree, with the selector's value table naming the messages; when
//! they do not agree, the fields of the later message are left out and a comment says so.

mod layout;
mod text;

#[cfg(test)]
mod tests;

use super::{MessageDef, Trigger};
use crate::ident::Address;
use std::collections::BTreeMap;

/// What a DBC needs to know beyond the message table: the network's name, its bit rate and how
/// often the field nodes really send.
#[derive(Clone, Debug, PartialEq)]
pub struct Network {
    /// Name of the machine (written in the file's comment).
    pub name: String,
    /// Bit rate, bit/s (the `Baudrate` attribute).
    pub bitrate: u32,
    /// For each field node that runs a behaviour script: the catalogue messages it sends and
    /// when. A scripted node's messages missing here are not sent on their own (no cycle time);
    /// nodes missing here send as the catalogue says.
    pub scripted: BTreeMap<Address, BTreeMap<String, Trigger>>,
}

impl Network {
    /// A network where every node sends exactly as the catalogue says.
    pub fn catalogue(name: &str, bitrate: u32) -> Network {
        Network {
            name: name.to_string(),
            bitrate,
            scripted: BTreeMap::new(),
        }
    }

    /// When `message`, exchanged with field node `node`, is sent. The monitor's messages follow
    /// the catalogue: the reference monitor sends them as it says.
    pub fn trigger(&self, message: &MessageDef, node: Address) -> Trigger {
        match (message.direction, self.scripted.get(&node)) {
            (super::Direction::ToMonitor, Some(sends)) => {
                sends.get(message.name).copied().unwrap_or(Trigger::Event)
            }
            _ => message.trigger,
        }
    }

    /// Every node on the network: the catalogue's, then any other scripted address.
    fn nodes(&self) -> Vec<Address> {
        let mut all: Vec<Address> = Address::all().collect();
        for a in self.scripted.keys() {
            if !all.contains(a) {
                all.push(*a);
            }
        }
        all
    }
}

/// The DBC text of `messages` (normally [`super::MESSAGES`]) on `network`.
pub fn generate(messages: &'static [MessageDef], network: &Network) -> String {
    let nodes = network.nodes();
    let frames = layout::frames(messages, network, &nodes);
    text::write(network, &nodes, &frames)
}
