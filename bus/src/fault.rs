//! Fault confinement of one CAN node: its transmit and receive error counters (TEC, REC) and the
//! error state they imply, rule by rule after the Bosch CAN 2.0 specification (rules 1–11 of the
//! project's fact sheet).
//!
//! [`FaultConfinement`] is a pure, deterministic state machine. The caller (the hub, which sees
//! every bit time) reports what happened on the bus from this node's point of view, one method
//! per rule, and gets back the [`Changes`] it should announce (state transitions and crossings of
//! the warning limit). There is no clock: bus-off recovery advances only on the recessive bits
//! the caller reports, and [`FaultConfinement::recovery_bits_remaining`] says how long an idle
//! bus must stay recessive for the node to come back, so a simulator can schedule it exactly.
//!
//! Calling contract:
//! - Report each error once, after the error flag it caused has been sent: exception 3a depends
//!   on what the node saw while sending its passive error flag.
//! - The error state is never stored, it is read off the counters (rules 9 and 10), so it cannot
//!   disagree with them: bus off iff TEC >= 256, else error passive iff TEC >= 128 or REC >= 128,
//!   else error active.
//! - While bus off the node takes no part in bus activity: every input except the recovery inputs
//!   ([`recessive_bits`](FaultConfinement::recessive_bits),
//!   [`recessive_sequence`](FaultConfinement::recessive_sequence),
//!   [`dominant_bit`](FaultConfinement::dominant_bit)) and [`reset`](FaultConfinement::reset) is
//!   ignored, and both counters keep the values they had when the node went bus off until
//!   recovery sets them to 0. Outside bus off the recovery inputs are ignored.
//!
//! Where the specification leaves a choice, this module makes one and names it in a constant:
//! - Warning level (rule 11): a counter *reaches or exceeds* the limit (`>=`), which is how the
//!   SJA1000 sets its ES bit against EWLR and how Linux compares with
//!   `CAN_ERROR_WARNING_THRESHOLD` (96). With the default limit, 96 is a warning and 95 is not.
//! - Rule 8 above 127: REC is set to [`REC_AFTER_PASSIVE_RECEPTION`] = 119, the lower end of the
//!   permitted 119..=127.
//! - REC saturates at [`REC_MAX`] = 255, what an 8-bit RXERR register can show; above 127 its
//!   exact value changes nothing, since rule 8 resets it to 119 on the next good reception.
//! - TEC stops counting at bus off, so it ends between 256 and 263 and never overflows.

use serde::{Deserialize, Serialize};

/// The warning limit after power-up, the SJA1000's EWLR reset value.
pub const DEFAULT_WARNING_LIMIT: u8 = 96;
/// A counter at or above this makes the node error passive (rule 9).
pub const PASSIVE_LIMIT: u16 = 128;
/// TEC at or above this makes the node bus off (rule 10).
pub const BUS_OFF_LIMIT: u16 = 256;
/// The value rule 8 gives REC when a frame is received while REC is above 127. The specification
/// allows 119 to 127; this is the lower end, so a node leaving error passive this way always
/// lands on the same counter.
pub const REC_AFTER_PASSIVE_RECEPTION: u16 = 119;
/// REC never counts past this (the range of an 8-bit RXERR register).
pub const REC_MAX: u16 = 255;
/// Occurrences of [`RECOVERY_SEQUENCE_BITS`] consecutive recessive bits a bus-off node must see
/// before it is error active again (rule 10).
pub const RECOVERY_SEQUENCES: u8 = 128;
/// Length in bits of one recovery sequence of consecutive recessive bits (rule 10).
pub const RECOVERY_SEQUENCE_BITS: u32 = 11;

/// The penalty of rules 2–6.
const PENALTY: u16 = 8;

/// The error state of a node (rules 9 and 10).
#[derive(Clone, Copy, PartialEq, Eq, Debug, Hash, Serialize, Deserialize)]
pub enum ErrorState {
    /// Takes full part in bus communication and signals errors with an active (dominant) flag.
    Active,
    /// Still communicates but signals errors with a passive (recessive) flag, which cannot
    /// destroy other nodes' frames.
    Passive,
    /// Takes no part in bus activity until recovery.
    BusOff,
}

impl core::fmt::Display for ErrorState {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            ErrorState::Active => "error active",
            ErrorState::Passive => "error passive",
            ErrorState::BusOff => "bus off",
        })
    }
}

/// The kind of error a transmitter detected (rule 3).
#[derive(Clone, Copy, PartialEq, Eq, Debug, Hash, Serialize, Deserialize)]
pub enum TxErrorKind {
    /// The bit read back differs from the bit sent (outside arbitration and the ACK slot).
    Bit,
    /// Six equal bits in a row where stuffing applies.
    Stuff,
    /// A CRC mismatch. Normally only receivers detect it; it is accepted here for completeness
    /// and counts like any other transmit error.
    Crc,
    /// A fixed-form bit field held an illegal bit.
    Form,
    /// No receiver drove the ACK slot dominant.
    Ack,
}

/// What a transmitter knows about an error it signalled, enough for the state machine to decide
/// the exceptions of rule 3 itself.
///
/// Build it with [`TransmitError::new`] and set the flags that apply with struct update syntax:
/// `TransmitError { dominant_during_passive_flag: true, ..TransmitError::new(TxErrorKind::Ack) }`.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Hash, Serialize, Deserialize)]
pub struct TransmitError {
    /// The kind of error detected.
    pub kind: TxErrorKind,
    /// A dominant bit was seen while the node sent its passive error flag. Only meaningful for an
    /// error-passive node (an error-active node sends a dominant flag); decides exception 3a.
    pub dominant_during_passive_flag: bool,
    /// The error was detected during arbitration on a stuff bit sent recessive and read back
    /// dominant. Only meaningful for [`TxErrorKind::Stuff`]; decides exception 3b.
    pub in_arbitration_on_recessive_stuff_bit: bool,
}

impl TransmitError {
    /// An error of `kind` with neither exception's circumstances present.
    pub const fn new(kind: TxErrorKind) -> TransmitError {
        TransmitError {
            kind,
            dominant_during_passive_flag: false,
            in_arbitration_on_recessive_stuff_bit: false,
        }
    }
}

/// The kind of flag a node sent before a run of dominant bits (rule 6).
#[derive(Clone, Copy, PartialEq, Eq, Debug, Hash, Serialize, Deserialize)]
pub enum ErrorFlag {
    /// An active error flag or an overload flag: 6 dominant bits.
    Active,
    /// A passive error flag: 6 recessive bits.
    Passive,
}

