//! One controller's protocol state machine, a bit at a time, as the Bosch CAN 2.0 specification
//! (part B, sections 6 and 7) and ISO 11898-1 describe it: frame decoding with destuffing and
//! the CRC check, error and overload flags, delimiters, intermission, suspend transmission and
//! bus off.
//!
//! [`Mac::drive`] says what the controller puts on the bus for the next bit; the bus takes the
//! wired AND of every controller's level, a disturbance may change what one controller samples,
//! and [`Mac::sample`] takes the sampled level and says what the controller detected
//! ([`Detected`]). The caller (the episode runner) applies the fault-confinement rules and
//! records events: this module counts nothing, so every counting decision lives in one place.
//!
//! Levels are `bool`s, `true` for recessive (1), as in [`crate::bits::BitStream`].

use super::inject::{Field, Place};
use crate::bits::BitStream;

/// Recessive.
pub(crate) const REC: bool = true;
/// Dominant.
pub(crate) const DOM: bool = false;

/// Length of an active error flag and of an overload flag.
pub(crate) const FLAG_BITS: u8 = 6;
/// Error and overload delimiter.
pub(crate) const DELIMITER_BITS: u8 = 8;
/// Intermission.
pub(crate) const INTERMISSION_BITS: u8 = 3;
/// Suspend transmission of an error-passive transmitter.
pub(crate) const SUSPEND_BITS: u8 = 8;

/// Where in a frame or error frame something happened, as SocketCAN's `CAN_ERR_PROT_LOC_*`
/// names the places.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, serde::Serialize)]
pub enum Location {
    /// Start of frame.
    Sof,
    /// Identifier bits 28..21 (the first eight bits of identifier A).
    Id28To21,
    /// Identifier bits 20..18.
    Id20To18,
    /// The SRR bit of an extended frame (or the RTR bit of a base frame).
    Srtr,
    /// The IDE bit.
    Ide,
    /// Identifier bits 17..13.
    Id17To13,
    /// Identifier bits 12..5.
    Id12To05,
    /// Identifier bits 4..0.
    Id04To00,
    /// The RTR bit of an extended frame.
    Rtr,
    /// Reserved bit r1.
    Res1,
    /// Reserved bit r0.
    Res0,
    /// Data length code.
    Dlc,
    /// Data field.
    Data,
    /// CRC sequence.
    CrcSeq,
    /// CRC delimiter.
    CrcDel,
    /// ACK slot.
    Ack,
    /// ACK delimiter.
    AckDel,
    /// End of frame.
    Eof,
    /// Intermission.
    Intermission,
    /// An error or overload flag.
    Flag,
    /// An error or overload delimiter.
    Delimiter,
    /// Anywhere else.
    Unspecified,
}

impl Location {
    /// The `CAN_ERR_PROT_LOC_*` value of `linux/can/error.h`.
    pub fn socketcan(self) -> u8 {
        match self {
            Location::Sof => 0x03,
            Location::Id28To21 => 0x02,
            Location::Id20To18 => 0x06,
            Location::Srtr => 0x04,
            Location::Ide => 0x05,
            Location::Id17To13 => 0x07,
            Location::Id12To05 => 0x0F,
            Location::Id04To00 => 0x0E,
            Location::Rtr => 0x0C,
            Location::Res1 => 0x0D,
            Location::Res0 => 0x09,
            Location::Dlc => 0x0B,
            Location::Data => 0x0A,
            Location::CrcSeq => 0x08,
            Location::CrcDel => 0x18,
            Location::Ack => 0x19,
            Location::AckDel => 0x1B,
            Location::Eof => 0x1A,
            Location::Intermission => 0x12,
            Location::Flag | Location::Delimiter | Location::Unspecified => 0x00,
        }
    }
}

