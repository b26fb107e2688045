//! Behaviour scripts: each field node's behaviour as data (RON), and the interpreter that runs
//! one as a [`NodeLogic`](bus::node::NodeLogic).
//!
//! A script names the node (address, name, kind), its states, the messages it sends and when
//! (periodic with period and phase, on change with a heartbeat, or on request), what each field
//! of each message is bound to (a plant signal, a constant, a variable, the state code, a field of
//! the frame being answered), its reactions to received frames (match on message and field
//! values; reply, set state, start or stop messages, write a plant input, set a variable), timers
//! (watchdogs), a boot delay, acknowledgement tracking, per-signal fault hooks (stuck, drift,
//! noise, offset, dropout), and the acceptance filter of its CAN controller in the registers of
//! its chip (Atmel CANIDT/CANIDM, SJA1000 ACR/AMR, or a SocketCAN filter list), and generators
//! of moving values (ramp, sine, random walk, counter, cycle). Scaling, byte order and ranges
//! come from the message catalogue, or from the DBC file a script of an imported network names
//! (`database`, [`Def`]), never from the script. A script file may
//! instead be an instance of a template with parameters ([`expand`]). The format is documented
//! in `docs/BEHAVIOUR.md`.

mod book;
mod filter;
mod load;
mod model;
mod run;
mod template;

pub use book::{Def, Received};
pub use filter::FilterProblem;
pub use load::{Signals, from_file_text, from_text, load, parse, validate};
pub use model::*;
pub(crate) use run::gaussian;
pub use run::{Environment, Port, ScriptedNode, SharedEnv};
pub(crate) use template::position_of;
pub use template::{Reader, check as check_template, disk, expand, top_name};

#[cfg(test)]
mod tests;
