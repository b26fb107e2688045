//! The bench the engine's conformance cases share: the test frame `F` (012#80, laid out bit by
//! bit in `conformance.rs`), a bus with one transmitter and some receivers, and readers of the
//! events in bit times. Not every test file uses every helper.
#![allow(dead_code, unused_imports)]

pub use bus::Frame;
pub use bus::bits;
pub use bus::engine::{
    BitPosition, Bus, BusConfig, BusError, ControllerConfig, Disturbance, Effect, Event, Location, NodeId,
    Rule, Schedule, SeenBy, Target,
};
pub use bus::fault::ErrorState;
pub use bus::time::{BusDuration, BusTime};

/// One bit time at 250 kbit/s, in nanoseconds.
pub const BIT: BusDuration = BusDuration::from_micros(4);
/// The stuffed bitstream of [`f`], SOF to the last CRC bit, laid out in the module docs.
pub const F_STUFFED: &str = "0000010010010000010011000001001000101011111000";
/// Stuffed length of [`f`].
pub const S: u64 = 46;
/// A clean [`f`] on the bus, intermission included: S + 13.
pub const F_BITS: u64 = S + 13;

pub const DOMINANT: Option<bool> = Some(false);
pub const RECESSIVE: Option<bool> = Some(true);
pub const INVERT: Option<bool> = None;

/// The test frame 012#80.
pub fn f() -> Frame {
    Frame::base(0x012, &[0x80]).unwrap()
}

/// Bus time of bit `n` (counted from a SOF at time 0).
pub fn at(n: u64) -> BusTime {
    BusTime::ZERO + BIT * n
}

/// A bus time in bits.
pub fn bits_at(t: BusTime) -> u64 {
    let n = t.elapsed() / BIT;
    assert_eq!(BIT * n, t.elapsed(), "{t:?} is not on a bit boundary");
    n
}

/// A bus with a transmitter `tx` that has `f()` queued at time 0, and `receivers` receivers.
pub struct Net {
    pub b: Bus,
    pub tx: NodeId,
    pub rx: Vec<NodeId>,
}

pub fn net(receivers: usize) -> Net {
    let mut b = Bus::new(BusConfig::default()).unwrap();
    let tx = b.attach(ControllerConfig::named("tx"));
    let rx = (0..receivers)
        .map(|i| b.attach(ControllerConfig::named(format!("r{i}"))))
        .collect();
    b.submit(tx, f(), BusTime::ZERO).unwrap();
    Net { b, tx, rx }
}

impl Net {
    /// From bit `from` (of the attempt that starts at bit 0), for `bits` bits, the controllers
    /// in `nodes` (all when `None`) sample `level` (`None`: the inverse of the bus).
    pub fn disturb(&mut self, from: u64, bits: u32, level: Option<bool>, nodes: Option<Vec<NodeId>>) {
        self.b.disturb(Disturbance {
            at: at(from),
            bits,
            level,
            nodes,
        });
    }
    /// Commits one attempt and returns its events.
    pub fn step(&mut self) -> Vec<Event> {
        assert!(self.b.step(), "nothing to do");
        self.b.take_events().collect()
    }
    /// Runs everything that starts in the next `bits` bit times.
    pub fn run_for(&mut self, bits: u64) -> Vec<Event> {
        let until = self.b.committed() + BIT * bits;
        self.b.run_until(until);
        self.b.take_events().collect()
    }
    pub fn tec(&self, n: NodeId) -> u16 {
        self.b.controller(n).unwrap().fault().tec()
    }
    pub fn rec(&self, n: NodeId) -> u16 {
        self.b.controller(n).unwrap().fault().rec()
    }
    pub fn state(&self, n: NodeId) -> ErrorState {
        self.b.controller(n).unwrap().fault().state()
    }
}