/// Where the tail of a frame is, counted from the bit after the stuffed part.
pub(crate) mod tail {
    /// CRC delimiter.
    pub const CRC_DEL: u8 = 0;
    /// ACK slot.
    pub const ACK: u8 = 1;
    /// ACK delimiter.
    pub const ACK_DEL: u8 = 2;
    /// First EOF bit; EOF bit n is `EOF + n - 1`.
    pub const EOF: u8 = 3;
    /// The last but one EOF bit: a receiver takes the frame once it has passed.
    pub const EOF6: u8 = EOF + 5;
    /// The last EOF bit.
    pub const EOF7: u8 = EOF + 6;
}

/// A receiver's view of the frame on the bus: destuffing, fields, CRC.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Decoder {
    /// Unstuffed bits taken so far, SOF included.
    n: u32,
    /// Level and length of the current run of equal bits (for stuffing).
    last: bool,
    run: u8,
    ide: bool,
    rtr: bool,
    dlc: u8,
    /// Unstuffed bits from SOF to the last CRC bit, once the DLC is known (0 before).
    end: u32,
    crc: u16,
    rx_crc: u16,
    /// Position in the tail, once the stuffed part is over.
    pub tail: Option<u8>,
    crc_ok: bool,
    /// Stuff bits taken so far.
    stuffs: u16,
}

/// What one sampled bit was to a decoder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Decoded {
    /// A bit of the frame, nothing wrong.
    Bit,
    /// Six equal bits where stuffing applies.
    StuffError,
    /// A fixed-form bit was dominant.
    FormError,
}

impl Decoder {
    /// A decoder that has just taken a SOF bit.
    pub fn after_sof() -> Decoder {
        Decoder {
            n: 1,
            last: DOM,
            run: 1,
            ..Decoder::default()
        }
    }

    /// The next bit is a stuff bit.
    pub fn expects_stuff_bit(&self) -> bool {
        self.tail.is_none() && self.run == 5
    }

    /// Unstuffed index the next data bit will have (SOF is 0).
    pub fn next_index(&self) -> u32 {
        self.n
    }

    /// The CRC sequence matched (known from the end of the CRC field).
    pub fn crc_ok(&self) -> bool {
        self.crc_ok
    }

    /// The field the next bit belongs to.
    pub fn location(&self) -> Location {
        if let Some(t) = self.tail {
            return match t {
                tail::CRC_DEL => Location::CrcDel,
                tail::ACK => Location::Ack,
                tail::ACK_DEL => Location::AckDel,
                _ => Location::Eof,
            };
        }
        let i = self.n;
        let known = i > 13;
        if known && self.end > 0 && i >= self.end - 15 {
            return Location::CrcSeq;
        }
        match i {
            0 => Location::Sof,
            1..=8 => Location::Id28To21,
            9..=11 => Location::Id20To18,
            12 => Location::Srtr,
            13 => Location::Ide,
            _ if !self.ide => match i {
                14 => Location::Res0,
                15..=18 => Location::Dlc,
                _ => Location::Data,
            },
            14..=18 => Location::Id17To13,
            19..=26 => Location::Id12To05,
            27..=31 => Location::Id04To00,
            32 => Location::Rtr,
            33 => Location::Res1,
            34 => Location::Res0,
            35..=38 => Location::Dlc,
            _ => Location::Data,
        }
    }