impl ErrorFlag {
    /// The consecutive dominant bit that brings the first rule-6 penalty, as the specification
    /// counts: the 14th from the start of an active flag (its own six bits included, so the
    /// 8th after it), the 8th after a passive flag. Each further 8 bits bring another. Either
    /// way the first penalty falls on the 8th dominant bit after the flag.
    pub const fn first_penalty_bit(self) -> u32 {
        match self {
            ErrorFlag::Active => 14,
            ErrorFlag::Passive => 8,
        }
    }

    /// How many rule-6 penalties a run of `bits` consecutive dominant bits brings, counted as
    /// [`first_penalty_bit`](ErrorFlag::first_penalty_bit) counts (from the start of an active
    /// flag, from the end of a passive one): 0 below it, then one more every 8 bits.
    pub const fn penalties(self, bits: u32) -> u32 {
        let first = self.first_penalty_bit();
        if bits < first { 0 } else { 1 + (bits - first) / 8 }
    }
}

/// The node's part in the frame during which an error occurred (rule 6).
#[derive(Clone, Copy, PartialEq, Eq, Debug, Hash, Serialize, Deserialize)]
pub enum Role {
    /// The node was sending the frame: penalties go to TEC.
    Transmitter,
    /// The node was receiving the frame: penalties go to REC.
    Receiver,
}

/// A change of error state.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Hash, Serialize, Deserialize)]
pub struct Transition {
    /// The state before the input.
    pub from: ErrorState,
    /// The state after it; never equal to `from`.
    pub to: ErrorState,
}

impl Transition {
    /// True for the return from bus off to error active (recovery or reset).
    pub fn is_recovery(&self) -> bool {
        self.from == ErrorState::BusOff && self.to == ErrorState::Active
    }
}

/// A crossing of the warning limit (rule 11).
#[derive(Clone, Copy, PartialEq, Eq, Debug, Hash, Serialize, Deserialize)]
pub enum WarningChange {
    /// A counter reached the warning limit while neither had before.
    Entered,
    /// Both counters are below the warning limit again.
    Left,
}

/// What one input changed, for the caller to turn into events. Both parts can be present: a
/// rule-6 run can cross the warning limit and the passive limit at once, and recovery from bus
/// off also leaves the warning level.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default, Hash, Serialize, Deserialize)]
pub struct Changes {
    /// The change of error state, if any.
    pub transition: Option<Transition>,
    /// The crossing of the warning limit, if any.
    pub warning: Option<WarningChange>,
}

impl Changes {
    /// Nothing changed.
    pub const NONE: Changes = Changes {
        transition: None,
        warning: None,
    };

    /// True when nothing worth announcing changed.
    pub fn is_empty(&self) -> bool {
        self.transition.is_none() && self.warning.is_none()
    }

    /// The new error state, if it changed.
    pub fn new_state(&self) -> Option<ErrorState> {
        self.transition.map(|t| t.to)
    }

    fn between(before: (ErrorState, bool), after: (ErrorState, bool)) -> Changes {
        Changes {
            transition: (before.0 != after.0).then_some(Transition {
                from: before.0,
                to: after.0,
            }),
            warning: match (before.1, after.1) {
                (false, true) => Some(WarningChange::Entered),
                (true, false) => Some(WarningChange::Left),
                _ => None,
            },
        }
    }
}

/// The fault-confinement state of one CAN node. See the module documentation for the calling
/// contract.
#[derive(Clone, PartialEq, Eq, Debug, Hash)]
pub struct FaultConfinement {
    tec: u16,
    rec: u16,
    warning_limit: u8,
    /// Recovery sequences seen since the node went bus off; 0 whenever it is not bus off.
    recovery_seen: u8,
    /// Recessive bits of the current run that do not yet make up a whole sequence (always below
    /// [`RECOVERY_SEQUENCE_BITS`]); 0 whenever the node is not bus off.
    recovery_run: u32,
    /// The rules count nothing (a controller in listen-only mode: SJA1000 data sheet 6.4.3,
    /// MOD.LOM, "the error counters are stopped at the current value").
    frozen: bool,
}

impl Default for FaultConfinement {
    /// Error active, both counters 0, the default warning limit.
    fn default() -> Self {
        FaultConfinement::with_warning_limit(DEFAULT_WARNING_LIMIT)
    }
}

impl FaultConfinement {
    /// A node after power-up: error active, both counters 0, warning limit 96.
    pub fn new() -> FaultConfinement {
        FaultConfinement::default()
    }

    /// A node after power-up with another warning limit (the SJA1000's EWLR).
    pub fn with_warning_limit(warning_limit: u8) -> FaultConfinement {
        FaultConfinement {
            tec: 0,
            rec: 0,
            warning_limit,
            recovery_seen: 0,
            recovery_run: 0,
            frozen: false,
        }
    }

    /// Stops the counting rules (1 to 8) at the current values, or lets them count again. The
    /// host's writes ([`FaultConfinement::set_counters`]), a reset and bus-off recovery still
    /// act.
    pub fn set_frozen(&mut self, frozen: bool) {
        self.frozen = frozen;
    }

    /// True while the counting rules are stopped ([`FaultConfinement::set_frozen`]).
    pub fn is_frozen(&self) -> bool {
        self.frozen
    }

    /// The transmit error counter: 0–255 outside bus off, 256–263 while bus off.
    pub fn tec(&self) -> u16 {
        self.tec
    }

    /// The receive error counter, 0–255.
    pub fn rec(&self) -> u16 {
        self.rec
    }

    /// The warning limit the counters are compared with.
    pub fn warning_limit(&self) -> u8 {
        self.warning_limit
    }

    /// The error state the counters imply (rules 9 and 10).
    pub fn state(&self) -> ErrorState {
        if self.tec >= BUS_OFF_LIMIT {
            ErrorState::BusOff
        } else if self.tec >= PASSIVE_LIMIT || self.rec >= PASSIVE_LIMIT {
            ErrorState::Passive
        } else {
            ErrorState::Active
        }
    }

    /// True when either counter has reached or exceeded the warning limit (`>=`, as the
    /// SJA1000's ES bit). Always true while bus off, whose TEC is above any limit.
    pub fn is_warning(&self) -> bool {
        let limit = u16::from(self.warning_limit);
        self.tec >= limit || self.rec >= limit
    }

    /// Recovery sequences (11 consecutive recessive bits) seen since the node went bus off,
    /// 0–127; 0 when it is not bus off.
    pub fn recovery_progress(&self) -> u8 {
        self.recovery_seen
    }

    /// Recessive bits of the current run that do not yet make a whole sequence (0 to 10).
    pub fn recovery_run(&self) -> u32 {
        self.recovery_run
    }

