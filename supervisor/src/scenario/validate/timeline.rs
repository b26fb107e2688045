//! One timeline step checked and resolved: the nodes, frames, times and values its action names,
//! turned into what the run carries out ([`Act`]), or the problems that stop it.

use super::{Checks, MAX_OVERLOAD_FRAMES};
use crate::scenario::model::{Action, ErrorKind, Hits, Level, ReadBy, SeenBy, Step, Target};
use crate::scenario::plan::{Act, Resolved, Todo};
use bus::candump::parse_frame;
use bus::engine::{BitPosition, Disturb, Effect, Field, Place, Rule, Schedule};
use bus::node::NodeFault;
use bus::text::quote;
use bus::time::BusTime;
use nodes::plant::Plant;

/// Checks step `index` (its field path `at`, `timeline[i]`); resolved when it has no problem.
pub(super) fn step(c: &mut Checks, at: &str, index: usize, step: &Step) -> Option<Resolved> {
    let before = c.found.len();
    c.time(format!("{at}.at_s"), step.at_s);
    let act = action(c, at, step.at_s, &step.action);
    let end = |t: f64, what| Some((BusTime::from_secs_f64(t), what));
    let ends = match &step.action {
        Action::BitErrors { until_s: Some(u), .. }
        | Action::Overload { until_s: Some(u), .. }
        | Action::Disturb { until_s: Some(u), .. } => end(*u, Todo::EndRule(index)),
        Action::Babble { until_s, .. } => end(*until_s, Todo::EndBabble),
        _ => None,
    };
    let act = act.filter(|_| c.found.len() == before)?;
    Some(Resolved {
        index,
        at: BusTime::from_secs_f64(step.at_s),
        name: step.action.name(),
        act,
        ends,
    })
}

/// The longest disturbance, bit times: far past anything the rules count (rule 6 adds 8 for
/// every 8 dominant bits; 32 of those put any node bus off).
pub const MAX_DISTURB_BITS: u16 = 4096;

/// Checks that bit `bit` of `field` can exist in a frame `target` selects: in any frame at all,
/// and, where the frames are known (a scripted node's messages and the timeline's `SendFrame`s
/// of it), in one of them.
fn place(c: &mut Checks, at: &str, target: &Target, field: Field, bit: u16) {
    let most = field.max_bits();
    if bit >= most {
        c.push(
            format!("{at}.action.bit"),
            format!(
                "bit {bit} is past the field {field:?}, which has at most {most} bit(s), 0 to {}",
                most - 1
            ),
        );
        return;
    }
    let Target::Node(name) = target else { return };
    let Some(frames) = c.frames_of(name) else { return };
    if field == Field::StuffBit || field.after_error() {
        return;
    }
    let fits = |f: &bus::Frame| field.bits_in(f).is_none_or(|n| bit < n);
    if !frames.iter().any(fits) {
        let most = frames.iter().filter_map(|f| field.bits_in(f)).max().unwrap_or(0);
        let message = if frames.is_empty() {
            format!(
                "{name} sends no frame of its own (no message in its script, no SendFrame of it in the timeline): nothing to disturb"
            )
        } else if most == 0 {
            format!("no frame {name} sends has a {field:?} field")
        } else {
            format!(
                "bit {bit} of {field:?} is in no frame {name} sends: its frames have at most {most} bit(s) there"
            )
        };
        c.push(format!("{at}.action.bit"), message);
    }
}

