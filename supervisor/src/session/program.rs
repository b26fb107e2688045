//! The program's node on the bus: frames that pass its filters go to a queue the session reads
//! (its own frames too, when it asks for them, at their end of frame), and the bus stops at each
//! while the session waits for one. Commands for its controller (listen-only mode) go out at
//! its next wake.

use super::{Delivered, ErrorReceived, Received};
use bus::Frame;
use bus::node::{ControllerCommand, ControllerEvent, NodeLogic};
use bus::time::BusDuration;
use bus::time::BusTime;
use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;
use std::sync::{Arc, Mutex};

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

/// Error frames for the program, filled by the hub's error observer as the engine commits them
/// (so possibly ahead of the bus time reached: they are handed over once it has come).
#[derive(Debug, Default)]
pub struct Errors {
    /// Oldest first, with their bus time.
    queue: VecDeque<(BusTime, ErrorReceived)>,
    /// Dropped because the queue was full.
    pub dropped: u64,
    /// Set while the session waits: the run then stops at the next one.
    pub waiting: bool,
}

impl Errors {
    /// Takes an error frame of bus time `at`; answers whether the run is to stop there.
    pub fn take(&mut self, at: BusTime, e: ErrorReceived) -> bool {
        if self.queue.len() >= QUEUE {
            self.queue.pop_front();
            self.dropped += 1;
        }
        self.queue.push_back((at, e));
        self.waiting
    }
}

/// The error frames, shared with the hub's observer (which must be `Send`).
pub type SharedErrors = Arc<Mutex<Errors>>;

/// Locks the error frames; a panic elsewhere while they were held leaves them usable.
pub fn lock(errors: &SharedErrors) -> std::sync::MutexGuard<'_, Errors> {
    errors.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Frames for the program, and what it waits for.
#[derive(Debug, Default)]
pub struct Inbox {
    /// Error frames, when the program asked for some.
    pub errors: SharedErrors,
    queue: VecDeque<Received>,
    /// Frames dropped because the queue was full.
    pub dropped: u64,
    /// Frames pass when any of these passes them (all frames when empty).
    filters: Vec<Filter>,
    /// Set while the session waits for a frame: the bus then stops at the next one.
    pub waiting: bool,
    stop: bool,
    /// Frames sent over and over, in bus time.
    tasks: Vec<Task>,
    /// The number the next task gets.
    next_task: u64,
    /// Frames due from the tasks, for the controller.
    outbox: VecDeque<Frame>,
    /// Commands for the controller, for its next wake.
    pub commands: VecDeque<ControllerCommand>,
    /// The frames the controller sent go to the queue too.
    pub own_frames: bool,
}

/// Frames sent over and over: `frames` in turn, one every `period`, until `end`.
#[derive(Debug)]
struct Task {
    id: u64,
    frames: Vec<Frame>,
    turn: usize,
    period: BusDuration,
    next: BusTime,
    end: Option<BusTime>,
}

impl Inbox {
    /// The oldest frame or error frame waiting whose time has come by `now`.
    pub fn pop(&mut self, now: BusTime) -> Option<Delivered> {
        let mut errors = lock(&self.errors);
        let error = errors.queue.front().map(|(at, _)| *at).filter(|&at| at <= now);
        match (error, self.queue.front()) {
            (Some(e), Some(f)) if e.as_secs_f64() > f.at_s => self.queue.pop_front().map(Delivered::Frame),
            (Some(_), _) => errors.queue.pop_front().map(|(_, e)| Delivered::Error(e)),
            (None, _) => self.queue.pop_front().map(Delivered::Frame),
        }
    }

    /// Whether something waits whose time has come by `now`.
    pub fn ready(&self, now: BusTime) -> bool {
        !self.queue.is_empty() || lock(&self.errors).queue.front().is_some_and(|(at, _)| *at <= now)
    }

