//! A socketcand-compatible TCP gateway to the virtual bus, so that python-can's `socketcand`
//! interface and other socketcand clients can watch and inject frames, in socketcand's BCM mode
//! (cyclic sends and subscriptions, run on the bus's clock) or raw mode (every frame).
//!
//! Contract: many clients at once; each has a bounded queue of outgoing messages, and a client
//! too slow to read loses frames (counted, logged) instead of holding up the bus or growing
//! memory; messages are length-limited; commands are read as socketcand reads them, and a
//! malformed or unknown one is answered with nothing, as socketcand answers a bad `send`
//! (counted in [`GatewayStats::malformed`], logged at a bounded rate), and the connection goes
//! on; the server never sends `< error ... >`, which socketcand clients read as an error frame;
//! a raw-mode client never sees its own frames echoed (as with a raw socket); when `accept` fails
//! (out of file descriptors) the gateway backs off and logs at a bounded rate, and the clients
//! already connected are served on. A server bound to a loopback address announces itself with
//! socketcand's discovery beacon, to that address only. Frames carry the bus time at their end
//! stamped with the hub's [`bus::time::Epoch`] (seconds since 1970, as the trace writes them).

mod backoff;
mod bcm;
pub mod beacon;
pub mod protocol;
pub mod scan;
mod server;

pub use bcm::{MAX_OPS, MIN_INTERVAL};
pub use server::{Gateway, GatewayConfig, GatewayStats};