    /// How many more consecutive recessive bits, continuing the current run, would bring a
    /// bus-off node back to error active: `(128 - recovery_progress()) * 11` minus the bits of
    /// the current run already counted towards the next sequence. 0 when the node is not bus
    /// off.
    pub fn recovery_bits_remaining(&self) -> u32 {
        if self.state() != ErrorState::BusOff {
            return 0;
        }
        let sequences = u32::from(RECOVERY_SEQUENCES - self.recovery_seen);
        sequences * RECOVERY_SEQUENCE_BITS - self.recovery_run
    }

    /// Rule 1: the node, as a receiver, detected an error: REC +1.
    ///
    /// A bit error while sending an active error flag or overload flag is not reported here but
    /// with [`receive_flag_bit_error`](FaultConfinement::receive_flag_bit_error) (rule 5).
    pub fn receive_error(&mut self) -> Changes {
        self.counting(|fc| fc.add_rec(1))
    }

    /// Rule 2: the node, as a receiver, saw a dominant bit as the first bit after sending its
    /// own error flag: REC +8.
    ///
    /// That bit also starts the run of dominant bits that rule 6 counts; report the run with
    /// [`dominant_bits_after_flag`](FaultConfinement::dominant_bits_after_flag) as well.
    pub fn receive_error_dominant_after_flag(&mut self) -> Changes {
        self.counting(|fc| fc.add_rec(PENALTY))
    }

    /// Rule 3: the node, as a transmitter, sent an error flag: TEC +8, except
    /// - (3a) when the node is error passive, the error is an ACK error and no dominant bit was
    ///   seen during its passive error flag, and
    /// - (3b) for a stuff error during arbitration on a stuff bit sent recessive and read back
    ///   dominant,
    ///
    /// in which cases TEC is unchanged. Call it once the flag has been sent. The node's state
    /// for 3a is the one it had when it detected the error, i.e. the state before this call.
    pub fn transmit_error(&mut self, error: TransmitError) -> Changes {
        let exception_3a = self.state() == ErrorState::Passive
            && error.kind == TxErrorKind::Ack
            && !error.dominant_during_passive_flag;
        let exception_3b = error.kind == TxErrorKind::Stuff && error.in_arbitration_on_recessive_stuff_bit;
        if exception_3a || exception_3b {
            return Changes::NONE;
        }
        self.counting(|fc| fc.add_tec(PENALTY))
    }

    /// Rule 4: the node, as a transmitter, detected a bit error while sending an active error
    /// flag or an overload flag: TEC +8.
    pub fn transmit_flag_bit_error(&mut self) -> Changes {
        self.counting(|fc| fc.add_tec(PENALTY))
    }

    /// Rule 5: the node, as a receiver, detected a bit error while sending an active error flag
    /// or an overload flag: REC +8.
    pub fn receive_flag_bit_error(&mut self) -> Changes {
        self.counting(|fc| fc.add_rec(PENALTY))
    }

    /// Rule 6: the node saw a run of `bits` consecutive dominant bits with its `flag` (an
    /// overload flag counts as [`ErrorFlag::Active`]). Each penalty adds 8 to TEC for a
    /// [`Role::Transmitter`] or to REC for a [`Role::Receiver`]; there is one penalty at the
    /// 14th dominant bit counted from the start of an active flag (the 8th after a passive one)
    /// and one more at each further 8th bit, so with an active flag 13 bits bring none, 14–21
    /// one, 22–29 two.
    ///
    /// `bits` is the length of the whole run as counted so far; nothing is remembered between
    /// calls, so a caller that applies penalties as they fall (the bus engine) passes
    /// [`ErrorFlag::first_penalty_bit`] once per penalty. Penalties are applied one at a time
    /// and stop when the node goes bus off.
    pub fn dominant_bits_after_flag(&mut self, bits: u32, flag: ErrorFlag, role: Role) -> Changes {
        // 33 penalties take TEC from 0 to bus off and 32 take REC from 0 to its cap, so a longer
        // run changes nothing more: bounding the loop keeps a huge `bits` cheap.
        let penalties = flag.penalties(bits).min(33);
        self.counting(|fc| {
            for _ in 0..penalties {
                if fc.state() == ErrorState::BusOff {
                    break;
                }
                match role {
                    Role::Transmitter => fc.add_tec(PENALTY),
                    Role::Receiver => fc.add_rec(PENALTY),
                }
            }
        })
    }

    /// Rule 7: the node transmitted a frame successfully (ACK received, no error up to the end
    /// of EOF): TEC -1, not below 0.
    pub fn transmit_success(&mut self) -> Changes {
        // The common case on a healthy bus: nothing to count down, nothing can change.
        if self.tec == 0 {
            return Changes::NONE;
        }
        self.counting(|fc| fc.tec = fc.tec.saturating_sub(1))
    }

    /// Rule 8: the node received a frame successfully (no error up to the ACK slot, and the ACK
    /// bit sent): REC -1 when it is 1–127, set to [`REC_AFTER_PASSIVE_RECEPTION`] (119) when it
    /// is above 127, unchanged at 0.
    pub fn receive_success(&mut self) -> Changes {
        if self.rec == 0 {
            return Changes::NONE;
        }
        self.counting(|fc| {
            fc.rec = if fc.rec >= PASSIVE_LIMIT {
                REC_AFTER_PASSIVE_RECEPTION
            } else {
                fc.rec.saturating_sub(1)
            }
        })
    }

    /// Rule 10, recovery: a bus-off node saw `bits` more consecutive recessive bits on the bus.
    ///
    /// They continue the run of the previous `recessive_bits` call unless
    /// [`dominant_bit`](FaultConfinement::dominant_bit) was reported in between, so a run may be
    /// reported in pieces: every 11 bits of a run count as one sequence, and the remainder
    /// below 11 waits for the next piece. A caller that reports each run whole in one call gets
    /// exactly `floor(run / 11)` sequences per run provided it reports a dominant bit between
    /// runs. After the 128th sequence the node is error active with both counters 0; bits beyond
    /// it are not carried over. Ignored when the node is not bus off.
    pub fn recessive_bits(&mut self, bits: u32) -> Changes {
        self.recovering(|fc| {
            // Saturating: a run near u32::MAX is far more than recovery needs anyway.
            let run = fc.recovery_run.saturating_add(bits);
            let sequences = run / RECOVERY_SEQUENCE_BITS;
            fc.recovery_run = run % RECOVERY_SEQUENCE_BITS;
            fc.add_recovery_sequences(sequences);
        })
    }

