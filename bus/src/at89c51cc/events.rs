//! The bus side: what the bus reports, transmission scheduling, reception into the channels,
//! errors and the CAN timer.

use super::{CHANNELS, CanController, conch, git, stch};
use crate::engine::BusError;
use crate::fault::ErrorState;
use crate::filter::{AcceptanceFilter, AtmelFilter};
use crate::sja1000::{Action, BusSide};
use crate::{ExtendedId, Frame, Id, StandardId};

/// CAN clock periods per CAN timer tick before the CANTCON prescaler (see docs/AT89C51CC03.md).
pub(super) const TIMER_DIVIDER: u64 = 6;

impl CanController {
    /// Takes what the bus did for this controller. Call [`set_time`](CanController::set_time)
    /// first so that time stamps carry the moment of the event.
    pub fn on_event(&mut self, event: BusSide) {
        match event {
            BusSide::Received(frame) => self.received(&frame),
            // The held frame was sent, even if the CPU asked to drop it meanwhile (an attempt
            // on the wire runs to its end): TXOK on its channel. The communication is over, so
            // its CANEN bit is cleared, unless the CPU configured the channel again since.
            BusSide::Transmitted => {
                if let Some(c) = self.release() {
                    if !std::mem::take(&mut self.rearmed) {
                        self.en &= !(1 << c);
                        self.replies &= !(1 << c);
                    }
                    let stamp = self.timer;
                    let ch = &mut self.channels[c];
                    ch.stch |= stch::TXOK;
                    ch.stmp = stamp;
                    self.schedule();
                }
            }
            // The held frame was dropped: on request (ABRQ or CONCH = 00 cleared the channel's
            // CANEN bit already; ENA cleared leaves the channel enabled, to send after ENA), or
            // by the bus going bus off (the channel stays enabled). The model sets no flag (the
            // data sheet names none). The bus holds nothing now: the next channel may go.
            BusSide::Aborted => {
                if self.release().is_some() {
                    self.rearmed = false;
                    self.schedule();
                }
            }
            // The controller has no arbitration-lost register; the frame stays pending. The model
            // has no sleep mode, so it is never woken.
            BusSide::ArbitrationLost { .. } | BusSide::Woken => {}
            BusSide::BusError {
                error, transmitting, ..
            } => self.bus_error(error, transmitting),
            BusSide::Counters { tec, rec, state } => {
                self.tec = tec;
                self.rec = rec;
                self.state = state;
            }
            BusSide::RecoveryDone => {
                self.tec = 0;
                self.rec = 0;
                self.state = ErrorState::Active;
            }
        }
    }

    /// The bus no longer holds a frame of this controller: the channel it held.
    fn release(&mut self) -> Option<usize> {
        self.dropping = false;
        self.pending.take()
    }

    /// The time of the last [`set_time`](CanController::set_time), in CAN clock periods.
    pub fn time(&self) -> u64 {
        self.now
    }

    /// The time now, in CAN clock periods since power-on. The CAN timer counts while the
    /// controller is enabled, one tick every 6 · (CANTCON + 1) periods; passing 0xFFFF to 0
    /// sets OVRTIM. Times earlier than the last one are ignored.
    pub fn set_time(&mut self, can_clock_periods: u64) {
        let elapsed = can_clock_periods.saturating_sub(self.now);
        self.now = self.now.max(can_clock_periods);
        // With no time elapsed the ticks are still worked out: a smaller CANTCON written since
        // may leave a whole tick in the fraction.
        if !self.enabled {
            return;
        }
        let period = TIMER_DIVIDER * (u64::from(self.tcon) + 1);
        let total = self.timer_frac + elapsed;
        self.timer_frac = total % period;
        let ticks = total / period;
        let sum = u64::from(self.timer) + ticks;
        if sum > 0xFFFF {
            self.git |= git::OVRTIM;
        }
        self.timer = (sum & 0xFFFF) as u16;
    }

    /// Offers the lowest-numbered enabled producer (a channel launched for transmission, or one
    /// waiting to send an automatic reply) to the bus, when the controller is enabled and the
    /// bus holds none of its frames.
    pub(super) fn schedule(&mut self) {
        if !self.enabled || self.pending.is_some() || self.gcon & super::gcon::AUTBAUD != 0 {
            return;
        }
        let next = (0..CHANNELS).find(|&c| self.en & (1 << c) != 0 && self.produces(c));
        let Some(c) = next else {
            return;
        };
        match self.channel_frame(c) {
            Some(frame) => {
                self.pending = Some(c);
                self.actions.push(Action::Transmit {
                    frame,
                    self_reception: false,
                    single_shot: false,
                });
            }
            // Unreachable with the masks used, but never panic: leave the channel unsent.
            None => {
                self.en &= !(1 << c);
                self.replies &= !(1 << c);
            }
        }
    }

