//! A transmission attempt bit by bit: what the bus does when something goes wrong.
//!
//! A clean attempt (one frame, acknowledged, nothing injected, every controller idle) is
//! committed in closed form by `Bus::succeed`. Every other attempt runs here: each controller's
//! protocol state machine ([`super::wire::Mac`]) drives a level, the bus is their wired AND,
//! disturbances change what chosen controllers sample, and each controller's detections are
//! counted by the fault-confinement rules in [`crate::fault`]. The episode ends when no
//! controller is in a frame or a flag any more; what is left of delimiters, intermission and
//! suspend is carried to the next attempt, so a start of frame that comes while a controller is
//! still in its error delimiter is a form error to it, as on a real bus.

use super::controller::Pending;
use super::wire::{self, Detected, Location, Phase, Sending};
use super::{Bus, BusError, Event, NodeId};
use crate::fault::{ErrorFlag, ErrorState, Role, TransmitError, TxErrorKind};
use crate::filter::AcceptanceFilter;
use crate::time::BusTime;

/// Longest episode, in bits: a disturbance that holds the bus dominant for longer is cut here
/// (every controller is bus off or error passive long before).
const MAX_EPISODE_BITS: u32 = 20_000;

/// A change to what controllers sample, in bits counted from an episode's SOF.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Flip {
    /// First bit.
    pub from: u32,
    /// Bits it lasts.
    pub bits: u32,
    /// The level forced, or `None` to invert the bus level.
    pub level: Option<bool>,
    /// Who samples it.
    pub who: Who,
}

/// Controllers a flip reaches.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Who {
    /// Every controller.
    All,
    /// Every controller that is not a transmitter of the frame.
    Receivers,
    /// These controllers (transmitters included if named).
    Nodes(Vec<NodeId>),
    /// These receivers (transmitters left out even if named).
    ReceiversIn(Vec<NodeId>),
}

impl Who {
    /// True when it names `node`, a transmitter of the frame or not.
    fn reaches(&self, node: NodeId, transmitter: bool) -> bool {
        match self {
            Who::All => true,
            Who::Receivers => !transmitter,
            Who::Nodes(list) => list.contains(&node),
            Who::ReceiversIn(list) => !transmitter && list.contains(&node),
        }
    }
}

impl Flip {
    fn reaches(&self, node: NodeId, transmitter: bool) -> bool {
        self.who.reaches(node, transmitter)
    }
}

/// A disturbance at a place ([`super::inject::Disturb`]): each controller it reaches reads
/// `level` for `bits` bit times from the bit at which it is itself at `place`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Anchored {
    /// The rule it comes from (for its hits and misses).
    pub rule: super::RuleId,
    pub place: super::Place,
    pub level: bool,
    pub bits: u32,
    pub who: Who,
    /// Per controller: the episode bit at which it reached the place.
    pub from: Vec<Option<u32>>,
}

impl Anchored {
    /// Its level, if it acts on controller `i` at bit `k`.
    fn acts(&self, i: usize, k: u32) -> Option<bool> {
        let from = self.from.get(i).copied().flatten()?;
        (from..from.saturating_add(self.bits))
            .contains(&k)
            .then_some(self.level)
    }

    /// True while it may still act at bit `k`: started on some controller and not over, or
    /// not started on one it reaches (`reaches`) that is still before the end of its
    /// intermission (`unfinished`), where recessive bits alone can bring it to a delimiter or
    /// intermission bit. Other places need a dominant bit to come, which only something still
    /// running can give.
    fn pending(&self, k: u32, reaches: &[bool], unfinished: &[bool]) -> bool {
        let running = self
            .from
            .iter()
            .flatten()
            .any(|&f| k < f.saturating_add(self.bits));
        let ahead = matches!(
            self.place.field,
            super::Field::ErrorDelimiter | super::Field::OverloadDelimiter | super::Field::Intermission
        ) && (0..self.from.len()).any(|i| self.from[i].is_none() && reaches[i] && unfinished[i]);
        running || ahead
    }
}

