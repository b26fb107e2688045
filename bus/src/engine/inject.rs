//! Error injection: rules that corrupt chosen frames, or follow them with overload frames.
//!
//! A rule picks frames (by transmitter or identifier), decides which of them to hit (once, every
//! n-th, always, with a probability, or at a bit-error rate), what the hit does ([`Effect`]) and
//! who sees it ([`SeenBy`]). A [`Effect::Bit`] flips a bit on the wire: everybody samples it,
//! and the transmitter sees a bit error before anything else. [`Effect::Stuff`],
//! [`Effect::Crc`] and [`Effect::Form`] are a disturbance near the receivers: the receivers named
//! (all of them by default) sample one bit flipped, chosen so that it is a stuff, CRC or form
//! error to them, while the transmitter reads its own bits correctly. [`Effect::Overload`] makes
//! receivers that are not ready send overload frames after the frame. [`Effect::Disturb`] makes
//! the nodes named read a chosen level for a few bit times from a chosen bit of a chosen field
//! ([`Place`]), each node counting the field as it is in it itself; what they detect then is
//! whatever the protocol makes of the bits they read. A frame that lacks the place (a data bit
//! past its data field) is a miss, and so is one in which no node reached it (an error flag in
//! an attempt without error): [`Injector::disturb_counts`] tells hits and misses.
//!
//! Randomness comes from one generator seeded by the run's seed, so a run repeats exactly.

use super::NodeId;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Which transmission attempts a rule looks at.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Serialize, Deserialize)]
pub enum Target {
    /// Every frame on the bus.
    Any,
    /// Frames sent by one node.
    Node(NodeId),
    /// Frames whose raw identifier matches `id` on the bits set in `mask`.
    Id {
        /// Identifier bits to match.
        id: u32,
        /// Which bits count.
        mask: u32,
    },
}

/// Which of the matching attempts are hit.
#[derive(Clone, Copy, PartialEq, Debug, Serialize, Deserialize)]
pub enum Schedule {
    /// The first matching attempt only.
    Once,
    /// Every n-th matching attempt (n, 2n, ...).
    EveryNth(u32),
    /// Every matching attempt.
    Always,
    /// Each matching attempt with this probability.
    Probability(f64),
    /// Each bit of a matching attempt flips with this probability (bit-error rate).
    BitErrorRate(f64),
}

/// Where the flipped bit is, counted in the stuffed bitstream from SOF.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Serialize, Deserialize)]
pub enum BitPosition {
    /// This bit (clamped to the last bit of the CRC field).
    At(u16),
    /// A bit after the arbitration field, chosen at random.
    Random,
}

/// What a hit does.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default, Serialize, Deserialize)]
pub enum Effect {
    /// A bit flipped on the wire, seen by every controller (a bit error to the transmitter).
    #[default]
    Bit,
    /// A stuff bit flipped for the receivers: six equal bits, a stuff error.
    Stuff,
    /// A data or CRC bit flipped for the receivers: the CRC does not match.
    Crc,
    /// A fixed-form bit (CRC delimiter, ACK delimiter, EOF 1 to 6) made dominant for the
    /// receivers: a form error.
    Form,
    /// Receivers that are not ready send this many overload frames (1 or 2) after the frame.
    Overload(u8),
    /// The nodes named read a chosen level at a chosen place ([`Disturb`]).
    Disturb(Disturb),
}

