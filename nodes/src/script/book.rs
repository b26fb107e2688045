//! Where a script's messages are defined: the harvester's catalogue, or the DBC database of a
//! network imported from one (a script with `database`). Both give a message by name, its
//! fields, a frame from field values and the field values of a received frame.

use bus::{Frame, Id, extended_id, standard_id};
use protocol::catalogue::{self, Decoded, MessageDef};
use protocol::database::{Database, Message};
use std::sync::Arc;

/// A message a script sends or answers.
#[derive(Clone, Debug)]
pub enum Def {
    /// A harvester catalogue message.
    Catalogue(&'static MessageDef),
    /// Message `index` of a DBC database.
    Dbc(Arc<Database>, usize),
}

impl Def {
    /// The message called `name`: in `db` when the script has one, else in the catalogue.
    pub fn find(db: Option<&Arc<Database>>, name: &str) -> Option<Def> {
        match db {
            Some(db) => db
                .messages
                .iter()
                .position(|m| m.name == name)
                .map(|i| Def::Dbc(Arc::clone(db), i)),
            None => catalogue::by_name(name).map(Def::Catalogue),
        }
    }

    /// The DBC message, for a DBC definition.
    pub fn dbc(&self) -> Option<&Message> {
        match self {
            Def::Dbc(db, i) => db.messages.get(*i),
            Def::Catalogue(_) => None,
        }
    }

    /// Its name.
    pub fn name(&self) -> &str {
        match self {
            Def::Catalogue(d) => d.name,
            Def::Dbc(..) => self.dbc().map_or("", |m| m.name.as_str()),
        }
    }

    /// Whether it has a field (signal) called `name`.
    pub fn has_field(&self, name: &str) -> bool {
        match self {
            Def::Catalogue(d) => d.field(name).is_some(),
            Def::Dbc(..) => self.dbc().is_some_and(|m| m.signal(name).is_some()),
        }
    }
}

/// A DBC message's identifier.
pub fn dbc_id(m: &Message) -> Option<Id> {
    Some(if m.extended {
        extended_id(m.id).ok()?.into()
    } else {
        standard_id(u16::try_from(m.id).ok()?).ok()?.into()
    })
}

/// The field values of a received frame, for reactions and `Field(...)`.
pub enum Received {
    /// A catalogue message addressed to the node.
    Catalogue(Decoded),
    /// A DBC message: its name and each signal present in the frame (raw, physical).
    Dbc {
        /// The message's name.
        message: String,
        /// Signal name, raw value, physical value.
        values: Vec<(String, i128, f64)>,
    },
}

impl Received {
    /// The DBC message a frame is, with the values of the signals it carries (for a
    /// multiplexed message, the multiplexor's and those multiplexed on its value); `None` when
    /// the database has no message with this identifier.
    pub fn of_dbc(db: &Database, frame: &Frame) -> Option<Received> {
        let m = db
            .messages
            .iter()
            .find(|m| m.extended == frame.is_extended() && m.id == frame.raw_id())?;
        let values = m
            .decode(frame.data())
            .into_iter()
            .filter_map(|(s, raw)| {
                let raw = raw?;
                Some((s.name.clone(), raw, s.physical(raw)))
            })
            .collect();
        Some(Received::Dbc {
            message: m.name.clone(),
            values,
        })
    }

    /// The message's name.
    pub fn message(&self) -> &str {
        match self {
            Received::Catalogue(d) => d.message.name,
            Received::Dbc { message, .. } => message,
        }
    }

    /// A field's raw value.
    pub fn raw(&self, name: &str) -> Option<i128> {
        match self {
            Received::Catalogue(d) => d.get(name).map(|v| i128::from(v.raw)),
            Received::Dbc { values, .. } => values.iter().find(|v| v.0 == name).map(|v| v.1),
        }
    }

    /// A field's physical value.
    pub fn physical(&self, name: &str) -> Option<f64> {
        match self {
            Received::Catalogue(d) => d.get(name).map(|v| v.physical),
            Received::Dbc { values, .. } => values.iter().find(|v| v.0 == name).map(|v| v.2),
        }
    }
}