    /// The field and bit the next bit is, as a disturbance names them; `extended` says what
    /// the frame on the bus is while the decoder cannot know yet (its bit 12, before IDE).
    pub fn place(&self, extended: bool) -> Place {
        let at = |field, bit: u32| Place {
            field,
            bit: u16::try_from(bit).unwrap_or(u16::MAX),
        };
        if let Some(t) = self.tail {
            return match t {
                tail::CRC_DEL => at(Field::CrcDelimiter, 0),
                tail::ACK => at(Field::AckSlot, 0),
                tail::ACK_DEL => at(Field::AckDelimiter, 0),
                t => at(Field::Eof, u32::from(t - tail::EOF)),
            };
        }
        if self.expects_stuff_bit() {
            return at(Field::StuffBit, u32::from(self.stuffs));
        }
        let i = self.n;
        if self.end > 0 && i >= self.end - 15 {
            return at(Field::Crc, i - (self.end - 15));
        }
        let ext = if i > 13 { self.ide } else { extended };
        match i {
            0 => at(Field::Sof, 0),
            1..=11 => at(Field::Identifier, i - 1),
            12 if ext => at(Field::Srr, 0),
            12 => at(Field::Rtr, 0),
            13 => at(Field::Ide, 0),
            _ if !ext => match i {
                14 => at(Field::Reserved, 0),
                15..=18 => at(Field::Dlc, i - 15),
                _ => at(Field::Data, i - 19),
            },
            14..=31 => at(Field::Identifier, i - 3),
            32 => at(Field::Rtr, 0),
            33 | 34 => at(Field::Reserved, i - 33),
            35..=38 => at(Field::Dlc, i - 35),
            _ => at(Field::Data, i - 39),
        }
    }

    /// First unstuffed index of the DLC.
    fn dlc_start(&self) -> u32 {
        if self.ide { 35 } else { 15 }
    }

    /// Takes one sampled bit.
    pub fn feed(&mut self, bit: bool) -> Decoded {
        if let Some(t) = self.tail {
            self.tail = Some(t.saturating_add(1));
            let fixed = matches!(t, tail::CRC_DEL | tail::ACK_DEL) || (tail::EOF..=tail::EOF6).contains(&t);
            return if fixed && bit == DOM {
                Decoded::FormError
            } else {
                Decoded::Bit
            };
        }
        if self.run == 5 {
            // A stuff bit: it must differ from the run it ends.
            if bit == self.last {
                return Decoded::StuffError;
            }
            self.last = bit;
            self.run = 1;
            self.stuffs = self.stuffs.saturating_add(1);
            if self.end > 0 && self.n == self.end {
                self.tail = Some(tail::CRC_DEL);
            }
            return Decoded::Bit;
        }
        if bit == self.last && self.run > 0 {
            self.run += 1;
        } else {
            self.last = bit;
            self.run = 1;
        }
        let i = self.n;
        self.n += 1;
        let b = u16::from(bit);
        let in_crc = self.end > 0 && i >= self.end - 15;
        if in_crc {
            self.rx_crc = (self.rx_crc << 1) | b;
        } else {
            // CRC-15 (x^15 + x^14 + x^10 + x^8 + x^7 + x^4 + x^3 + 1), bit-serial, from zero.
            let top = ((self.crc >> 14) & 1) ^ b;
            self.crc = (self.crc << 1) & 0x7FFF;
            if top == 1 {
                self.crc ^= 0x4599;
            }
        }
        match i {
            12 => self.rtr = bit,
            13 => self.ide = bit,
            32 if self.ide => self.rtr = bit,
            _ => {}
        }
        let dlc_start = self.dlc_start();
        if i > 13 && (dlc_start..dlc_start + 4).contains(&i) {
            self.dlc = (self.dlc << 1) | u8::from(bit);
            if i == dlc_start + 3 {
                let bytes = if self.rtr { 0 } else { u32::from(self.dlc.min(8)) };
                self.end = dlc_start + 4 + 8 * bytes + 15;
            }
        }
        if self.end > 0 && self.n == self.end {
            self.crc_ok = self.crc == self.rx_crc;
            if self.run < 5 {
                self.tail = Some(tail::CRC_DEL);
            }
        }
        Decoded::Bit
    }
}