    /// Sets whether the session waits: the run then stops at the next frame or error frame.
    pub fn set_waiting(&mut self, on: bool) {
        self.waiting = on;
        lock(&self.errors).waiting = on;
    }

    /// New filters; the frames waiting that they do not pass are dropped.
    pub fn set_filters(&mut self, filters: Vec<Filter>) {
        self.filters = filters;
        let f = &self.filters;
        self.queue
            .retain(|r| f.is_empty() || f.iter().any(|x| x.passes(&r.frame)));
    }

    /// Starts sending `frames` in turn, the first at `now`, then one every `period` (more than
    /// zero), until `end` if given; answers with the task's number.
    pub fn start_task(
        &mut self,
        frames: Vec<Frame>,
        period: BusDuration,
        now: BusTime,
        end: Option<BusTime>,
    ) -> u64 {
        self.next_task += 1;
        self.tasks.push(Task {
            id: self.next_task,
            frames,
            turn: 0,
            period,
            next: now,
            end,
        });
        self.next_task
    }

    /// Stops a task; false when there is none by that number (any more).
    pub fn stop_task(&mut self, id: u64) -> bool {
        let before = self.tasks.len();
        self.tasks.retain(|t| t.id != id);
        self.tasks.len() < before
    }

    /// New frames for a task, from its next sending on; false when there is no such task.
    pub fn modify_task(&mut self, id: u64, frames: Vec<Frame>) -> bool {
        match self.tasks.iter_mut().find(|t| t.id == id) {
            Some(t) => {
                t.frames = frames;
                t.turn = 0;
                true
            }
            None => false,
        }
    }

    /// When the next task frame is due.
    fn due(&self) -> Option<BusTime> {
        self.tasks.iter().map(|t| t.next).min()
    }

    /// Queues the task frames due at `now`, and ends the tasks whose time is over.
    fn tick(&mut self, now: BusTime) {
        for t in &mut self.tasks {
            while t.next <= now && t.end.is_none_or(|e| t.next < e) {
                if let Some(f) = t.frames.get(t.turn % t.frames.len().max(1)) {
                    self.outbox.push_back(*f);
                }
                t.turn += 1;
                t.next += t.period;
            }
        }
        self.tasks.retain(|t| t.end.is_none_or(|e| t.next < e));
    }

    fn take(&mut self, at: BusTime, frame: &Frame, own: bool) {
        if !self.filters.is_empty() && !self.filters.iter().any(|f| f.passes(frame)) {
            return;
        }
        if self.queue.len() >= QUEUE {
            self.queue.pop_front();
            self.dropped += 1;
        }
        self.queue.push_back(Received {
            at_s: at.as_secs_f64(),
            frame: *frame,
            own,
        });
        self.stop |= self.waiting;
    }
}

/// The program's logic: it receives, and sends its periodic tasks' frames when they fall due;
/// what it sends once is submitted to its controller directly.
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
        self.inbox.borrow_mut().take(now, frame, false);
    }
    fn handle_event(&mut self, now: BusTime, event: ControllerEvent) {
        let mut inbox = self.inbox.borrow_mut();
        if let ControllerEvent::Sent(frame) = event
            && inbox.own_frames
        {
            inbox.take(now, &frame, true);
        }
    }
    /// Its own frames wake it at their end of frame, so that a `recv` waiting gets them then.
    fn wants_every_event(&self) -> bool {
        self.inbox.borrow().own_frames
    }
    fn poll_command(&mut self) -> Option<(usize, ControllerCommand)> {
        self.inbox.borrow_mut().commands.pop_front().map(|c| (0, c))
    }
    fn handle_timeout(&mut self, now: BusTime) {
        self.inbox.borrow_mut().tick(now);
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        self.inbox.borrow_mut().outbox.pop_front()
    }
    fn poll_timeout(&self) -> Option<BusTime> {
        self.inbox.borrow().due()
    }
    fn stop_here(&mut self) -> bool {
        std::mem::take(&mut self.inbox.borrow_mut().stop)
    }
}
