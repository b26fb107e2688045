//! Instruction execution from the decoded form ([`crate::decode`]): the meaning of each
//! operation, written once for all its operands.
//!
//! Read-modify-write instructions (ANL/ORL/XRL direct, INC/DEC direct, DJNZ direct, JBC,
//! CPL/CLR/SETB bit, MOV bit,C) read a port's latch; every other read of a port reads its pins.

use super::access::{AC, Port};
use super::{B, Cpu, DPH, DPL, PSW};
use crate::decode::{Decoded, Ins, Opnd, decode};
use crate::{Cover, Error, Xdata};

/// A `match` on the opcode byte with one arm per opcode, each calling `Cpu::exec::<OP>`: every
/// arm is compiled with its decoded entry as constants, so the matches on the operation and its
/// operands fold away and execution costs what a hand-written arm per opcode would.
macro_rules! dispatch {
    ($cpu:ident, $x:ident, $skip:ident, $cover:ident, $op:expr; $($n:literal)*) => {
        match $op {
            $($n => $cpu.exec::<$n, C>($x, $skip, $cover),)*
        }
    };
}

impl Cpu {
    /// Executes the instruction at PC; returns its machine cycles. A DJNZ delay loop onto
    /// itself is passed in closed form instead, as far as it may go before cycle `skip_until`
    /// ([`Cpu::skip_delay_loop`]): then it returns 0, which no instruction takes.
    // Optimised, inlined into the run loop: as a call, its prologue and epilogue (the frame of
    // every opcode's arm) cost about 17 host instructions per instruction, a tenth of the
    // whole firmware harvester's.
    #[cfg_attr(not(debug_assertions), inline(always))]
    pub(crate) fn execute<C: Cover>(
        &mut self,
        x: &mut dyn Xdata,
        skip_until: u64,
        cover: &mut C,
    ) -> Result<u8, Error> {
        let op = self.code[self.pc as usize];
        dispatch!(self, x, skip_until, cover, op;
            0x00 0x01 0x02 0x03 0x04 0x05 0x06 0x07 0x08 0x09 0x0A 0x0B 0x0C 0x0D 0x0E 0x0F
            0x10 0x11 0x12 0x13 0x14 0x15 0x16 0x17 0x18 0x19 0x1A 0x1B 0x1C 0x1D 0x1E 0x1F
            0x20 0x21 0x22 0x23 0x24 0x25 0x26 0x27 0x28 0x29 0x2A 0x2B 0x2C 0x2D 0x2E 0x2F
            0x30 0x31 0x32 0x33 0x34 0x35 0x36 0x37 0x38 0x39 0x3A 0x3B 0x3C 0x3D 0x3E 0x3F
            0x40 0x41 0x42 0x43 0x44 0x45 0x46 0x47 0x48 0x49 0x4A 0x4B 0x4C 0x4D 0x4E 0x4F
            0x50 0x51 0x52 0x53 0x54 0x55 0x56 0x57 0x58 0x59 0x5A 0x5B 0x5C 0x5D 0x5E 0x5F
            0x60 0x61 0x62 0x63 0x64 0x65 0x66 0x67 0x68 0x69 0x6A 0x6B 0x6C 0x6D 0x6E 0x6F
            0x70 0x71 0x72 0x73 0x74 0x75 0x76 0x77 0x78 0x79 0x7A 0x7B 0x7C 0x7D 0x7E 0x7F
            0x80 0x81 0x82 0x83 0x84 0x85 0x86 0x87 0x88 0x89 0x8A 0x8B 0x8C 0x8D 0x8E 0x8F
            0x90 0x91 0x92 0x93 0x94 0x95 0x96 0x97 0x98 0x99 0x9A 0x9B 0x9C 0x9D 0x9E 0x9F
            0xA0 0xA1 0xA2 0xA3 0xA4 0xA5 0xA6 0xA7 0xA8 0xA9 0xAA 0xAB 0xAC 0xAD 0xAE 0xAF
            0xB0 0xB1 0xB2 0xB3 0xB4 0xB5 0xB6 0xB7 0xB8 0xB9 0xBA 0xBB 0xBC 0xBD 0xBE 0xBF
            0xC0 0xC1 0xC2 0xC3 0xC4 0xC5 0xC6 0xC7 0xC8 0xC9 0xCA 0xCB 0xCC 0xCD 0xCE 0xCF
            0xD0 0xD1 0xD2 0xD3 0xD4 0xD5 0xD6 0xD7 0xD8 0xD9 0xDA 0xDB 0xDC 0xDD 0xDE 0xDF
            0xE0 0xE1 0xE2 0xE3 0xE4 0xE5 0xE6 0xE7 0xE8 0xE9 0xEA 0xEB 0xEC 0xED 0xEE 0xEF
            0xF0 0xF1 0xF2 0xF3 0xF4 0xF5 0xF6 0xF7 0xF8 0xF9 0xFA 0xFB 0xFC 0xFD 0xFE 0xFF
        )
    }

