//! The Philips (now NXP) SJA1000 stand-alone CAN controller at register level, as a sans-IO
//! model: a CPU reads and writes its registers, the bus side tells it what happened on the bus,
//! and it says what the bus must do.
//!
//! Contract:
//! - [`Sja1000::read`], [`Sja1000::peek`] and [`Sja1000::write`] take the chip's CAN address
//!   (0–31 for the registers, and in PeliCAN mode 32–108 for the internal RAM). Reads have the
//!   chip's side effects (reading IR clears it except RI, reading ALC/ECC re-arms their
//!   capture); `peek` returns the same value without them. Unassigned addresses read 00h and
//!   ignore writes. Nothing panics on any address or value.
//! - [`Sja1000::take_actions`] drains, in order, what the bus must do for this chip
//!   ([`Action`]); [`Sja1000::on_event`] takes what the bus did for it ([`BusSide`]). The chip
//!   keeps its own acceptance filter and receive FIFO: the bus hands it every frame received
//!   correctly while it is online, and the chip decides what to store.
//! - [`Sja1000::int_active`] is the level of the active-low INT pin: true while an interrupt
//!   flag that its enable bit allows is set.
//!
//! Register behaviour follows the Philips SJA1000 data sheet (product specification, 2000 Jan 04)
//! section by section; `docs/SJA1000.md` lists the register map and every choice made where the
//! data sheet leaves room. [`ecc_segment`] maps the engine's error locations to the data sheet's
//! ECC segment codes; [`BitTiming`] interprets BTR0/BTR1.

mod events;
mod fifo;
mod regs;
mod timing;

#[cfg(test)]
mod tests;

pub use fifo::{FIFO_BYTES, message_bytes};
pub use timing::BitTiming;
pub(crate) use timing::{iso_tolerance, within_tolerance};

use crate::Frame;
use crate::engine::{BusError, Location};
use crate::fault::{DEFAULT_WARNING_LIMIT, ErrorState};
use crate::filter::{Sja1000Filter, Sja1000Mode};
use fifo::RxFifo;

/// Bits of the PeliCAN mode register (MOD, address 0), data sheet 6.4.3.
pub mod mod_bits {
    /// Reset mode.
    pub const RM: u8 = 0x01;
    /// Listen only mode.
    pub const LOM: u8 = 0x02;
    /// Self test mode.
    pub const STM: u8 = 0x04;
    /// Acceptance filter mode: single filter.
    pub const AFM: u8 = 0x08;
    /// Sleep mode.
    pub const SM: u8 = 0x10;
}

/// Bits of the command register (CMR, address 1), data sheet 6.3.4 and 6.4.4.
pub mod cmr {
    /// Transmission request.
    pub const TR: u8 = 0x01;
    /// Abort transmission.
    pub const AT: u8 = 0x02;
    /// Release receive buffer.
    pub const RRB: u8 = 0x04;
    /// Clear data overrun.
    pub const CDO: u8 = 0x08;
    /// PeliCAN: self reception request. BasicCAN: go to sleep (GTS).
    pub const SRR: u8 = 0x10;
}

/// Bits of the status register (SR, address 2), data sheet 6.3.5 and 6.4.5.
pub mod sr {
    /// Receive buffer status: a message is available.
    pub const RBS: u8 = 0x01;
    /// Data overrun status.
    pub const DOS: u8 = 0x02;
    /// Transmit buffer status: released.
    pub const TBS: u8 = 0x04;
    /// Transmission complete status.
    pub const TCS: u8 = 0x08;
    /// Receive status.
    pub const RS: u8 = 0x10;
    /// Transmit status.
    pub const TS: u8 = 0x20;
    /// Error status: a counter at or above the warning limit.
    pub const ES: u8 = 0x40;
    /// Bus status: bus-off.
    pub const BS: u8 = 0x80;
}

/// Bits of the interrupt register (IR, address 3) and, in PeliCAN mode, of the interrupt
/// enable register (IER, address 4), data sheet 6.3.6, 6.4.6 and 6.4.7. BasicCAN has only the
/// low five; its enables are CR bits 1–4 (RIE, TIE, EIE, OIE).
pub mod ir {
    /// Receive interrupt.
    pub const RI: u8 = 0x01;
    /// Transmit interrupt.
    pub const TI: u8 = 0x02;
    /// Error warning interrupt.
    pub const EI: u8 = 0x04;
    /// Data overrun interrupt.
    pub const DOI: u8 = 0x08;
    /// Wake-up interrupt.
    pub const WUI: u8 = 0x10;
    /// Error passive interrupt.
    pub const EPI: u8 = 0x20;
    /// Arbitration lost interrupt.
    pub const ALI: u8 = 0x40;
    /// Bus error interrupt.
    pub const BEI: u8 = 0x80;
}

