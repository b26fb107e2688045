//! The interpreter: a [`NodeScript`] run as a sans-IO [`NodeLogic`].

use super::book::{Def, Received, dbc_id};
use super::model::*;
use bus::Frame;
use bus::node::{NodeFault, NodeLogic, Refused};
use bus::time::{BusDuration, BusTime};
use protocol::catalogue::{self, Direction};
use protocol::ident::Address;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::cell::RefCell;
use std::collections::{BTreeMap, VecDeque};
use std::rc::Rc;

/// What a node samples and drives: the plant. Shared by every node of one harvester on one
/// thread; it moves only forward in time.
pub trait Environment {
    /// Brings the environment to bus time `t` (no-op for a time already passed).
    fn advance_to(&mut self, t: BusTime);
    /// The port of a named signal: readers resolve their names once, when they load, and read
    /// by port. `None` for a name the environment does not have.
    fn port(&self, name: &str) -> Option<Port>;
    /// The value of a signal.
    fn read(&self, port: Port) -> Option<f64>;
    /// Sets an input; false when the port is not an input's or the value not one it takes.
    fn write(&mut self, port: Port, value: f64) -> bool;
    /// The first time after `t` at which a signal may change on its own (the plant's next
    /// step); `BusTime::NEVER` when signals change only when someone writes or overrides them.
    fn next_change(&self, _t: BusTime) -> BusTime {
        BusTime::NEVER
    }
}

/// A signal of an [`Environment`], resolved from its name ([`Environment::port`]): a number
/// that only the environment that gave it reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Port(pub u32);

/// The environment shared by the nodes of one harvester.
pub type SharedEnv = Rc<RefCell<dyn Environment>>;

#[derive(Clone, Debug)]
struct SendState {
    enabled: bool,
    next: BusTime,
    last: Vec<Frame>,
    last_sent: Option<BusTime>,
    /// On-change entries look at their value on a grid of their own; `next` is the earlier of
    /// that and the heartbeat.
    check_next: BusTime,
    /// An on-change entry that reads only the node's own state and variables.
    internal: bool,
    /// Such an entry whose last check found nothing new, and nothing of the node has changed
    /// since: its checks would all find the same, so only its heartbeat is scheduled, and the
    /// check grid resumes where it would be when the node changes (`touch`).
    idle: bool,
}

/// A frame spec resolved against the catalogue or the script's database.
struct Resolved {
    def: Def,
    /// For each of the spec's fields, in its order, the position in the message's fields or
    /// signals (None for a name the message does not have: validation reports it, the frame
    /// leaves it out).
    slots: Rc<[Option<usize>]>,
}

impl Resolved {
    fn of(db: Option<&std::sync::Arc<protocol::database::Database>>, spec: &FrameSpec) -> Option<Resolved> {
        let def = Def::find(db, &spec.message)?;
        let slots = spec
            .fields
            .keys()
            .map(|name| match &def {
                Def::Catalogue(d) => d.field_index(name),
                Def::Dbc(..) => def.dbc()?.signals.iter().position(|s| &s.name == name),
            })
            .collect();
        Some(Resolved { def, slots })
    }
}

/// The running value of a `RandomWalk` or `Counter`.
type Generated = BTreeMap<usize, f64>;

/// A value could not be had: a sensor was read through a dropout fault, or the arithmetic gave
/// no number (a NaN, or a clamp whose range is empty or not a number, which a validated script
/// never has). The message is not sent, the variable or input is not written.
struct NoValue;

/// The acknowledgement state of the node's connection: one connection, however many entries
/// (groups) it is made of, so one count.
///
/// A send is awaited from the moment it goes out until its acknowledgement is due (send time +
/// its entry's `timeout_ms`); only then, if no acknowledgement came, is it missed. Counting at
/// the send instead would count every group whose acknowledgement is simply still on the bus, and
/// the count would flip between 0 and the number of groups of a cycle every cycle.
#[derive(Clone, Debug, Default)]
struct Acks {
    /// Sends not yet acknowledged whose acknowledgement is not yet due: (due, entry), in sending
    /// order.
    awaited: VecDeque<(BusTime, usize)>,
    /// Sends in a row whose acknowledgement is overdue.
    missed: u32,
}