    /// Executes opcode `OP` at PC: the cycle count and PC move on first, then the operation;
    /// the timers catch up if an event fell within it.
    // Optimised, every opcode is inlined into `execute`'s one jump table: with a call per
    // instruction the firmware-cpu bench ran about a quarter slower, though it executed fewer
    // host instructions. Unoptimised, each stays a function of its own: inlined there, every
    // copy keeps its own stack slots and `execute` needs a frame of nearly 1 MB.
    #[cfg_attr(not(debug_assertions), inline(always))]
    #[cfg_attr(debug_assertions, inline)]
    fn exec<const OP: u8, C: Cover>(
        &mut self,
        x: &mut dyn Xdata,
        skip_until: u64,
        cover: &mut C,
    ) -> Result<u8, Error> {
        let d = const { decode(OP) };
        // Tested here, where it folds away for every other opcode.
        if matches!(d.ins, Ins::Djnz) && self.skip_delay_loop(self.djnz_bound(skip_until), cover) {
            return Ok(0);
        }
        let pc = self.pc;
        self.op_pc = pc;
        self.pc = pc.wrapping_add(d.len as u16);
        let start = self.cycles;
        self.cycles = start + d.cycles as u64;
        // The first machine cycle passes before the instruction's effect (a timer started by
        // SETB TRx does not count that instruction's cycle), the others after it; conditional
        // jumps test after all their cycles. This is where s51 places them too.
        let before = if d.ins.tests_late() { d.cycles } else { 1 };
        self.effect_at = start + before as u64;
        // Not `?`: an unoptimised build makes it a call, and this runs for every instruction.
        match self.perform(x, d, pc) {
            Ok(()) => {
                if self.cycles >= self.next_event {
                    self.sync(self.cycles);
                }
                if d.ins.tests_late() || matches!(d.ins, Ins::Jbc) {
                    cover.jumped(pc, self.pc != pc.wrapping_add(d.len as u16));
                } else {
                    cover.ran(pc);
                }
                Ok(d.cycles)
            }
            // A fault returns before the timers catch up.
            Err(e) => Err(e),
        }
    }

    /// The byte at offset `k` from the opcode at `pc`.
    #[inline(always)]
    fn arg(&self, pc: u16, k: u8) -> u8 {
        self.code[pc.wrapping_add(k as u16) as usize]
    }