/// Checks an action that starts at `at_s` and resolves it; `None` when a problem was found.
fn action(c: &mut Checks, at: &str, at_s: f64, action: &Action) -> Option<Act> {
    match action {
        Action::BitErrors {
            target,
            hits,
            until_s,
            kind,
            seen_by,
        } => {
            let frames = c.frames(at, target, hits);
            if let Some(u) = until_s {
                c.end(format!("{at}.action.until_s"), at_s, *u);
            }
            let seen_by = match seen_by {
                SeenBy::All => Some(bus::engine::SeenBy::All),
                SeenBy::Nodes(nodes) => {
                    if nodes.is_empty() {
                        c.push(
                            format!("{at}.action.seen_by"),
                            "Nodes([]): name at least one node, or leave seen_by out for All",
                        );
                    }
                    let ids: Vec<_> = nodes
                        .iter()
                        .enumerate()
                        .map(|(k, n)| c.node(format!("{at}.action.seen_by[{k}]"), n))
                        .collect();
                    if *kind == ErrorKind::Bit {
                        c.push(
                            format!("{at}.action.seen_by"),
                            "a bit error is a bit flipped on the wire, which every node sees: \
                             seen_by: Nodes(..) needs kind Stuff, Crc or Form",
                        );
                    }
                    ids.into_iter()
                        .collect::<Option<_>>()
                        .map(bus::engine::SeenBy::Nodes)
                }
            };
            let effect = match kind {
                ErrorKind::Bit => Effect::Bit,
                ErrorKind::Stuff => Effect::Stuff,
                ErrorKind::Crc => Effect::Crc,
                ErrorKind::Form => Effect::Form,
            };
            let (target, schedule) = frames?;
            Some(Act::Rule(Rule {
                target,
                schedule,
                bit: BitPosition::Random,
                effect,
                seen_by: seen_by?,
            }))
        }
        Action::Disturb {
            target,
            hits,
            until_s,
            field,
            bit,
            level,
            bits,
            seen_by,
        } => {
            let frames = c.frames(at, target, hits);
            if let Some(u) = until_s {
                c.end(format!("{at}.action.until_s"), at_s, *u);
            }
            place(c, at, target, *field, *bit);
            if !(1..=MAX_DISTURB_BITS).contains(bits) {
                c.push(
                    format!("{at}.action.bits"),
                    format!("{bits} bit times: a disturbance lasts 1 to {MAX_DISTURB_BITS}"),
                );
            }
            let seen_by = match seen_by {
                ReadBy::All => Some(bus::engine::SeenBy::All),
                ReadBy::Nodes(nodes) => {
                    if nodes.is_empty() {
                        c.push(
                            format!("{at}.action.seen_by"),
                            "Nodes([]): name at least one node, or leave seen_by out for All",
                        );
                    }
                    let ids: Vec<_> = nodes
                        .iter()
                        .enumerate()
                        .map(|(k, n)| c.node(format!("{at}.action.seen_by[{k}]"), n))
                        .collect();
                    ids.into_iter()
                        .collect::<Option<_>>()
                        .map(bus::engine::SeenBy::Nodes)
                }
            };
            let (target, schedule) = frames?;
            Some(Act::Rule(Rule {
                target,
                schedule,
                bit: BitPosition::Random,
                effect: Effect::Disturb(Disturb {
                    place: Place {
                        field: *field,
                        bit: *bit,
                    },
                    level: *level == Level::Recessive,
                    bits: *bits,
                }),
                seen_by: seen_by?,
            }))
        }
        Action::Overload {
            target,
            hits,
            until_s,
            by,
            frames,
        } => {
            let selected = c.frames(at, target, hits);
            if let Some(u) = until_s {
                c.end(format!("{at}.action.until_s"), at_s, *u);
            }
            let ids: Vec<_> = by
                .iter()
                .enumerate()
                .map(|(k, n)| c.node(format!("{at}.action.by[{k}]"), n))
                .collect();
            if !(1..=MAX_OVERLOAD_FRAMES).contains(frames) {
                c.push(
                    format!("{at}.action.frames"),
                    format!(
                        "{frames} overload frames in a row: a receiver may send 1 or \
                         {MAX_OVERLOAD_FRAMES} (CAN 2.0, overload frame)"
                    ),
                );
            }
            let ids: Vec<_> = ids.into_iter().collect::<Option<_>>()?;
            let seen_by = if ids.is_empty() {
                bus::engine::SeenBy::All
            } else {
                bus::engine::SeenBy::Nodes(ids)
            };
            let (target, schedule) = selected?;
            Some(Act::Rule(Rule {
                target,
                schedule,
                bit: BitPosition::Random,
                effect: Effect::Overload(*frames),
                seen_by,
            }))
        }
        Action::AckFailure(n) => Some(Act::Ack(c.node(format!("{at}.action"), n)?, false)),
        Action::AckRestored(n) => Some(Act::Ack(c.node(format!("{at}.action"), n)?, true)),
        Action::Disconnect(n) => Some(Act::Connect(c.node(format!("{at}.action"), n)?, false)),
        Action::Reconnect(n) => Some(Act::Connect(c.node(format!("{at}.action"), n)?, true)),
        Action::Hang(n) => Some(Act::Hang(c.node(format!("{at}.action"), n)?, true)),
        Action::Resume(n) => Some(Act::Hang(c.node(format!("{at}.action"), n)?, false)),
        Action::Crash(n) => c.node(format!("{at}.action"), n).map(|_| Act::Crash(n.clone())),
        Action::Babble { frame, until_s } => {
            c.end(format!("{at}.action.until_s"), at_s, *until_s);
            Some(Act::Babble(c.frame(format!("{at}.action.frame"), frame)?))
        }
        Action::SendFrame { node, frame } => {
            let id = c.node(format!("{at}.action.node"), node);
            let frame = c.frame(format!("{at}.action.frame"), frame);
            Some(Act::Send(id?, frame?))
        }
        Action::SensorFault { node, signal, fault } => {
            if let Some(m) = fault.problem() {
                c.push(format!("{at}.action.fault"), m);
            }
            sensor(c, at, node, signal)?;
            let fault = NodeFault::Sensor {
                signal: signal.clone(),
                reads: (*fault).into(),
            };
            Some(Act::Inject {
                node: node.clone(),
                fault,
            })
        }
        Action::SensorRepaired { node, signal } => {
            sensor(c, at, node, signal)?;
            let fault = NodeFault::SensorRepaired {
                signal: signal.clone(),
            };
            Some(Act::Inject {
                node: node.clone(),
                fault,
            })
        }
        Action::Plant { input, value } => match Plant::input_range(input) {
            None => {
                c.push(
                    format!("{at}.action.input"),
                    format!("{} is not a plant input", quote(input)),
                );
                None
            }
            // The plant would refuse it when the step runs.
            Some(range) if !range.contains(*value) => {
                c.push(
                    format!("{at}.action.value"),
                    format!("{value} is not {range}, the range of plant input {input}"),
                );
                None
            }
            Some(_) => Some(Act::Plant {
                input: input.clone(),
                value: *value,
            }),
        },
        Action::PowerCycle => Some(Act::PowerCycle),
    }
}