/// A field of a frame, or of what follows an error or overload, in which a disturbance starts.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
pub enum Field {
    /// Start of frame (1 bit).
    Sof,
    /// The identifier: 11 bits (base) or 29 (extended: ID28..ID18, then after SRR and IDE
    /// ID17..ID0, counted on from 11).
    Identifier,
    /// Substitute remote request (extended frames only, 1 bit).
    Srr,
    /// Identifier extension (1 bit).
    Ide,
    /// Remote transmission request (1 bit).
    Rtr,
    /// Reserved bits: r0 in a base frame (1 bit); r1, r0 in an extended one (2 bits).
    Reserved,
    /// Data length code (4 bits).
    Dlc,
    /// Data field (8 bits a byte; none in a remote frame).
    Data,
    /// CRC sequence (15 bits).
    Crc,
    /// CRC delimiter (1 bit).
    CrcDelimiter,
    /// ACK slot (1 bit).
    AckSlot,
    /// ACK delimiter (1 bit).
    AckDelimiter,
    /// End of frame (7 bits).
    Eof,
    /// Intermission (3 bits).
    Intermission,
    /// The stuff bits of the frame, counted from the first.
    StuffBit,
    /// The node's own error flag (6 bits; a passive flag can last longer).
    ErrorFlag,
    /// The node's error delimiter: bit 0 is the first bit after its flag, bits 1 to 7 the seven
    /// after the recessive bit that ends its wait (8 bits).
    ErrorDelimiter,
    /// The node's own overload flag (6 bits).
    OverloadFlag,
    /// The node's overload delimiter, counted as the error delimiter (8 bits).
    OverloadDelimiter,
}

impl Field {
    /// Every field, in the order of a frame and what follows it.
    pub const ALL: [Field; 19] = [
        Field::Sof,
        Field::Identifier,
        Field::Srr,
        Field::Ide,
        Field::Rtr,
        Field::Reserved,
        Field::Dlc,
        Field::Data,
        Field::Crc,
        Field::CrcDelimiter,
        Field::AckSlot,
        Field::AckDelimiter,
        Field::Eof,
        Field::Intermission,
        Field::StuffBit,
        Field::ErrorFlag,
        Field::ErrorDelimiter,
        Field::OverloadFlag,
        Field::OverloadDelimiter,
    ];

    /// The most bits the field has in any frame (a frame's stuff bits: at most 29, one after the
    /// first five and then one per four of an extended frame's 118 bits before stuffing).
    pub fn max_bits(self) -> u16 {
        match self {
            Field::Sof | Field::Srr | Field::Ide | Field::Rtr => 1,
            Field::CrcDelimiter | Field::AckSlot | Field::AckDelimiter => 1,
            Field::Identifier => 29,
            Field::Reserved => 2,
            Field::Dlc => 4,
            Field::Data => 64,
            Field::Crc => 15,
            Field::Eof => 7,
            Field::Intermission => 3,
            Field::StuffBit => 29,
            Field::ErrorFlag | Field::OverloadFlag => 6,
            Field::ErrorDelimiter | Field::OverloadDelimiter => 8,
        }
    }

    /// The bits the field has in `frame`; `None` for the fields after an error or overload,
    /// which an attempt may or may not have.
    pub fn bits_in(self, frame: &crate::Frame) -> Option<u16> {
        let ext = frame.is_extended();
        Some(match self {
            Field::Identifier => {
                if ext {
                    29
                } else {
                    11
                }
            }
            Field::Srr => u16::from(ext),
            Field::Reserved => 1 + u16::from(ext),
            Field::Data => 8 * frame.data().len() as u16,
            Field::StuffBit => crate::bits::encode(frame).stuff_bits as u16,
            f if f.after_error() => return None,
            other => other.max_bits(),
        })
    }

    /// True for the fields after an error or overload.
    pub fn after_error(self) -> bool {
        matches!(
            self,
            Field::ErrorFlag | Field::ErrorDelimiter | Field::OverloadFlag | Field::OverloadDelimiter
        )
    }
}

/// A bit of a field: `bit` counts from 0 in the field's bits as sent (stuff bits are a field of
/// their own, [`Field::StuffBit`]).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
pub struct Place {
    /// The field.
    pub field: Field,
    /// The bit in it.
    pub bit: u16,
}

