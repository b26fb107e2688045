//! The CPU side: SFR reads and writes.

use super::{CHANNELS, CanController, conch, gcon, git, gsta, sfr};
use crate::sja1000::Action;

impl CanController {
    /// Reads CAN SFR `addr`: `Some(value)`, or `None` for an SFR that is not the CAN
    /// controller's. Reading CANMSG moves CANPAGE.INDX on when AINC is 0.
    pub fn sfr_read(&mut self, addr: u8) -> Option<u8> {
        let value = self.sfr_peek(addr)?;
        if addr == sfr::CANMSG {
            self.step_index();
        }
        Some(value)
    }

    /// [`sfr_read`](CanController::sfr_read) without side effects.
    pub fn sfr_peek(&self, addr: u8) -> Option<u8> {
        let ch = self.page_channel();
        let v = match addr {
            sfr::CANGIT => self.git | if self.canit() { git::CANIT } else { 0 },
            sfr::CANTEC => counter(self.tec),
            sfr::CANREC => counter(self.rec),
            sfr::CANTCON => self.tcon,
            sfr::CANMSG => ch.map_or(0, |c| c.msg[self.index()]),
            sfr::CANTTCL => self.ttc as u8,
            sfr::CANTTCH => (self.ttc >> 8) as u8,
            sfr::CANGSTA => self.gsta(),
            sfr::CANGCON => self.gcon,
            sfr::CANTIML => self.timer as u8,
            sfr::CANTIMH => (self.timer >> 8) as u8,
            sfr::CANSTMPL => ch.map_or(0, |c| c.stmp as u8),
            sfr::CANSTMPH => ch.map_or(0, |c| (c.stmp >> 8) as u8),
            sfr::CANPAGE => self.page,
            sfr::CANSTCH => ch.map_or(0, |c| c.stch),
            sfr::CANCONCH => ch.map_or(0, |c| c.conch),
            sfr::CANBT1 => self.bt[0],
            sfr::CANBT2 => self.bt[1],
            sfr::CANBT3 => self.bt[2],
            sfr::CANSIT1 => (self.sit() >> 8) as u8,
            sfr::CANSIT2 => self.sit() as u8,
            0xBC..=0xBF => ch.map_or(0, |c| c.idt[usize::from(addr - sfr::CANIDT1)]),
            sfr::CANGIE => self.gie,
            sfr::CANIE1 => (self.ie >> 8) as u8,
            sfr::CANIE2 => self.ie as u8,
            0xC4..=0xC7 => ch.map_or(0, |c| c.idm[usize::from(addr - sfr::CANIDM1)]),
            sfr::CANEN1 => (self.en >> 8) as u8,
            sfr::CANEN2 => self.en as u8,
            _ => return None,
        };
        Some(v)
    }

    /// Writes CAN SFR `addr`; false (and nothing done) for an SFR that is not the CAN
    /// controller's. Read-only CAN registers ignore the write and still answer true.
    pub fn sfr_write(&mut self, addr: u8, value: u8) -> bool {
        let page = self.page_index();
        match addr {
            // CANIT is read only; the flags are cleared (or set) by writing them.
            sfr::CANGIT => self.git = value & !git::CANIT & 0x3F,
            sfr::CANTCON => self.tcon = value,
            sfr::CANMSG => {
                if let Some(c) = page {
                    let i = self.index();
                    self.channels[c].msg[i] = value;
                }
                self.step_index();
            }
            sfr::CANGCON => self.write_gcon(value),
            sfr::CANPAGE => self.page = value,
            sfr::CANSTCH => {
                if let Some(c) = page {
                    self.channels[c].stch = value;
                }
            }
            sfr::CANCONCH => {
                if let Some(c) = page {
                    self.write_conch(c, value);
                }
            }
            // Reserved bits read 0: CANBT1 bits 7 and 0, CANBT2 bits 7 and 4 and 0, CANBT3 bit 7.
            sfr::CANBT1 => self.bt[0] = value & 0x7E,
            sfr::CANBT2 => self.bt[1] = value & 0x6E,
            sfr::CANBT3 => self.bt[2] = value & 0x7F,
            0xBC..=0xBF => {
                if let Some(c) = page {
                    self.channels[c].idt[usize::from(addr - sfr::CANIDT1)] = value;
                }
            }
            sfr::CANGIE => self.gie = value & 0x3F,
            sfr::CANIE1 => self.ie = (self.ie & 0x00FF) | (u16::from(value & 0x7F) << 8),
            sfr::CANIE2 => self.ie = (self.ie & 0xFF00) | u16::from(value),
            0xC4..=0xC7 => {
                if let Some(c) = page {
                    self.channels[c].idm[usize::from(addr - sfr::CANIDM1)] = value;
                }
            }
            // Read only: counters, status, TTC timer, CAN timer, stamps, CANSIT, CANEN.
            sfr::CANTEC
            | sfr::CANREC
            | sfr::CANTTCL
            | sfr::CANTTCH
            | sfr::CANGSTA
            | sfr::CANTIML
            | sfr::CANTIMH
            | sfr::CANSTMPL
            | sfr::CANSTMPH
            | sfr::CANSIT1
            | sfr::CANSIT2
            | sfr::CANEN1
            | sfr::CANEN2 => {}
            _ => return false,
        }
        true
    }