/// A node that gave up for lack of acknowledgements and resumes at the next one.
#[derive(Clone, Copy, Debug)]
struct GaveUp {
    /// The state it gave up in, to go back to.
    from: usize,
    /// The state it entered; an acknowledgement in any other state resumes nothing.
    into: usize,
}

impl Acks {
    /// The earliest time an awaited acknowledgement falls due.
    fn next_due(&self) -> Option<BusTime> {
        self.awaited.iter().map(|&(due, _)| due).min()
    }

    /// Takes out one send whose acknowledgement is overdue at `now`, counts it as missed and
    /// returns its entry.
    fn take_overdue(&mut self, now: BusTime) -> Option<usize> {
        let i = self.awaited.iter().position(|&(due, _)| due <= now)?;
        let (_, k) = self.awaited.remove(i)?;
        self.missed = self.missed.saturating_add(1);
        Some(k)
    }
}

/// A behaviour script running as a node.
pub struct ScriptedNode {
    /// Shared so that building a frame can borrow its spec while the node changes.
    s: Rc<NodeScript>,
    /// The catalogue entry of every frame of every send, and the position in it of each of the
    /// frame's fields (in the spec's order), looked up once.
    defs: Vec<Vec<Option<Resolved>>>,
    address: Address,
    env: SharedEnv,
    boot_at: BusTime,
    booted: bool,
    state: usize,
    vars: BTreeMap<String, f64>,
    sends: Vec<SendState>,
    timers: Vec<Option<BusTime>>,
    /// Sensor faults, each with the port of its signal and when it began.
    faults: Vec<(SignalFault, Option<Port>, BusTime)>,
    /// Acknowledgement tracking of the sends of entries with an `ack`.
    acks: Acks,
    /// Set when the node gave up under an `ack` with `resume`.
    gave_up: Option<GaveUp>,
    out: VecDeque<Frame>,
    /// A frame buffer to build into (see `build`).
    spare: Vec<Frame>,
    /// Within `handle_timeout`: the first send entry whose check at `now` is still ahead (the
    /// entries before it have been handled); None outside the sends pass and what precedes it.
    unchecked_from: Option<usize>,
    rng: ChaCha8Rng,
    /// The values of the script's `RandomWalk`s and `Counter`s, by the address of their
    /// expression in the script (which the node holds, unchanged, for its life).
    generated: Generated,
    now: BusTime,
    sent: u64,
    skipped: u64,
}

impl ScriptedNode {
    /// A node that powers on at `power_on`; `seed` drives its noise faults.
    pub fn new(mut script: NodeScript, env: SharedEnv, power_on: BusTime, seed: u64) -> ScriptedNode {
        let boot_at = power_on + BusDuration::from_millis(script.boot_delay_ms);
        resolve_ports(&mut script, &*env.borrow());
        let faults = script
            .faults
            .iter()
            .map(|f| (f.clone(), env.borrow().port(&f.signal), power_on))
            .collect();
        ScriptedNode {
            address: Address(script.address),
            vars: script.vars.clone(),
            sends: script
                .messages
                .iter()
                .map(|m| SendState {
                    enabled: m.enabled,
                    next: BusTime::NEVER,
                    last: Vec::new(),
                    last_sent: None,
                    check_next: BusTime::NEVER,
                    internal: matches!(m.when, When::OnChange { .. })
                        && m.frames.iter().all(|f| f.fields.values().all(Expr::is_internal)),
                    idle: false,
                })
                .collect(),
            timers: vec![None; script.timers.len()],
            defs: script
                .messages
                .iter()
                .map(|m| {
                    m.frames
                        .iter()
                        .map(|f| Resolved::of(script.db.as_ref(), f))
                        .collect()
                })
                .collect(),
            s: Rc::new(script),
            env,
            boot_at,
            booted: false,
            state: 0,
            faults,
            acks: Acks::default(),
            gave_up: None,
            out: VecDeque::new(),
            spare: Vec::new(),
            unchecked_from: None,
            rng: ChaCha8Rng::seed_from_u64(
                seed ^ 0x5eed_0000_0000_0000 ^ u64::from(power_on.as_nanos() as u32),
            ),
            generated: Generated::new(),
            now: power_on,
            sent: 0,
            skipped: 0,
        }
    }