/// The phase of a controller's protocol state machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Phase {
    /// The bus is idle: a dominant bit is a start of frame.
    Idle,
    /// In a frame, transmitting or receiving.
    Frame,
    /// Sending an error flag, `sent` bits of it so far: an active one ends after six; a passive
    /// one after six equal bits (`run` of `last`), and remembers whether it saw a dominant bit
    /// (exception 3a).
    ErrorFlag {
        active: bool,
        sent: u8,
        last: bool,
        run: u8,
        saw_dominant: bool,
    },
    /// Sending an overload flag.
    OverloadFlag { sent: u8 },
    /// A flag has been sent; sending recessive and waiting for a recessive bit. `dominant`
    /// counts the dominant bits seen since the flag (rules 2 and 6).
    AfterFlag {
        error: bool,
        active: bool,
        dominant: u32,
    },
    /// `done` bits of an error (`error`) or overload delimiter seen (the first is the recessive
    /// bit that ended [`Phase::AfterFlag`]).
    Delimiter { done: u8, error: bool },
    /// `done` bits of intermission seen.
    Intermission { done: u8 },
    /// `done` bits of suspend transmission seen.
    Suspend { done: u8 },
}

/// What a controller detected at one bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Detected {
    /// Nothing to report.
    Nothing,
    /// A start of frame from another controller: it is now a receiver.
    Sof,
    /// It lost arbitration at this bit of the arbitration field (0 = the first identifier bit,
    /// the numbering of the SJA1000's ALC register) and is now a receiver.
    LostArbitration(u16),
    /// An error in a frame or a delimiter: its error flag starts at the next bit.
    Error(Found),
    /// A CRC error: its flag starts at the next bit (the one after the ACK delimiter).
    CrcError,
    /// A bit error while sending an active error flag or an overload flag (rules 4 and 5).
    FlagBitError,
    /// A receiver took the frame (no error up to the last but one EOF bit).
    Received,
    /// A transmitter sent the frame (no error up to the end of EOF).
    Sent,
    /// Its overload flag starts at the next bit.
    Overload,
    /// It finished an error flag (passive ones end here; exception 3a is decided now).
    FlagDone { saw_dominant: bool },
    /// A dominant bit right after its error flag (rule 2 for a receiver).
    DominantAfterFlag,
    /// Another 8 consecutive dominant bits after its flag (rule 6).
    DominantRun,
}

/// An error found in a frame or delimiter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Found {
    pub kind: crate::fault::TxErrorKind,
    pub location: Location,
    /// Exception 3b: a stuff bit sent recessive in the arbitration field, read dominant.
    pub arbitration_stuff: bool,
}

/// The frame a transmitter is sending.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sending {
    pub stuffed: BitStream,
    /// Unstuffed index of its last arbitration bit (RTR): 12 base, 32 extended.
    pub arbitration_end: u32,
}

/// One controller's protocol state.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Mac {
    pub phase: Phase,
    /// The frame it is sending, while it is a transmitter of the frame on the bus.
    pub sending: Option<Sending>,
    /// It was a transmitter when the current frame began (for suspend transmission and for
    /// whose counter rule 6 raises), even if it has lost arbitration since.
    pub transmitter: bool,
    /// It is the transmitter of the current frame, or was until an error ended it: the role
    /// rules 2 to 6 count by. Losing arbitration makes it a receiver.
    pub tx_role: bool,
    pub dec: Decoder,
    /// It takes part in acknowledging.
    pub acks: bool,
    /// Listen-only: it drives nothing dominant. Its error flags are passive ones (ISO 11898-1's
    /// bus monitoring mode sends only recessive bits), and an overload condition makes it wait
    /// for the bus to be recessive as after a flag.
    pub silent: bool,
    /// Its own frames need no acknowledge (self-test mode): a recessive ACK slot is no error.
    pub presume_ack: bool,
    /// Overload frames it still sends after this frame (a receiver that is not ready).
    pub overloads: u8,
    /// Stuffed bits of the current frame so far.
    pub pos: u32,
    /// It is error passive (set by the caller before each bit).
    pub passive: bool,
}