/// A disturbance at a place: from the bit at [`Place`] on, for `bits` bit times, the nodes it
/// reaches read `level` (`true` recessive), whatever the bus carries.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
pub struct Disturb {
    /// Where it starts, for each node as that node is in the frame.
    pub place: Place,
    /// The level read: `true` recessive, `false` dominant.
    pub level: bool,
    /// How many bit times it lasts (at least 1).
    pub bits: u16,
}

/// Who sees a hit.
#[derive(Clone, PartialEq, Eq, Debug, Default, Serialize, Deserialize)]
pub enum SeenBy {
    /// Everyone it can reach: every controller for [`Effect::Bit`], every receiver otherwise.
    #[default]
    All,
    /// These receivers only (ignored for [`Effect::Bit`]; a transmitter in the list is left out).
    Nodes(Vec<NodeId>),
}

impl SeenBy {
    /// True when `node` is one of those named (or all are).
    pub fn includes(&self, node: NodeId) -> bool {
        match self {
            SeenBy::All => true,
            SeenBy::Nodes(list) => list.contains(&node),
        }
    }
}

/// One injection rule.
#[derive(Clone, PartialEq, Debug, Serialize, Deserialize)]
pub struct Rule {
    /// Which attempts it looks at.
    pub target: Target,
    /// Which of them it hits.
    pub schedule: Schedule,
    /// Where the bit flips.
    pub bit: BitPosition,
    /// What a hit does.
    #[serde(default)]
    pub effect: Effect,
    /// Who sees it.
    #[serde(default)]
    pub seen_by: SeenBy,
}

impl Rule {
    /// A wire bit flip at `bit` on the attempts `target` and `schedule` pick.
    pub fn bit_errors(target: Target, schedule: Schedule, bit: BitPosition) -> Rule {
        Rule {
            target,
            schedule,
            bit,
            effect: Effect::Bit,
            seen_by: SeenBy::All,
        }
    }
}

/// What the rules decided for one attempt.
#[derive(Clone, PartialEq, Debug, Default)]
pub struct Decision {
    /// A corrupted bit: the effect, the stuffed bit (counted from SOF; tail bits follow the
    /// stuffed part) and who samples it flipped.
    pub corrupt: Option<(Effect, u16, SeenBy)>,
    /// Overload frames after the frame: how many, and which receivers send them.
    pub overload: Option<(u8, SeenBy)>,
    /// Disturbances at places, with the rule each comes from and the nodes it reaches (all
    /// controllers, transmitters included, for [`SeenBy::All`]).
    pub disturb: Vec<(RuleId, Disturb, SeenBy)>,
}

impl Decision {
    /// Nothing happens to the attempt.
    pub fn is_none(&self) -> bool {
        self.corrupt.is_none() && self.overload.is_none() && self.disturb.is_empty()
    }
}

/// What became of the attempts a [`Effect::Disturb`] rule selected.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default, Serialize, Deserialize)]
pub struct DisturbCounts {
    /// Attempts in which at least one node it reaches read the disturbance.
    pub hits: u64,
    /// Attempts without its place (not in the frame, or reached by none of its nodes).
    pub misses: u64,
}

/// Handle of an installed rule, to remove it.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
pub struct RuleId(pub u64);

#[derive(Clone, Debug)]
struct Installed {
    id: RuleId,
    rule: Rule,
    matched: u64,
    fired: u64,
}

/// The rules of one bus and the generator they draw from.
#[derive(Clone, Debug)]
pub struct Injector {
    rules: Vec<Installed>,
    next_id: u64,
    rng: ChaCha8Rng,
    /// Hits and misses of every disturbance rule ever installed (kept after it is removed, so
    /// that a run's report can tell them; one entry per rule).
    disturbed: Vec<(RuleId, DisturbCounts)>,
}

impl Injector {
    /// No rules; randomness seeded from `seed`.
    pub fn new(seed: u64) -> Injector {
        Injector {
            rules: Vec::new(),
            next_id: 1,
            rng: ChaCha8Rng::seed_from_u64(seed),
            disturbed: Vec::new(),
        }
    }