    /// The node's name.
    pub fn name(&self) -> &str {
        &self.s.name
    }
    /// The current state's name.
    pub fn state(&self) -> &str {
        self.s.states.get(self.state).map_or("", |d| d.name.as_str())
    }
    /// True once boot is over.
    pub fn booted(&self) -> bool {
        self.booted
    }
    /// A variable's value.
    pub fn var(&self, name: &str) -> Option<f64> {
        self.vars.get(name).copied()
    }
    /// Frames produced so far, and sends skipped (dropout, or a value the catalogue refused).
    pub fn counts(&self) -> (u64, u64) {
        (self.sent, self.skipped)
    }
    /// Installs (Some) or removes (None) a sensor fault on a signal, from `now`.
    pub fn set_fault(&mut self, signal: &str, fault: Option<FaultKind>, now: BusTime) {
        self.faults.retain(|(f, ..)| f.signal != signal);
        if let Some(fault) = fault {
            let port = self.env.borrow().port(signal);
            self.faults.push((
                SignalFault {
                    signal: signal.to_string(),
                    fault,
                },
                port,
                now,
            ));
        }
    }

    fn active(&self, states: &[String]) -> bool {
        self.booted && (states.is_empty() || states.iter().any(|s| s == self.state()))
    }

    fn state_index(&self, name: &str) -> Option<usize> {
        self.s.states.iter().position(|d| d.name == name)
    }

    fn set_state(&mut self, name: &str) {
        if let Some(i) = self.state_index(name) {
            self.set_state_index(i);
        }
    }

    fn set_state_index(&mut self, i: usize) {
        if i == self.state && self.booted {
            return;
        }
        self.state = i;
        self.touch();
        let name = &self.s.states[i].name;
        tracing::debug!(node = %self.s.name, state = %name, "state");
        // Timers restart on entering a state they run in, and stop outside their states.
        for (k, t) in self.s.timers.iter().enumerate() {
            let on = self.booted && (t.states.is_empty() || t.states.iter().any(|s| s == name));
            self.timers[k] = on.then(|| self.now + BusDuration::from_millis(t.after_ms));
        }
    }

    fn boot(&mut self) {
        self.booted = true;
        let b = self.boot_at;
        for (k, m) in self.s.messages.iter().enumerate() {
            self.sends[k].next = match m.when {
                When::Periodic { phase_ms, .. } => b + BusDuration::from_millis(phase_ms),
                When::OnChange { .. } => {
                    self.sends[k].check_next = b;
                    b
                }
                When::OnRequest => BusTime::NEVER,
            };
        }
        let initial = self.s.initial.clone();
        self.state = usize::MAX;
        self.set_state(&initial);
    }

    /// A plant signal through this node's fault hooks. `None` (a name the environment does not
    /// have, which only a script built in code can hold) reads 0, with no fault applied.
    fn read_signal(&mut self, port: Option<Port>) -> Result<f64, NoValue> {
        let truth = port.and_then(|p| self.env.borrow().read(p)).unwrap_or(0.0);
        let mut value = truth;
        for (f, fault_port, since) in &self.faults {
            if port.is_none() || *fault_port != port {
                continue;
            }
            value = match f.fault {
                FaultKind::Stuck(v) => v,
                FaultKind::Offset(o) => value + o,
                FaultKind::Drift(rate) => value + rate * self.now.since(*since).as_secs_f64(),
                FaultKind::Noise(sigma) => value + sigma * gaussian(&mut self.rng),
                FaultKind::Dropout => return Err(NoValue),
            };
        }
        Ok(value)
    }

    /// The value of `e`, never NaN: f64 arithmetic is not trusted to have a meaning here, since a
    /// script built in code need not have been validated.
    fn eval(&mut self, e: &Expr, frame: Option<&Received>) -> Result<f64, NoValue> {
        let v = self.eval_unchecked(e, frame)?;
        if v.is_nan() { Err(NoValue) } else { Ok(v) }
    }