/// What an episode is asked to do beyond the frames that start it.
#[derive(Clone, Debug, Default)]
pub(crate) struct Plan {
    pub flips: Vec<Flip>,
    /// Disturbances at places.
    pub anchored: Vec<Anchored>,
    /// The frame on the bus (the winner's) is an extended one: what a receiver's bit 12 is (SRR
    /// or RTR) before it has read IDE.
    pub extended: bool,
    /// Overload frames the named receivers send after the frame (receivers not ready).
    pub overload: Option<(u8, super::inject::SeenBy)>,
}

/// What an episode gathers while it runs.
struct Tally {
    events: Vec<Event>,
    destroyed: Vec<Destroyed>,
    /// Per controller: an ACK error whose count waits for its passive flag (exception 3a), with
    /// where its flag began; its bus error is told once counted.
    deferred_3a: Vec<Option<(BusTime, Location)>>,
    /// The kind of the first error detected since the last error flag began: the kind of the
    /// next error frame.
    error_kind: Option<BusError>,
    /// The frame's `Frame` event is out (identical frames sent together give one).
    sent_frame: bool,
    /// Per controller: it took the frame at its last but one EOF bit.
    received: Vec<bool>,
    /// Per controller: it sent the frame successfully.
    sent: Vec<bool>,
    /// The frame that completed, with who was on the bus when it did.
    completed: Option<(crate::Frame, Vec<bool>)>,
}

/// Per transmitter: the attempt it lost, for the `ErrorFrame` event.
struct Destroyed {
    node: usize,
    frame: crate::Frame,
    flag: BusTime,
    error: BusError,
    bit: u16,
}

impl BusError {
    fn of(kind: TxErrorKind) -> BusError {
        match kind {
            TxErrorKind::Bit => BusError::Bit,
            TxErrorKind::Stuff => BusError::Stuff,
            TxErrorKind::Crc => BusError::Crc,
            TxErrorKind::Form => BusError::Form,
            TxErrorKind::Ack => BusError::Ack,
        }
    }
}

impl Bus {
    /// Brings a controller's carried protocol state to `at` through the recessive bits since.
    pub(super) fn settle(&mut self, i: usize, at: BusTime) {
        let bit = self.bit;
        let c = &mut self.controllers[i];
        if c.mac.phase == Phase::Idle || at <= c.mac_at {
            c.mac_at = c.mac_at.max(at);
            return;
        }
        c.mac.passive = c.flags_passive();
        c.mac.idle_through((at - c.mac_at) / bit);
        c.mac_at = at;
    }