impl Default for Mac {
    fn default() -> Self {
        Mac {
            phase: Phase::Idle,
            sending: None,
            transmitter: false,
            tx_role: false,
            dec: Decoder::default(),
            acks: true,
            silent: false,
            presume_ack: false,
            overloads: 0,
            pos: 0,
            passive: false,
        }
    }
}

impl Mac {
    /// Starts transmitting `sending` with this bit as its SOF.
    pub fn start(&mut self, sending: Sending) {
        self.phase = Phase::Frame;
        self.sending = Some(sending);
        self.transmitter = true;
        self.tx_role = true;
        self.pos = 0;
        self.dec = Decoder::default();
    }

    /// True when it is past every flag and frame: only recessive bits from the bus (and a
    /// frame of its own) can make it act again, and none of them is counted by a rule.
    pub fn quiet(&self) -> bool {
        self.overloads == 0
            && matches!(
                self.phase,
                Phase::Idle
                    | Phase::Intermission { .. }
                    | Phase::Suspend { .. }
                    | Phase::Delimiter { .. }
                    | Phase::AfterFlag { .. }
            )
    }

    /// True when a dominant bit now would start a frame for it: idle, suspending, or in the
    /// last intermission bit.
    pub fn idle_for_sof(&self) -> bool {
        matches!(
            self.phase,
            Phase::Idle | Phase::Suspend { .. } | Phase::Intermission { done: 2 }
        )
    }

    /// Where it is for the next bit, as a disturbance names places: `None` where no field is
    /// (idle, suspending, waiting after its flag for a recessive bit). `sof` says the next bit
    /// is an attempt's start of frame, which a controller that is not sending takes as such only
    /// once it has read it; `extended` what that frame is (see [`Decoder::place`]).
    pub fn place(&self, sof: bool, extended: bool) -> Option<Place> {
        let at = |field, bit: u8| {
            Some(Place {
                field,
                bit: u16::from(bit),
            })
        };
        match self.phase {
            _ if sof && self.idle_for_sof() => at(Field::Sof, 0),
            Phase::Frame => Some(self.dec.place(extended)),
            Phase::ErrorFlag { sent, .. } => at(Field::ErrorFlag, sent),
            Phase::OverloadFlag { sent } => at(Field::OverloadFlag, sent),
            Phase::AfterFlag {
                error, dominant: 0, ..
            } => at(delimiter(error), 0),
            Phase::Delimiter { done, error } => at(delimiter(error), done),
            Phase::Intermission { done } => at(Field::Intermission, done),
            Phase::Idle | Phase::Suspend { .. } | Phase::AfterFlag { .. } => None,
        }
    }

    /// The level it drives for the next bit.
    pub fn drive(&self) -> bool {
        if self.silent {
            return REC;
        }
        match self.phase {
            Phase::Frame => match (&self.sending, self.dec.tail) {
                (Some(s), None) => s.stuffed.get(self.pos as usize).unwrap_or(REC),
                (Some(_), Some(_)) => REC,
                (None, Some(tail::ACK)) => !(self.acks && self.dec.crc_ok()),
                (None, _) => REC,
            },
            Phase::ErrorFlag { active, .. } => !active,
            Phase::OverloadFlag { .. } => DOM,
            _ => REC,
        }
    }

    fn signal_error(&mut self, found: Found) -> Detected {
        // A receiver that is not ready has no frame to delay any more.
        self.overloads = 0;
        self.enter_flag();
        Detected::Error(found)
    }

    /// Its error flag starts at the next bit, active or passive by its state now.
    pub fn enter_flag(&mut self) {
        self.phase = Phase::ErrorFlag {
            active: !self.passive,
            sent: 0,
            last: REC,
            run: 0,
            saw_dominant: false,
        };
    }

    fn become_receiver(&mut self) {
        self.phase = Phase::Frame;
        self.sending = None;
        self.transmitter = false;
        self.tx_role = false;
        self.pos = 1;
        self.dec = Decoder::after_sof();
    }

