//! The CAN controller on chip in the Atmel AT89C51CC03 (and T89C51CC01) at register level, as a
//! sans-IO model: the 80C51 core reads and writes its special function registers, the bus side
//! tells it what happened on the bus, and it says what the bus must do.
//!
//! Contract:
//! - [`CanController::sfr_read`], [`CanController::sfr_peek`] and [`CanController::sfr_write`]
//!   take an SFR address. The CAN SFRs ([`sfr`]) answer `Some(value)` / `true`; every other
//!   address answers `None` / `false` and is left to the core. Reads of CANMSG move the page's
//!   data index on (CANPAGE.AINC = 0); `sfr_peek` returns the same value without that. Nothing
//!   panics on any address or value.
//! - The controller speaks the SJA1000's [`Action`] and [`BusSide`]: `Online` when CANGCON.ENA
//!   is set (with `filter: None`: each message object filters for itself), `Offline` when it is
//!   cleared or on a general reset, `Transmit` for the lowest-numbered channel enabled for
//!   transmission or waiting to send an automatic reply, `Abort` for CANGCON.ABRQ or a pending
//!   channel disabled by the CPU, `SetCounters` on a general reset. The bus hands it every frame
//!   received correctly while it is enabled; the channels decide what to keep.
//! - The bus holds at most one frame of the controller, from its `Transmit` until the bus
//!   answers `Transmitted` or `Aborted`, whatever the CPU does meanwhile (an `Abort` or
//!   `Offline` is answered too: `Aborted` for a frame dropped, `Transmitted` for an attempt that
//!   was on the wire and succeeded). Only then is the next channel offered.
//! - Bus-off recovery is automatic (the bus counts 128 × 11 recessive bits by itself,
//!   `engine::Recovery::Automatic`): the controller never sends `StartRecovery`.
//! - [`CanController::interrupt`] is the CAN interrupt request (CANGIT.CANIT) to the core's CAN
//!   interrupt source (ECAN in IEN1); [`CanController::timer_interrupt`] is the CAN timer
//!   overflow (OVRTIM) to its own source (ETIM in IEN1).
//! - Time enters through [`CanController::set_time`], in periods of the CAN clock; the CAN timer
//!   (CANTIMH/L) and the time stamps (CANSTMPH/L) follow it.
//!   [`CanController::next_timer_overflow`] tells when the timer sets OVRTIM next, so that a
//!   caller can give the time then and raise the timer interrupt on time.
//!
//! Register behaviour follows the AT89C51CC03 data sheet (Atmel 4182) and the T89C51CC01 data
//! sheet (Atmel 4129), whose CAN controllers are the same; `docs/AT89C51CC03.md` lists the
//! register map, the facts with their sections and every choice made where they leave room.

mod events;
mod regs;
mod timing;

#[cfg(test)]
mod tests;

pub use timing::BitTiming;

use crate::fault::ErrorState;
use crate::filter::AtmelFilter;
pub use crate::sja1000::{Action, BusSide};

/// Number of message objects (channels 0 to 14).
pub const CHANNELS: usize = 15;

/// CANIDT4 bit 2: RTRTAG.
const RTRTAG: u8 = 0x04;

