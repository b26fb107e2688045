//! Timer 2 of the AT89C51CC03 (as on the 8052): T2CON, T2MOD, RCAP2L/H, TL2/TH2.
//!
//! Modes (AT89C51CC03 data sheet, "Timer 2"; Intel 8052 description): with RCLK = TCLK = 0,
//! CP/RL2 = 0 is 16-bit auto-reload (an overflow loads RCAP2 and sets TF2; with EXEN2 a
//! falling edge on T2EX = P1.1 also reloads and sets EXF2) and CP/RL2 = 1 is capture (the
//! 16-bit count wraps to 0000h and sets TF2; with EXEN2 a falling T2EX edge copies TL2/TH2 into
//! RCAP2 and sets EXF2). With RCLK or TCLK set, timer 2 is the serial port's baud-rate
//! generator: it counts every state (6 counts per machine cycle), reloads from RCAP2 and sets no
//! TF2; a T2EX edge with EXEN2 sets EXF2 only. C/T2 = 1 counts falling edges on T2 = P1.0
//! instead. Only TCLK matters here (the core sends, it never receives). Not modelled: T2MOD.DCEN
//! (up/down counting) and T2MOD.T2OE (clock output); T2MOD is stored.

use super::Cpu;

pub(crate) const T2CON: u8 = 0xC8;
pub(crate) const T2MOD: u8 = 0xC9;
pub(crate) const RCAP2L: u8 = 0xCA;
pub(crate) const RCAP2H: u8 = 0xCB;
pub(crate) const TL2: u8 = 0xCC;
pub(crate) const TH2: u8 = 0xCD;

const TF2: u8 = 0x80;
const EXF2: u8 = 0x40;
const EXEN2: u8 = 0x08;
const TR2: u8 = 0x04;
const CT2: u8 = 0x02;
const CPRL2: u8 = 0x01;
/// RCLK or TCLK: baud-rate generator mode.
const BAUD: u8 = 0x30;

impl Cpu {
    fn t2(&self) -> u32 {
        u32::from_le_bytes([
            self.sfr[(TL2 - 0x80) as usize],
            self.sfr[(TH2 - 0x80) as usize],
            0,
            0,
        ])
    }
    fn set_t2(&mut self, v: u32) {
        self.sfr[(TL2 - 0x80) as usize] = v as u8;
        self.sfr[(TH2 - 0x80) as usize] = (v >> 8) as u8;
    }
    fn rcap2(&self) -> u32 {
        u32::from_le_bytes([
            self.sfr[(RCAP2L - 0x80) as usize],
            self.sfr[(RCAP2H - 0x80) as usize],
            0,
            0,
        ])
    }
    fn t2con(&self) -> u8 {
        self.sfr[(T2CON - 0x80) as usize]
    }

    /// Whether the serial transmitter is clocked by timer 2 (T2CON.TCLK).
    pub(crate) fn tx_on_timer2(&self) -> bool {
        self.cc03() && self.t2con() & 0x10 != 0
    }

    /// Whether timer 2 runs as a timer in baud-rate generator mode.
    pub(crate) fn timer2_runs(&self) -> bool {
        self.t2con() & TR2 != 0
    }

    /// Counts `n` machine cycles (or, with `edge`, one falling edge on T2); returns the
    /// overflows.
    pub(crate) fn advance_timer2(&mut self, n: u64, edge: bool) -> u64 {
        let con = self.t2con();
        if con & TR2 == 0 || (con & CT2 != 0) != edge {
            return 0;
        }
        let baud = con & BAUD != 0;
        let inc = if baud && !edge { 6 * n } else { n };
        if inc == 0 {
            return 0;
        }
        let total = self.t2() as u64 + inc;
        if total < 0x1_0000 {
            self.set_t2(total as u32);
            return 0;
        }
        let over = total - 0x1_0000;
        let ov = if con & CPRL2 != 0 && !baud {
            self.set_t2((over & 0xFFFF) as u32);
            1 + (over >> 16)
        } else {
            let reload = self.rcap2() as u64;
            let period = 0x1_0000 - reload;
            self.set_t2((reload + over % period) as u32);
            1 + over / period
        };
        if !baud {
            self.raise(T2CON, TF2);
        }
        ov
    }

    /// Machine cycles from `synced` to timer 2's next overflow that matters (one that sets TF2,
    /// or one the transmitter waits for), if timer 2 counts cycles.
    pub(crate) fn timer2_cycles_to_event(&self, tx_waits: bool) -> Option<u64> {
        let con = self.t2con();
        if con & TR2 == 0 || con & CT2 != 0 {
            return None;
        }
        let left = 0x1_0000 - self.t2() as u64;
        if con & BAUD == 0 {
            Some(left)
        } else if tx_waits {
            Some(left.div_ceil(6))
        } else {
            None
        }
    }

    /// Port 1 pins changed: a falling edge on T2 (P1.0) counts, one on T2EX (P1.1) captures or
    /// reloads when EXEN2 is set.
    pub(crate) fn p1_changed(&mut self, before: u8) {
        self.irq_quiet = false;
        let falling = before & !self.pins(1);
        if falling & 0x01 != 0 {
            let ov = self.advance_timer2(1, true);
            if self.tx_on_timer2() {
                self.serial_tick(0, ov);
            }
        }
        let con = self.t2con();
        if falling & 0x02 != 0 && con & EXEN2 != 0 {
            if con & BAUD == 0 {
                if con & CPRL2 != 0 {
                    let [l, h, ..] = self.t2().to_le_bytes();
                    self.sfr[(RCAP2L - 0x80) as usize] = l;
                    self.sfr[(RCAP2H - 0x80) as usize] = h;
                } else {
                    self.set_t2(self.rcap2());
                }
            }
            self.raise(T2CON, EXF2);
        }
    }
}
