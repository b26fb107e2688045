//! `harvemu run --tui`: a live cab display in the terminal.
//!
//! Contract: [`View::build`] turns what the running harvester exposes (a hub [`Snapshot`], the
//! monitor's [`Display`], the plant) into a plain view model, with no I/O and no clock;
//! [`draw`] renders a view into any ratatui frame, cutting whatever does not fit the area and
//! never panicking, however small the area. Only [`live`] touches the terminal: it switches to
//! the alternate screen in raw mode, restores the terminal on every way out (errors and panics
//! included), redraws a few times per second of wall time and quits on `q`, Esc or Ctrl-C.
//!
//! [`Snapshot`]: bus_runtime::hub::Snapshot
//! [`Display`]: nodes::monitor::Display

mod draw;
mod fit;
mod keys;
mod live;
mod rates;
mod view;

pub use draw::draw;
pub use keys::quits;
pub use live::{live, require_terminal};
pub use rates::RateMeter;
pub use view::{AlarmView, BusView, Clock, FieldView, IdView, MonitorView, NodeView, Reading, Sources, View};

#[cfg(test)]
mod tests;