/// SFR addresses of the CAN controller (AT89C51CC03 data sheet, SFR mapping table; the same in
/// Atmel's `at89c51cc03.h` register header).
pub mod sfr {
    /// General interrupt flags.
    pub const CANGIT: u8 = 0x9B;
    /// Transmit error counter.
    pub const CANTEC: u8 = 0x9C;
    /// Receive error counter.
    pub const CANREC: u8 = 0x9D;
    /// CAN timer prescaler.
    pub const CANTCON: u8 = 0xA1;
    /// Data byte of the page's channel, at CANPAGE.INDX.
    pub const CANMSG: u8 = 0xA3;
    /// TTC timer, low byte.
    pub const CANTTCL: u8 = 0xA4;
    /// TTC timer, high byte.
    pub const CANTTCH: u8 = 0xA5;
    /// General status.
    pub const CANGSTA: u8 = 0xAA;
    /// General control.
    pub const CANGCON: u8 = 0xAB;
    /// CAN timer, low byte.
    pub const CANTIML: u8 = 0xAC;
    /// CAN timer, high byte.
    pub const CANTIMH: u8 = 0xAD;
    /// Time stamp of the page's channel, low byte.
    pub const CANSTMPL: u8 = 0xAE;
    /// Time stamp of the page's channel, high byte.
    pub const CANSTMPH: u8 = 0xAF;
    /// Page: CHNB (7:4), AINC (3), INDX (2:0).
    pub const CANPAGE: u8 = 0xB1;
    /// Status of the page's channel.
    pub const CANSTCH: u8 = 0xB2;
    /// Control and DLC of the page's channel.
    pub const CANCONCH: u8 = 0xB3;
    /// Bit timing 1: BRP.
    pub const CANBT1: u8 = 0xB4;
    /// Bit timing 2: SJW, PRS.
    pub const CANBT2: u8 = 0xB5;
    /// Bit timing 3: PHS2, PHS1, SMP.
    pub const CANBT3: u8 = 0xB6;
    /// Channels 14..8 with a pending interrupt.
    pub const CANSIT1: u8 = 0xBA;
    /// Channels 7..0 with a pending interrupt.
    pub const CANSIT2: u8 = 0xBB;
    /// Identifier tag 1 of the page's channel (CANIDT2..4 follow).
    pub const CANIDT1: u8 = 0xBC;
    /// Identifier tag 4: ID4..0, RTRTAG, RB1TAG, RB0TAG.
    pub const CANIDT4: u8 = 0xBF;
    /// General interrupt enables.
    pub const CANGIE: u8 = 0xC1;
    /// Interrupt enables of channels 14..8.
    pub const CANIE1: u8 = 0xC2;
    /// Interrupt enables of channels 7..0.
    pub const CANIE2: u8 = 0xC3;
    /// Identifier mask 1 of the page's channel (CANIDM2..4 follow).
    pub const CANIDM1: u8 = 0xC4;
    /// Identifier mask 4: ID4..0, RTRMSK, IDEMSK.
    pub const CANIDM4: u8 = 0xC7;
    /// Channels 14..8 in use (read only).
    pub const CANEN1: u8 = 0xCE;
    /// Channels 7..0 in use (read only).
    pub const CANEN2: u8 = 0xCF;
}

/// Bits of CANGCON.
pub mod gcon {
    /// Abort request: every channel's enable is cleared, the pending frame dropped.
    pub const ABRQ: u8 = 0x80;
    /// Overload frame request (not modelled; reads 0).
    pub const OVRQ: u8 = 0x40;
    /// Time trigger communication.
    pub const TTC: u8 = 0x20;
    /// TTC synchronisation on EOF (1) or SOF (0).
    pub const SYNCTTC: u8 = 0x10;
    /// Listening mode (auto baud): receive without acknowledging or transmitting.
    pub const AUTBAUD: u8 = 0x08;
    /// Test mode (reserved).
    pub const TEST: u8 = 0x04;
    /// Enable the controller.
    pub const ENA: u8 = 0x02;
    /// General reset (reads 0).
    pub const GRES: u8 = 0x01;
}

/// Bits of CANGSTA (read only).
pub mod gsta {
    /// Overload frame being sent (never set in this model).
    pub const OVFG: u8 = 0x40;
    /// Transmitter busy: a frame is given to the bus.
    pub const TBSY: u8 = 0x10;
    /// Receiver busy (never set: frames arrive whole).
    pub const RBSY: u8 = 0x08;
    /// The controller is enabled.
    pub const ENFG: u8 = 0x04;
    /// Bus off.
    pub const BOFF: u8 = 0x02;
    /// Error passive.
    pub const ERRP: u8 = 0x01;
}

/// Bits of CANGIT.
pub mod git {
    /// Some enabled CAN interrupt is pending (read only).
    pub const CANIT: u8 = 0x80;
    /// The CAN timer overflowed.
    pub const OVRTIM: u8 = 0x20;
    /// The reception buffer is full.
    pub const OVRBUF: u8 = 0x10;
    /// Stuff error, general.
    pub const SERG: u8 = 0x08;
    /// CRC error, general.
    pub const CERG: u8 = 0x04;
    /// Form error, general.
    pub const FERG: u8 = 0x02;
    /// Acknowledgement error, general.
    pub const AERG: u8 = 0x01;
}

/// Bits of CANGIE.
pub mod gie {
    /// Receive interrupts of the channels.
    pub const ENRX: u8 = 0x20;
    /// Transmit interrupts of the channels.
    pub const ENTX: u8 = 0x10;
    /// Error interrupts of the channels.
    pub const ENERCH: u8 = 0x08;
    /// Buffer-full interrupt.
    pub const ENBUF: u8 = 0x04;
    /// General error interrupts.
    pub const ENERG: u8 = 0x02;
}

