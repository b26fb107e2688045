//! The program's node on the bus: frames that pass its filters go to a queue the session reads,
//! and the bus stops at each while the session waits for one.

use super::Received;
use bus::Frame;
use bus::node::NodeLogic;
use bus::time::BusTime;
use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

/// Most frames waiting for the program; the oldest go beyond it.
pub const QUEUE: usize = 65_536;

/// A python-can filter: a frame passes when `id & mask == can_id & mask`, and, when `extended`
/// is given, its identifier is of that kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Filter {
    /// The identifier to compare with.
    pub id: u32,
    /// The bits that count.
    pub mask: u32,
    /// Only extended (or only base) identifiers, when given.
    pub extended: Option<bool>,
}

impl Filter {
    /// Whether `frame` passes.
    pub fn passes(&self, frame: &Frame) -> bool {
        frame.raw_id() & self.mask == self.id & self.mask
            && self.extended.is_none_or(|e| e == frame.is_extended())
    }
}

/// Frames for the program, and what it waits for.
#[derive(Debug, Default)]
pub struct Inbox {
    queue: VecDeque<Received>,
    /// Frames dropped because the queue was full.
    pub dropped: u64,
    /// Frames pass when any of these passes them (all frames when empty).
    filters: Vec<Filter>,
    /// Set while the session waits for a frame: the bus then stops at the next one.
    pub waiting: bool,
    stop: bool,
}

impl Inbox {
    /// The oldest frame waiting.
    pub fn pop(&mut self) -> Option<Received> {
        self.queue.pop_front()
    }

    /// New filters; the frames waiting that they do not pass are dropped.
    pub fn set_filters(&mut self, filters: Vec<Filter>) {
        self.filters = filters;
        let f = &self.filters;
        self.queue
            .retain(|r| f.is_empty() || f.iter().any(|x| x.passes(&r.frame)));
    }

    /// No frame waiting.
    pub fn is_empty(&self) -> bool {
        self.queue.is_empty()
    }

    fn take(&mut self, at: BusTime, frame: &Frame) {
        if !self.filters.is_empty() && !self.filters.iter().any(|f| f.passes(frame)) {
            return;
        }
        if self.queue.len() >= QUEUE {
            self.queue.pop_front();
            self.dropped += 1;
        }
        self.queue.push_back(Received {
            at_s: super::seconds(at),
            frame: *frame,
        });
        self.stop |= self.waiting;
    }
}

/// The program's logic: it only receives; what it sends is submitted to its controller
/// directly.
pub struct Program {
    inbox: Rc<RefCell<Inbox>>,
}

impl Program {
    /// A program that fills `inbox`.
    pub fn new(inbox: Rc<RefCell<Inbox>>) -> Program {
        Program { inbox }
    }
}

impl NodeLogic for Program {
    fn handle_frame(&mut self, now: BusTime, frame: &Frame) {
        self.inbox.borrow_mut().take(now, frame);
    }
    fn handle_timeout(&mut self, _: BusTime) {}
    fn poll_transmit(&mut self) -> Option<Frame> {
        None
    }
    fn poll_timeout(&self) -> Option<BusTime> {
        None
    }
    fn stop_here(&mut self) -> bool {
        std::mem::take(&mut self.inbox.borrow_mut().stop)
    }
}