    fn eval_unchecked(&mut self, e: &Expr, frame: Option<&Received>) -> Result<f64, NoValue> {
        Ok(match e {
            Expr::Const(v) => *v,
            Expr::Port(p) => self.read_signal(Some(*p))?,
            // Left by the start only where the name is unknown: a script built in code.
            Expr::Signal(s) => {
                let port = self.env.borrow().port(s);
                self.read_signal(port)?
            }
            Expr::Var(v) => self.vars.get(v).copied().unwrap_or(0.0),
            Expr::Field(f) => frame.and_then(|d| d.physical(f)).unwrap_or(0.0),
            Expr::StateCode => f64::from(self.s.states.get(self.state).map_or(0, |d| d.code)),
            Expr::Scaled(inner, gain, offset) => self.eval(inner, frame)? * gain + offset,
            // f64::clamp panics on such a range.
            Expr::Clamp(_, lo, hi) if lo.is_nan() || hi.is_nan() || lo > hi => return Err(NoValue),
            Expr::Clamp(inner, lo, hi) => self.eval(inner, frame)?.clamp(*lo, *hi),
            Expr::Quantize(inner, step) => {
                let v = self.eval(inner, frame)?;
                if *step > 0.0 { (v / step).round() * step } else { v }
            }
            Expr::Ramp { from, to, period_s } => {
                let t = self.since_boot();
                // Weighted, so that the ends' difference never overflows.
                let w = if *period_s > 0.0 {
                    (t % period_s) / period_s
                } else {
                    0.0
                };
                from * (1.0 - w) + to * w
            }
            Expr::Sine {
                mean,
                amplitude,
                period_s,
            } => {
                let t = self.since_boot();
                if *period_s > 0.0 {
                    mean + amplitude * (std::f64::consts::TAU * t / period_s).sin()
                } else {
                    *mean
                }
            }
            Expr::RandomWalk {
                start,
                step,
                min,
                max,
            } => {
                use rand::Rng;
                let key = e as *const Expr as usize;
                let next = match self.generated.get(&key) {
                    None => *start,
                    Some(v) => {
                        // A uniform move in -step..=step, however wide (rand's ranges refuse
                        // one wider than f64 spans).
                        let u: f64 = self.rng.random();
                        v + (2.0 * u - 1.0) * step
                    }
                };
                // f64::clamp panics on such a range.
                if min.is_nan() || max.is_nan() || min > max {
                    return Err(NoValue);
                }
                let next = next.clamp(*min, *max);
                self.generated.insert(key, next);
                next
            }
            Expr::Counter { from, to, step } => {
                let key = e as *const Expr as usize;
                let next = match self.generated.get(&key) {
                    None => *from,
                    Some(v) => {
                        let n = v + step;
                        let past = if *step >= 0.0 { n > *to } else { n < *to };
                        if past { *from } else { n }
                    }
                };
                self.generated.insert(key, next);
                next
            }
            Expr::Cycle(values) => {
                // The position in the list is what is kept.
                let key = e as *const Expr as usize;
                let at = self.generated.get(&key).map_or(0, |&i| i as usize + 1);
                let at = if at < values.len() { at } else { 0 };
                self.generated.insert(key, at as f64);
                *values.get(at).ok_or(NoValue)?
            }
        })
    }

    /// Seconds since the end of boot (0 before it).
    fn since_boot(&self) -> f64 {
        if self.now > self.boot_at {
            self.now.since(self.boot_at).as_secs_f64()
        } else {
            0.0
        }
    }

    /// The frames of send `k` as they would go out now.
    fn build(&mut self, k: usize, frame: Option<&Received>) -> Option<Vec<Frame>> {
        let script = Rc::clone(&self.s);
        let specs = &script.messages[k].frames;
        // The buffer of a build that was not sent: checks build far more often than they send.
        let mut frames = std::mem::take(&mut self.spare);
        frames.clear();
        for (j, spec) in specs.iter().enumerate() {
            let (def, slots) = match &self.defs[k][j] {
                Some(r) => (r.def.clone(), Rc::clone(&r.slots)),
                None => return None,
            };
            match &def {
                Def::Catalogue(def) => {
                    let mut values = [None; 8];
                    for (e, slot) in spec.fields.values().zip(slots.iter()) {
                        let v = self.eval(e, frame).ok()?;
                        if let (Some(i), Some(f)) = (*slot, slot.and_then(|i| def.fields.get(i))) {
                            // A sensor saturates at the ends of what its message can carry.
                            if let Some(value) = values.get_mut(i) {
                                *value = Some(v.clamp(f.min, f.max));
                            }
                        }
                    }
                    let value = |i: usize| values.get(i).copied().flatten();
                    frames.push(def.encode_indexed(self.address, value).ok()?);
                }
                Def::Dbc(..) => {
                    let m = def.dbc()?;
                    let mut values = vec![None; m.signals.len()];
                    for (e, slot) in spec.fields.values().zip(slots.iter()) {
                        let v = self.eval(e, frame).ok()?;
                        if let Some(value) = slot.and_then(|i| values.get_mut(i)) {
                            *value = Some(v);
                        }
                    }
                    // Each signal is limited to its range and bits as it is encoded.
                    let data = m.encode_with(|i| values.get(i).copied().flatten())?;
                    frames.push(Frame::new_data(dbc_id(m)?, &data).ok()?);
                }
            }
        }
        Some(frames)
    }

