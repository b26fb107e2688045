//! One client's BCM mode, sans IO: its cyclic sends and its subscriptions, as the kernel's CAN
//! broadcast manager (`net/can/bcm.c`) runs the jobs socketcand's `state_bcm.c` sets up. Time
//! is bus time, passed in.
//!
//! - `add` (`TX_SETUP` with `SETTIMER | STARTTIMER`) sends the frame at once and then every
//!   interval; an `add` for an identifier that has a job replaces its content and interval and
//!   starts it again; an interval of 0 sends once. Intervals under [`MIN_INTERVAL`] run at
//!   [`MIN_INTERVAL`] (the bus carries a few frames a millisecond at most; shorter timers would
//!   only cost wakes).
//! - `update` (`TX_SETUP`, no flags) replaces the content of a job; its timing goes on untouched.
//!   `delete` ends a job.
//! - `subscribe` (`RX_SETUP` with `RX_FILTER_ID`) passes every frame of an identifier; `filter`
//!   passes the first frame and then those whose bits under the mask differ from the last frame
//!   passed (a frame without data never differs). With a throttle interval, a frame passed within
//!   the interval after the previous one is held, and the latest held frame goes out when the
//!   interval ends (the kernel's `bcm_rx_update_and_send` and throttle timer).
//!   `unsubscribe` ends it. Subscribing again to an identifier replaces its subscription.
//! - Each table holds at most [`MAX_OPS`] entries: more are refused.

use bus::time::{BusDuration, BusTime};
use bus::{Frame, Id};

/// The shortest cyclic interval.
pub const MIN_INTERVAL: BusDuration = BusDuration::from_millis(1);
/// Most cyclic jobs, and most subscriptions, per client.
pub const MAX_OPS: usize = 256;

#[derive(Debug)]
struct TxJob {
    frame: Frame,
    /// Nanoseconds; 0 for none.
    interval: BusDuration,
    /// The next cyclic send.
    next: Option<BusTime>,
    /// To be sent at the next wake, which starts its timer.
    announce: bool,
}

#[derive(Debug)]
struct RxOp {
    id: Id,
    throttle: BusDuration,
    /// `None` for `subscribe`.
    mask: Option<[u8; 8]>,
    /// The last frame passed (held or sent), and when it ended.
    last: Option<(BusTime, Frame)>,
    /// `last` is held by the throttle.
    held: bool,
    /// When the throttle timer ends.
    timer: Option<BusTime>,
    /// When a frame last went out directly (the kernel's `kt_lastmsg`).
    last_sent: Option<BusTime>,
}

/// A client's jobs and subscriptions.
#[derive(Debug, Default)]
pub struct Bcm {
    tx: Vec<TxJob>,
    rx: Vec<RxOp>,
}

fn data8(frame: &Frame) -> [u8; 8] {
    let mut d = [0u8; 8];
    d[..frame.data().len()].copy_from_slice(frame.data());
    d
}

impl Bcm {
    /// `add`; false when the table is full.
    pub fn add(&mut self, interval: BusDuration, frame: Frame) -> bool {
        let interval = if interval == BusDuration::ZERO {
            BusDuration::ZERO
        } else {
            interval.max(MIN_INTERVAL)
        };
        let job = TxJob {
            frame,
            interval,
            next: None,
            announce: true,
        };
        match self.tx.iter().position(|j| j.frame.id() == frame.id()) {
            Some(i) => self.tx[i] = job,
            None if self.tx.len() < MAX_OPS => self.tx.push(job),
            None => return false,
        }
        true
    }

    /// `update`; false when there is no job for its identifier.
    pub fn update(&mut self, frame: Frame) -> bool {
        match self.tx.iter_mut().find(|j| j.frame.id() == frame.id()) {
            Some(j) => {
                j.frame = frame;
                true
            }
            None => false,
        }
    }

    /// `delete`; false when there was no job.
    pub fn delete(&mut self, id: Id) -> bool {
        let before = self.tx.len();
        self.tx.retain(|j| j.frame.id() != id);
        self.tx.len() != before
    }

    /// `subscribe` (no mask) or `filter`; false when the table is full.
    pub fn subscribe(&mut self, id: Id, throttle: BusDuration, mask: Option<[u8; 8]>) -> bool {
        let op = RxOp {
            id,
            throttle,
            mask,
            last: None,
            held: false,
            timer: None,
            last_sent: None,
        };
        match self.rx.iter().position(|o| o.id == id) {
            Some(i) => self.rx[i] = op,
            None if self.rx.len() < MAX_OPS => self.rx.push(op),
            None => return false,
        }
        true
    }

