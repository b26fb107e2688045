//! A trace sink that counts the records the hub hands it ([`TraceTally`]).
//!
//! Contract: every record is counted once, as it arrives; the counts are shared (`Rc`): the hub
//! owns the sink, the runner reads the counts.

use super::books::TraceTally;
use bus::trace::{Record, Sink};
use std::cell::RefCell;
use std::io;
use std::rc::Rc;

/// Counts records.
pub struct Counting(Rc<RefCell<TraceTally>>);

impl Counting {
    /// A sink and the counts it keeps.
    pub fn new() -> (Counting, Rc<RefCell<TraceTally>>) {
        let tally = Rc::new(RefCell::new(TraceTally::default()));
        (Counting(tally.clone()), tally)
    }
}

impl Sink for Counting {
    fn record(&mut self, r: &Record<'_>) -> io::Result<()> {
        self.0.borrow_mut().record(r);
        Ok(())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}