    fn emit(&mut self, k: usize, frame: Option<&Received>) {
        let built = self.build(k, frame);
        self.send(k, built);
    }

    /// Sends frames built for send `k` (None: the build was skipped).
    fn send(&mut self, k: usize, built: Option<Vec<Frame>>) {
        let Some(frames) = built else {
            self.skipped += 1;
            return;
        };
        self.sent += frames.len() as u64;
        self.out.extend(frames.iter().copied());
        self.spare = std::mem::replace(&mut self.sends[k].last, frames);
        self.sends[k].last_sent = Some(self.now);
        if let Some(ack) = &self.s.messages[k].ack {
            let due = self.now + BusDuration::from_millis(ack.timeout_ms);
            self.acks.awaited.push_back((due, k));
        }
    }

    /// Counts every send whose acknowledgement is overdue at `now` as missed, in the order they
    /// fell due; the entry of each says which count variable shows it and when to give up.
    fn count_overdue(&mut self, now: BusTime) {
        let script = Rc::clone(&self.s);
        while let Some(k) = self.acks.take_overdue(now) {
            let Some(ack) = &script.messages[k].ack else {
                continue;
            };
            let missed = self.acks.missed;
            if let Some(v) = &ack.count_var {
                self.set_var(v, f64::from(missed));
            }
            if missed >= ack.limit {
                let from = self.state;
                self.set_state(&ack.state);
                let into = self.state;
                if ack.resume && into != from {
                    self.gave_up = Some(GaveUp { from, into });
                }
            }
        }
    }

    /// Sets a variable without allocating its name again when it exists.
    fn set_var(&mut self, name: &str, value: f64) {
        match self.vars.get_mut(name) {
            Some(v) if v.to_bits() == value.to_bits() => return,
            Some(v) => *v = value,
            None => {
                self.vars.insert(name.to_string(), value);
            }
        }
        self.touch();
    }

    /// Something of the node's own changed (state, a variable, a send switched on or off): idle
    /// on-change entries check again from the grid point a check that never stopped would be
    /// at. Within `handle_timeout` at `now`, entries from `unchecked_from` on have their check at
    /// `now` still ahead; every other check at `now` is behind.
    fn touch(&mut self) {
        let now = self.now;
        for (j, st) in self.sends.iter_mut().enumerate() {
            if !st.idle {
                continue;
            }
            st.idle = false;
            let When::OnChange { check_ms, .. } = self.s.messages[j].when else {
                continue;
            };
            let from = if self.unchecked_from.is_some_and(|first| j >= first) {
                now
            } else {
                now + BusDuration::from_ticks(1)
            };
            st.check_next = grid_from(st.check_next, BusDuration::from_millis(check_ms), from);
            st.next = st.next.min(st.check_next);
        }
    }