    /// Rule 10, recovery: a bus-off node saw one complete sequence of 11 consecutive recessive
    /// bits, for a caller that detects the sequences itself. The partial run of
    /// [`recessive_bits`](FaultConfinement::recessive_bits) is left as it is. Ignored when the
    /// node is not bus off.
    pub fn recessive_sequence(&mut self) -> Changes {
        self.recovering(|fc| fc.add_recovery_sequences(1))
    }

    /// A bus-off node saw a dominant bit: the run of recessive bits is broken and its bits not
    /// yet making a whole sequence are dropped. Sequences already counted stay counted (they
    /// need not be back to back). Changes nothing else, and nothing when the node is not bus
    /// off.
    pub fn dominant_bit(&mut self) {
        self.recovery_run = 0;
    }

    /// The host writes the counters (the SJA1000's TXERR and RXERR in reset mode): TEC 256 or
    /// more puts the node bus off with no recovery counted yet; a TEC below 256 written while
    /// bus off ends bus off. Values are clamped to 256 (TEC) and 255 (REC).
    pub fn set_counters(&mut self, tec: u16, rec: u16) -> Changes {
        self.observe(|fc| {
            fc.tec = tec.min(BUS_OFF_LIMIT);
            fc.rec = rec.min(255);
            fc.recovery_seen = 0;
            fc.recovery_run = 0;
        })
    }

    /// A controller reset: error active, both counters 0, recovery forgotten, counting on. The
    /// warning limit is configuration and is kept.
    pub fn reset(&mut self) -> Changes {
        self.observe(|fc| *fc = FaultConfinement::with_warning_limit(fc.warning_limit))
    }

    /// Applies `update` and reports what it changed.
    fn observe(&mut self, update: impl FnOnce(&mut Self)) -> Changes {
        let before = (self.state(), self.is_warning());
        update(self);
        Changes::between(before, (self.state(), self.is_warning()))
    }

    /// Applies a counter update unless the node is bus off, where counting stops.
    fn counting(&mut self, update: impl FnOnce(&mut Self)) -> Changes {
        if self.frozen || self.state() == ErrorState::BusOff {
            return Changes::NONE;
        }
        self.observe(update)
    }

    /// Applies a recovery update only while the node is bus off.
    fn recovering(&mut self, update: impl FnOnce(&mut Self)) -> Changes {
        if self.state() != ErrorState::BusOff {
            return Changes::NONE;
        }
        self.observe(update)
    }

    fn add_tec(&mut self, amount: u16) {
        // Counting stops at bus off, so TEC never exceeds 255 + 8; saturating is belt and braces.
        self.tec = self.tec.saturating_add(amount);
    }

    fn add_rec(&mut self, amount: u16) {
        self.rec = self.rec.saturating_add(amount).min(REC_MAX);
    }