    /// Takes the level it sampled for the bit it drove `sent` on.
    pub fn sample(&mut self, sent: bool, bit: bool) -> Detected {
        if self.silent && matches!(self.phase, Phase::OverloadFlag { .. }) {
            // A silent controller sends no overload flag: it waits for a recessive bit, as
            // after a flag, and counts nothing meanwhile.
            self.phase = Phase::AfterFlag {
                error: false,
                active: false,
                dominant: 0,
            };
        }
        match self.phase {
            Phase::Idle => {
                if bit == DOM {
                    self.become_receiver();
                    Detected::Sof
                } else {
                    Detected::Nothing
                }
            }
            Phase::Suspend { done } => {
                if bit == DOM {
                    self.become_receiver();
                    return Detected::Sof;
                }
                self.phase = if done + 1 >= SUSPEND_BITS {
                    Phase::Idle
                } else {
                    Phase::Suspend { done: done + 1 }
                };
                Detected::Nothing
            }
            Phase::Frame => self.sample_frame(sent, bit),
            Phase::ErrorFlag {
                active: true,
                sent: n,
                ..
            } => {
                if bit == REC {
                    self.enter_flag();
                    return Detected::FlagBitError;
                }
                if n + 1 == FLAG_BITS {
                    self.phase = Phase::AfterFlag {
                        error: true,
                        active: true,
                        dominant: 0,
                    };
                    Detected::FlagDone { saw_dominant: true }
                } else {
                    self.phase = Phase::ErrorFlag {
                        active: true,
                        sent: n + 1,
                        last: DOM,
                        run: n + 1,
                        saw_dominant: true,
                    };
                    Detected::Nothing
                }
            }
            Phase::ErrorFlag {
                active: false,
                sent,
                last,
                run,
                saw_dominant,
            } => {
                let run = if run > 0 && bit == last { run + 1 } else { 1 };
                let saw_dominant = saw_dominant || bit == DOM;
                if run == FLAG_BITS {
                    self.phase = Phase::AfterFlag {
                        error: true,
                        active: false,
                        dominant: 0,
                    };
                    Detected::FlagDone { saw_dominant }
                } else {
                    self.phase = Phase::ErrorFlag {
                        active: false,
                        sent: sent.saturating_add(1),
                        last: bit,
                        run,
                        saw_dominant,
                    };
                    Detected::Nothing
                }
            }
            Phase::OverloadFlag { sent: n } => {
                if bit == REC {
                    self.enter_flag();
                    return Detected::FlagBitError;
                }
                self.phase = if n + 1 == FLAG_BITS {
                    Phase::AfterFlag {
                        error: false,
                        active: true,
                        dominant: 0,
                    }
                } else {
                    Phase::OverloadFlag { sent: n + 1 }
                };
                Detected::Nothing
            }
            Phase::AfterFlag {
                error,
                active,
                dominant,
            } => {
                if bit == REC {
                    self.phase = Phase::Delimiter { done: 1, error };
                    return Detected::Nothing;
                }
                let dominant = dominant + 1;
                self.phase = Phase::AfterFlag {
                    error,
                    active,
                    dominant,
                };
                if dominant.is_multiple_of(8) {
                    Detected::DominantRun
                } else if dominant == 1 && error {
                    Detected::DominantAfterFlag
                } else {
                    Detected::Nothing
                }
            }
            Phase::Delimiter { done, error } => {
                if bit == DOM {
                    if done + 1 == DELIMITER_BITS {
                        // Overload condition: a dominant last delimiter bit.
                        self.phase = Phase::OverloadFlag { sent: 0 };
                        return Detected::Overload;
                    }
                    return self.signal_error(Found {
                        kind: crate::fault::TxErrorKind::Form,
                        location: Location::Delimiter,
                        arbitration_stuff: false,
                    });
                }
                if done + 1 == DELIMITER_BITS {
                    self.enter_intermission()
                } else {
                    self.phase = Phase::Delimiter {
                        done: done + 1,
                        error,
                    };
                    Detected::Nothing
                }
            }
            Phase::Intermission { done } => {
                if bit == DOM {
                    if done < 2 {
                        self.phase = Phase::OverloadFlag { sent: 0 };
                        return Detected::Overload;
                    }
                    // A dominant third intermission bit is a start of frame.
                    self.become_receiver();
                    return Detected::Sof;
                }
                self.phase = if done + 1 < INTERMISSION_BITS {
                    Phase::Intermission { done: done + 1 }
                } else if std::mem::take(&mut self.transmitter) && self.passive {
                    Phase::Suspend { done: 0 }
                } else {
                    Phase::Idle
                };
                Detected::Nothing
            }
        }
    }

