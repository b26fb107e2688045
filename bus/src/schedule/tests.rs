//! The scheduling policy stepped by hand: no runtime, no actor. A driver of a few lines below
//! plays the part of the hub and the node actors, feeding each wake to its logic with
//! [`drive_counted`], as they do.

use super::*;
use crate::candump::parse_frame;
use crate::node::{NodeLogic, drive_counted};
use std::cell::RefCell;
use std::rc::Rc;

/// What a logic heard, in order: (wake time, what).
type Heard = Rc<RefCell<Vec<(BusTime, String)>>>;

/// Ticks every `period` from `next`, sending `send` (if any) at every tick; records what it
/// hears; may let its frames wait, want every event, or fail at a time.
struct Probe {
    heard: Heard,
    period: Option<BusDuration>,
    next: Option<BusTime>,
    send: Option<Frame>,
    owed: usize,
    can_wait: bool,
    every_event: bool,
    fail_at: Option<BusTime>,
    failed: Option<String>,
    unheeded: Option<crate::node::Unheeded>,
    /// Commands for its controller 0, each given at the first wake at or after its time.
    commands: Vec<(BusTime, crate::node::ControllerCommand)>,
    due: Vec<crate::node::ControllerCommand>,
}

impl Probe {
    fn new(heard: &Heard) -> Probe {
        Probe {
            heard: heard.clone(),
            period: None,
            next: None,
            send: None,
            owed: 0,
            can_wait: false,
            every_event: false,
            fail_at: None,
            failed: None,
            unheeded: None,
            commands: Vec::new(),
            due: Vec::new(),
        }
    }
    fn ticking(mut self, first_ms: u64, period_ms: u64) -> Probe {
        self.next = Some(BusTime::from_millis(first_ms));
        self.period = Some(BusDuration::from_millis(period_ms));
        self
    }
    fn sending(mut self, frame: &str) -> Probe {
        self.send = parse_frame(frame).ok();
        self
    }
    fn note(&self, at: BusTime, what: String) {
        self.heard.borrow_mut().push((at, what));
    }
}

impl NodeLogic for Probe {
    fn handle_frame(&mut self, now: BusTime, frame: &Frame) {
        self.note(now, format!("frame {:X}", frame.raw_id()));
    }
    fn handle_timeout(&mut self, now: BusTime) {
        if self.fail_at.is_some_and(|t| now >= t) {
            self.failed = Some("stopped".into());
            self.next = None;
            return;
        }
        while self.commands.first().is_some_and(|(t, _)| *t <= now) {
            self.due.push(self.commands.remove(0).1);
        }
        // The first wake of all (at attach) is not a tick.
        if let Some(next) = self.next.filter(|&t| t <= now) {
            self.note(now, "tick".into());
            self.owed += usize::from(self.send.is_some());
            self.next = self.period.map(|p| next + p);
        }
    }
    fn handle_event(&mut self, now: BusTime, event: ControllerEvent) {
        let what = match event {
            ControllerEvent::Sent(_) => "sent".to_string(),
            ControllerEvent::Counters { tec, rec } => format!("counters {tec} {rec}"),
            other => format!("{other:?}"),
        };
        self.note(now, what);
    }
    fn poll_command(&mut self) -> Option<(usize, crate::node::ControllerCommand)> {
        (!self.due.is_empty()).then(|| (0, self.due.remove(0)))
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        let frame = self.send.filter(|_| self.owed > 0)?;
        self.owed -= 1;
        Some(frame)
    }
    fn poll_timeout(&self) -> Option<BusTime> {
        self.next
    }
    fn frames_can_wait(&self) -> bool {
        self.can_wait
    }
    fn wants_every_event(&self) -> bool {
        self.every_event
    }
    fn failed(&self) -> Option<String> {
        self.failed.clone()
    }
    fn unheeded(&self) -> Option<crate::node::Unheeded> {
        self.unheeded.clone()
    }
}

/// The scheduler with the logics it wakes (by first slot), and every wake it asked for.
struct Driver {
    sched: Scheduler,
    logics: Vec<Option<Box<dyn NodeLogic>>>,
    /// (node, time, controllers) of every wake.
    wakes: Vec<(usize, BusTime, Vec<usize>)>,
    notices: Vec<String>,
}

