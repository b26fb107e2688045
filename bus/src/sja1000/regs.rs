//! The register maps: BasicCAN (data sheet 6.3.1, Table 1) and PeliCAN (6.4.1, Table 8).

use super::{Mode, Sja1000, cmr, mod_bits, sr};
use crate::{ExtendedId, Frame, StandardId};

/// PeliCAN addresses of the frame window (RX buffer on read, TX buffer on write).
const WINDOW: core::ops::RangeInclusive<u8> = 16..=28;
/// PeliCAN addresses of the receive FIFO RAM.
const FIFO_RAM: core::ops::RangeInclusive<u8> = 32..=95;
/// PeliCAN addresses of the transmit buffer RAM.
const TX_RAM: core::ops::RangeInclusive<u8> = 96..=108;

/// CDR bits the CPU can change only in reset mode: CAN mode, CBP, RXINTEN (data sheet 6.5.4).
const CDR_RESET_ONLY: u8 = 0xE0;
/// CDR bits the CPU can change at any time: clock off and the divider.
const CDR_ANY_TIME: u8 = 0x0F;

impl Sja1000 {
    /// A CPU read of CAN address `addr`, with the chip's side effects: reading IR clears every
    /// flag but RI; reading ALC or ECC re-arms its capture.
    pub fn read(&mut self, addr: u8) -> u8 {
        let value = self.peek(addr);
        match (self.mode(), addr) {
            (_, 3) => self.ir = 0,
            (Mode::PeliCan, 11) => self.alc_held = false,
            (Mode::PeliCan, 12) => self.ecc_held = false,
            _ => {}
        }
        value
    }

    /// The value a CPU read of `addr` would return, without its side effects.
    pub fn peek(&self, addr: u8) -> u8 {
        match self.mode() {
            Mode::PeliCan => self.peek_peli(addr),
            Mode::BasicCan => self.peek_basic(addr),
        }
    }

    /// A CPU write of `value` to CAN address `addr`.
    pub fn write(&mut self, addr: u8, value: u8) {
        match self.mode() {
            Mode::PeliCan => self.write_peli(addr, value),
            Mode::BasicCan => self.write_basic(addr, value),
        }
    }

    /// SR: RS and TS are both set while the chip waits for the bus to become idle (PeliCAN reset
    /// mode, data sheet 6.4.5 note 3, and bus-off recovery); the model does not see frames in
    /// progress, so they are 0 otherwise.
    fn status(&self) -> u8 {
        let waiting = self.recovering || (self.reset && self.mode() == Mode::PeliCan);
        let bit = |on: bool, b: u8| if on { b } else { 0 };
        bit(self.fifo.count() > 0, sr::RBS)
            | bit(self.dos, sr::DOS)
            | bit(self.tbs, sr::TBS)
            | bit(self.tcs, sr::TCS)
            | bit(waiting, sr::RS | sr::TS)
            | bit(self.es, sr::ES)
            | bit(self.bs, sr::BS)
    }

    fn peek_peli(&self, addr: u8) -> u8 {
        let reset = self.reset;
        match addr {
            0 => self.mode_bits | u8::from(reset) | if self.sleep { mod_bits::SM } else { 0 },
            1 => 0x00, // write only; reads 00h (data sheet 6.4.4)
            2 => self.status(),
            3 => self.ir_value(),
            4 => self.ier,
            6 => self.btr0,
            7 => self.btr1,
            8 => self.ocr,
            9 => self.test,
            11 => self.alc,
            12 => self.ecc,
            13 => self.ewlr,
            14 => self.rec as u8,
            15 => self.tec as u8,
            16..=19 if reset => self.acr[usize::from(addr - 16)],
            20..=23 if reset => self.amr[usize::from(addr - 20)],
            a if WINDOW.contains(&a) && !reset => self.fifo.at(usize::from(a - 16)),
            29 => self.fifo.count() as u8 & 0x1F,
            30 => self.fifo.start,
            31 => self.cdr,
            a if FIFO_RAM.contains(&a) => self.fifo.ram[usize::from(a - 32)],
            a if TX_RAM.contains(&a) => self.tx[usize::from(a - 96)],
            _ => 0x00,
        }
    }

