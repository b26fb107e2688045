//! Code coverage of a firmware image: how often each instruction ran, and which way each
//! conditional jump went.
//!
//! Contract: [`Counts`] holds, per code address, the executions of the instruction that starts
//! there and, for a conditional jump, how many of them jumped and how many fell through. A
//! firmware node given counts ([`super::FirmwareNode::with_coverage`]) adds to them exactly
//! the instructions of the path it took: a run ahead that an input sent back is never
//! counted, and turns of an idle loop passed in closed form count as if each had run.

use std::cell::RefCell;
use std::ops::Range;
use std::rc::Rc;

/// What ran at one code address.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Count {
    /// Executions of the instruction that starts here.
    pub runs: u64,
    /// Of those, for a conditional jump: how many jumped.
    pub taken: u64,
    /// And how many fell through to the next instruction.
    pub not_taken: u64,
}

/// Per-address counts of one image (see the module docs).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Counts {
    /// Indexed by address: every address of the code memory, so that counting needs no check.
    per: Box<[Count; 0x10000]>,
}

impl Default for Counts {
    fn default() -> Counts {
        let per: Box<[Count]> = vec![Count::default(); 0x10000].into_boxed_slice();
        Counts {
            // A slice of 65536 counts is an array of them.
            per: per.try_into().unwrap_or_else(|_| unreachable!()),
        }
    }
}

/// Counts several nodes running one image add to.
pub type SharedCounts = Rc<RefCell<Counts>>;

impl Counts {
    /// What ran at `addr`.
    pub fn get(&self, addr: u16) -> Count {
        self.per[usize::from(addr)]
    }

    /// Every address where something ran, in order.
    pub fn iter(&self) -> impl Iterator<Item = (u16, Count)> + '_ {
        self.per
            .iter()
            .enumerate()
            .filter(|(_, c)| c.runs > 0)
            .filter_map(|(a, c)| Some((u16::try_from(a).ok()?, *c)))
    }

    /// Adds `count` at `addr` (merging runs).
    pub fn add(&mut self, addr: u16, count: Count) {
        let c = &mut self.per[usize::from(addr)];
        c.runs = c.runs.saturating_add(count.runs);
        c.taken = c.taken.saturating_add(count.taken);
        c.not_taken = c.not_taken.saturating_add(count.not_taken);
    }

    /// Adds every count of `other`.
    pub fn merge(&mut self, other: &Counts) {
        for (addr, count) in other.iter() {
            self.add(addr, count);
        }
    }

    #[inline(always)]
    fn at(&mut self, addr: u16) -> &mut Count {
        &mut self.per[usize::from(addr)]
    }
}

impl mcs51::Cover for Counts {
    #[inline(always)]
    fn ran(&mut self, pc: u16) {
        self.at(pc).runs += 1;
    }

    #[inline(always)]
    fn jumped(&mut self, pc: u16, taken: bool) {
        let c = self.at(pc);
        c.runs += 1;
        if taken {
            c.taken += 1;
        } else {
            c.not_taken += 1;
        }
    }

    fn looped(&mut self, pc: u16, times: u32, ended: bool) {
        let times = u64::from(times);
        let c = self.at(pc);
        c.runs += times;
        c.taken += times - u64::from(ended);
        c.not_taken += u64::from(ended);
    }
}

/// The instructions a run ahead executed, in order, until it is known which of them the node
/// keeps ([`Journal::apply`]). Each entry is a `u32`: the address in the low half and the kind
/// above it; a delay loop passed in closed form takes a second entry with its iterations.
#[derive(Clone, Debug, Default)]
pub(crate) struct Journal {
    entries: Vec<u32>,
}

const RAN: u32 = 0;
const FELL: u32 = 1 << 16;
const JUMPED: u32 = 2 << 16;
const LOOPED: u32 = 3 << 16;
const ENDED: u32 = 1 << 31;

impl Journal {
    /// Entries so far: a machine that ran with this journal is at this position.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn clear(&mut self) {
        self.entries.clear();
    }

    /// Adds the entries in `range` to `into`, `times` over. `range` must start and end between
    /// instructions, as machines' positions do.
    // Every instruction a node keeps passes here once: the counts are plain additions (a
    // count of 2^64 instructions is centuries of bus time), one per entry.
    pub fn apply(&self, range: Range<usize>, times: u64, into: &mut Counts) {
        if times == 0 {
            return;
        }
        let entries = self.entries.get(range).unwrap_or_default();
        let mut i = 0;
        while let Some(&e) = entries.get(i) {
            let c = into.at(e as u16);
            match e & !0xFFFF {
                RAN => c.runs += times,
                FELL => {
                    c.runs += times;
                    c.not_taken += times;
                }
                JUMPED => {
                    c.runs += times;
                    c.taken += times;
                }
                _ => {
                    i += 1;
                    let n = entries.get(i).copied().unwrap_or(0);
                    let iterations = u64::from(n & !ENDED);
                    let ended = u64::from(n & ENDED != 0);
                    c.runs += iterations * times;
                    c.taken += (iterations - ended) * times;
                    c.not_taken += ended * times;
                }
            }
            i += 1;
        }
    }
}

impl mcs51::Cover for Journal {
    #[inline(always)]
    fn ran(&mut self, pc: u16) {
        self.entries.push(u32::from(pc) | RAN);
    }

    #[inline(always)]
    fn jumped(&mut self, pc: u16, taken: bool) {
        self.entries
            .push(u32::from(pc) | if taken { JUMPED } else { FELL });
    }

    fn looped(&mut self, pc: u16, times: u32, ended: bool) {
        self.entries.push(u32::from(pc) | LOOPED);
        self.entries.push(times | if ended { ENDED } else { 0 });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mcs51::Cover;

    #[test]
    fn a_journal_applied_counts_as_running_directly() {
        let (mut direct, mut journal) = (Counts::default(), Journal::default());
        let steps: [(u16, u8); 5] = [(0x10, 0), (0x12, 1), (0x12, 2), (0x300, 3), (0x12, 4)];
        for (pc, kind) in steps {
            match kind {
                0 => {
                    direct.ran(pc);
                    journal.ran(pc);
                }
                1 | 2 => {
                    direct.jumped(pc, kind == 2);
                    journal.jumped(pc, kind == 2);
                }
                3 => {
                    direct.looped(pc, 200, true);
                    journal.looped(pc, 200, true);
                }
                _ => {
                    direct.looped(pc, 7, false);
                    journal.looped(pc, 7, false);
                }
            }
        }
        let mut applied = Counts::default();
        journal.apply(0..journal.len(), 1, &mut applied);
        assert_eq!(applied, direct);
        // The loop at 300h: 200 runs, 199 back, the last through.
        assert_eq!(
            applied.get(0x300),
            Count {
                runs: 200,
                taken: 199,
                not_taken: 1
            }
        );
        // Three times over, from the second entry: 0x10 is left out.
        let mut thrice = Counts::default();
        journal.apply(1..journal.len(), 3, &mut thrice);
        assert_eq!(thrice.get(0x10), Count::default());
        assert_eq!(
            thrice.get(0x12),
            Count {
                runs: 3 * 9,
                taken: 3 * 8,
                not_taken: 3
            }
        );
    }
}