    /// The channel CANPAGE.CHNB selects; `None` for CHNB = 15, which has no message object.
    fn page_index(&self) -> Option<usize> {
        let c = usize::from(self.page >> 4);
        (c < CHANNELS).then_some(c)
    }

    fn page_channel(&self) -> Option<&super::Channel> {
        self.page_index().map(|c| &self.channels[c])
    }

    fn index(&self) -> usize {
        usize::from(self.page & 0x07)
    }

    /// CANPAGE.INDX + 1, wrapping within 0–7, when AINC (bit 3) is 0.
    fn step_index(&mut self) {
        if self.page & 0x08 == 0 {
            self.page = (self.page & 0xF8) | ((self.page + 1) & 0x07);
        }
    }

    fn gsta(&self) -> u8 {
        let mut v = 0;
        if self.pending.is_some() {
            v |= gsta::TBSY;
        }
        if self.enabled {
            v |= gsta::ENFG;
        }
        match self.state {
            crate::fault::ErrorState::BusOff => v |= gsta::BOFF,
            crate::fault::ErrorState::Passive => v |= gsta::ERRP,
            _ => {}
        }
        v
    }

    /// CANCONCH: a CONCH other than 00 enables the channel (sets its CANEN bit); 00 disables it,
    /// asking the bus to drop its frame if it holds it. Either ends a reply the channel waited
    /// to send. The bus holds the frame until it answers (see `BusSide::Aborted`).
    fn write_conch(&mut self, c: usize, value: u8) {
        self.channels[c].conch = value;
        self.replies &= !(1 << c);
        let enable = value & conch::MASK != conch::DISABLE;
        if self.pending == Some(c) && self.dropping {
            self.rearmed = enable;
        }
        if enable {
            self.en |= 1 << c;
        } else {
            self.en &= !(1 << c);
            if self.pending == Some(c) {
                self.drop_pending();
            }
        }
        self.schedule();
    }

    /// Asks the bus to drop the frame it holds (once: a second request would find nothing more).
    fn drop_pending(&mut self) {
        if self.pending.is_some() && !self.dropping {
            self.dropping = true;
            self.actions.push(Action::Abort);
        }
    }

    fn write_gcon(&mut self, value: u8) {
        if value & gcon::GRES != 0 {
            self.general_reset();
            return;
        }
        let was = self.gcon;
        // OVRQ is a one-shot request the model does not carry out; GRES never stays set.
        self.gcon = value & !(gcon::OVRQ | gcon::GRES);
        if value & gcon::ABRQ != 0 && was & gcon::ABRQ == 0 {
            self.en = 0;
            self.rearmed = false;
            self.replies = 0;
            self.drop_pending();
        }
        match (was & gcon::ENA != 0, value & gcon::ENA != 0) {
            (false, true) => self.enable(),
            (true, false) => self.disable(),
            _ => self.schedule(),
        }
    }

    fn enable(&mut self) {
        self.enabled = true;
        self.actions.push(Action::Online {
            listen_only: self.gcon & gcon::AUTBAUD != 0,
            self_test: false,
            filter: None,
        });
        self.schedule();
    }

    /// ENA cleared: the controller leaves the bus (`Offline`, which drops the frame the bus
    /// holds unless its attempt is on the wire and succeeds). Until the bus answers, the frame is
    /// still held; if it was dropped, its channel stays enabled and is sent again once ENA is
    /// set; if it was sent, TXOK.
    fn disable(&mut self) {
        if self.enabled {
            self.enabled = false;
            self.dropping |= self.pending.is_some();
            self.actions.push(Action::Offline);
        }
    }

    /// CANGCON.GRES: the general registers take their reset values; the message objects keep
    /// theirs (they have none).
    fn general_reset(&mut self) {
        self.disable();
        let channels = self.channels;
        let (clock, now) = (self.clock_hz, self.now);
        // A frame the bus still holds is answered later: the answer is that frame's.
        let (pending, dropping) = (self.pending, self.dropping);
        let counters = self.tec != 0 || self.rec != 0;
        let actions = std::mem::take(&mut self.actions);
        *self = CanController::new(clock);
        self.channels = channels;
        self.now = now;
        self.pending = pending;
        self.dropping = dropping;
        self.actions = actions;
        if counters {
            self.actions.push(Action::SetCounters { tec: 0, rec: 0 });
        }
    }
}

/// A counter as its 8-bit register shows it.
fn counter(value: u16) -> u8 {
    value.min(255) as u8
}