    /// Runs an attempt that starts at `sof` with `starters` sending their queued frames.
    pub(super) fn episode(&mut self, sof: BusTime, starters: &[usize], plan: Plan) {
        let bit = self.bit;
        let n = self.controllers.len();
        // Bus-off controllers have been counting an idle bus since `recessive_since`.
        for c in &mut self.controllers {
            if c.connected && c.counts_recovery() {
                let bits = (sof.max(c.recessive_since) - c.recessive_since) / bit;
                c.fault.recessive_bits(bits.min(u64::from(u32::MAX)) as u32);
            }
        }
        for &s in starters {
            let frame = self.controllers[s].tx[0].frame;
            let arbitration_end = if frame.is_extended() { 32 } else { 12 };
            let c = &mut self.controllers[s];
            c.mac.start(Sending {
                stuffed: crate::bits::encode(&frame).stuffed,
                arbitration_end,
            });
        }
        for (i, c) in self.controllers.iter_mut().enumerate() {
            c.mac.acks = c.acks();
            c.mac.silent = c.listen_only;
            c.mac.presume_ack = c.presume_ack;
            if !starters.contains(&i) {
                // A unit stays transmitter of its message until the bus is idle (Bosch CAN 2.0,
                // part B, 2): another node's start of frame begins a message it receives, even
                // while it is still in the delimiter of its own.
                c.mac.tx_role = false;
                c.mac.transmitter = false;
            }
            if !starters.contains(&i)
                && let Some((frames, by)) = &plan.overload
                && by.includes(NodeId(i as u16))
            {
                c.mac.overloads = *frames;
            }
        }
        let sending: Vec<bool> = (0..n).map(|i| starters.contains(&i)).collect();
        let last_flip = plan.flips.iter().map(|f| f.from + f.bits).max().unwrap_or(0);
        let extended = plan.extended;
        let mut anchored = plan.anchored;
        // Per disturbance at a place, the controllers it reaches.
        let reaches: Vec<Vec<bool>> = anchored
            .iter()
            .map(|a| {
                (0..n)
                    .map(|i| a.who.reaches(NodeId(i as u16), sending[i]))
                    .collect()
            })
            .collect();
        let mut tally = Tally {
            events: Vec::new(),
            destroyed: Vec::new(),
            deferred_3a: vec![None; n],
            error_kind: None,
            sent_frame: false,
            received: vec![false; n],
            sent: vec![false; n],
            completed: None,
        };
        let tokens: Vec<(usize, u64)> = starters
            .iter()
            .filter_map(|&s| self.controllers[s].tx.front().map(|p| (s, p.token)))
            .collect();
        let mut drives = vec![wire::REC; n];
        let mut k: u32 = 0;
        let mut flagging = false;
        let mut last_dominant = self.last_dominant;
        loop {
            let t = sof + u64::from(k) * bit;
            let next = t + bit;
            // An error frame on the bus: error flags that begin while no other is being sent
            // (overlapping flags are one error frame). A listen-only controller sends none.
            let flags = self
                .controllers
                .iter()
                .any(|c| c.on_bus() && !c.listen_only && matches!(c.mac.phase, Phase::ErrorFlag { .. }));
            if flags {
                if !flagging {
                    self.stats.error(tally.error_kind.unwrap_or(BusError::Bit).name());
                }
                tally.error_kind = None;
            }
            flagging = flags;
            let mut level = wire::REC;
            for (i, c) in self.controllers.iter_mut().enumerate() {
                c.mac.passive = c.flags_passive();
                drives[i] = c.mac.drive();
                if c.on_bus() {
                    level &= drives[i];
                }
            }
            if level == wire::DOM {
                last_dominant = next;
            }
            for i in 0..n {
                let c = &self.controllers[i];
                if !c.connected {
                    continue;
                }
                let node = NodeId(i as u16);
                let mut sampled = level;
                for f in &plan.flips {
                    if (f.from..f.from + f.bits).contains(&k) && f.reaches(node, sending[i]) {
                        sampled = f.level.unwrap_or(!sampled);
                    }
                }
                if !anchored.is_empty() && c.on_bus() && c.integrating.is_none() {
                    let place = c.mac.place(k == 0, extended);
                    for (a, reach) in anchored.iter_mut().zip(&reaches) {
                        if reach[i] && a.from[i].is_none() && place == Some(a.place) {
                            a.from[i] = Some(k);
                        }
                        if let Some(l) = a.acts(i, k) {
                            sampled = l;
                        }
                    }
                }
                if c.fault.state() == ErrorState::BusOff {
                    if c.counts_recovery() {
                        self.count_recovery(i, sampled, next, &mut tally.events);
                    }
                    continue;
                }
                if c.integrating.is_some() {
                    self.integrate_bit(i, sampled, next);
                    continue;
                }
                let detected = self.controllers[i].mac.sample(drives[i], sampled);
                self.react(i, detected, sof, next, &mut tally);
            }
            k += 1;
            // An episode lasts as long as a disturbance that reaches it: no frame starts within
            // it (a limit of the model, documented with `Disturbance`).
            let quiet = self.controllers.iter().all(|c| !c.on_bus() || c.mac.quiet());
            let mut done = quiet && k >= last_flip;
            if done && !anchored.is_empty() {
                let unfinished: Vec<bool> = self
                    .controllers
                    .iter()
                    .map(|c| c.on_bus() && !matches!(c.mac.phase, Phase::Idle | Phase::Suspend { .. }))
                    .collect();
                done = !anchored
                    .iter()
                    .zip(&reaches)
                    .any(|(a, r)| a.pending(k, r, &unfinished));
            }
            if done || k >= MAX_EPISODE_BITS {
                break;
            }
        }
        let end = sof + u64::from(k) * bit;
        for a in &anchored {
            let hit = a.from.iter().any(Option::is_some);
            self.injector.count_disturb(a.rule, hit);
        }
        self.last_dominant = self.last_dominant.max(last_dominant);
        // The bus is busy until the last controller is through its intermission.
        let mut busy_to = end;
        for c in &mut self.controllers {
            if !c.connected {
                continue;
            }
            if c.fault.state() == ErrorState::BusOff {
                c.recessive_since = end;
                continue;
            }
            c.mac_at = end;
            let mut probe = c.mac;
            probe.passive = c.flags_passive();
            let to_bus_idle = probe.bits_until_bus_idle(64);
            let to_idle = probe.idle_through(64).unwrap_or(64);
            c.ready_at = c.ready_at.max(end + to_idle * bit);
            busy_to = busy_to.max(end + to_bus_idle * bit);
        }
        let busy_from = sof.max(self.stats.busy_until);
        let busy_to = busy_to.max(busy_from);
        self.stats.advance_to(end);
        self.stats.busy(
            busy_from,
            busy_to,
            ((busy_to - busy_from) / bit).min(u64::from(u32::MAX)) as u32,
        );
        let Tally {
            mut events,
            destroyed,
            received,
            sent,
            completed,
            ..
        } = tally;
        if let Some((frame, on_bus)) = completed {
            self.place_unreceived(&frame, &on_bus, &received, &sent);
        }
        for d in &destroyed {
            let c = &self.controllers[d.node];
            events.push(Event::ErrorFrame {
                start: sof,
                flag: d.flag,
                end,
                node: NodeId(d.node as u16),
                frame: d.frame,
                error: d.error,
                bit: d.bit,
                tec: c.fault.tec(),
                rec: c.fault.rec(),
            });
        }
        // An attempt is over for its transmitters when the episode is; a single-shot frame that
        // did not go out is dropped then.
        let from = self.events.len();
        for (s, token) in tokens {
            self.controllers[s].attempt = (token, end);
            if !sent[s] {
                self.drop_single_shot(s, end, token);
            }
        }
        events.extend(self.events.drain(from..));
        // Events come out in time order, and at one time as the closed form gives them: the
        // frame, its confirmations, then what receivers did with it.
        events.sort_by_key(|e| (e.at(), rank(e)));
        self.events.extend(events);
        self.idle_at = self.idle_at.max(busy_to);
        self.committed = self.committed.max(sof);
    }