    /// Does what `d` says; PC is already past the instruction at `pc`.
    #[inline(always)]
    fn perform(&mut self, x: &mut dyn Xdata, d: Decoded, pc: u16) -> Result<(), Error> {
        use Ins::*;
        let [o1, o2, _] = d.opnds;
        // The bytes after the opcode, and each operand's first (0 for an operand without bytes,
        // unused). A 16-bit operand is the only one with two, at offsets 1 and 2.
        let bytes = [0, self.arg(pc, 1), self.arg(pc, 2)];
        let [b1, b2, b3] = [
            bytes[d.at[0] as usize],
            bytes[d.at[1] as usize],
            bytes[d.at[2] as usize],
        ];
        match d.ins {
            Nop => {}
            Ajmp | Ljmp => self.pc = o1.target(self.pc, b1, bytes[2]),
            Acall | Lcall => self.call(o1.target(self.pc, b1, bytes[2]))?,
            Ret | Reti => {
                let hi = self.pop();
                let lo = self.pop();
                self.pc = u16::from_be_bytes([hi, lo]);
                if matches!(d.ins, Reti) {
                    self.end_of_interrupt();
                }
            }
            Sjmp => self.jump_rel(b1),
            Jmp => self.pc = self.dptr().wrapping_add(self.a() as u16),
            Jc | Jnc | Jz | Jnz => {
                let take = match d.ins {
                    Jc => self.cy(),
                    Jnc => !self.cy(),
                    Jz => self.a() == 0,
                    _ => self.a() != 0,
                };
                if take {
                    self.jump_rel(b1);
                }
            }
            Jbc | Jb | Jnb => {
                let set = if matches!(d.ins, Jbc) {
                    let (byte, mask) = Self::bit_loc(b1);
                    self.latch(x, byte) & mask != 0
                } else {
                    self.bit(x, b1)
                };
                if matches!(d.ins, Jbc) && set {
                    self.set_bit(x, b1, false);
                }
                if set != matches!(d.ins, Jnb) {
                    self.jump_rel(b2);
                }
            }
            Cjne => {
                let l = self.load(x, o1, b1, Port::Pins);
                let r = self.load(x, o2, b2, Port::Pins);
                self.set_cy(l < r);
                if l != r {
                    self.jump_rel(b3);
                }
            }
            Djnz => {
                let v = self.load(x, o1, b1, Port::Latch).wrapping_sub(1);
                self.store(x, o1, b1, v);
                if v != 0 {
                    self.jump_rel(b2);
                }
            }
            Rr => self.set_a(self.a().rotate_right(1)),
            Rl => self.set_a(self.a().rotate_left(1)),
            Rrc => {
                let a = self.a();
                self.set_a(a >> 1 | (self.cy() as u8) << 7);
                self.set_cy(a & 1 != 0);
            }
            Rlc => {
                let a = self.a();
                self.set_a(a << 1 | self.cy() as u8);
                self.set_cy(a & 0x80 != 0);
            }
            Swap => self.set_a(self.a().rotate_left(4)),
            Da => self.decimal_adjust(),
            Inc if matches!(o1, Opnd::Dptr) => {
                let [lo, hi] = self.dptr().wrapping_add(1).to_le_bytes();
                self.sfr[(DPL - 0x80) as usize] = lo;
                self.sfr[(DPH - 0x80) as usize] = hi;
            }
            Inc | Dec => {
                let v = self.load(x, o1, b1, Port::Latch);
                let v = if matches!(d.ins, Inc) {
                    v.wrapping_add(1)
                } else {
                    v.wrapping_sub(1)
                };
                self.store(x, o1, b1, v);
            }
            Add | Addc | Subb => {
                let v = self.load(x, o2, b2, Port::Pins);
                match d.ins {
                    Add => self.add(v, false),
                    Addc => self.add(v, self.cy()),
                    _ => self.subb(v),
                }
            }
            Orl | Anl if matches!(o1, Opnd::C) => {
                let v = self.bit(x, b2);
                let v = if matches!(o2, Opnd::NotBit) { !v } else { v };
                let c = self.cy();
                self.set_cy(if matches!(d.ins, Orl) { c | v } else { c & v });
            }
            Orl | Anl | Xrl => {
                let v = self.load(x, o2, b2, Port::Pins);
                let old = self.load(x, o1, b1, Port::Latch);
                let r = match d.ins {
                    Orl => old | v,
                    Anl => old & v,
                    _ => old ^ v,
                };
                self.store(x, o1, b1, r);
            }
            Mul => {
                let p = self.a() as u16 * self.sfr[(B - 0x80) as usize] as u16;
                self.set_a(p as u8);
                self.sfr[(B - 0x80) as usize] = (p >> 8) as u8;
                self.set_cy_ov(false, p > 0xFF);
            }
            Div => {
                // Division by zero leaves A and B as they were (s51 does too) and sets OV.
                let (a, b) = (self.a(), self.sfr[(B - 0x80) as usize]);
                match (a.checked_div(b), a.checked_rem(b)) {
                    (Some(q), Some(r)) => {
                        self.set_a(q);
                        self.sfr[(B - 0x80) as usize] = r;
                        self.set_cy_ov(false, false);
                    }
                    _ => self.set_cy_ov(false, true),
                }
            }
            Mov => match (o1, o2) {
                (Opnd::Dptr, _) => {
                    self.sfr[(DPH - 0x80) as usize] = b2;
                    self.sfr[(DPL - 0x80) as usize] = bytes[2];
                }
                (Opnd::Bit, _) => self.set_bit(x, b1, self.cy()),
                (Opnd::C, _) => {
                    let v = self.bit(x, b2);
                    self.set_cy(v);
                }
                _ => {
                    let v = self.load(x, o2, b2, Port::Pins);
                    self.store(x, o1, b1, v);
                }
            },
            Movc => {
                let base = if matches!(o2, Opnd::AtAPc) {
                    self.pc
                } else {
                    self.dptr()
                };
                self.set_a(self.code[base.wrapping_add(self.a() as u16) as usize]);
            }
            Movx if matches!(o1, Opnd::A) => {
                let addr = self.movx_addr(o2);
                let v = self.movx_read(x, addr);
                self.set_a(v);
            }
            Movx => {
                let addr = self.movx_addr(o1);
                self.movx_write(x, addr, self.a());
            }
            Push => {
                // SP <- SP + 1, then ((SP)) <- (direct): `PUSH SP` stores the incremented SP.
                let at = self.push_slot()?;
                let v = self.direct(x, b1);
                self.iram[at] = v;
            }
            Pop => {
                // ((SP)) is read and SP decremented before the write, so `POP SP` leaves SP at
                // the value popped (the manual's example).
                let v = self.pop();
                self.set_direct(x, b1, v);
            }
            Xch => {
                let v = self.load(x, o2, b2, Port::Pins);
                let a = self.a();
                self.store(x, o2, b2, a);
                self.set_a(v);
            }
            Xchd => {
                let v = self.load(x, o2, b2, Port::Pins);
                let a = self.a();
                self.store(x, o2, b2, (v & 0xF0) | (a & 0x0F));
                self.set_a((a & 0xF0) | (v & 0x0F));
            }
            Cpl | Clr | Setb => match o1 {
                Opnd::A => self.set_a(if matches!(d.ins, Cpl) { !self.a() } else { 0 }),
                Opnd::C => self.set_cy(match d.ins {
                    Cpl => !self.cy(),
                    Clr => false,
                    _ => true,
                }),
                _ => {
                    let v = match d.ins {
                        Cpl => {
                            let (byte, mask) = Self::bit_loc(b1);
                            self.latch(x, byte) & mask == 0
                        }
                        Clr => false,
                        _ => true,
                    };
                    self.set_bit(x, b1, v);
                }
            },
            Reserved => return Err(self.fail(Error::ReservedOpcode { pc: self.op_pc })),
        }
        Ok(())
    }

    /// DA A: decimal adjust after a BCD addition.
    fn decimal_adjust(&mut self) {
        let mut a = self.a() as u16;
        if self.sfr[(PSW - 0x80) as usize] & AC != 0 || a & 0x0F > 9 {
            a += 0x06;
        }
        if self.cy() || a & 0x1F0 > 0x90 {
            a += 0x60;
        }
        self.set_a(a as u8);
        if a > 0xFF {
            self.set_cy(true);
        }
    }
}