    /// `unsubscribe`; false when there was no subscription.
    pub fn unsubscribe(&mut self, id: Id) -> bool {
        let before = self.rx.len();
        self.rx.retain(|o| o.id != id);
        self.rx.len() != before
    }

    /// True when a job waits to be started at the next wake, whatever the time.
    #[cfg(test)]
    pub fn wants_wake(&self) -> bool {
        self.tx.iter().any(|j| j.announce)
    }

    /// The earliest timer.
    pub fn deadline(&self) -> Option<BusTime> {
        let tx = self.tx.iter().filter_map(|j| j.next);
        let rx = self.rx.iter().filter_map(|o| o.timer);
        tx.chain(rx).min()
    }

    /// Runs what is due at `now`: frames to send go to `send`, frames for the client (with their
    /// end times) to `deliver`.
    pub fn run(&mut self, now: BusTime, send: &mut Vec<Frame>, deliver: &mut Vec<(BusTime, Frame)>) {
        for j in &mut self.tx {
            let due = j.next.is_some_and(|t| t <= now);
            if j.announce || due {
                j.announce = false;
                send.push(j.frame);
                j.next = (j.interval > BusDuration::ZERO).then(|| now + j.interval);
            }
        }
        for o in &mut self.rx {
            if o.timer.is_none_or(|t| t > now) {
                continue;
            }
            match o.last {
                Some(last) if o.held => {
                    o.held = false;
                    deliver.push(last);
                    o.timer = Some(now + o.throttle);
                }
                _ => {
                    // Nothing came in the interval: the next frame goes out at once.
                    o.timer = None;
                    o.last_sent = None;
                }
            }
        }
    }