    /// Intermission begins at the next bit, or the overload flag of a receiver that is not
    /// ready (which may only start at the first intermission bit).
    fn enter_intermission(&mut self) -> Detected {
        if self.overloads > 0 {
            self.overloads -= 1;
            self.phase = Phase::OverloadFlag { sent: 0 };
            Detected::Overload
        } else {
            self.phase = Phase::Intermission { done: 0 };
            Detected::Nothing
        }
    }

    fn sample_frame(&mut self, sent: bool, bit: bool) -> Detected {
        let location = self.dec.location();
        let stuff_bit = self.dec.expects_stuff_bit();
        let tail = self.dec.tail;
        self.pos += 1;
        if let Some(s) = self.sending {
            let index = self.dec.next_index();
            let in_arbitration = tail.is_none() && (1..=s.arbitration_end).contains(&index);
            if tail == Some(tail::ACK) {
                if bit == REC && !self.presume_ack {
                    return self.signal_error(Found {
                        kind: crate::fault::TxErrorKind::Ack,
                        location: Location::Ack,
                        arbitration_stuff: false,
                    });
                }
            } else if sent != bit {
                if sent == REC && in_arbitration && stuff_bit {
                    return self.signal_error(Found {
                        kind: crate::fault::TxErrorKind::Stuff,
                        location,
                        arbitration_stuff: true,
                    });
                }
                if sent == REC && in_arbitration {
                    self.sending = None;
                    self.transmitter = false;
                    self.tx_role = false;
                    self.dec.feed(bit);
                    return Detected::LostArbitration(
                        u16::try_from(index.saturating_sub(1)).unwrap_or(u16::MAX),
                    );
                }
                return self.signal_error(Found {
                    kind: crate::fault::TxErrorKind::Bit,
                    location,
                    arbitration_stuff: false,
                });
            }
            self.dec.feed(bit);
            if tail == Some(tail::EOF7) {
                self.sending = None;
                return self.enter_frame_end(Detected::Sent);
            }
            return Detected::Nothing;
        }
        // A receiver: its own ACK is the only bit it drives.
        if sent == DOM && bit == REC {
            return self.signal_error(Found {
                kind: crate::fault::TxErrorKind::Bit,
                location,
                arbitration_stuff: false,
            });
        }
        match self.dec.feed(bit) {
            Decoded::StuffError => self.signal_error(Found {
                kind: crate::fault::TxErrorKind::Stuff,
                location,
                arbitration_stuff: false,
            }),
            Decoded::FormError => self.signal_error(Found {
                kind: crate::fault::TxErrorKind::Form,
                location,
                arbitration_stuff: false,
            }),
            Decoded::Bit => match tail {
                Some(tail::ACK_DEL) if !self.dec.crc_ok() => {
                    self.overloads = 0;
                    self.enter_flag();
                    Detected::CrcError
                }
                Some(tail::EOF6) => Detected::Received,
                Some(tail::EOF7) => {
                    if bit == DOM {
                        self.phase = Phase::OverloadFlag { sent: 0 };
                        self.transmitter = false;
                        Detected::Overload
                    } else {
                        self.enter_frame_end(Detected::Nothing)
                    }
                }
                _ => Detected::Nothing,
            },
        }
    }