    /// Books a completed frame for every controller whose filter accepts it but that neither
    /// sent nor received it, as the closed form does for a clean frame: a controller off the bus
    /// missed it; one on the bus had detected an error in it that did not destroy it for the
    /// others (its passive flag, or a disturbance only it sampled). Without this, an accepted
    /// frame that completed in an episode would be in no counter of such a controller.
    fn place_unreceived(&mut self, frame: &crate::Frame, on_bus: &[bool], received: &[bool], sent: &[bool]) {
        for (i, c) in self.controllers.iter_mut().enumerate() {
            if received[i] || sent[i] || !c.config.filter.accepts(frame) {
                continue;
            }
            if on_bus[i] {
                c.counters.rx_errored += 1;
            } else {
                c.counters.rx_missed += 1;
            }
        }
    }

    /// A controller integrating into the bus samples a bit: a dominant one starts its count of
    /// recessive bits again; the 11th recessive one makes it take part from the next bit.
    fn integrate_bit(&mut self, i: usize, sampled: bool, next: BusTime) {
        let needed = self.bit * super::INTEGRATION_BITS;
        let c = &mut self.controllers[i];
        let Some(since) = c.integrating else { return };
        if sampled == wire::DOM {
            c.integrating = Some(next);
        } else if since + needed <= next {
            c.integrating = None;
            c.mac = c.idle_mac();
            c.mac_at = next;
        }
    }