    /// The frame a channel describes: identifier from CANIDT by CONCH.IDE, RTR from RTRTAG,
    /// DLC from CONCH (above 8 sends 8 bytes and DLC 8), data from CANMSG. A channel sending its
    /// automatic reply has RTRTAG cleared already: a data frame.
    fn channel_frame(&self, c: usize) -> Option<Frame> {
        let ch = &self.channels[c];
        let image = u32::from_be_bytes(ch.idt);
        let id: Id = if ch.conch & conch::IDE != 0 {
            ExtendedId::new(image >> 3)?.into()
        } else {
            StandardId::new((image >> 21) as u16)?.into()
        };
        let dlc = usize::from(ch.conch & conch::DLC).min(8);
        let frame = if ch.rtr_tag() {
            Frame::new_remote(id, dlc)
        } else {
            Frame::new_data(id, &ch.msg[..dlc])
        };
        frame.ok()
    }

    /// Whether a channel would take `frame` now: the controller is enabled and a channel enabled
    /// for reception accepts it. A frame no channel takes changes nothing in the controller.
    pub fn takes(&self, frame: &Frame) -> bool {
        self.enabled && self.hit(frame).is_some()
    }

    /// The filters of the channels that would take a frame now: [`CanController::takes`] is
    /// true of a frame exactly when one of them accepts it (none while the controller is
    /// disabled).
    pub fn heeded(&self) -> impl Iterator<Item = AtmelFilter> + '_ {
        (0..CHANNELS)
            .filter(|&c| self.enabled && self.en & (1 << c) != 0 && self.receives(c))
            .map(|c| self.channels[c].filter())
    }

    /// The lowest-numbered enabled receiving channel whose filter accepts `frame`.
    fn hit(&self, frame: &Frame) -> Option<usize> {
        (0..CHANNELS).find(|&c| {
            let ch = &self.channels[c];
            self.en & (1 << c) != 0 && self.receives(c) && ch.filter().accepts(frame)
        })
    }

    /// A frame received correctly: the lowest-numbered enabled receiving channel whose filter
    /// accepts it stores it. A buffer channel that was the last of the buffer sets OVRBUF.
    ///
    /// Automatic reply (AT90CAN32/64/128 data sheet, Atmel 7679, "Automatic Reply" and the
    /// "MOb Configuration" table; the AT89C51CC03 data sheet's CANCONCH table gives RPLV
    /// alone): a channel enabled for reception (CONCH 10) with RPLV and RTRTAG set that takes a
    /// remote frame stores its identifier, IDE and DLC, clears RTRTAG and RPLV and sets no flag;
    /// it stays enabled and sends its buffer as a data frame with them, and TXOK comes when that
    /// reply is sent.
    fn received(&mut self, frame: &Frame) {
        if !self.enabled {
            return;
        }
        let Some(c) = self.hit(frame) else {
            return;
        };
        let ch = &self.channels[c];
        let reply =
            frame.is_remote() && ch.mode() == conch::RX && ch.conch & conch::RPLV != 0 && ch.rtr_tag();
        let stamp = self.timer;
        let ch = &mut self.channels[c];
        let expected = ch.conch & conch::DLC;
        let ide = if frame.is_extended() { conch::IDE } else { 0 };
        ch.conch = (ch.conch & (conch::MASK | conch::RPLV)) | ide | frame.dlc();
        if expected != frame.dlc() {
            ch.stch |= stch::DLCW;
        }
        if reply {
            ch.conch &= !conch::RPLV;
            // The identifier as received, RTRTAG cleared: the reply is a data frame.
            ch.idt = crate::filter::canidt_bytes(frame.id(), false);
            self.replies |= 1 << c;
            self.schedule();
            return;
        }
        self.en &= !(1 << c);
        ch.stch |= stch::RXOK;
        // The identifier as received replaces the tag (bits the mask ignores included); the
        // reserved bits read 0 as the bus sends them dominant.
        ch.idt = crate::filter::canidt_bytes(frame.id(), frame.is_remote());
        let data = frame.data();
        ch.msg[..data.len()].copy_from_slice(data);
        ch.stmp = stamp;
        if ch.mode() == conch::RX_BUFFER {
            let buffer_left =
                (0..CHANNELS).any(|b| self.en & (1 << b) != 0 && self.channels[b].mode() == conch::RX_BUFFER);
            if !buffer_left {
                self.git |= git::OVRBUF;
            }
        }
    }

    /// A bus error: while transmitting, the error bit of the channel the bus holds; otherwise
    /// the general flag of its kind (there is none for bit errors). An error set in a channel
    /// sets no general flag (AT90CAN32/64/128 data sheet, "Interrupt Behavior", for the same
    /// controller design).
    fn bus_error(&mut self, error: BusError, transmitting: bool) {
        if !self.enabled {
            return;
        }
        let (general, channel) = match error {
            BusError::Bit => (0, stch::BERR),
            BusError::Stuff => (git::SERG, stch::SERR),
            BusError::Crc => (git::CERG, stch::CERR),
            BusError::Form => (git::FERG, stch::FERR),
            BusError::Ack => (git::AERG, stch::AERR),
        };
        match self.pending {
            Some(c) if transmitting => self.channels[c].stch |= channel,
            _ => self.git |= general,
        }
    }
}