    fn peek_basic(&self, addr: u8) -> u8 {
        let reset = self.reset;
        // Registers of reset mode only read FFh in operating mode, the transmit buffer FFh in
        // reset mode (data sheet Table 1).
        let reset_only = |v: u8| if reset { v } else { 0xFF };
        match addr {
            // CR: bit 5 always reads 1, bit 7 reads 0 (data sheet 6.3.3, notes 1 and 3).
            0 => (self.cr & 0x5E) | 0x20 | u8::from(reset),
            1 => 0xFF, // write only; reads FFh (data sheet 6.3.4)
            2 => self.status(),
            3 => self.ir_value() | 0xE0, // IR bits 7:5 are reserved and read 1
            4 => reset_only(self.acr[0]),
            5 => reset_only(self.amr[0]),
            6 => reset_only(self.btr0),
            7 => reset_only(self.btr1),
            8 => reset_only(self.ocr),
            9 => self.test,
            10..=19 if reset => 0xFF,
            10..=19 => self.tx[usize::from(addr - 10)],
            20..=29 => self.basic_rx(usize::from(addr - 20)),
            31 => self.cdr,
            _ => 0x00,
        }
    }

    /// Byte `i` of the BasicCAN receive buffer: ID10..3, then ID2..0 | RTR | DLC, then data,
    /// read from the front message of the FIFO (stored in PeliCAN layout).
    fn basic_rx(&self, i: usize) -> u8 {
        let info = self.fifo.at(0);
        match i {
            0 => self.fifo.at(1),
            1 => (self.fifo.at(2) & 0xE0) | ((info & 0x40) >> 2) | (info & 0x0F),
            n => self.fifo.at(n + 1),
        }
    }

    fn write_peli(&mut self, addr: u8, value: u8) {
        let reset = self.reset;
        match addr {
            0 => {
                // LOM, STM and AFM change only in reset mode (data sheet 6.4.3).
                if reset {
                    self.mode_bits = value & (mod_bits::LOM | mod_bits::STM | mod_bits::AFM);
                }
                if value & mod_bits::RM != 0 {
                    self.enter_reset();
                } else if reset {
                    self.leave_reset();
                } else {
                    self.set_sleep(value & mod_bits::SM != 0);
                }
            }
            1 => self.command(value, true),
            4 => self.ier = value,
            6 if reset => self.btr0 = value,
            7 if reset => self.btr1 = value,
            8 if reset => self.ocr = value,
            9 => self.test = value,
            13 if reset => self.ewlr = value,
            // RXERR cannot be changed while bus-off (data sheet 6.4.11).
            14 if reset && !self.bus_off => {
                self.rec = u16::from(value);
                self.counters_written = true;
                self.push_counters();
            }
            15 if reset => {
                // 0–254 while bus-off clears bus-off; 255 asks for a bus-off when reset mode
                // is left (data sheet 6.4.12).
                self.tec = u16::from(value);
                if self.bus_off && value < 255 {
                    self.bus_off = false;
                }
                self.counters_written = true;
                self.push_counters();
            }
            16..=19 if reset => self.acr[usize::from(addr - 16)] = value,
            20..=23 if reset => self.amr[usize::from(addr - 20)] = value,
            a if WINDOW.contains(&a) && !reset => self.write_tx(usize::from(a - 16), value),
            30 if reset => self.fifo.start = value & 0x3F,
            31 => self.write_cdr(value),
            a if FIFO_RAM.contains(&a) && reset => self.fifo.ram[usize::from(a - 32)] = value,
            a if TX_RAM.contains(&a) && reset => self.tx[usize::from(a - 96)] = value,
            _ => {}
        }
    }