    /// A bus-off controller counts the bit towards recovery (rule 12).
    fn count_recovery(&mut self, i: usize, sampled: bool, next: BusTime, events: &mut Vec<Event>) {
        let before = self.controllers[i].fault.recovery_progress();
        let from = self.events.len();
        let c = &mut self.controllers[i];
        let changes = if sampled == wire::REC {
            c.fault.recessive_bits(1)
        } else {
            c.fault.dominant_bit();
            crate::fault::Changes::NONE
        };
        if c.fault.state() != ErrorState::BusOff {
            // 128 × 11 recessive bits: integrated as well.
            c.integrating = None;
            c.mac = c.idle_mac();
            c.mac_at = next;
            c.ready_at = c.ready_at.max(next);
        }
        self.progress(i, next, before);
        events.extend(self.events.drain(from..));
        self.note_into(NodeId(i as u16), next, changes, events);
    }

    fn react(&mut self, i: usize, detected: Detected, sof: BusTime, next: BusTime, tally: &mut Tally) {
        let Tally {
            events,
            destroyed,
            deferred_3a,
            error_kind,
            sent_frame,
            received,
            sent,
            completed,
        } = tally;
        let node = NodeId(i as u16);
        let bit = self.bit;
        match detected {
            Detected::Nothing | Detected::Sof => {}
            Detected::LostArbitration(at_bit) => {
                self.controllers[i].counters.arbitration_lost += 1;
                if self.arbitration_events {
                    events.push(Event::ArbitrationLost {
                        node,
                        at: next,
                        bit: at_bit,
                    });
                }
            }
            Detected::Error(found) => {
                let c = &mut self.controllers[i];
                let error = BusError::of(found.kind);
                error_kind.get_or_insert(error);
                let transmitting = c.mac.tx_role;
                let changes = if transmitting {
                    c.counters.tx_errors += 1;
                    if found.kind == TxErrorKind::Ack && c.fault.state() == ErrorState::Passive {
                        // Exception 3a is decided once the passive flag has been sent; the bus
                        // error is told then, with the counters as counted.
                        deferred_3a[i] = Some((next, found.location));
                        destroyed.extend(lose_attempt(i, c, next, error));
                        return;
                    } else {
                        c.fault.transmit_error(TransmitError {
                            in_arbitration_on_recessive_stuff_bit: found.arbitration_stuff,
                            ..TransmitError::new(found.kind)
                        })
                    }
                } else {
                    c.counters.rx_errors += 1;
                    c.fault.receive_error()
                };
                destroyed.extend(lose_attempt(i, c, next, error));
                self.bus_error(i, next, error, transmitting, found.location, events);
                self.counted(i, next, changes, events);
            }
            Detected::CrcError => {
                error_kind.get_or_insert(BusError::Crc);
                let c = &mut self.controllers[i];
                c.counters.rx_errors += 1;
                let changes = c.fault.receive_error();
                self.bus_error(i, next, BusError::Crc, false, Location::CrcSeq, events);
                self.counted(i, next, changes, events);
            }
            Detected::FlagBitError => {
                error_kind.get_or_insert(BusError::Bit);
                let c = &mut self.controllers[i];
                let changes = if c.mac.tx_role {
                    c.fault.transmit_flag_bit_error()
                } else {
                    c.fault.receive_flag_bit_error()
                };
                let tx = c.mac.tx_role;
                self.bus_error(i, next, BusError::Bit, tx, Location::Flag, events);
                self.counted(i, next, changes, events);
            }
            Detected::FlagDone { saw_dominant } => {
                if let Some((flag, location)) = deferred_3a[i].take() {
                    let c = &mut self.controllers[i];
                    let changes = c.fault.transmit_error(TransmitError {
                        dominant_during_passive_flag: saw_dominant,
                        ..TransmitError::new(TxErrorKind::Ack)
                    });
                    self.bus_error(i, flag, BusError::Ack, true, location, events);
                    self.counted(i, next, changes, events);
                }
            }
            Detected::DominantAfterFlag => {
                let c = &mut self.controllers[i];
                if !c.mac.tx_role {
                    let changes = c.fault.receive_error_dominant_after_flag();
                    self.counted(i, next, changes, events);
                }
            }
            Detected::DominantRun => {
                let c = &mut self.controllers[i];
                let flag = match c.mac.phase {
                    Phase::AfterFlag { active: false, .. } => ErrorFlag::Passive,
                    _ => ErrorFlag::Active,
                };
                let role = if c.mac.tx_role {
                    Role::Transmitter
                } else {
                    Role::Receiver
                };
                let changes = c
                    .fault
                    .dominant_bits_after_flag(flag.first_penalty_bit(), flag, role);
                self.counted(i, next, changes, events);
            }
            Detected::Overload => {
                self.stats.overloads += 1;
                events.push(Event::Overload { node, at: next });
            }
            Detected::Received => {
                // The frame ends with the next bit (EOF 7); receivers have it from then.
                let end = next + bit;
                // The frame on the bus is its transmitter's, which stays transmitter through its
                // own error flag (a passive flag after an ACK error leaves the frame intact).
                let Some((t, p)) = self
                    .controllers
                    .iter()
                    .enumerate()
                    .find(|(_, c)| c.mac.tx_role && c.mac.transmitter)
                    .and_then(|(t, c)| c.tx.front().map(|p| (t, *p)))
                else {
                    return;
                };
                let frame = p.frame;
                received[i] = true;
                if !*sent_frame {
                    // Valid for its receivers from here, whatever its transmitter then makes of
                    // the frame's last bit: on the bus, and to every sink, now.
                    *sent_frame = true;
                    let on_bus = self.controllers.iter().map(|c| c.on_bus()).collect();
                    *completed = Some((frame, on_bus));
                    self.on_the_bus(t, p, sof, end, events);
                }
                let c = &mut self.controllers[i];
                // Rule 8 counts a reception only with the node's ACK sent.
                let acked = c.acks();
                let recovering = c.fault.rec() > 0 && acked;
                let changes = if acked {
                    c.fault.receive_success()
                } else {
                    crate::fault::Changes::NONE
                };
                if c.config.filter.accepts(&frame) {
                    if c.store(end, frame) {
                        self.stats.deliveries += 1;
                        events.push(Event::Delivered { node, at: end });
                    } else {
                        self.stats.overruns += 1;
                        events.push(Event::Overrun { node, at: end });
                    }
                } else {
                    c.counters.rx_filtered += 1;
                }
                self.note_into(node, end, changes, events);
                if recovering {
                    self.sample(node, end);
                }
            }
            Detected::Sent => {
                let end = next;
                let c = &mut self.controllers[i];
                let Some(p) = c.tx.pop_front() else { return };
                sent[i] = true;
                c.counters.tx_frames += 1;
                if c.config.filter.accepts(&p.frame) {
                    c.counters.rx_own += 1;
                }
                let recovering = c.fault.tec() > 0;
                let changes = c.fault.transmit_success();
                events.push(Event::TxDone {
                    node,
                    at: end,
                    token: p.token,
                    frame: p.frame,
                });
                if !*sent_frame {
                    *sent_frame = true;
                    // Receivers took it at the bit before (EOF 6): who is on the bus now is who
                    // was when it became valid for them.
                    let on_bus = self.controllers.iter().map(|c| c.on_bus()).collect();
                    *completed = Some((p.frame, on_bus));
                    self.on_the_bus(i, p, sof, end, events);
                }
                self.note_into(node, end, changes, events);
                if recovering {
                    self.sample(node, end);
                }
            }
        }
    }