    /// A frame on the bus, ended at `at`: the frame to deliver at once, if any, and the time of
    /// a throttle timer it started, if it did.
    pub fn frame(&mut self, at: BusTime, frame: &Frame) -> (Option<(BusTime, Frame)>, Option<BusTime>) {
        let Some(o) = self.rx.iter_mut().find(|o| o.id == frame.id()) else {
            return (None, None);
        };
        if let (Some(mask), Some((_, last))) = (o.mask, o.last) {
            let (new, old) = (data8(frame), data8(&last));
            let changed = !frame.data().is_empty() && (0..8).any(|i| new[i] & mask[i] != old[i] & mask[i]);
            if !changed {
                return (None, None);
            }
        }
        o.last = Some((at, *frame));
        o.held = true;
        if o.throttle == BusDuration::ZERO {
            o.held = false;
            return (Some((at, *frame)), None);
        }
        if o.timer.is_some() {
            return (None, None);
        }
        if let Some(sent) = o.last_sent
            && at - sent < o.throttle
        {
            // A second frame within the interval: held until the interval ends.
            o.timer = Some(sent + o.throttle);
            return (None, o.timer);
        }
        o.held = false;
        o.last_sent = Some(at);
        (Some((at, *frame)), None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bus::candump::parse_frame;

    fn ms(n: u64) -> BusTime {
        BusTime::from_millis(n)
    }
    fn f(text: &str) -> Frame {
        parse_frame(text).unwrap()
    }
    impl Bcm {
        /// What `frame` delivers at once.
        fn frame0(&mut self, at: BusTime, frame: &Frame) -> Option<(BusTime, Frame)> {
            self.frame(at, frame).0
        }
    }
    fn run(b: &mut Bcm, now: BusTime) -> (Vec<Frame>, Vec<(BusTime, Frame)>) {
        let (mut s, mut d) = (Vec::new(), Vec::new());
        b.run(now, &mut s, &mut d);
        (s, d)
    }

    #[test]
    fn a_job_sends_at_once_then_every_interval_until_deleted() {
        let mut b = Bcm::default();
        assert!(b.add(BusDuration::from_nanos(20_000_000), f("123#42424242")));
        assert!(b.wants_wake());
        assert_eq!(run(&mut b, ms(5)).0, [f("123#42424242")]);
        assert_eq!(b.deadline(), Some(ms(25)));
        assert!(run(&mut b, ms(24)).0.is_empty());
        // update: new content, same timing.
        assert!(b.update(f("123#112233")));
        assert_eq!(b.deadline(), Some(ms(25)));
        assert_eq!(run(&mut b, ms(25)).0, [f("123#112233")]);
        assert_eq!(b.deadline(), Some(ms(45)));
        assert!(b.delete(f("123#").id()));
        assert_eq!(b.deadline(), None);
        assert!(!b.update(f("123#01")), "no job left");
    }

    #[test]
    fn add_again_restarts_and_zero_sends_once_and_short_intervals_are_floored() {
        let mut b = Bcm::default();
        b.add(BusDuration::from_nanos(10_000_000), f("123#01"));
        run(&mut b, ms(0));
        b.add(BusDuration::ZERO, f("123#02"));
        assert_eq!(run(&mut b, ms(3)).0, [f("123#02")]);
        assert_eq!(b.deadline(), None);
        b.add(BusDuration::from_nanos(10_000), f("00000123#03"));
        run(&mut b, ms(4));
        assert_eq!(b.deadline(), Some(ms(5)), "10 us runs at 1 ms");
        // A standard and an extended identifier are different jobs.
        assert!(b.delete(f("123#").id()));
        assert_eq!(b.deadline(), Some(ms(5)));
    }

    #[test]
    fn subscriptions_throttle_as_the_kernel_does() {
        let mut b = Bcm::default();
        b.subscribe(f("123#").id(), BusDuration::from_nanos(100_000_000), None);
        let x = |n: u8| f(&format!("123#{n:02X}"));
        // The first frame goes out at once; those within 100 ms are held; the latest goes out
        // when the interval ends.
        assert_eq!(b.frame0(ms(0), &x(1)), Some((ms(0), x(1))));
        assert_eq!(b.frame0(ms(10), &x(2)), None);
        assert_eq!(b.deadline(), Some(ms(100)));
        assert_eq!(b.frame0(ms(20), &x(3)), None);
        assert_eq!(run(&mut b, ms(100)).1, [(ms(20), x(3))]);
        assert_eq!(b.deadline(), Some(ms(200)));
        // Nothing in the next interval: the timer stops, and the next frame goes out at once.
        assert!(run(&mut b, ms(200)).1.is_empty());
        assert_eq!(b.deadline(), None);
        assert_eq!(b.frame0(ms(250), &x(4)), Some((ms(250), x(4))));
        assert_eq!(
            b.frame0(ms(400), &x(5)),
            Some((ms(400), x(5))),
            "a gap longer than 100 ms"
        );
        assert_eq!(b.frame0(ms(1), &f("124#00")), None, "not subscribed");
        assert!(b.unsubscribe(f("123#").id()));
        assert_eq!(b.frame0(ms(500), &x(6)), None);
    }

    #[test]
    fn filters_pass_changes_under_the_mask() {
        let mut b = Bcm::default();
        b.subscribe(
            f("123#").id(),
            BusDuration::ZERO,
            Some([0xFF, 0, 0xF8, 0, 0, 0, 0, 0]),
        );
        let first = f("123#0011220000000000");
        assert_eq!(b.frame0(ms(0), &first), Some((ms(0), first)));
        assert_eq!(
            b.frame0(ms(1), &f("123#00FF220000000000")),
            None,
            "byte 1 not masked"
        );
        assert_eq!(
            b.frame0(ms(2), &f("123#0011270000000000")),
            None,
            "low bits of byte 2"
        );
        let change = f("123#00112A0000000000");
        assert_eq!(b.frame0(ms(3), &change), Some((ms(3), change)));
        assert_eq!(b.frame0(ms(4), &f("123#")), None, "no data never differs");
        // Compared with the last frame passed, bytes past a frame's data as zeros.
        let short = f("123#01");
        assert_eq!(b.frame0(ms(5), &short), Some((ms(5), short)));
        assert_eq!(b.frame0(ms(6), &f("123#00112A")), Some((ms(6), f("123#00112A"))));
    }

    #[test]
    fn tables_are_bounded() {
        let mut b = Bcm::default();
        for i in 0..MAX_OPS as u16 {
            let frame = Frame::new_data(bus::standard_id(i).unwrap(), &[]).unwrap();
            assert!(b.add(BusDuration::ZERO, frame));
            assert!(b.subscribe(frame.id(), BusDuration::ZERO, None));
        }
        assert!(!b.add(BusDuration::ZERO, f("7FF#")));
        assert!(!b.subscribe(f("7FF#").id(), BusDuration::ZERO, None));
        assert!(
            b.add(BusDuration::from_nanos(5_000_000), f("000#01")),
            "replacing is not adding"
        );
    }
}