    fn write_basic(&mut self, addr: u8, value: u8) {
        let reset = self.reset;
        match addr {
            0 => {
                self.cr = value & 0x5E;
                if value & 0x01 != 0 {
                    self.enter_reset();
                } else if reset {
                    self.leave_reset();
                }
            }
            1 => self.command(value, false),
            4 if reset => self.acr[0] = value,
            5 if reset => self.amr[0] = value,
            6 if reset => self.btr0 = value,
            7 if reset => self.btr1 = value,
            8 if reset => self.ocr = value,
            9 => self.test = value,
            10..=19 if !reset => self.write_tx(usize::from(addr - 10), value),
            31 => self.write_cdr(value),
            _ => {}
        }
    }

    fn write_cdr(&mut self, value: u8) {
        let mask = if self.reset {
            CDR_RESET_ONLY | CDR_ANY_TIME
        } else {
            CDR_ANY_TIME
        };
        self.cdr = (self.cdr & !mask) | (value & mask);
    }

    /// The transmit buffer takes writes only while released (data sheet 6.3.5 note 5).
    fn write_tx(&mut self, i: usize, value: u8) {
        if self.tbs
            && self.pending.is_none()
            && let Some(b) = self.tx.get_mut(i)
        {
            *b = value;
        }
    }

    fn push_counters(&mut self) {
        self.actions.push(super::Action::SetCounters {
            tec: self.tec,
            rec: self.rec,
        });
    }

    /// CMR (data sheet 6.3.4, 6.4.4). Commands other than CDO need operating mode.
    fn command(&mut self, value: u8, peli: bool) {
        if value & cmr::CDO != 0 {
            self.dos = false;
        }
        if self.reset {
            return;
        }
        let self_reception = peli && value & cmr::SRR != 0;
        let single_shot = value & cmr::AT != 0;
        if value & cmr::TR != 0 || self_reception {
            self.request(self_reception, single_shot);
        } else if single_shot && self.pending.is_some() {
            self.actions.push(super::Action::Abort);
        }
        if value & cmr::RRB != 0 {
            self.fifo.release();
        }
        if !peli {
            self.set_sleep(value & cmr::SRR != 0); // GTS
        }
    }

    /// The frame in the transmit buffer. PeliCAN: frame information (FF, RTR, DLC), 2 or 4
    /// identifier bytes, data (data sheet 6.4.13); bits below the identifier are ignored, RTR
    /// comes from the frame information. BasicCAN: ID10..3, ID2..0 | RTR | DLC, data (6.3.7).
    /// A DLC above 8 sends 8 data bytes and is given as 8.
    pub(super) fn tx_frame(&self) -> Option<Frame> {
        let t = &self.tx;
        let (ext, rtr, dlc, id, data) = match self.mode() {
            Mode::PeliCan => {
                let ext = t[0] & 0x80 != 0;
                let id = if ext {
                    (u32::from(t[1]) << 21)
                        | (u32::from(t[2]) << 13)
                        | (u32::from(t[3]) << 5)
                        | (u32::from(t[4]) >> 3)
                } else {
                    (u32::from(t[1]) << 3) | (u32::from(t[2]) >> 5)
                };
                let start = if ext { 5 } else { 3 };
                (ext, t[0] & 0x40 != 0, t[0] & 0x0F, id, &t[start..])
            }
            Mode::BasicCan => {
                let id = (u32::from(t[0]) << 3) | (u32::from(t[1]) >> 5);
                (false, t[1] & 0x10 != 0, t[1] & 0x0F, id, &t[2..10])
            }
        };
        let n = usize::from(dlc.min(8));
        let id: crate::Id = if ext {
            ExtendedId::new(id)?.into()
        } else {
            StandardId::new(id as u16)?.into()
        };
        if rtr {
            Frame::new_remote(id, n).ok()
        } else {
            Frame::new_data(id, data.get(..n)?).ok()
        }
    }
}