    /// Hits and misses of a disturbance rule, removed or not; `None` for another rule.
    pub fn disturb_counts(&self, id: RuleId) -> Option<DisturbCounts> {
        self.disturbed.iter().find(|(r, _)| *r == id).map(|(_, c)| *c)
    }

    /// Counts an attempt a disturbance rule selected: hit or missed.
    pub(crate) fn count_disturb(&mut self, id: RuleId, hit: bool) {
        if let Some((_, c)) = self.disturbed.iter_mut().find(|(r, _)| *r == id) {
            if hit {
                c.hits += 1;
            } else {
                c.misses += 1;
            }
        }
    }

    /// Installs a rule.
    pub fn add(&mut self, rule: Rule) -> RuleId {
        let id = RuleId(self.next_id);
        self.next_id += 1;
        if matches!(rule.effect, Effect::Disturb(_)) {
            self.disturbed.push((id, DisturbCounts::default()));
        }
        self.rules.push(Installed {
            id,
            rule,
            matched: 0,
            fired: 0,
        });
        id
    }

    /// Removes a rule; false if it was not there.
    pub fn remove(&mut self, id: RuleId) -> bool {
        let before = self.rules.len();
        self.rules.retain(|r| r.id != id);
        self.rules.len() != before
    }

    /// How often a rule has fired.
    pub fn fired(&self, id: RuleId) -> Option<u64> {
        self.rules.iter().find(|r| r.id == id).map(|r| r.fired)
    }

    /// True when no rule is installed (the hot path skips everything else).
    pub fn is_empty(&self) -> bool {
        self.rules.is_empty()
    }