/// A sensor of a node: a field node's, of a plant signal.
fn sensor(c: &mut Checks, at: &str, node: &str, signal: &str) -> Option<()> {
    let id = c.node(format!("{at}.action.node"), node);
    if node == "F5" {
        c.push(format!("{at}.action.node"), "the monitor has no sensors");
    }
    let known = c.signal(format!("{at}.action.signal"), signal);
    id.filter(|_| node != "F5" && known).map(|_| ())
}

impl Checks<'_> {
    /// Which frames a fault selects, in the engine's form.
    fn frames(&mut self, at: &str, target: &Target, hits: &Hits) -> Option<(bus::engine::Target, Schedule)> {
        let field = format!("{at}.action.target");
        let target = match target {
            Target::Any => Some(bus::engine::Target::Any),
            Target::Node(n) => self.node(field, n).map(bus::engine::Target::Node),
            Target::Id(text) => match u32::from_str_radix(text, 16) {
                Ok(id) if text.len() == 8 && id <= 0x1FFF_FFFF => Some(bus::engine::Target::Id {
                    id,
                    mask: 0x1FFF_FFFF,
                }),
                _ => {
                    self.push(
                        field,
                        format!("{} is not an 8-digit 29-bit identifier", quote(text)),
                    );
                    None
                }
            },
            Target::Priority(p) => match protocol::ident::Priority::new(*p) {
                Ok(priority) => {
                    let (id, mask) = priority.id_and_mask();
                    Some(bus::engine::Target::Id { id, mask })
                }
                Err(_) => {
                    self.push(field, format!("priority {p} is over 31"));
                    None
                }
            },
        };
        let field = format!("{at}.action.hits");
        let schedule = match *hits {
            Hits::EveryNth(0) => {
                self.push(field, "EveryNth(0)");
                None
            }
            Hits::BitErrorRate(r) if !(0.0..=1.0).contains(&r) => {
                self.push(field, format!("bit-error rate {r} is outside 0..1"));
                None
            }
            Hits::Once => Some(Schedule::Once),
            Hits::EveryNth(n) => Some(Schedule::EveryNth(n)),
            Hits::Always => Some(Schedule::Always),
            Hits::BitErrorRate(r) => Some(Schedule::BitErrorRate(r)),
        };
        Some((target?, schedule?))
    }

    /// A frame in candump notation.
    fn frame(&mut self, field: String, text: &str) -> Option<bus::Frame> {
        parse_frame(text)
            .map_err(|e| self.push(field, e.to_string()))
            .ok()
    }
}
