//! What the bus reports, reset mode, error state and interrupts.

use super::{Action, BusSide, Mode, Pending, Sja1000, ir};
use crate::Frame;
use crate::engine::BusError;
use crate::fault::{ErrorState, PASSIVE_LIMIT};
use crate::filter::AcceptanceFilter;

/// ECC bits 7:6 (data sheet 6.4.9, Table 20): bit, form, stuff, other.
fn error_code(error: BusError) -> u8 {
    match error {
        BusError::Bit => 0,
        BusError::Form => 1,
        BusError::Stuff => 2,
        BusError::Crc | BusError::Ack => 3,
    }
}

/// The highest value the 8-bit counter registers show.
fn reg(counter: u16) -> u16 {
    counter.min(255)
}

impl Sja1000 {
    /// Takes what the bus did for this chip.
    pub fn on_event(&mut self, event: BusSide) {
        match event {
            BusSide::Received(frame) => self.received(&frame),
            BusSide::Transmitted => {
                if let Some(p) = self.pending.take() {
                    self.tbs = true;
                    self.tcs = true;
                    self.raise(ir::TI);
                    // Self reception: the own frame goes through the filter like any other
                    // (data sheet 6.4.4, SRR).
                    if p.self_reception && self.filter().accepts(&p.frame) {
                        self.store(&p.frame);
                    }
                }
            }
            BusSide::Aborted => {
                if self.pending.take().is_some() {
                    // TCS stays 0: the last request did not complete (data sheet 6.4.4, AT).
                    self.tbs = true;
                    self.raise(ir::TI);
                }
            }
            BusSide::ArbitrationLost { bit } => {
                if self.mode() == Mode::PeliCan && !self.reset && !self.alc_held {
                    self.alc = bit & 0x1F;
                    self.alc_held = true;
                    self.raise(ir::ALI);
                }
            }
            BusSide::BusError {
                error,
                transmitting,
                segment,
            } => {
                if self.mode() == Mode::PeliCan && !self.reset && !self.ecc_held {
                    let rx = u8::from(!transmitting) << 5;
                    self.ecc = (error_code(error) << 6) | rx | (segment & 0x1F);
                    self.ecc_held = true;
                    self.raise(ir::BEI);
                }
            }
            BusSide::Counters { tec, rec, state } => self.counters(tec, rec, state),
            // Bus activity wakes the chip (data sheet 6.4.3, MOD.SM); the bus does not give it the
            // frame that did.
            BusSide::Woken => {
                if self.sleep {
                    self.sleep = false;
                    self.raise(ir::WUI);
                }
            }
            BusSide::RecoveryDone => {
                if self.recovering {
                    self.recovering = false;
                    self.bus_off = false;
                    self.tec = 0;
                    self.rec = 0;
                    self.state = ErrorState::Active;
                    self.update_status();
                }
            }
        }
    }

    fn received(&mut self, frame: &Frame) {
        if self.reset || self.recovering {
            return;
        }
        if self.mode() == Mode::BasicCan && frame.is_extended() {
            return; // extended frames are acknowledged but never stored in BasicCAN mode
        }
        if self.filter().accepts(frame) {
            self.store(frame);
        }
    }

    /// Puts an accepted frame into the FIFO, or flags the overrun.
    pub(super) fn store(&mut self, frame: &Frame) {
        if !self.fifo.push(frame) && !self.dos {
            self.dos = true;
            self.raise(ir::DOI); // on the 0-to-1 transition of DOS only
        }
    }

    fn counters(&mut self, tec: u16, rec: u16, state: ErrorState) {
        if self.reset {
            return;
        }
        if self.recovering {
            // TXERR shows the recovery counting down (data sheet 6.4.12).
            self.tec = reg(tec);
            self.rec = reg(rec);
            return;
        }
        if state == ErrorState::BusOff {
            self.enter_bus_off();
            return;
        }
        self.tec = reg(tec);
        self.rec = reg(rec);
        self.set_state(state);
        self.update_status();
    }

    /// A change between error active and error passive raises EPI (data sheet 6.4.6).
    fn set_state(&mut self, state: ErrorState) {
        let was_passive = self.state == ErrorState::Passive;
        let from_bus_off = self.state == ErrorState::BusOff;
        self.state = state;
        if !from_bus_off && was_passive != (state == ErrorState::Passive) {
            self.raise(ir::EPI);
        }
    }

    /// Bus-off (data sheet 6.4.5 note 1): reset mode, TXERR 127, RXERR 0, BS set, EI.
    fn enter_bus_off(&mut self) {
        self.bus_off = true;
        self.state = ErrorState::BusOff;
        self.tec = 127;
        self.rec = 0;
        self.enter_reset();
        self.update_status();
    }