    /// Decides whether this attempt of `frame` is corrupted, and at which stuffed bit. `first`
    /// and `last` bound the positions a random wire flip may take (after arbitration, up to the
    /// last CRC bit); `positions` gives the bits where another effect can fall (empty: it
    /// cannot, and the rule does not fire on this attempt). A disturbance whose place the frame
    /// lacks is counted a miss here.
    pub(crate) fn decide(
        &mut self,
        node: NodeId,
        frame: &crate::Frame,
        first: u16,
        last: u16,
        positions: &mut dyn FnMut(Effect) -> Vec<u16>,
    ) -> Decision {
        let raw_id = frame.raw_id();
        let mut decision = Decision::default();
        let mut missed = Vec::new();
        for r in &mut self.rules {
            let matches = match r.rule.target {
                Target::Any => true,
                Target::Node(n) => n == node,
                Target::Id { id, mask } => raw_id & mask == id & mask,
            };
            if !matches {
                continue;
            }
            r.matched += 1;
            let fire = match r.rule.schedule {
                Schedule::Once => r.fired == 0,
                Schedule::EveryNth(n) => n > 0 && r.matched.is_multiple_of(u64::from(n)),
                Schedule::Always => true,
                Schedule::Probability(p) => self.rng.random_bool(p.clamp(0.0, 1.0)),
                Schedule::BitErrorRate(ber) => {
                    // P(at least one of the frame's bits flips) = 1 - (1 - ber)^bits.
                    let bits = f64::from(last) + 1.0;
                    let p = 1.0 - (1.0 - ber.clamp(0.0, 1.0)).powf(bits);
                    self.rng.random_bool(p.clamp(0.0, 1.0))
                }
            };
            if !fire {
                continue;
            }
            match r.rule.effect {
                Effect::Disturb(d) => {
                    r.fired += 1;
                    match d.place.field.bits_in(frame) {
                        Some(bits) if d.place.bit >= bits => missed.push(r.id),
                        _ => decision.disturb.push((r.id, d, r.rule.seen_by.clone())),
                    }
                }
                Effect::Overload(frames) => {
                    if decision.overload.is_none() {
                        r.fired += 1;
                        decision.overload = Some((frames.clamp(1, 2), r.rule.seen_by.clone()));
                    }
                }
                Effect::Bit => {
                    if decision.corrupt.is_none() {
                        r.fired += 1;
                        let bit = match r.rule.bit {
                            BitPosition::At(b) => b.min(last),
                            BitPosition::Random => self.rng.random_range(first..=last.max(first)),
                        };
                        decision.corrupt = Some((Effect::Bit, bit, SeenBy::All));
                    }
                }
                effect => {
                    if decision.corrupt.is_some() {
                        continue;
                    }
                    let candidates = positions(effect);
                    let bit = match r.rule.bit {
                        _ if candidates.is_empty() => continue,
                        BitPosition::At(b) => candidates
                            .iter()
                            .copied()
                            .find(|&c| c >= b)
                            .or(candidates.last().copied()),
                        BitPosition::Random => candidates
                            .get(self.rng.random_range(0..candidates.len()))
                            .copied(),
                    };
                    if let Some(bit) = bit {
                        r.fired += 1;
                        decision.corrupt = Some((effect, bit, r.rule.seen_by.clone()));
                    }
                }
            }
        }
        for id in missed {
            self.count_disturb(id, false);
        }
        decision
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rule(schedule: Schedule) -> Rule {
        Rule::bit_errors(Target::Node(NodeId(1)), schedule, BitPosition::At(40))
    }

    /// The wire-flip bit an attempt got, if any.
    fn flip(inj: &mut Injector, node: u16, raw_id: u32, first: u16, last: u16) -> Option<u16> {
        let frame = crate::Frame::extended(raw_id, &[]).unwrap();
        inj.decide(NodeId(node), &frame, first, last, &mut |_| Vec::new())
            .corrupt
            .map(|(_, b, _)| b)
    }

    #[test]
    fn schedules() {
        let mut inj = Injector::new(7);
        let once = inj.add(rule(Schedule::Once));
        let hits: Vec<bool> = (0..4).map(|_| flip(&mut inj, 1, 0, 33, 100).is_some()).collect();
        assert_eq!(hits, [true, false, false, false]);
        assert_eq!(inj.fired(once), Some(1));
        assert!(inj.remove(once));

        inj.add(rule(Schedule::EveryNth(3)));
        let hits: Vec<bool> = (0..7).map(|_| flip(&mut inj, 1, 0, 33, 100).is_some()).collect();
        assert_eq!(hits, [false, false, true, false, false, true, false]);
        // Other nodes are not looked at.
        assert!((0..10).all(|_| flip(&mut inj, 2, 0, 33, 100).is_none()));
    }

    #[test]
    fn positions_and_ids() {
        let mut inj = Injector::new(1);
        inj.add(Rule::bit_errors(
            Target::Id {
                id: 0x0601F5D0,
                mask: 0xFF,
            },
            Schedule::Always,
            BitPosition::Random,
        ));
        for _ in 0..200 {
            let b = flip(&mut inj, 0, 0x0000_00D0, 33, 90).unwrap();
            assert!((33..=90).contains(&b));
        }
        assert!(flip(&mut inj, 0, 0x0000_00D1, 33, 90).is_none());
        let mut at = Injector::new(1);
        at.add(Rule::bit_errors(
            Target::Any,
            Schedule::Always,
            BitPosition::At(500),
        ));
        assert_eq!(
            flip(&mut at, 0, 0, 33, 90),
            Some(90),
            "clamped to the last CRC bit"
        );
    }

    #[test]
    fn same_seed_same_choices() {
        let run = |seed| {
            let mut inj = Injector::new(seed);
            inj.add(Rule::bit_errors(
                Target::Any,
                Schedule::Probability(0.3),
                BitPosition::Random,
            ));
            (0..100).map(|_| flip(&mut inj, 0, 0, 10, 80)).collect::<Vec<_>>()
        };
        assert_eq!(run(5), run(5));
        assert_ne!(run(5), run(6));
        let hits = run(5).iter().filter(|h| h.is_some()).count();
        assert!((15..=45).contains(&hits), "about 30 of 100: {hits}");
    }
}