    fn add_recovery_sequences(&mut self, sequences: u32) {
        let seen = u32::from(self.recovery_seen).saturating_add(sequences);
        if seen >= u32::from(RECOVERY_SEQUENCES) {
            *self = FaultConfinement::with_warning_limit(self.warning_limit);
        } else {
            // Below 128 here, so the conversion cannot fail.
            self.recovery_seen = u8::try_from(seen).unwrap_or(RECOVERY_SEQUENCES - 1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const ALL_KINDS: [TxErrorKind; 5] = [
        TxErrorKind::Bit,
        TxErrorKind::Stuff,
        TxErrorKind::Crc,
        TxErrorKind::Form,
        TxErrorKind::Ack,
    ];

    fn transition(from: ErrorState, to: ErrorState) -> Option<Transition> {
        Some(Transition { from, to })
    }

    /// A node (default warning limit) whose counters were brought to `tec` (below 256) and
    /// `rec` through ordinary inputs: rule 1 for REC, rules 4 and 7 for TEC.
    fn node(tec: u16, rec: u16) -> FaultConfinement {
        let mut fc = FaultConfinement::new();
        for _ in 0..rec {
            fc.receive_error();
        }
        let mut current = 0;
        while current + 8 <= tec {
            fc.transmit_flag_bit_error();
            current += 8;
        }
        let rest = tec - current;
        if rest > 0 {
            // Reach the odd value by stepping down first and up by 8 last, so that TEC never
            // passes above the target (it could otherwise touch 256 on the way to 255).
            if current >= 8 - rest {
                for _ in 0..8 - rest {
                    fc.transmit_success();
                }
                fc.transmit_flag_bit_error();
            } else {
                fc.transmit_flag_bit_error();
                for _ in 0..8 - rest {
                    fc.transmit_success();
                }
            }
        }
        assert_eq!((fc.tec(), fc.rec()), (tec, rec), "test setup");
        fc
    }

    /// A node that has just gone bus off with TEC exactly 256.
    fn bus_off() -> FaultConfinement {
        let mut fc = node(248, 0);
        fc.transmit_flag_bit_error();
        assert_eq!((fc.tec(), fc.state()), (256, ErrorState::BusOff), "test setup");
        fc
    }

    #[test]
    fn power_up_is_error_active_with_zero_counters() {
        let fc = FaultConfinement::default();
        assert_eq!(fc, FaultConfinement::new());
        assert_eq!(fc, FaultConfinement::with_warning_limit(96));
        assert_eq!((fc.tec(), fc.rec()), (0, 0));
        assert_eq!(fc.state(), ErrorState::Active);
        assert!(!fc.is_warning());
        assert_eq!(fc.warning_limit(), 96);
        assert_eq!(fc.recovery_progress(), 0);
        assert_eq!(fc.recovery_bits_remaining(), 0);
    }

    #[test]
    fn rule_1_receive_error_adds_one() {
        for start in [0, 5, 126, 200, 254] {
            let mut fc = node(0, start);
            fc.receive_error();
            assert_eq!(fc.rec(), start + 1, "from {start}");
            assert_eq!(fc.tec(), 0);
        }
        let mut fc = node(0, 127);
        let changes = fc.receive_error();
        assert_eq!(fc.rec(), 128);
        assert_eq!(
            changes.transition,
            transition(ErrorState::Active, ErrorState::Passive)
        );
        // REC saturates rather than overflows.
        let mut fc = node(0, 255);
        assert!(fc.receive_error().is_empty());
        assert_eq!(fc.rec(), 255);
    }

    #[test]
    fn rule_2_dominant_bit_after_own_flag_adds_eight() {
        let mut fc = node(3, 10);
        fc.receive_error_dominant_after_flag();
        assert_eq!((fc.tec(), fc.rec()), (3, 18));
        let mut fc = node(0, 250);
        fc.receive_error_dominant_after_flag();
        assert_eq!(fc.rec(), 255);
    }

    #[test]
    fn rule_3_transmit_error_adds_eight() {
        for kind in ALL_KINDS {
            let mut fc = node(16, 4);
            fc.transmit_error(TransmitError::new(kind));
            assert_eq!((fc.tec(), fc.rec()), (24, 4), "{kind:?} while active");
        }
        for kind in [
            TxErrorKind::Bit,
            TxErrorKind::Stuff,
            TxErrorKind::Crc,
            TxErrorKind::Form,
        ] {
            let mut fc = node(130, 0);
            fc.transmit_error(TransmitError::new(kind));
            assert_eq!(fc.tec(), 138, "{kind:?} while passive");
        }
    }

    #[test]
    fn rule_3a_passive_ack_error_without_dominant_bit_is_free() {
        let ack = TransmitError::new(TxErrorKind::Ack);

        // The exception itself: error passive (through TEC or through REC alone).
        for (tec, rec) in [(128, 0), (200, 0), (0, 128), (5, 255)] {
            let mut fc = node(tec, rec);
            assert_eq!(fc.transmit_error(ack), Changes::NONE);
            assert_eq!((fc.tec(), fc.rec()), (tec, rec));
        }

        // Not while error active, even at the last step before passive.
        for tec in [0, 127] {
            let mut fc = node(tec, 0);
            fc.transmit_error(ack);
            assert_eq!(fc.tec(), tec + 8);
        }

        // Not when a dominant bit was seen during the passive flag.
        let mut fc = node(128, 0);
        fc.transmit_error(TransmitError {
            dominant_during_passive_flag: true,
            ..ack
        });
        assert_eq!(fc.tec(), 136);

        // Not for another kind of error, even with no dominant bit seen.
        let mut fc = node(128, 0);
        fc.transmit_error(TransmitError::new(TxErrorKind::Form));
        assert_eq!(fc.tec(), 136);
    }

    #[test]
    fn rule_3b_stuff_error_on_recessive_stuff_bit_in_arbitration_is_free() {
        let in_arbitration = TransmitError {
            in_arbitration_on_recessive_stuff_bit: true,
            ..TransmitError::new(TxErrorKind::Stuff)
        };
        for (tec, rec) in [(0, 0), (100, 0), (130, 0), (0, 200)] {
            let mut fc = node(tec, rec);
            assert_eq!(fc.transmit_error(in_arbitration), Changes::NONE);
            assert_eq!((fc.tec(), fc.rec()), (tec, rec));
        }

        // A stuff error elsewhere counts.
        let mut fc = node(0, 0);
        fc.transmit_error(TransmitError::new(TxErrorKind::Stuff));
        assert_eq!(fc.tec(), 8);

        // The arbitration circumstance excuses only a stuff error.
        for kind in [TxErrorKind::Bit, TxErrorKind::Form, TxErrorKind::Crc] {
            let mut fc = node(0, 0);
            fc.transmit_error(TransmitError {
                kind,
                ..in_arbitration
            });
            assert_eq!(fc.tec(), 8, "{kind:?}");
        }
    }

    #[test]
    fn rule_4_transmitter_bit_error_in_flag_adds_eight_to_tec() {
        for (tec, rec) in [(0, 0), (10, 3), (130, 7)] {
            let mut fc = node(tec, rec);
            fc.transmit_flag_bit_error();
            assert_eq!((fc.tec(), fc.rec()), (tec + 8, rec));
        }
    }

    #[test]
    fn rule_5_receiver_bit_error_in_flag_adds_eight_to_rec() {
        for (tec, rec) in [(0, 0), (10, 3), (7, 130)] {
            let mut fc = node(tec, rec);
            fc.receive_flag_bit_error();
            assert_eq!((fc.tec(), fc.rec()), (tec, rec + 8));
        }
    }

    /// Rule 6 by enumeration: the penalty points are the `first`th dominant bit and every 8th
    /// after it; count those the run reaches.
    fn penalties_by_counting(bits: u32, flag: ErrorFlag) -> u16 {
        let first = match flag {
            ErrorFlag::Active => 14,
            ErrorFlag::Passive => 8,
        };
        (first..=bits).step_by(8).count() as u16
    }

    #[test]
    fn rule_6_dominant_bits_after_flag() {
        let table = [
            (ErrorFlag::Active, 0, 0),
            (ErrorFlag::Active, 13, 0),
            (ErrorFlag::Active, 14, 8),
            (ErrorFlag::Active, 21, 8),
            (ErrorFlag::Active, 22, 16),
            (ErrorFlag::Active, 30, 24),
            (ErrorFlag::Passive, 7, 0),
            (ErrorFlag::Passive, 8, 8),
            (ErrorFlag::Passive, 15, 8),
            (ErrorFlag::Passive, 16, 16),
        ];
        for (flag, bits, added) in table {
            let mut tx = node(1, 2);
            tx.dominant_bits_after_flag(bits, flag, Role::Transmitter);
            assert_eq!((tx.tec(), tx.rec()), (1 + added, 2), "{flag:?} {bits}");
            let mut rx = node(1, 2);
            rx.dominant_bits_after_flag(bits, flag, Role::Receiver);
            assert_eq!((rx.tec(), rx.rec()), (1, 2 + added), "{flag:?} {bits}");
        }
        for flag in [ErrorFlag::Active, ErrorFlag::Passive] {
            for bits in 0..=120 {
                let mut rx = FaultConfinement::new();
                rx.dominant_bits_after_flag(bits, flag, Role::Receiver);
                assert_eq!(rx.rec(), 8 * penalties_by_counting(bits, flag));
            }
        }
    }

    #[test]
    fn rule_6_stops_at_bus_off_and_saturates() {
        // Six penalties are due, but the first one already takes the node bus off.
        let mut fc = node(250, 0);
        fc.dominant_bits_after_flag(14 + 5 * 8, ErrorFlag::Active, Role::Transmitter);
        assert_eq!((fc.tec(), fc.state()), (258, ErrorState::BusOff));

        let mut fc = FaultConfinement::new();
        fc.dominant_bits_after_flag(u32::MAX, ErrorFlag::Passive, Role::Transmitter);
        assert_eq!((fc.tec(), fc.state()), (256, ErrorState::BusOff));

        let mut fc = FaultConfinement::new();
        fc.dominant_bits_after_flag(u32::MAX, ErrorFlag::Active, Role::Receiver);
        assert_eq!((fc.rec(), fc.state()), (255, ErrorState::Passive));
    }

    #[test]
    fn rule_7_transmit_success_subtracts_one_not_below_zero() {
        let mut fc = node(0, 0);
        assert!(fc.transmit_success().is_empty());
        assert_eq!(fc.tec(), 0);
        let mut fc = node(9, 4);
        fc.transmit_success();
        assert_eq!((fc.tec(), fc.rec()), (8, 4));
    }

    #[test]
    fn rule_8_receive_success() {
        for (start, expected) in [(0, 0), (1, 0), (50, 49), (127, 126)] {
            let mut fc = node(3, start);
            fc.receive_success();
            assert_eq!((fc.tec(), fc.rec()), (3, expected), "from {start}");
        }
        assert!((119..=127).contains(&REC_AFTER_PASSIVE_RECEPTION));
        for start in [128, 129, 200, 255] {
            let mut fc = node(0, start);
            let changes = fc.receive_success();
            assert_eq!(fc.rec(), 119, "from {start}");
            assert_eq!(
                changes.transition,
                transition(ErrorState::Passive, ErrorState::Active)
            );
            // 119 is still at the default warning level.
            assert_eq!(changes.warning, None);
        }
        // With TEC passive too, the node stays error passive.
        let mut fc = node(130, 200);
        assert_eq!(fc.receive_success(), Changes::NONE);
        assert_eq!((fc.rec(), fc.state()), (119, ErrorState::Passive));
    }

    #[test]
    fn rule_9_passive_at_128_active_again_at_127() {
        // TEC alone: 127 is active, 120 + 8 = 128 is passive.
        let mut fc = node(119, 0);
        let changes = fc.transmit_flag_bit_error();
        assert_eq!((fc.tec(), fc.state()), (127, ErrorState::Active));
        assert_eq!(changes.transition, None);
        let mut fc = node(120, 0);
        let changes = fc.transmit_error(TransmitError::new(TxErrorKind::Bit));
        assert_eq!((fc.tec(), fc.state()), (128, ErrorState::Passive));
        assert_eq!(
            changes.transition,
            transition(ErrorState::Active, ErrorState::Passive)
        );

        let mut fc = node(128, 0);
        assert_eq!(fc.state(), ErrorState::Passive);
        let changes = fc.transmit_success();
        assert_eq!((fc.tec(), fc.state()), (127, ErrorState::Active));
        assert_eq!(
            changes.transition,
            transition(ErrorState::Passive, ErrorState::Active)
        );

        // REC alone.
        let mut fc = node(0, 127);
        assert_eq!(fc.state(), ErrorState::Active);
        fc.receive_error();
        assert_eq!((fc.rec(), fc.state()), (128, ErrorState::Passive));

        // Both: active again only when both are at most 127.
        let mut fc = node(128, 128);
        assert_eq!(fc.transmit_success(), Changes::NONE);
        assert_eq!((fc.tec(), fc.state()), (127, ErrorState::Passive));
        let changes = fc.receive_success();
        assert_eq!((fc.rec(), fc.state()), (119, ErrorState::Active));
        assert_eq!(
            changes.transition,
            transition(ErrorState::Passive, ErrorState::Active)
        );
    }

    #[test]
    fn rule_10_bus_off_at_256() {
        let mut fc = node(255, 0);
        assert_eq!(fc.state(), ErrorState::Passive);
        let changes = fc.transmit_error(TransmitError::new(TxErrorKind::Bit));
        assert_eq!((fc.tec(), fc.state()), (263, ErrorState::BusOff));
        assert_eq!(
            changes,
            Changes {
                transition: transition(ErrorState::Passive, ErrorState::BusOff),
                warning: None,
            }
        );

        // 32 penalties from 0: the 31st leaves 248 (passive), the 32nd exactly 256.
        let mut fc = FaultConfinement::new();
        for _ in 0..31 {
            fc.transmit_flag_bit_error();
        }
        assert_eq!((fc.tec(), fc.state()), (248, ErrorState::Passive));
        fc.transmit_flag_bit_error();
        assert_eq!((fc.tec(), fc.state()), (256, ErrorState::BusOff));
        assert_eq!(fc.recovery_progress(), 0);
        assert_eq!(fc.recovery_bits_remaining(), 128 * 11);
        // The warning level is never left while bus off.
        assert!(fc.is_warning());
    }

    #[test]
    fn bus_off_node_counts_nothing() {
        let mut fc = node(248, 60);
        fc.transmit_flag_bit_error();
        assert_eq!(fc.state(), ErrorState::BusOff);
        let frozen = fc.clone();
        let mut results = vec![
            fc.receive_error(),
            fc.receive_error_dominant_after_flag(),
            fc.transmit_flag_bit_error(),
            fc.receive_flag_bit_error(),
            fc.dominant_bits_after_flag(100, ErrorFlag::Active, Role::Transmitter),
            fc.dominant_bits_after_flag(100, ErrorFlag::Passive, Role::Receiver),
            fc.transmit_success(),
            fc.receive_success(),
        ];
        for kind in ALL_KINDS {
            results.push(fc.transmit_error(TransmitError::new(kind)));
        }
        assert!(results.iter().all(Changes::is_empty));
        assert_eq!(fc, frozen);
        assert_eq!((fc.tec(), fc.rec()), (256, 60));
    }

    #[test]
    fn recovery_after_128_sequences() {
        let mut fc = node(248, 77);
        fc.transmit_flag_bit_error();
        for seen in 1..=127u8 {
            assert!(fc.recessive_sequence().is_empty());
            assert_eq!(fc.recovery_progress(), seen);
        }
        assert_eq!(fc.state(), ErrorState::BusOff);
        assert_eq!(fc.recovery_bits_remaining(), 11);
        let changes = fc.recessive_sequence();
        assert_eq!((fc.tec(), fc.rec(), fc.state()), (0, 0, ErrorState::Active));
        assert_eq!(
            changes,
            Changes {
                transition: transition(ErrorState::BusOff, ErrorState::Active),
                warning: Some(WarningChange::Left),
            }
        );
        assert!(changes.transition.is_some_and(|t| t.is_recovery()));
        assert_eq!(fc.recovery_progress(), 0);
        assert_eq!(fc.recovery_bits_remaining(), 0);
    }

    #[test]
    fn recovery_needs_128_times_11_recessive_bits() {
        let mut fc = bus_off();
        assert!(fc.recessive_bits(128 * 11 - 1).is_empty());
        assert_eq!(fc.state(), ErrorState::BusOff);
        assert_eq!(fc.recovery_progress(), 127);
        assert_eq!(fc.recovery_bits_remaining(), 1);
        let changes = fc.recessive_bits(1);
        assert_eq!(changes.new_state(), Some(ErrorState::Active));
        assert_eq!((fc.tec(), fc.rec()), (0, 0));

        let mut fc = bus_off();
        fc.recessive_bits(128 * 11);
        assert_eq!(fc.state(), ErrorState::Active);

        // More than enough recovers just the same, and nothing is carried over.
        let mut fc = bus_off();
        fc.recessive_bits(u32::MAX);
        assert_eq!(fc, FaultConfinement::new());
    }

    #[test]
    fn recovery_run_may_be_reported_in_pieces() {
        let mut fc = bus_off();
        let needed = 128 * 11;
        let mut total = 0;
        while total + 5 < needed {
            fc.recessive_bits(5);
            total += 5;
            assert_eq!(u32::from(fc.recovery_progress()), total / 11);
            assert_eq!(fc.recovery_bits_remaining(), needed - total);
            assert_eq!(fc.state(), ErrorState::BusOff);
        }
        fc.recessive_bits(needed - total);
        assert_eq!(fc.state(), ErrorState::Active);
    }

    #[test]
    fn dominant_bit_breaks_the_run_but_keeps_sequences() {
        let mut fc = bus_off();
        fc.recessive_bits(10);
        fc.dominant_bit();
        fc.recessive_bits(10);
        assert_eq!(fc.recovery_progress(), 0);
        assert_eq!(fc.recovery_bits_remaining(), 128 * 11 - 10);
        fc.recessive_bits(1);
        assert_eq!(fc.recovery_progress(), 1);

        // Sequences need not be back to back.
        let mut fc = bus_off();
        for _ in 0..127 {
            fc.recessive_bits(11 + 7);
            fc.dominant_bit();
        }
        assert_eq!(fc.recovery_progress(), 127);
        fc.recessive_bits(10);
        fc.dominant_bit();
        assert_eq!(fc.state(), ErrorState::BusOff);
        fc.recessive_bits(11);
        assert_eq!(fc.state(), ErrorState::Active);
    }

    #[test]
    fn recovery_inputs_are_ignored_unless_bus_off() {
        let mut fc = node(200, 10);
        let before = fc.clone();
        assert!(fc.recessive_bits(10_000).is_empty());
        assert!(fc.recessive_sequence().is_empty());
        fc.recessive_bits(5);
        fc.dominant_bit();
        assert_eq!(fc, before);
        assert_eq!(fc.recovery_bits_remaining(), 0);

        // A later bus off starts its recovery from scratch.
        for _ in 0..7 {
            fc.transmit_flag_bit_error();
        }
        assert_eq!(fc.state(), ErrorState::BusOff);
        assert_eq!(fc.recovery_bits_remaining(), 128 * 11);
    }

    #[test]
    fn warning_level_at_exactly_the_limit() {
        let mut fc = node(0, 95);
        assert!(!fc.is_warning());
        let changes = fc.receive_error();
        assert_eq!(fc.rec(), 96);
        assert!(fc.is_warning());
        assert_eq!(
            changes,
            Changes {
                transition: None,
                warning: Some(WarningChange::Entered),
            }
        );
        assert_eq!(fc.receive_success().warning, Some(WarningChange::Left));
        assert!(!fc.is_warning());

        let mut fc = node(88, 0);
        assert!(!fc.is_warning());
        assert_eq!(fc.transmit_flag_bit_error().warning, Some(WarningChange::Entered));
        assert_eq!(fc.tec(), 96);
        assert_eq!(fc.transmit_success().warning, Some(WarningChange::Left));
        assert_eq!(fc.tec(), 95);

        // Either counter is enough; leaving needs both below.
        let mut fc = node(96, 96);
        assert_eq!(fc.transmit_success().warning, None);
        assert_eq!(fc.receive_success().warning, Some(WarningChange::Left));
    }

    #[test]
    fn warning_limit_is_configurable() {
        let mut fc = FaultConfinement::with_warning_limit(100);
        for _ in 0..99 {
            fc.receive_error();
        }
        assert!(!fc.is_warning());
        assert_eq!(fc.receive_error().warning, Some(WarningChange::Entered));

        // Above the passive limit, a node can be passive without a warning.
        let mut fc = FaultConfinement::with_warning_limit(200);
        for _ in 0..16 {
            fc.transmit_flag_bit_error();
        }
        assert_eq!(
            (fc.tec(), fc.state(), fc.is_warning()),
            (128, ErrorState::Passive, false)
        );

        // One rule-6 run can cross the warning and the passive limit at once.
        let mut fc = FaultConfinement::new();
        let changes = fc.dominant_bits_after_flag(8 + 15 * 8, ErrorFlag::Passive, Role::Receiver);
        assert_eq!(fc.rec(), 128);
        assert_eq!(
            changes,
            Changes {
                transition: transition(ErrorState::Active, ErrorState::Passive),
                warning: Some(WarningChange::Entered),
            }
        );
    }

    #[test]
    fn lone_transmitter_goes_passive_but_never_bus_off() {
        // Nobody acknowledges and nobody else drives the bus: every attempt ends in an ACK error
        // with no dominant bit during a passive flag, and the frame is retransmitted for ever.
        let mut fc = FaultConfinement::new();
        let mut transitions = Vec::new();
        let mut warnings = Vec::new();
        for _ in 0..10_000 {
            let changes = fc.transmit_error(TransmitError::new(TxErrorKind::Ack));
            transitions.extend(changes.transition);
            warnings.extend(changes.warning);
            assert_ne!(fc.state(), ErrorState::BusOff);
        }
        // 16 penalties of 8 reach 128; from then on exception 3a applies.
        assert_eq!(fc.tec(), 16 * 8);
        assert_eq!(fc.state(), ErrorState::Passive);
        assert_eq!(
            transitions,
            [Transition {
                from: ErrorState::Active,
                to: ErrorState::Passive,
            }]
        );
        assert_eq!(warnings, [WarningChange::Entered]);
    }

    #[test]
    fn reset_returns_to_power_up_state_keeping_the_limit() {
        let mut fc = bus_off();
        fc.recessive_bits(100);
        let changes = fc.reset();
        assert_eq!(fc, FaultConfinement::new());
        assert_eq!(
            changes,
            Changes {
                transition: transition(ErrorState::BusOff, ErrorState::Active),
                warning: Some(WarningChange::Left),
            }
        );

        let mut fc = FaultConfinement::with_warning_limit(50);
        for _ in 0..30 {
            fc.receive_flag_bit_error();
        }
        assert_eq!(fc.state(), ErrorState::Passive);
        fc.reset();
        assert_eq!(fc, FaultConfinement::with_warning_limit(50));
        assert_eq!(fc.reset(), Changes::NONE);
    }

    #[test]
    fn state_names() {
        assert_eq!(ErrorState::Active.to_string(), "error active");
        assert_eq!(ErrorState::Passive.to_string(), "error passive");
        assert_eq!(ErrorState::BusOff.to_string(), "bus off");
    }

    #[derive(Clone, Debug)]
    enum Input {
        ReceiveError,
        ReceiveDominantAfterFlag,
        TransmitError(TransmitError),
        TransmitFlagBitError,
        ReceiveFlagBitError,
        DominantRun(u32, ErrorFlag, Role),
        TransmitSuccess,
        ReceiveSuccess,
        RecessiveBits(u32),
        RecessiveSequence,
        DominantBit,
        Reset,
    }

    impl Input {
        fn is_recovery(&self) -> bool {
            matches!(
                self,
                Input::RecessiveBits(_) | Input::RecessiveSequence | Input::DominantBit | Input::Reset
            )
        }

        fn apply(&self, fc: &mut FaultConfinement) -> Changes {
            match *self {
                Input::ReceiveError => fc.receive_error(),
                Input::ReceiveDominantAfterFlag => fc.receive_error_dominant_after_flag(),
                Input::TransmitError(error) => fc.transmit_error(error),
                Input::TransmitFlagBitError => fc.transmit_flag_bit_error(),
                Input::ReceiveFlagBitError => fc.receive_flag_bit_error(),
                Input::DominantRun(bits, flag, role) => fc.dominant_bits_after_flag(bits, flag, role),
                Input::TransmitSuccess => fc.transmit_success(),
                Input::ReceiveSuccess => fc.receive_success(),
                Input::RecessiveBits(bits) => fc.recessive_bits(bits),
                Input::RecessiveSequence => fc.recessive_sequence(),
                Input::DominantBit => {
                    fc.dominant_bit();
                    Changes::NONE
                }
                Input::Reset => fc.reset(),
            }
        }
    }

    fn input() -> impl Strategy<Value = Input> {
        let kind = prop::sample::select(ALL_KINDS.to_vec());
        let flag = prop_oneof![Just(ErrorFlag::Active), Just(ErrorFlag::Passive)];
        let role = prop_oneof![Just(Role::Transmitter), Just(Role::Receiver)];
        prop_oneof![
            4 => Just(Input::ReceiveError),
            1 => Just(Input::ReceiveDominantAfterFlag),
            6 => (kind, any::<bool>(), any::<bool>()).prop_map(|(kind, dominant, arbitration)| {
                Input::TransmitError(TransmitError {
                    kind,
                    dominant_during_passive_flag: dominant,
                    in_arbitration_on_recessive_stuff_bit: arbitration,
                })
            }),
            2 => Just(Input::TransmitFlagBitError),
            2 => Just(Input::ReceiveFlagBitError),
            1 => (0u32..60, flag, role).prop_map(|(bits, flag, role)| Input::DominantRun(bits, flag, role)),
            4 => Just(Input::TransmitSuccess),
            4 => Just(Input::ReceiveSuccess),
            3 => (0u32..400).prop_map(Input::RecessiveBits),
            2 => Just(Input::RecessiveSequence),
            1 => Just(Input::DominantBit),
            1 => Just(Input::Reset),
        ]
    }

    /// The state rules 9 and 10 give for these counters, written out separately from the code.
    fn expected_state(tec: u16, rec: u16) -> ErrorState {
        match (tec, rec) {
            (256.., _) => ErrorState::BusOff,
            (128.., _) | (_, 128..) => ErrorState::Passive,
            _ => ErrorState::Active,
        }
    }

    proptest! {
        #[test]
        fn invariants_hold_for_any_inputs(
            limit in any::<u8>(),
            inputs in prop::collection::vec(input(), 0..400),
        ) {
            let mut fc = FaultConfinement::with_warning_limit(limit);
            for input in &inputs {
                let before = fc.clone();
                let changes = input.apply(&mut fc);

                prop_assert!(fc.tec() <= 263);
                prop_assert!(fc.rec() <= 255);
                prop_assert_eq!(fc.state(), expected_state(fc.tec(), fc.rec()));
                let limit = u16::from(limit);
                prop_assert_eq!(fc.is_warning(), fc.tec() >= limit || fc.rec() >= limit);
                prop_assert_eq!(fc.warning_limit(), before.warning_limit());

                // The reported changes are exactly the differences.
                let expected_transition = (before.state() != fc.state()).then_some(Transition {
                    from: before.state(),
                    to: fc.state(),
                });
                prop_assert_eq!(changes.transition, expected_transition);
                let expected_warning = match (before.is_warning(), fc.is_warning()) {
                    (false, true) => Some(WarningChange::Entered),
                    (true, false) => Some(WarningChange::Left),
                    _ => None,
                };
                prop_assert_eq!(changes.warning, expected_warning);

                if fc.state() == ErrorState::BusOff {
                    prop_assert!(fc.recovery_progress() < 128);
                    let whole = (128 - u32::from(fc.recovery_progress())) * 11;
                    let remaining = fc.recovery_bits_remaining();
                    prop_assert!(remaining <= whole && whole - remaining < 11);
                } else {
                    prop_assert_eq!(fc.recovery_progress(), 0);
                    prop_assert_eq!(fc.recovery_bits_remaining(), 0);
                }

                // A bus-off node's counters move only by recovery or reset.
                if before.state() == ErrorState::BusOff && !input.is_recovery() {
                    prop_assert_eq!(&fc, &before);
                }
                // Leaving bus off always lands on the power-up state.
                if before.state() == ErrorState::BusOff && fc.state() != ErrorState::BusOff {
                    prop_assert_eq!(&fc, &FaultConfinement::with_warning_limit(before.warning_limit()));
                }
            }
        }

        #[test]
        fn recovery_counts_like_a_bit_by_bit_reference(
            pieces in prop::collection::vec(prop::option::weighted(0.8, 0u32..40), 0..600),
        ) {
            let mut fc = bus_off();
            // Reference: walk the bits one at a time.
            let (mut run, mut sequences) = (0u32, 0u32);
            for piece in pieces {
                match piece {
                    Some(bits) => {
                        fc.recessive_bits(bits);
                        for _ in 0..bits {
                            run += 1;
                            if run == 11 {
                                run = 0;
                                sequences += 1;
                            }
                        }
                    }
                    None => {
                        fc.dominant_bit();
                        run = 0;
                    }
                }
                if sequences >= 128 {
                    prop_assert_eq!(&fc, &FaultConfinement::new());
                    break;
                }
                prop_assert_eq!(fc.state(), ErrorState::BusOff);
                prop_assert_eq!(u32::from(fc.recovery_progress()), sequences);
                prop_assert_eq!(fc.recovery_bits_remaining(), (128 - sequences) * 11 - run);
            }
        }
    }
}