/// The register set the chip presents, chosen by bit 7 of the clock divider register.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub enum Mode {
    /// PCA82C200-compatible mode (after hardware reset): base frames only.
    BasicCan,
    /// The extended mode: base and extended frames, error counters and captures.
    PeliCan,
}

/// What the bus must do for the chip, in the order the chip asks.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Action {
    /// The CPU left reset mode (or, on the AT89C51CC03, set CANGCON.ENA): take part in the bus
    /// (after 11 recessive bits) with the counters of the last [`Action::SetCounters`] or as the
    /// bus last reported them. `filter` is the acceptance filter now in force, for the bus's own
    /// bookkeeping; the chip filters itself.
    Online {
        /// MOD.LOM: receive and never drive the bus (no ACK, no error flags).
        listen_only: bool,
        /// MOD.STM: a transmission succeeds without an acknowledge.
        self_test: bool,
        /// The single acceptance filter in force (the SJA1000's); `None` for a controller with a
        /// filter per message object, such as the AT89C51CC03 ([`crate::at89c51cc`]).
        filter: Option<Sja1000Filter>,
    },
    /// Reset mode entered (by the CPU or by bus-off): leave the bus and drop the pending frame
    /// without reporting it.
    Offline,
    /// A transmission request: send `frame` (retrying as CAN does unless `single_shot`) and answer
    /// with [`BusSide::Transmitted`] or [`BusSide::Aborted`].
    Transmit {
        /// The frame from the transmit buffer.
        frame: Frame,
        /// CMR.SRR: the chip stores its own frame if its filter passes it.
        self_reception: bool,
        /// CMR.AT given with TR or SRR: no retransmission after an error or lost arbitration.
        single_shot: bool,
    },
    /// CMR.AT: drop the pending frame if its transmission has not started.
    Abort,
    /// Sleep mode entered (true: off the bus until bus activity, answered with
    /// [`BusSide::Woken`]) or left by the CPU (false: take part again after 11 recessive bits).
    Sleep(bool),
    /// The CPU wrote TXERR or RXERR in reset mode: the node's counters are now these. A TEC of
    /// 256 is the bus-off that leaving reset mode with TXERR 255 performs (data sheet 6.4.12).
    SetCounters {
        /// Transmit error counter.
        tec: u16,
        /// Receive error counter.
        rec: u16,
    },
    /// The CPU left reset mode while bus-off: wait for 128 occurrences of 11 recessive bits
    /// (reporting [`BusSide::Counters`] as TXERR counts down and [`BusSide::RecoveryDone`] at the
    /// end), then take part in the bus as for [`Action::Online`].
    StartRecovery {
        /// MOD.LOM, as for `Online`.
        listen_only: bool,
        /// MOD.STM, as for `Online`.
        self_test: bool,
    },
}

/// What the bus did for the chip.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum BusSide {
    /// A frame was received correctly (any frame: the chip filters).
    Received(Frame),
    /// The pending frame was sent.
    Transmitted,
    /// The pending frame was dropped (abort, or a failed single-shot attempt).
    Aborted,
    /// The chip lost arbitration at this bit (the ALC code: 0 = ID28/ID10, 31 = RTR of an
    /// extended frame).
    ArbitrationLost {
        /// Bit number as ALC counts it.
        bit: u8,
    },
    /// The chip detected a bus error.
    BusError {
        /// What kind.
        error: BusError,
        /// The chip was transmitting.
        transmitting: bool,
        /// ECC segment code ([`ecc_segment`]).
        segment: u8,
    },
    /// The error counters or the error state changed.
    Counters {
        /// Transmit error counter.
        tec: u16,
        /// Receive error counter.
        rec: u16,
        /// The state they imply.
        state: ErrorState,
    },
    /// Bus-off recovery is complete.
    RecoveryDone,
    /// Asleep, the chip saw bus activity and woke (the frame that woke it is not received).
    Woken,
}

/// The ECC segment code (ECC bits 4:0, data sheet 6.4.9, Table 21) of an error at `location`.
///
/// The codes equal SocketCAN's `CAN_ERR_PROT_LOC_*` values for every field of a frame. Where the
/// engine's location is coarser than the chip's table, the nearest code is taken:
/// [`Location::Flag`] gives 11h (active error flag; the table also has passive error flag 16h,
/// tolerate dominant bits 13h and overload flag 1Ch), [`Location::Delimiter`] gives 17h (error
/// delimiter; overload delimiters have no code of their own), and [`Location::Unspecified`]
/// gives 00h, which the table does not use.
pub fn ecc_segment(location: Location) -> u8 {
    match location {
        Location::Flag => 0x11,
        Location::Delimiter => 0x17,
        other => other.socketcan(),
    }
}