    fn run_actions(&mut self, actions: &[Action], frame: Option<&Received>) {
        for a in actions {
            match a {
                Action::SetState(s) => self.set_state(s),
                Action::Start(m) | Action::Stop(m) => {
                    if let Some(k) = self.s.messages.iter().position(|d| &d.name == m) {
                        self.sends[k].enabled = matches!(a, Action::Start(_));
                        self.touch();
                    }
                }
                Action::Send(m) => {
                    if let Some(k) = self.s.messages.iter().position(|d| &d.name == m) {
                        self.emit(k, frame);
                    }
                }
                Action::WritePort(port, e) => {
                    if let Ok(v) = self.eval(e, frame) {
                        self.env.borrow_mut().write(*port, v);
                    }
                }
                // Left by the start only where the name is unknown: nothing to write to.
                Action::Write(..) => {}
                Action::Set(var, e) => {
                    if let Ok(v) = self.eval(e, frame) {
                        self.set_var(var, v);
                    }
                }
                Action::Acknowledged => {
                    self.acks = Acks::default();
                    if let Some(g) = self.gave_up.take()
                        && g.into == self.state
                    {
                        self.set_state_index(g.from);
                    }
                    let script = Rc::clone(&self.s);
                    for m in &script.messages {
                        if let Some(v) = m.ack.as_ref().and_then(|a| a.count_var.as_ref()) {
                            self.set_var(v, 0.0);
                        }
                    }
                }
                Action::Restart(t) => {
                    if let Some(k) = self.s.timers.iter().position(|d| &d.name == t)
                        && self.timers[k].is_some()
                    {
                        self.timers[k] = Some(self.now + BusDuration::from_millis(self.s.timers[k].after_ms));
                    }
                }
            }
        }
    }
}

/// The first point of the grid `start + n × step` at or after `from`.
fn grid_from(start: BusTime, step: BusDuration, from: BusTime) -> BusTime {
    if start >= from || step == BusDuration::ZERO {
        return start;
    }
    start + step * (from - start).div_ceil(step)
}

/// A standard normal deviate (Box–Muller) from a seeded generator.
pub(crate) fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    use rand::Rng;
    let u1: f64 = rng.random_range(f64::MIN_POSITIVE..1.0);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

impl NodeLogic for ScriptedNode {
    fn handle_frame(&mut self, now: BusTime, frame: &Frame) {
        self.now = now;
        if !self.booted {
            return;
        }
        let d = match &self.s.db {
            // A DBC node answers any frame of the database but its own.
            Some(db) => match Received::of_dbc(db, frame) {
                Some(d) => {
                    let sender = db.message(d.message()).and_then(|m| m.transmitter.as_deref());
                    if sender == Some(self.s.name.as_str()) {
                        return;
                    }
                    d
                }
                None => return,
            },
            None => {
                let Ok(Some(d)) = catalogue::decode(frame) else {
                    return;
                };
                if d.node != self.address || d.message.direction != Direction::FromMonitor {
                    return;
                }
                Received::Catalogue(d)
            }
        };
        self.env.borrow_mut().advance_to(now);
        let script = Rc::clone(&self.s);
        // Which reactions apply is decided before any of them runs (one may change the state).
        let matching: Vec<&Reaction> = script
            .reactions
            .iter()
            .filter(|r| r.message == d.message() && self.active(&r.states))
            .filter(|r| {
                r.when
                    .iter()
                    .all(|(f, v)| d.raw(f).is_some_and(|x| x as f64 == *v))
            })
            .collect();
        for r in matching {
            self.run_actions(&r.actions, Some(&d));
        }
    }