/// Every controller's detected errors: (node, first bit of its flag, error).
pub fn bus_errors(ev: &[Event]) -> Vec<(NodeId, u64, BusError)> {
    let mut v: Vec<_> = ev
        .iter()
        .filter_map(|e| match *e {
            Event::BusError { node, at, error, .. } => Some((node, bits_at(at), error)),
            _ => None,
        })
        .collect();
    v.sort_by_key(|&(n, t, _)| (t, n));
    v
}

/// Every controller's detected errors with their locations.
pub fn locations(ev: &[Event]) -> Vec<(NodeId, Location)> {
    ev.iter()
        .filter_map(|e| match *e {
            Event::BusError { node, location, .. } => Some((node, location)),
            _ => None,
        })
        .collect()
}

/// Overload flags: (node, first bit).
pub fn overloads(ev: &[Event]) -> Vec<(NodeId, u64)> {
    let mut v: Vec<_> = ev
        .iter()
        .filter_map(|e| match *e {
            Event::Overload { node, at } => Some((node, bits_at(at))),
            _ => None,
        })
        .collect();
    v.sort_by_key(|&(n, t)| (t, n));
    v
}

/// Starts of the frames that went through, with their transmitters.
pub fn frames(ev: &[Event]) -> Vec<(NodeId, u64)> {
    ev.iter()
        .filter_map(|e| match *e {
            Event::Frame { node, start, .. } => Some((node, bits_at(start))),
            _ => None,
        })
        .collect()
}

/// Starts of the attempts an error frame destroyed.
pub fn destroyed(ev: &[Event]) -> Vec<u64> {
    ev.iter()
        .filter_map(|e| match *e {
            Event::ErrorFrame { start, .. } => Some(bits_at(start)),
            _ => None,
        })
        .collect()
}

/// The single `ErrorFrame` of an attempt: (detection bit, first flag bit, end of the last
/// flag, error).
pub fn error_frame(ev: &[Event]) -> (u64, u64, u64, BusError) {
    let v: Vec<_> = ev
        .iter()
        .filter_map(|e| match *e {
            Event::ErrorFrame {
                start,
                flag,
                end,
                bit,
                error,
                ..
            } => Some((
                u64::from(bit),
                bits_at(flag) - bits_at(start),
                bits_at(end) - bits_at(start),
                error,
            )),
            _ => None,
        })
        .collect();
    assert_eq!(v.len(), 1, "one destroyed attempt: {ev:?}");
    v[0]
}

/// Deliveries: (receiver, time in bits).
pub fn delivered(ev: &[Event]) -> Vec<(NodeId, u64)> {
    ev.iter()
        .filter_map(|e| match *e {
            Event::Delivered { node, at } => Some((node, bits_at(at))),
            _ => None,
        })
        .collect()
}

/// State changes: (node, time in bits, from, to, tec, rec).
pub fn states(ev: &[Event]) -> Vec<(NodeId, u64, ErrorState, ErrorState, u16, u16)> {
    ev.iter()
        .filter_map(|e| match *e {
            Event::State {
                node,
                at,
                from,
                to,
                tec,
                rec,
            } => Some((node, bits_at(at), from, to, tec, rec)),
            _ => None,
        })
        .collect()
}

/// Brings a lone node to TEC 128 (error passive) through 16 ACK errors, each signalled with an
/// active flag: TEC 8, 16, ..., 128 (rule 3). Each of the first 15 attempts lasts S + 19 = 65
/// bits (ACK slot S + 1, flag S + 2..S + 7, delimiter S + 8..S + 15, intermission
/// S + 16..S + 18); the 16th ends error passive, so 8 bits of suspend follow its intermission:
/// S + 27 = 73 bits. The 17th attempt starts at 15·65 + 73 = 1048.
pub const LONE_17TH_SOF: u64 = 15 * (S + 19) + (S + 27);

pub fn lone_passive(n: &mut Net) {
    for _ in 0..16 {
        n.step();
    }
    assert_eq!(
        (n.tec(n.tx), n.state(n.tx)),
        (128, ErrorState::Passive),
        "setup: 16 ACK errors at +8"
    );
}