/// Bits of CANSTCH.
pub mod stch {
    /// The received DLC differs from the one expected.
    pub const DLCW: u8 = 0x80;
    /// Transmission complete.
    pub const TXOK: u8 = 0x40;
    /// Reception complete.
    pub const RXOK: u8 = 0x20;
    /// Bit error (transmission only).
    pub const BERR: u8 = 0x10;
    /// Stuff error.
    pub const SERR: u8 = 0x08;
    /// CRC error.
    pub const CERR: u8 = 0x04;
    /// Form error.
    pub const FERR: u8 = 0x02;
    /// Acknowledgement error.
    pub const AERR: u8 = 0x01;
    /// The five error bits.
    pub const ERRORS: u8 = 0x1F;
}

/// CANCONCH bits 7:6 (CONCH) and the others.
pub mod conch {
    /// CONCH field mask.
    pub const MASK: u8 = 0xC0;
    /// Channel disabled.
    pub const DISABLE: u8 = 0x00;
    /// Launch a transmission.
    pub const TX: u8 = 0x40;
    /// Enable reception.
    pub const RX: u8 = 0x80;
    /// Enable reception into the buffer.
    pub const RX_BUFFER: u8 = 0xC0;
    /// Reply valid: a channel enabled for reception with RPLV and RTRTAG set answers a matching
    /// remote frame with a data frame of its own (automatic reply).
    pub const RPLV: u8 = 0x20;
    /// Extended identifier.
    pub const IDE: u8 = 0x10;
    /// DLC mask.
    pub const DLC: u8 = 0x0F;
}

/// One message object. The data sheet gives none of these a reset value; the model starts
/// them at 0.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Channel {
    conch: u8,
    stch: u8,
    idt: [u8; 4],
    idm: [u8; 4],
    msg: [u8; 8],
    stmp: u16,
}

impl Channel {
    fn mode(&self) -> u8 {
        self.conch & conch::MASK
    }

    /// RTRTAG (CANIDT4 bit 2).
    fn rtr_tag(&self) -> bool {
        self.idt[3] & RTRTAG != 0
    }

    fn filter(&self) -> AtmelFilter {
        AtmelFilter {
            idt: self.idt,
            idm: self.idm,
            ide: self.conch & conch::IDE != 0,
            ide_mask: self.idm[3] & AtmelFilter::IDEMSK != 0,
        }
    }
}

/// The AT89C51CC03's CAN controller: general registers and 15 message objects. See the module
/// docs.
#[derive(Clone, Debug, PartialEq)]
pub struct CanController {
    clock_hz: u64,
    channels: [Channel; CHANNELS],
    page: u8,
    /// CANGCON as stored (GRES and OVRQ never stay set).
    gcon: u8,
    /// CANGIT flags other than CANIT.
    git: u8,
    gie: u8,
    /// CANIE1:CANIE2, channel 0 in bit 0.
    ie: u16,
    /// CANEN1:CANEN2, channel 0 in bit 0: the channel waits to send or receive.
    en: u16,
    /// Channels (bit 0 for channel 0) that took a remote frame with RPLV set and now wait to
    /// send their reply: producers, no longer receivers, until the reply is sent or the
    /// channel is written.
    replies: u16,
    bt: [u8; 3],
    tec: u16,
    rec: u16,
    state: ErrorState,
    /// CANGSTA.ENFG: enabled and on the bus.
    enabled: bool,
    /// The channel whose frame the bus holds: from the `Transmit` until the bus answers it
    /// (`Transmitted` or `Aborted`), whatever the CPU does meanwhile.
    pending: Option<usize>,
    /// The bus was asked to drop that frame (`Abort`, or `Offline`) and has not answered yet.
    dropping: bool,
    /// The CPU configured the held channel again (CONCH other than 00) after asking to drop its
    /// frame: its CANEN bit belongs to the new configuration, which the answer leaves alone.
    rearmed: bool,
    tcon: u8,
    timer: u16,
    /// CAN clock periods since the last timer tick.
    timer_frac: u64,
    /// The time of the last `set_time`, in CAN clock periods.
    now: u64,
    ttc: u16,
    actions: Vec<Action>,
}