    fn handle_timeout(&mut self, now: BusTime) {
        self.now = now;
        self.env.borrow_mut().advance_to(now);
        if !self.booted {
            if now >= self.boot_at {
                self.boot();
            } else {
                return;
            }
        }
        // Acknowledgements overdue by now count before anything is sent: a node that gives up
        // sends nothing more of its connection.
        self.unchecked_from = Some(0);
        self.count_overdue(now);
        for k in 0..self.sends.len() {
            if self.sends[k].next > now {
                continue;
            }
            self.unchecked_from = Some(k + 1);
            let m = &self.s.messages[k];
            let go = self.sends[k].enabled && self.active(&m.states);
            match m.when {
                When::Periodic { period_ms, .. } => {
                    self.sends[k].next += BusDuration::from_millis(period_ms);
                    if go {
                        self.emit(k, None);
                    }
                }
                When::OnChange {
                    heartbeat_ms,
                    check_ms,
                } => {
                    let was_idle = self.sends[k].idle;
                    if was_idle {
                        // Woken for its heartbeat: the grid is where it would be by now.
                        let st = &mut self.sends[k];
                        st.idle = false;
                        st.check_next = grid_from(st.check_next, BusDuration::from_millis(check_ms), now);
                    }
                    let checking = self.sends[k].check_next <= now;
                    if checking {
                        self.sends[k].check_next += BusDuration::from_millis(check_ms);
                    }
                    if go {
                        let stale = self.sends[k]
                            .last_sent
                            .is_none_or(|t| now - t >= BusDuration::from_millis(heartbeat_ms));
                        // What a check built is what goes out: the node sends the values it saw.
                        let checked = if checking { self.build(k, None) } else { None };
                        let changed = checked.as_ref().is_some_and(|f| *f != self.sends[k].last);
                        // Set before sending, so that whatever the send changes in the node wakes
                        // it again through `touch`.
                        // (Idle and not on the grid: nothing changed, so it stays idle.)
                        self.sends[k].idle = self.sends[k].internal
                            && (checked.is_some() && !changed || was_idle && checked.is_none());
                        if stale || changed {
                            match checked {
                                Some(frames) => self.send(k, Some(frames)),
                                None => self.emit(k, None),
                            }
                        } else if let Some(frames) = checked {
                            self.spare = frames;
                        }
                    }
                    // The heartbeat is kept exactly, not rounded up to the next check.
                    let heartbeat = self.sends[k]
                        .last_sent
                        .map_or(BusTime::NEVER, |t| t + BusDuration::from_millis(heartbeat_ms));
                    let st = &mut self.sends[k];
                    st.next = if st.idle {
                        heartbeat
                    } else {
                        st.check_next.min(heartbeat)
                    };
                }
                When::OnRequest => self.sends[k].next = BusTime::NEVER,
            }
        }
        self.unchecked_from = None;
        for k in 0..self.timers.len() {
            if self.timers[k].is_some_and(|t| t <= now) {
                self.timers[k] = Some(now + BusDuration::from_millis(self.s.timers[k].after_ms));
                let script = Rc::clone(&self.s);
                let actions = &script.timers[k].actions;
                self.run_actions(actions, None);
            }
        }
    }

    fn poll_transmit(&mut self) -> Option<Frame> {
        self.out.pop_front()
    }

    /// Sensor faults, as [`ScriptedNode::set_fault`]: a script takes every one.
    fn inject(&mut self, fault: &NodeFault, now: BusTime) -> Result<(), Refused> {
        match fault {
            NodeFault::Sensor { signal, reads } => self.set_fault(signal, Some((*reads).into()), now),
            NodeFault::SensorRepaired { signal } => self.set_fault(signal, None, now),
        }
        Ok(())
    }

    fn poll_timeout(&self) -> Option<BusTime> {
        if !self.booted {
            return Some(self.boot_at);
        }
        let sends = self.sends.iter().map(|s| s.next);
        let timers = self.timers.iter().flatten().copied();
        let acks = self.acks.next_due();
        sends
            .chain(timers)
            .chain(acks)
            .filter(|&t| t < BusTime::NEVER)
            .min()
    }
}

/// Resolves the plant signals a script names to their ports, once, when its node starts: reads
/// and writes then go by port. A name the environment does not have (only a script built in
/// code can hold one: loading refuses it) stays a name.
fn resolve_ports(script: &mut NodeScript, env: &dyn Environment) {
    fn expr(e: &mut Expr, env: &dyn Environment) {
        match e {
            Expr::Signal(name) => {
                if let Some(p) = env.port(name) {
                    *e = Expr::Port(p);
                }
            }
            Expr::Scaled(inner, ..) | Expr::Clamp(inner, ..) | Expr::Quantize(inner, _) => expr(inner, env),
            Expr::Const(_)
            | Expr::Port(_)
            | Expr::Var(_)
            | Expr::Field(_)
            | Expr::StateCode
            | Expr::Ramp { .. }
            | Expr::Sine { .. }
            | Expr::RandomWalk { .. }
            | Expr::Counter { .. }
            | Expr::Cycle(_) => {}
        }
    }
    fn actions(list: &mut [Action], env: &dyn Environment) {
        for a in list {
            match a {
                Action::Write(name, e) => {
                    expr(e, env);
                    if let Some(p) = env.port(name) {
                        *a = Action::WritePort(p, e.clone());
                    }
                }
                Action::WritePort(_, e) | Action::Set(_, e) => expr(e, env),
                _ => {}
            }
        }
    }
    for m in &mut script.messages {
        for f in &mut m.frames {
            for e in f.fields.values_mut() {
                expr(e, env);
            }
        }
    }
    for r in &mut script.reactions {
        actions(&mut r.actions, env);
    }
    for t in &mut script.timers {
        actions(&mut t.actions, env);
    }
}