    /// A frame went through, for the bus: its `Frame` event and its statistics, once per
    /// attempt.
    fn on_the_bus(&mut self, t: usize, p: Pending, sof: BusTime, end: BusTime, events: &mut Vec<Event>) {
        let bit = self.bit;
        let frame = p.frame;
        let bits = ((end - sof) / bit) as u32 + wire::INTERMISSION_BITS as u32;
        let class = (self.latency_class)(&frame);
        self.stats.frame(
            crate::filter::kernel_can_id(&frame),
            frame.data(),
            class,
            end,
            end - p.submitted,
        );
        events.push(Event::Frame {
            start: sof,
            end,
            node: NodeId(t as u16),
            frame,
            bits,
        });
    }

    /// One controller's error, as its SocketCAN interface would report it.
    fn bus_error(
        &mut self,
        i: usize,
        at: BusTime,
        error: BusError,
        transmitting: bool,
        location: Location,
        events: &mut Vec<Event>,
    ) {
        let c = &self.controllers[i];
        events.push(Event::BusError {
            node: NodeId(i as u16),
            at,
            error,
            transmitting,
            location,
            tec: c.fault.tec(),
            rec: c.fault.rec(),
        });
    }

    /// After a counter moved: events, the history, and bus off.
    fn counted(&mut self, i: usize, at: BusTime, changes: crate::fault::Changes, events: &mut Vec<Event>) {
        let node = NodeId(i as u16);
        self.note_into(node, at, changes, events);
        self.sample(node, at);
        let c = &mut self.controllers[i];
        if c.fault.state() == ErrorState::BusOff {
            // A bus-off controller has no influence on the bus: it stops at once, and drops the
            // frame it was sending.
            c.recessive_since = at;
            c.recovery_requested = false;
            if c.mac.tx_role
                && let Some(p) = c.tx.pop_front()
            {
                c.counters.tx_aborted += 1;
                events.push(Event::TxAborted {
                    node,
                    at,
                    token: p.token,
                    frame: p.frame,
                });
            }
            c.mac = c.idle_mac();
        }
    }

    /// Like `note_events`, into an episode's list.
    fn note_into(
        &mut self,
        node: NodeId,
        at: BusTime,
        changes: crate::fault::Changes,
        events: &mut Vec<Event>,
    ) {
        let from = self.events.len();
        self.note_events(node, at, changes);
        events.extend(self.events.drain(from..));
    }
}

/// Controller `i`, sending, lost its attempt to an error flagged from `flag`: it sends no more
/// of it, and the attempt is one for an `ErrorFrame` event.
fn lose_attempt(i: usize, c: &mut super::Controller, flag: BusTime, error: BusError) -> Option<Destroyed> {
    c.mac.sending?;
    let p = c.tx.front()?;
    let lost = Destroyed {
        node: i,
        frame: p.frame,
        flag,
        error,
        bit: (c.mac.pos.saturating_sub(1)).min(u32::from(u16::MAX)) as u16,
    };
    c.mac.sending = None;
    Some(lost)
}

/// Order among events at the same time.
fn rank(e: &Event) -> u8 {
    match e {
        Event::Frame { .. } | Event::ErrorFrame { .. } => 0,
        Event::TxDone { .. } | Event::TxAborted { .. } => 1,
        _ => 2,
    }
}