impl CanController {
    /// The controller after a hardware reset, clocked at `clock_hz`: the CAN peripheral clock
    /// F_CAN, which is F_OSC / 2 in X1 mode and F_OSC in X2 mode with the CAN's own X2 bit set
    /// (T89C51CC01 data sheet, bit timing example: 12 MHz in X1 mode gives F_CAN = 6 MHz).
    pub fn new(clock_hz: u64) -> CanController {
        CanController {
            clock_hz,
            channels: [Channel::default(); CHANNELS],
            page: 0,
            gcon: 0,
            git: 0,
            gie: 0,
            ie: 0,
            en: 0,
            replies: 0,
            bt: [0; 3],
            tec: 0,
            rec: 0,
            state: ErrorState::Active,
            enabled: false,
            pending: None,
            dropping: false,
            rearmed: false,
            tcon: 0,
            timer: 0,
            timer_frac: 0,
            now: 0,
            ttc: 0,
            actions: Vec::new(),
        }
    }

    /// The bit timing programmed in CANBT1–3 with the CAN clock.
    pub fn bit_timing(&self) -> BitTiming {
        BitTiming::from_registers(self.bt, self.clock_hz)
    }

    /// The error counters as the bus last reported them (CANTEC and CANREC show at most 255)
    /// and the error state.
    pub fn error_counters(&self) -> (u16, u16, ErrorState) {
        (self.tec, self.rec, self.state)
    }

    /// CANGSTA.ENFG: the controller is enabled and takes part in the bus.
    pub fn enabled(&self) -> bool {
        self.enabled
    }

    /// The CAN interrupt request: CANGIT.CANIT.
    pub fn interrupt(&self) -> bool {
        self.canit()
    }

    /// The CAN timer overflow request: CANGIT.OVRTIM (its own source, ETIM in IEN1).
    pub fn timer_interrupt(&self) -> bool {
        self.git & git::OVRTIM != 0
    }

    /// While the controller is enabled, the time in CAN clock periods (as
    /// [`set_time`](CanController::set_time) counts them) at which the CAN timer next passes
    /// 0xFFFF to 0 and sets OVRTIM: `set_time` with this time or a later one sets it, an earlier
    /// one does not (unless the CPU changes CANTCON or the enable in between). `None` while
    /// disabled, when the timer stands still.
    pub fn next_timer_overflow(&self) -> Option<u64> {
        if !self.enabled {
            return None;
        }
        let period = events::TIMER_DIVIDER * (u64::from(self.tcon) + 1);
        let ticks = 0x1_0000 - u64::from(self.timer);
        Some(
            self.now
                .saturating_sub(self.timer_frac)
                .saturating_add(ticks * period),
        )
    }

    /// What the bus must do, in order, since the last call.
    pub fn take_actions(&mut self) -> impl Iterator<Item = Action> + use<> {
        std::mem::take(&mut self.actions).into_iter()
    }

    /// Channels with a pending interrupt (CANSIT1:CANSIT2): a channel whose interrupt is enabled
    /// (CANIE) with TXOK and ENTX, RXOK and ENRX, or an error bit and ENERCH.
    pub(crate) fn sit(&self) -> u16 {
        let mut sit = 0u16;
        // Only channels whose interrupt is enabled: the core asks after every register access.
        let mut enabled = self.ie & ((1 << CHANNELS) - 1);
        while enabled != 0 {
            let i = enabled.trailing_zeros() as usize;
            enabled &= enabled - 1;
            let ch = &self.channels[i];
            let tx = ch.stch & stch::TXOK != 0 && self.gie & gie::ENTX != 0;
            let rx = ch.stch & stch::RXOK != 0 && self.gie & gie::ENRX != 0;
            let err = ch.stch & stch::ERRORS != 0 && self.gie & gie::ENERCH != 0;
            if tx || rx || err {
                sit |= 1 << i;
            }
        }
        sit
    }

    /// Channel `c` is enabled for reception of data or remote frames (CONCH 10 or 11) and not
    /// waiting to send a reply.
    fn receives(&self, c: usize) -> bool {
        matches!(self.channels[c].mode(), conch::RX | conch::RX_BUFFER) && self.replies & (1 << c) == 0
    }

    /// Channel `c` sends when enabled: launched for transmission (CONCH 01), or waiting to send
    /// a reply.
    fn produces(&self, c: usize) -> bool {
        self.channels[c].mode() == conch::TX || self.replies & (1 << c) != 0
    }

    /// CANGIT.CANIT: a channel interrupt, the buffer-full flag with ENBUF, or a general error
    /// flag with ENERG.
    fn canit(&self) -> bool {
        let buf = self.git & git::OVRBUF != 0 && self.gie & gie::ENBUF != 0;
        let errors = git::SERG | git::CERG | git::FERG | git::AERG;
        let err = self.git & errors != 0 && self.gie & gie::ENERG != 0;
        self.sit() != 0 || buf || err
    }
}