impl Driver {
    fn new() -> Driver {
        let setup = Setup {
            bus: BusConfig::default(),
            iface: "t0".into(),
            paced: false,
            pacer: Pacer::new(std::time::Duration::ZERO, std::time::Duration::ZERO),
        };
        Driver {
            sched: Scheduler::new(setup, Vec::new()).unwrap(),
            logics: Vec::new(),
            wakes: Vec::new(),
            notices: Vec::new(),
        }
    }

    fn attach(&mut self, names: &[&str], reaction_us: u64, logic: Option<Probe>) -> Vec<NodeId> {
        let controllers = names.iter().map(|n| ControllerConfig::named(*n)).collect();
        let reaction = BusDuration::from_micros(reaction_us);
        let ids = self.sched.attach(controllers, reaction, logic.is_some()).unwrap();
        self.logics.resize_with(self.sched.slots.len(), || None);
        self.logics[ids[0].index()] = logic.map(|l| Box::new(l) as Box<dyn NodeLogic>);
        ids
    }

    /// A node "tx" that sends `frame` every `period_ms` from `first_ms`.
    fn sender(&mut self, first_ms: u64, period_ms: u64, frame: &str) {
        let probe = Probe::new(&Heard::default())
            .ticking(first_ms, period_ms)
            .sending(frame);
        self.attach(&["tx"], 0, Some(probe));
    }

    /// Runs to `t`, answering every wake at once; the time the run stopped at.
    fn run_until(&mut self, t: BusTime) -> BusTime {
        self.sched.run_until(t);
        self.sched.advance(0);
        loop {
            let mut answers = Vec::new();
            while let Some(wake) = self.sched.poll_wake() {
                let controllers = wake.inputs.iter().map(|i| i.controller).collect();
                self.wakes.push((wake.node, wake.now, controllers));
                let logic = self.logics[wake.node].as_mut().unwrap();
                let count = wake.inputs.len();
                for (k, i) in wake.inputs.into_iter().enumerate() {
                    let report =
                        drive_counted(logic.as_mut(), i.controller, wake.now, i.frames, i.events, &mut 0);
                    answers.push((wake.round, i.slot, report, k + 1 == count));
                }
            }
            let mut stopped = None;
            while let Some(notice) = self.sched.poll_notice() {
                match notice {
                    Notice::Stopped(result) => stopped = Some(result.unwrap()),
                    other => self.notices.push(format!("{other:?}")),
                }
            }
            if let Some(at) = stopped {
                assert!(answers.is_empty(), "a stop with wakes unanswered");
                return at;
            }
            assert!(!answers.is_empty(), "neither a wake nor a stop");
            for (round, slot, report, last) in answers {
                self.sched.handle_answer(round, slot, report, last, 0);
            }
        }
    }

    /// The wake times of node `n` (its first slot).
    fn wakes_of(&self, n: NodeId) -> Vec<BusTime> {
        self.wakes
            .iter()
            .filter(|w| w.0 == n.index())
            .map(|w| w.1)
            .collect()
    }
}

fn ms(n: u64) -> BusTime {
    BusTime::from_millis(n)
}

#[test]
fn nodes_are_woken_at_their_deadlines_in_time_order() {
    let (a_heard, b_heard) = (Heard::default(), Heard::default());
    let mut d = Driver::new();
    let a = d.attach(&["a"], 0, Some(Probe::new(&a_heard).ticking(10, 10)))[0];
    let b = d.attach(&["b"], 0, Some(Probe::new(&b_heard).ticking(15, 15)))[0];
    assert_eq!(d.run_until(ms(46)), ms(46));
    // The first wake of each is at attach (time zero); then every deadline exactly.
    assert_eq!(d.wakes_of(a), [0, 10, 20, 30, 40].map(ms));
    assert_eq!(d.wakes_of(b), [0, 15, 30, 45].map(ms));
    // At 30 ms both are due: one round wakes both, the first attached first.
    let at_30: Vec<usize> = d.wakes.iter().filter(|w| w.1 == ms(30)).map(|w| w.0).collect();
    assert_eq!(at_30, [a.index(), b.index()]);
    assert_eq!(d.sched.snapshot().wakes, 9);
}