    /// The frame is over for it: intermission (or an overload flag it owes) from the next bit.
    fn enter_frame_end(&mut self, what: Detected) -> Detected {
        let next = self.enter_intermission();
        if what == Detected::Nothing { next } else { what }
    }

    /// How many recessive bits, at most `limit`, it needs to be through its intermission (idle
    /// or suspending: the bus is free for others then).
    pub fn bits_until_bus_idle(&self, limit: u64) -> u64 {
        let mut probe = *self;
        for k in 0..limit {
            if matches!(probe.phase, Phase::Idle | Phase::Suspend { .. }) {
                return k;
            }
            probe.idle_through(1);
        }
        limit
    }

    /// Steps through `bits` recessive bits with nobody else on the bus (an idle stretch between
    /// episodes). Stops early once idle. Returns the bits it took to become idle, if it did.
    pub fn idle_through(&mut self, bits: u64) -> Option<u64> {
        for k in 0..bits {
            if self.phase == Phase::Idle {
                return Some(k);
            }
            let sent = self.drive();
            self.sample(sent, REC);
        }
        (self.phase == Phase::Idle).then_some(bits)
    }
}

/// The delimiter that follows an error flag (`error`) or an overload flag.
fn delimiter(error: bool) -> Field {
    if error {
        Field::ErrorDelimiter
    } else {
        Field::OverloadDelimiter
    }
}

/// Stuffed-bit indices that are stuff bits.
pub(crate) fn stuff_bits(stuffed: &BitStream) -> Vec<u16> {
    let mut out = Vec::new();
    let (mut last, mut run) = (DOM, 0u8);
    for (i, b) in stuffed.iter().enumerate() {
        if run == 5 {
            out.push(i as u16);
            last = b;
            run = 1;
            continue;
        }
        if run > 0 && b == last {
            run += 1;
        } else {
            last = b;
            run = 1;
        }
    }
    out
}

/// How a frame ends for a receiver.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Outcome {
    /// Received.
    Ok,
    /// A stuff error.
    Stuff,
    /// A form error.
    Form,
    /// A CRC error.
    Crc,
}

/// What a receiver makes of `stuffed` with bit `flip` inverted, followed by a correct tail
/// (acknowledged by someone else).
pub(crate) fn receiver_outcome(stuffed: &BitStream, flip: u32) -> Outcome {
    let mut dec = Decoder::after_sof();
    let n = stuffed.len() as u32;
    for i in 1..n + u32::from(tail::EOF7) + 1 {
        let mut b = if i < n {
            stuffed.get(i as usize).unwrap_or(REC)
        } else {
            i - n != u32::from(tail::ACK)
        };
        if i == flip {
            b = !b;
        }
        let tail_before = dec.tail;
        match dec.feed(b) {
            Decoded::StuffError => return Outcome::Stuff,
            Decoded::FormError => return Outcome::Form,
            Decoded::Bit => {
                if tail_before == Some(tail::ACK_DEL) && !dec.crc_ok() {
                    return Outcome::Crc;
                }
                if tail_before == Some(tail::EOF6) {
                    return Outcome::Ok;
                }
            }
        }
    }
    Outcome::Ok
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bits::encode;
    use crate::candump::parse_frame;

    #[test]
    fn a_clean_frame_decodes_with_its_crc() {
        for text in [
            "0300A0F5#0101",
            "123#R",
            "1FFFFFFF#FFFFFFFFFFFFFFFF",
            "000#",
            "7FF#00000000",
        ] {
            let f = parse_frame(text).unwrap();
            let e = encode(&f);
            assert_eq!(receiver_outcome(&e.stuffed, u32::MAX), Outcome::Ok, "{text}");
            assert_eq!(stuff_bits(&e.stuffed).len() as u32, e.stuff_bits, "{text}");
        }
    }
}
