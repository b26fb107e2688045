//! A socketcand-compatible TCP gateway to the virtual bus, so that python-can's `socketcand`
//! interface and other socketcand clients can watch and inject frames.
//!
//! Contract: many clients at once; each has a bounded queue of outgoing messages, and a client
//! too slow to read loses frames (counted, logged) instead of holding up the bus or growing
//! memory; messages are length-limited; malformed input gets `< error ... >` and the connection
//! goes on; a client never sees its own frames echoed (as with a raw socket); when `accept` fails
//! (out of file descriptors) the gateway backs off and logs at a bounded rate, and the clients
//! already connected are served on.

mod backoff;
pub mod protocol;
mod server;

pub use server::{Gateway, GatewayConfig, GatewayStats};