#[test]
fn a_receiver_is_woken_its_reaction_time_after_the_frame_ends() {
    let rx_heard = Heard::default();
    let mut d = Driver::new();
    d.sender(1, 1000, "123#11");
    let rx = d.attach(&["rx"], 250, Some(Probe::new(&rx_heard)))[0];
    d.run_until(ms(5));
    let heard = rx_heard.borrow();
    let (end, what) = &heard[0];
    assert_eq!(what, "frame 123");
    // Woken at attach, then once: 250 µs after the end of frame the logic was told of.
    assert_eq!(
        d.wakes_of(rx),
        [BusTime::ZERO, *end + BusDuration::from_micros(250)]
    );
    assert!(*end > ms(1));
}

#[test]
fn frames_that_can_wait_leave_the_fifo_and_reach_the_logic_at_its_deadline() {
    let rx_heard = Heard::default();
    let mut d = Driver::new();
    d.sender(1, 2, "123#11");
    let mut probe = Probe::new(&rx_heard).ticking(10, 10);
    probe.can_wait = true;
    let rx = d.attach(&["rx"], 100, Some(probe))[0];
    d.run_until(ms(9));
    // Frames at 1, 3, 5, 7 ms: none has woken the logic (only the wake at attach did), and
    // the four are held, out of the FIFO.
    assert_eq!(d.wakes_of(rx), [BusTime::ZERO]);
    let node = &d.sched.snapshot().nodes[rx.index()];
    assert_eq!((node.handover.held, node.rx_queued), (4, 0));
    // A run stops before what is due at its end.
    d.run_until(ms(10));
    assert_eq!(d.wakes_of(rx), [BusTime::ZERO]);
    d.run_until(ms(11));
    assert_eq!(d.wakes_of(rx), [BusTime::ZERO, ms(10)]);
    let heard: Vec<String> = rx_heard.borrow().iter().map(|h| h.1.clone()).collect();
    // The frame at 9 ms joined them: five, then the tick.
    assert_eq!(
        heard,
        [
            "frame 123",
            "frame 123",
            "frame 123",
            "frame 123",
            "frame 123",
            "tick"
        ]
    );
    let handover = d.sched.snapshot().nodes[rx.index()].handover;
    assert_eq!((handover.handled, handover.held, handover.in_flight), (5, 0, 0));
}

#[test]
fn frames_a_logic_does_not_heed_leave_the_fifo_without_waking_it() {
    let rx_heard = Heard::default();
    let mut d = Driver::new();
    d.sender(1, 2, "123#11");
    d.sender(2, 4, "456#22");
    let mut probe = Probe::new(&rx_heard);
    // Until 7 ms, only frames with identifier 456h matter to it.
    probe.unheeded = Some(crate::node::Unheeded {
        before: ms(7),
        heeded: smallvec::smallvec![crate::filter::AtmelFilter::exact(crate::Id::Standard(
            crate::StandardId::new(0x456).unwrap()
        ))],
    });
    let rx = d.attach(&["rx"], 100, Some(probe))[0];
    d.run_until(ms(10));
    let heard: Vec<String> = rx_heard.borrow().iter().map(|h| h.1.clone()).collect();
    // 123h at 1, 3, 5 ms left out; 456h at 2 and 6 ms, and everything from 7 ms on, heard.
    assert_eq!(heard, ["frame 456", "frame 456", "frame 123", "frame 123"]);
    assert_eq!(
        d.wakes_of(rx).len(),
        1 + 2 + 2,
        "the attach, 456h twice, 123h twice"
    );
    let node = &d.sched.snapshot().nodes[rx.index()];
    assert_eq!((node.handover.handled, node.rx_queued), (7, 0));
}

#[test]
fn a_new_logic_drops_the_frames_the_old_one_held() {
    let rx_heard = Heard::default();
    let mut d = Driver::new();
    d.sender(1, 2, "123#11");
    let mut probe = Probe::new(&rx_heard).ticking(100, 100);
    probe.can_wait = true;
    let rx = d.attach(&["rx"], 0, Some(probe))[0];
    d.run_until(ms(6));
    assert_eq!(d.sched.replace(rx).unwrap(), rx);
    d.logics[rx.index()] = Some(Box::new(Probe::new(&Heard::default())));
    d.run_until(ms(7));
    let handover = d.sched.snapshot().nodes[rx.index()].handover;
    // Frames at 1, 3 and 5 ms were held and dropped with the old logic.
    assert_eq!(
        (handover.dropped_at_replace, handover.held, handover.handled),
        (3, 0, 0)
    );
    // The new logic is woken at once, at the present.
    assert_eq!(*d.wakes_of(rx).last().unwrap(), ms(6));
}

