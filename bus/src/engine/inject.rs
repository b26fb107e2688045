//! Error injection: rules that corrupt chosen frames on the wire.
//!
//! A rule picks frames (by transmitter or identifier), decides which of them to hit (once, every
//! n-th, always, with a probability, or at a bit-error rate), and where in the frame the bit flips.
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

/// One injection rule.
#[derive(Clone, Copy, PartialEq, Debug, Serialize, Deserialize)]
pub struct Rule {
    /// Which attempts it looks at.
    pub target: Target,
    /// Which of them it hits.
    pub schedule: Schedule,
    /// Where the bit flips.
    pub bit: BitPosition,
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
}

impl Injector {
    /// No rules; randomness seeded from `seed`.
    pub fn new(seed: u64) -> Injector {
        Injector {
            rules: Vec::new(),
            next_id: 1,
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    /// Installs a rule.
    pub fn add(&mut self, rule: Rule) -> RuleId {
        let id = RuleId(self.next_id);
        self.next_id += 1;
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

    /// Decides whether this attempt is corrupted, and at which stuffed bit. `first` and `last`
    /// bound the positions a random choice may take (after arbitration, up to the last CRC bit).
    pub(crate) fn decide(&mut self, node: NodeId, raw_id: u32, first: u16, last: u16) -> Option<u16> {
        let mut hit = None;
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
            if fire && hit.is_none() {
                r.fired += 1;
                let bit = match r.rule.bit {
                    BitPosition::At(b) => b.min(last),
                    BitPosition::Random => self.rng.random_range(first..=last.max(first)),
                };
                hit = Some(bit);
            }
        }
        hit
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rule(schedule: Schedule) -> Rule {
        Rule {
            target: Target::Node(NodeId(1)),
            schedule,
            bit: BitPosition::At(40),
        }
    }

    #[test]
    fn schedules() {
        let mut inj = Injector::new(7);
        let once = inj.add(rule(Schedule::Once));
        let hits: Vec<bool> = (0..4)
            .map(|_| inj.decide(NodeId(1), 0, 33, 100).is_some())
            .collect();
        assert_eq!(hits, [true, false, false, false]);
        assert_eq!(inj.fired(once), Some(1));
        assert!(inj.remove(once));

        inj.add(rule(Schedule::EveryNth(3)));
        let hits: Vec<bool> = (0..7)
            .map(|_| inj.decide(NodeId(1), 0, 33, 100).is_some())
            .collect();
        assert_eq!(hits, [false, false, true, false, false, true, false]);
        // Other nodes are not looked at.
        assert!((0..10).all(|_| inj.decide(NodeId(2), 0, 33, 100).is_none()));
    }

    #[test]
    fn positions_and_ids() {
        let mut inj = Injector::new(1);
        inj.add(Rule {
            target: Target::Id {
                id: 0x0601F5D0,
                mask: 0xFF,
            },
            schedule: Schedule::Always,
            bit: BitPosition::Random,
        });
        for _ in 0..200 {
            let b = inj.decide(NodeId(0), 0x0000_00D0, 33, 90).unwrap();
            assert!((33..=90).contains(&b));
        }
        assert!(inj.decide(NodeId(0), 0x0000_00D1, 33, 90).is_none());
        let mut at = Injector::new(1);
        at.add(Rule {
            target: Target::Any,
            schedule: Schedule::Always,
            bit: BitPosition::At(500),
        });
        assert_eq!(
            at.decide(NodeId(0), 0, 33, 90),
            Some(90),
            "clamped to the last CRC bit"
        );
    }

    #[test]
    fn same_seed_same_choices() {
        let run = |seed| {
            let mut inj = Injector::new(seed);
            inj.add(Rule {
                target: Target::Any,
                schedule: Schedule::Probability(0.3),
                bit: BitPosition::Random,
            });
            (0..100)
                .map(|_| inj.decide(NodeId(0), 0, 10, 80))
                .collect::<Vec<_>>()
        };
        assert_eq!(run(5), run(5));
        assert_ne!(run(5), run(6));
        let hits = run(5).iter().filter(|h| h.is_some()).count();
        assert!((15..=45).contains(&hits), "about 30 of 100: {hits}");
    }
}