/// A frame waiting in the transmit buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Pending {
    frame: Frame,
    self_reception: bool,
}

/// One SJA1000: its registers, receive FIFO and transmit buffer. See the module docs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Sja1000 {
    xtal_hz: u32,
    cdr: u8,
    /// MOD.RM / CR.RR.
    reset: bool,
    /// MOD.LOM, STM and AFM.
    mode_bits: u8,
    sleep: bool,
    /// BasicCAN CR bits 1–4 (interrupt enables) and 6.
    cr: u8,
    ier: u8,
    /// IR flags other than RI (RI follows the FIFO).
    ir: u8,
    tbs: bool,
    tcs: bool,
    dos: bool,
    /// SR.ES and SR.BS as shown (their changes raise EI).
    es: bool,
    bs: bool,
    btr0: u8,
    btr1: u8,
    ocr: u8,
    test: u8,
    acr: [u8; 4],
    amr: [u8; 4],
    ewlr: u8,
    tec: u16,
    rec: u16,
    /// Error state as last reported or implied.
    state: ErrorState,
    /// The chip is bus-off (until recovery or a TXERR write).
    bus_off: bool,
    /// Bus-off recovery under way.
    recovering: bool,
    /// The CPU wrote TXERR or RXERR since entering reset mode.
    counters_written: bool,
    alc: u8,
    alc_held: bool,
    ecc: u8,
    ecc_held: bool,
    tx: [u8; 13],
    pending: Option<Pending>,
    fifo: RxFifo,
    actions: Vec<Action>,
}

impl Sja1000 {
    /// The chip after a hardware reset, clocked by a crystal of `xtal_hz`: BasicCAN mode, reset
    /// mode, the reset values of data sheet Tables 2 and 5 (see `docs/SJA1000.md` for the
    /// registers the data sheet leaves undefined).
    pub fn new(xtal_hz: u32) -> Sja1000 {
        Sja1000 {
            xtal_hz,
            cdr: 0x00,
            reset: true,
            mode_bits: 0,
            sleep: false,
            cr: 0,
            ier: 0,
            ir: 0,
            tbs: true,
            tcs: true,
            dos: false,
            es: false,
            bs: false,
            btr0: 0,
            btr1: 0,
            ocr: 0,
            test: 0,
            acr: [0; 4],
            amr: [0; 4],
            ewlr: DEFAULT_WARNING_LIMIT,
            tec: 0,
            rec: 0,
            state: ErrorState::Active,
            bus_off: false,
            recovering: false,
            counters_written: false,
            alc: 0,
            alc_held: false,
            ecc: 0,
            ecc_held: false,
            tx: [0; 13],
            pending: None,
            fifo: RxFifo::new(),
            actions: Vec::new(),
        }
    }

    /// BasicCAN or PeliCAN (CDR bit 7).
    pub fn mode(&self) -> Mode {
        if self.cdr & 0x80 != 0 {
            Mode::PeliCan
        } else {
            Mode::BasicCan
        }
    }

    /// True in reset mode (MOD.RM / CR.RR).
    pub fn in_reset(&self) -> bool {
        self.reset
    }

    /// The bit timing programmed in BTR0/BTR1.
    pub fn bit_timing(&self) -> BitTiming {
        BitTiming::from_registers(self.btr0, self.btr1, self.xtal_hz)
    }

    /// The acceptance filter in force. PeliCAN: ACR0–3, AMR0–3 and MOD.AFM. BasicCAN: ACR and
    /// AMR compare ID10..3 only, which is the single filter with ACR0/AMR0 and every other bit
    /// "don't care".
    pub fn filter(&self) -> Sja1000Filter {
        match self.mode() {
            Mode::PeliCan => Sja1000Filter {
                mode: Sja1000Mode::from_mod_register(self.mode_bits),
                acr: self.acr,
                amr: self.amr,
            },
            Mode::BasicCan => Sja1000Filter {
                mode: Sja1000Mode::Single,
                acr: [self.acr[0], 0, 0, 0],
                amr: [self.amr[0], 0xFF, 0xFF, 0xFF],
            },
        }
    }

    /// The error counters as the chip holds them (TXERR and RXERR, which read 127 and 0 from
    /// bus off on) and its error state.
    pub fn error_counters(&self) -> (u16, u16, ErrorState) {
        let state = if self.bus_off {
            ErrorState::BusOff
        } else {
            self.state
        };
        (self.tec, self.rec, state)
    }

    /// The INT pin is low (active): an enabled interrupt flag is set.
    pub fn int_active(&self) -> bool {
        self.ir_value() & self.enables() != 0
    }

    /// What the bus must do, in order, since the last call.
    pub fn take_actions(&mut self) -> impl Iterator<Item = Action> + use<> {
        std::mem::take(&mut self.actions).into_iter()
    }
}