#[test]
fn a_crash_stops_the_run_at_its_moment_and_the_node_is_never_woken_again() {
    let heard = Heard::default();
    let mut d = Driver::new();
    let mut probe = Probe::new(&heard).ticking(10, 10);
    probe.fail_at = Some(ms(30));
    let n = d.attach(&["n"], 0, Some(probe))[0];
    assert_eq!(d.run_until(ms(100)), ms(30));
    assert_eq!(d.notices, [r#"Crashed { node: "n", cause: Failed("stopped") }"#]);
    assert_eq!(d.sched.crashed(), [(n, CrashCause::Failed("stopped".into()))]);
    assert_eq!(d.run_until(ms(100)), ms(100));
    assert_eq!(d.wakes_of(n), [0, 10, 20, 30].map(ms));
}

#[test]
fn a_hung_node_is_not_woken_and_its_fifo_overruns_until_it_is_woken_again() {
    let rx_heard = Heard::default();
    let mut d = Driver::new();
    d.sender(1, 1, "00000123#1122334455667788");
    let rx = d.attach(&["rx"], 0, Some(Probe::new(&rx_heard)))[0];
    d.run_until(BusTime::from_micros(500));
    d.sched.set_hung(rx, true).unwrap();
    assert_eq!(d.run_until(ms(20)), ms(20));
    // 19 frames of 8 bytes (13 FIFO bytes each, SJA1000 rule) in a 64-byte FIFO: 4 kept, 15 lost.
    let node = &d.sched.snapshot().nodes[rx.index()];
    assert_eq!((node.rx_queued, node.counters.rx_overruns), (4, 15));
    assert_eq!(d.wakes_of(rx), [BusTime::ZERO]);
    d.sched.set_hung(rx, false).unwrap();
    d.run_until(ms(21));
    // Woken at once where it was let go, with the four frames kept and the overruns; then the
    // frame sent at 20 ms.
    assert_eq!(d.wakes_of(rx)[1], ms(20));
    let heard = rx_heard.borrow();
    assert_eq!(heard.iter().filter(|h| h.1 == "frame 123").count(), 5);
    // One notification per frame lost, as the counter counts them.
    assert_eq!(heard.iter().filter(|h| h.1 == "Overrun").count(), 15);
    // And none of it in the past: every wake after the hang is at 20 ms or later.
    assert!(
        d.wakes_of(rx)[1..].iter().all(|&t| t >= ms(20)),
        "{:?}",
        d.wakes_of(rx)
    );
}

#[test]
fn a_register_level_node_is_woken_by_its_confirmation_a_plain_one_is_not() {
    let mut times = Vec::new();
    for every_event in [false, true] {
        let heard = Heard::default();
        let mut d = Driver::new();
        let mut probe = Probe::new(&heard).ticking(1, 1000).sending("123#11");
        probe.every_event = every_event;
        let tx = d.attach(&["tx"], 0, Some(probe))[0];
        d.attach(&["rx"], 0, None);
        d.run_until(ms(5));
        let sent: Vec<BusTime> = heard
            .borrow()
            .iter()
            .filter(|h| h.1 == "sent")
            .map(|h| h.0)
            .collect();
        times.push((sent, d.wakes_of(tx)));
    }
    // Plain: the confirmation waits for a next wake, and there is none before 5 ms.
    assert_eq!(times[0], (vec![], [0, 1].map(ms).to_vec()));
    // Register level: woken at the confirmation's own time, after the frame went out at 1 ms.
    let sent = times[1].0[0];
    assert!(sent > ms(1) && sent < ms(2), "{sent}");
    assert_eq!(times[1].1, [ms(0), ms(1), sent]);
}

#[test]
fn a_node_with_two_controllers_is_woken_once_with_the_inputs_of_both() {
    let rx_heard = Heard::default();
    let mut d = Driver::new();
    d.sender(1, 1000, "123#11");
    let ids = d.attach(&["rx0", "rx1"], 0, Some(Probe::new(&rx_heard)));
    d.run_until(ms(2));
    let wakes: Vec<&(usize, BusTime, Vec<usize>)> =
        d.wakes.iter().filter(|w| w.0 == ids[0].index()).collect();
    assert_eq!(wakes.len(), 2);
    assert_eq!(wakes[1].2, [0, 1]);
    assert_eq!(rx_heard.borrow().iter().filter(|h| h.1 == "frame 123").count(), 2);
}

#[test]
fn a_report_that_ends_at_a_crash_counts_the_other_controllers_frames_as_lost() {
    let rx_heard = Heard::default();
    let mut d = Driver::new();
    d.sender(1, 1000, "123#11");
    let ids = d.attach(&["rx0", "rx1"], 0, Some(Probe::new(&rx_heard)));
    d.sched.run_until(ms(2));
    d.sched.advance(0);
    let mut last = None;
    while last.is_none() {
        while let Some(wake) = d.sched.poll_wake() {
            if wake.node == ids[0].index() && wake.inputs.len() == 2 {
                last = Some(wake);
                break;
            }
            let logic = d.logics[wake.node].as_mut().unwrap();
            let count = wake.inputs.len();
            for (k, i) in wake.inputs.into_iter().enumerate() {
                let report =
                    drive_counted(logic.as_mut(), i.controller, wake.now, i.frames, i.events, &mut 0);
                d.sched
                    .handle_answer(wake.round, i.slot, report, k + 1 == count, 0);
            }
        }
    }
    let wake = last.unwrap();
    // The logic crashed on controller 0's input before handling it: one report, no more.
    let crash = Report {
        crashed: Some(CrashCause::Panic("boom".into())),
        ..Report::default()
    };
    d.sched.handle_answer(wake.round, ids[0].index(), crash, true, 0);
    let nodes = d.sched.snapshot().nodes;
    for id in &ids {
        let h = nodes[id.index()].handover;
        assert_eq!(
            (h.crashed, h.handled, h.in_flight),
            (1, 0, 0),
            "{}",
            nodes[id.index()].name
        );
        assert_eq!(nodes[id.index()].crashed, Some(CrashCause::Panic("boom".into())));
    }
}

#[test]
fn a_paced_scheduler_waits_for_the_wall_clock_and_asks_to_be_advanced_then() {
    let heard = Heard::default();
    let setup = Setup {
        bus: BusConfig::default(),
        iface: "t0".into(),
        paced: true,
        pacer: Pacer::new(std::time::Duration::ZERO, std::time::Duration::from_millis(50)),
    };
    let mut sched = Scheduler::new(setup, Vec::new()).unwrap();
    sched
        .attach(vec![ControllerConfig::named("a")], BusDuration::ZERO, true)
        .unwrap();
    let mut logic = Probe::new(&heard).ticking(10, 10);
    sched.run_until(ms(100));
    sched.advance(0);
    // The wake at attach is due at once.
    let wake = sched.poll_wake().unwrap();
    let report = drive_counted(&mut logic, 0, wake.now, Vec::new(), Vec::new(), &mut 0);
    sched.handle_answer(wake.round, wake.node, report, true, 1_000);
    // Its next deadline, 10 ms, is not yet on the wall clock: no wake, a timeout instead.
    assert!(sched.poll_wake().is_none());
    assert_eq!(sched.poll_timeout(), Some(10_000_000));
    sched.advance(9_999_999);
    assert!(sched.poll_wake().is_none());
    sched.advance(10_000_000);
    assert_eq!(sched.poll_wake().map(|w| w.now), Some(ms(10)));
}

#[test]
fn a_node_with_a_far_deadline_is_woken_by_its_frames() {
    // A receiver with a deadline an hour away, woken by a frame every millisecond: each
    // answer sets that deadline again, and each frame makes it due earlier.
    let mut d = Driver::new();
    d.sender(1, 1, "123#11");
    let rx = d.attach(
        &["rx"],
        0,
        Some(Probe::new(&Heard::default()).ticking(3_600_000, 1)),
    )[0];
    d.run_until(ms(500));
    assert!(d.wakes_of(rx).len() > 400, "{} wakes", d.wakes_of(rx).len());
    assert_eq!(d.sched.dues.len(), d.sched.slots.len());
}

#[test]
fn a_node_without_a_logic_keeps_nothing_of_what_it_sent() {
    // A replay or a gateway client submits frames for ever; their confirmations must not pile
    // up where no logic will ever read them.
    let heard = Heard::default();
    let mut d = Driver::new();
    let gw = d.attach(&["gw"], 0, None)[0];
    d.attach(&["rx"], 0, Some(Probe::new(&heard)));
    for i in 0..200u64 {
        let frame = parse_frame("123#11").unwrap();
        assert!(d.sched.submit_at(gw, frame, ms(i)).unwrap(), "frame {i} refused");
        d.run_until(ms(i + 1));
    }
    assert_eq!(heard.borrow().iter().filter(|h| h.1 == "frame 123").count(), 200);
    assert!(
        d.sched.slots[gw.index()].events.is_empty(),
        "{} events kept",
        d.sched.slots[gw.index()].events.len()
    );
}

#[test]
fn a_controller_its_logic_starts_stays_off_the_bus_while_its_cable_is_out() {
    use crate::node::ControllerCommand::{Offline, Online};
    let online = Online {
        listen_only: false,
        self_test: false,
    };
    let heard = Heard::default();
    let mut d = Driver::new();
    // Firmware-like: the chip in reset at 1 ms, started again at 3 ms; a frame every 2 ms.
    let mut probe = Probe::new(&Heard::default()).ticking(2, 2).sending("123#11");
    probe.commands = vec![(ms(1), Offline), (ms(3), online)];
    let fw = d.attach(&["fw"], 0, Some(probe))[0];
    d.attach(&["rx"], 0, Some(Probe::new(&heard)));
    // The cable out before the chip starts: starting it does not plug it in.
    d.sched.set_connected(fw, false).unwrap();
    d.run_until(ms(10));
    assert_eq!(heard.borrow().iter().filter(|h| h.1 == "frame 123").count(), 0);
    // Plugged in again: its frames go out.
    d.sched.set_connected(fw, true).unwrap();
    d.run_until(ms(20));
    assert!(
        heard.borrow().iter().any(|h| h.1 == "frame 123"),
        "{:?}",
        heard.borrow()
    );
}

#[test]
fn error_observers_see_each_error_frame_and_may_stop_the_run_there() {
    use crate::trace::err;
    let seen: Rc<RefCell<Vec<ObservedError>>> = Rc::default();
    let mut d = Driver::new();
    // Alone on the bus: nobody acknowledges its frame (ISO 11898-1, 10.9.2 and 12.1.4).
    d.sender(1, 1000, "123#11");
    let log = seen.clone();
    d.sched.observe_errors(Box::new(move |e| {
        log.borrow_mut().push(e.clone());
        if log.borrow().len() == 1 {
            super::Heard::StopThere
        } else {
            super::Heard::Noted
        }
    }));
    let stopped = d.run_until(ms(100));
    let first = seen.borrow()[0].clone();
    // The run stopped at the first error frame: an acknowledgement error while transmitting,
    // TEC 8 (rule 3), in SocketCAN's encoding (linux/can/error.h).
    assert_eq!(stopped, first.at);
    assert!(first.at > ms(1) && first.at < ms(2), "{first:?}");
    assert_eq!(first.name, "tx");
    assert_eq!(
        first.frame.can_id,
        crate::filter::CAN_ERR_FLAG | err::PROT | err::ACK | err::BUSERROR | err::CNT
    );
    assert_eq!(
        (first.frame.data[2], first.frame.data[3], first.frame.data[6]),
        (err::PROT_TX, err::PROT_LOC_ACK, 8)
    );
    // Run on: each retransmission errs the same way, TEC 8 more each, until error passive at
    // 128 (the 16th); from then on an error passive transmitter's acknowledgement errors add
    // nothing (rule 3, exception 1).
    d.run_until(ms(100));
    let tecs: Vec<u8> = seen
        .borrow()
        .iter()
        .filter(|e| e.frame.can_id & err::ACK != 0)
        .map(|e| e.frame.data[6])
        .take(18)
        .collect();
    let expected: Vec<u8> = (1..=16).map(|n| n * 8).chain([128, 128]).collect();
    assert_eq!(tecs, expected);
    // The state changes are error frames too: warning (96) and passive (128).
    let crtl: Vec<u8> = seen
        .borrow()
        .iter()
        .filter(|e| e.frame.can_id & err::CRTL != 0)
        .map(|e| e.frame.data[1])
        .collect();
    assert_eq!(crtl, [err::CRTL_TX_WARNING, err::CRTL_TX_PASSIVE]);
}