    /// Recomputes SR.ES and SR.BS; a change of either raises EI (data sheet 6.4.6).
    fn update_status(&mut self) {
        let limit = u16::from(self.ewlr);
        let es = self.tec >= limit || self.rec >= limit;
        let bs = self.bus_off;
        if es != self.es || bs != self.bs {
            self.raise(ir::EI);
        }
        self.es = es;
        self.bs = bs;
    }

    /// Enters reset mode: the pending frame is dropped, the FIFO emptied (data sheet Table 9,
    /// "setting MOD.0 by software or due to bus-off").
    pub(super) fn enter_reset(&mut self) {
        if self.reset {
            return;
        }
        self.reset = true;
        self.sleep = false;
        self.recovering = false;
        self.pending = None;
        self.tbs = true;
        self.dos = false;
        self.fifo.clear();
        self.counters_written = false;
        self.actions.push(Action::Offline);
    }

    /// Leaves reset mode: joins the bus, starts bus-off recovery, or performs the bus-off a
    /// TXERR write of 255 asked for (data sheet 6.4.12).
    pub(super) fn leave_reset(&mut self) {
        let (listen_only, self_test) = self.test_modes();
        if self.counters_written {
            self.counters_written = false;
            if self.tec == 255 {
                // The CPU-driven bus-off (data sheet 6.4.12): as if forced by bus errors; reset
                // mode stays set. The bus side is told the node is bus off (TEC 256), so that
                // the next clearing of RM starts the recovery sequence there.
                self.bus_off = true;
                self.state = ErrorState::BusOff;
                self.tec = 127;
                self.rec = 0;
                self.update_status();
                self.actions.push(Action::SetCounters { tec: 256, rec: 0 });
                return;
            }
            if !self.bus_off {
                let passive = self.tec >= PASSIVE_LIMIT || self.rec >= PASSIVE_LIMIT;
                self.set_state(if passive {
                    ErrorState::Passive
                } else {
                    ErrorState::Active
                });
            }
        }
        self.reset = false;
        if self.bus_off {
            self.recovering = true;
            self.actions.push(Action::StartRecovery {
                listen_only,
                self_test,
            });
        } else {
            self.update_status();
            self.actions.push(Action::Online {
                listen_only,
                self_test,
                filter: Some(self.filter()),
            });
        }
    }

    /// MOD.LOM and MOD.STM (PeliCAN only).
    fn test_modes(&self) -> (bool, bool) {
        match self.mode() {
            Mode::PeliCan => (self.mode_bits & 0x02 != 0, self.mode_bits & 0x04 != 0),
            Mode::BasicCan => (false, false),
        }
    }

    /// Sleep requested (MOD.SM / CMR.GTS) or cancelled. Sleep needs operating mode and no
    /// pending interrupt; asking with one pending, or waking, raises WUI (data sheet 6.3.4 note 1).
    pub(super) fn set_sleep(&mut self, on: bool) {
        if self.reset {
            return;
        }
        if on && !self.sleep {
            if self.int_active() {
                self.raise(ir::WUI);
            } else {
                self.sleep = true;
                self.actions.push(Action::Sleep(true));
            }
        } else if !on && self.sleep {
            self.sleep = false;
            self.raise(ir::WUI);
            self.actions.push(Action::Sleep(false));
        }
    }

    /// A transmission request (TR or SRR): submits the transmit buffer.
    pub(super) fn request(&mut self, self_reception: bool, single_shot: bool) {
        if self.pending.is_some() || !self.tbs {
            return;
        }
        let Some(frame) = self.tx_frame() else {
            return;
        };
        self.pending = Some(Pending {
            frame,
            self_reception,
        });
        self.tbs = false;
        self.tcs = false;
        self.actions.push(Action::Transmit {
            frame,
            self_reception,
            single_shot,
        });
    }

    /// Sets an interrupt flag if its enable allows it.
    pub(super) fn raise(&mut self, flag: u8) {
        if self.enables() & flag != 0 {
            self.ir |= flag;
        }
    }

    /// Interrupt enables in IR bit positions: IER in PeliCAN mode; CR bits 1–4 in BasicCAN mode,
    /// where the wake-up interrupt has no enable bit.
    pub(super) fn enables(&self) -> u8 {
        match self.mode() {
            Mode::PeliCan => self.ier,
            Mode::BasicCan => ((self.cr >> 1) & 0x0F) | ir::WUI,
        }
    }

    /// IR as read: the latched flags and RI, which is set while the FIFO holds a message and
    /// RIE is set.
    pub(super) fn ir_value(&self) -> u8 {
        let ri = if self.fifo.count() > 0 && self.enables() & ir::RI != 0 {
            ir::RI
        } else {
            0
        };
        self.ir | ri
    }
}
