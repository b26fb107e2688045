//! Instruction decode and execution (Intel MCS-51 User's Manual, "Instruction Set").
//!
//! Read-modify-write instructions (ANL/ORL/XRL direct, INC/DEC direct, DJNZ direct, JBC,
//! CPL/CLR/SETB bit, MOV bit,C) read a port's latch; every other read of a port reads its pins.

use super::access::AC;
use super::{B, Cpu, DPH, DPL, PSW};
use crate::{Error, Xdata};

/// Machine cycles per opcode.
const CYCLES: [u8; 256] = {
    let mut t = [1u8; 256];
    let two: [u8; 50] = [
        0x02, 0x10, 0x12, 0x20, 0x22, 0x30, 0x32, 0x40, 0x43, 0x50, 0x53, 0x60, 0x63, 0x70, 0x72, 0x73, 0x75,
        0x80, 0x82, 0x83, 0x85, 0x86, 0x87, 0x90, 0x92, 0x93, 0xA0, 0xA3, 0xA6, 0xA7, 0xB0, 0xB4, 0xB5, 0xB6,
        0xB7, 0xC0, 0xD0, 0xD5, 0xE0, 0xE2, 0xE3, 0xF0, 0xF2, 0xF3, 0x88, 0xA8, 0xB8, 0xD8, 0x01, 0x11,
    ];
    let mut i = 0;
    while i < two.len() {
        t[two[i] as usize] = 2;
        i += 1;
    }
    // MOV direct,Rn; MOV Rn,direct; CJNE Rn; DJNZ Rn; AJMP/ACALL pages.
    let mut r = 0;
    while r < 8 {
        t[0x88 + r] = 2;
        t[0xA8 + r] = 2;
        t[0xB8 + r] = 2;
        t[0xD8 + r] = 2;
        t[(r << 5) | 0x01] = 2;
        t[(r << 5) | 0x11] = 2;
        r += 1;
    }
    t[0x84] = 4;
    t[0xA4] = 4;
    t
};

/// Conditional jumps test their operand in their last cycle: all their cycles pass first.
const TESTS_LATE: [bool; 256] = {
    let mut t = [false; 256];
    let ops = [0x20, 0x30, 0x40, 0x50, 0x60, 0x70, 0xB4, 0xB5, 0xB6, 0xB7, 0xD5];
    let mut i = 0;
    while i < ops.len() {
        t[ops[i]] = true;
        i += 1;
    }
    let mut r = 0;
    while r < 8 {
        t[0xB8 + r] = true;
        t[0xD8 + r] = true;
        r += 1;
    }
    t
};

impl Cpu {
    /// Executes the instruction at PC; returns its machine cycles.
    pub(crate) fn execute(&mut self, x: &mut dyn Xdata) -> Result<u8, Error> {
        self.op_pc = self.pc;
        let op = self.fetch();
        let n = CYCLES[op as usize];
        let start = self.cycles;
        self.cycles = start + n as u64;
        // The first machine cycle passes before the instruction's effect (a timer started by
        // SETB TRx does not count that instruction's cycle), the others after it; conditional
        // jumps test after all their cycles. This is where s51 places them too.
        let before = if TESTS_LATE[op as usize] { n } else { 1 };
        self.effect_at = start + before as u64;
        match op {
            0x00 => {}
            0x01 | 0x21 | 0x41 | 0x61 | 0x81 | 0xA1 | 0xC1 | 0xE1 => {
                let lo = self.fetch();
                self.pc = (self.pc & 0xF800) | (op as u16 >> 5) << 8 | lo as u16;
            }
            0x11 | 0x31 | 0x51 | 0x71 | 0x91 | 0xB1 | 0xD1 | 0xF1 => {
                let lo = self.fetch();
                let target = (self.pc & 0xF800) | (op as u16 >> 5) << 8 | lo as u16;
                self.call(target)?;
            }
            0x02 => {
                let hi = self.fetch();
                let lo = self.fetch();
                self.pc = u16::from_be_bytes([hi, lo]);
            }
            0x12 => {
                let hi = self.fetch();
                let lo = self.fetch();
                self.call(u16::from_be_bytes([hi, lo]))?;
            }
            0x22 | 0x32 => {
                let hi = self.pop();
                let lo = self.pop();
                self.pc = u16::from_be_bytes([hi, lo]);
                if op == 0x32 {
                    self.end_of_interrupt();
                }
            }
            0x03 => self.set_a(self.a().rotate_right(1)),
            0x23 => self.set_a(self.a().rotate_left(1)),
            0x13 => {
                let a = self.a();
                self.set_a(a >> 1 | (self.cy() as u8) << 7);
                self.set_cy(a & 1 != 0);
            }
            0x33 => {
                let a = self.a();
                self.set_a(a << 1 | self.cy() as u8);
                self.set_cy(a & 0x80 != 0);
            }
            0x04 => self.set_a(self.a().wrapping_add(1)),
            0x14 => self.set_a(self.a().wrapping_sub(1)),
            0x05 | 0x15 => {
                let d = self.fetch();
                let v = self.latch(x, d);
                self.set_direct(
                    x,
                    d,
                    if op == 0x05 {
                        v.wrapping_add(1)
                    } else {
                        v.wrapping_sub(1)
                    },
                );
            }
            0x06 | 0x07 | 0x16 | 0x17 => {
                let r = self.iram[self.rn(op & 1)];
                let v = self.indirect(r);
                self.set_indirect(
                    r,
                    if op < 0x10 {
                        v.wrapping_add(1)
                    } else {
                        v.wrapping_sub(1)
                    },
                );
            }
            0x08..=0x0F => {
                let r = self.rn(op & 7);
                self.iram[r] = self.iram[r].wrapping_add(1);
            }
            0x18..=0x1F => {
                let r = self.rn(op & 7);
                self.iram[r] = self.iram[r].wrapping_sub(1);
            }
            0x10 | 0x20 | 0x30 => {
                let bit = self.fetch();
                let rel = self.fetch();
                let set = if op == 0x10 {
                    let (byte, mask) = Self::bit_loc(bit);
                    self.latch(x, byte) & mask != 0
                } else {
                    self.bit(x, bit)
                };
                if op == 0x10 && set {
                    self.set_bit(x, bit, false);
                }
                if set == (op != 0x30) {
                    self.jump_rel(rel);
                }
            }
            0x40 | 0x50 | 0x60 | 0x70 | 0x80 => {
                let rel = self.fetch();
                let take = match op {
                    0x40 => self.cy(),
                    0x50 => !self.cy(),
                    0x60 => self.a() == 0,
                    0x70 => self.a() != 0,
                    _ => true,
                };
                if take {
                    self.jump_rel(rel);
                }
            }
            0x24..=0x2F | 0x34..=0x3F | 0x44..=0x4F | 0x54..=0x5F | 0x64..=0x6F | 0x94..=0x9F => {
                let v = self.alu_operand(x, op);
                match op >> 4 {
                    0x2 => self.add(v, false),
                    0x3 => self.add(v, self.cy()),
                    0x4 => self.set_a(self.a() | v),
                    0x5 => self.set_a(self.a() & v),
                    0x6 => self.set_a(self.a() ^ v),
                    _ => self.subb(v),
                }
            }
            0x42 | 0x43 | 0x52 | 0x53 | 0x62 | 0x63 => {
                let d = self.fetch();
                let v = if op & 1 == 0 { self.a() } else { self.fetch() };
                let old = self.latch(x, d);
                let r = match op >> 4 {
                    0x4 => old | v,
                    0x5 => old & v,
                    _ => old ^ v,
                };
                self.set_direct(x, d, r);
            }
            0x72 | 0x82 | 0xA0 | 0xB0 => {
                let b = self.fetch();
                let v = self.bit(x, b);
                let c = self.cy();
                self.set_cy(match op {
                    0x72 => c | v,
                    0x82 => c & v,
                    0xA0 => c | !v,
                    _ => c & !v,
                });
            }
            0x73 => self.pc = self.dptr().wrapping_add(self.a() as u16),
            0x74 => {
                let v = self.fetch();
                self.set_a(v);
            }
            0x75 => {
                let d = self.fetch();
                let v = self.fetch();
                self.set_direct(x, d, v);
            }
            0x76 | 0x77 => {
                let v = self.fetch();
                let r = self.iram[self.rn(op & 1)];
                self.set_indirect(r, v);
            }
            0x78..=0x7F => {
                let v = self.fetch();
                let r = self.rn(op & 7);
                self.iram[r] = v;
            }
            0x83 => self.set_a(self.code[self.pc.wrapping_add(self.a() as u16) as usize]),
            0x93 => self.set_a(self.code[self.dptr().wrapping_add(self.a() as u16) as usize]),
            0x84 => {
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
            0xA4 => {
                let p = self.a() as u16 * self.sfr[(B - 0x80) as usize] as u16;
                self.set_a(p as u8);
                self.sfr[(B - 0x80) as usize] = (p >> 8) as u8;
                self.set_cy_ov(false, p > 0xFF);
            }
            0x85 => {
                let src = self.fetch();
                let dst = self.fetch();
                let v = self.direct(x, src);
                self.set_direct(x, dst, v);
            }
            0x86..=0x8F => {
                let v = self.src_operand(x, op);
                let d = self.fetch();
                self.set_direct(x, d, v);
            }
            0x90 => {
                let hi = self.fetch();
                let lo = self.fetch();
                self.sfr[(DPH - 0x80) as usize] = hi;
                self.sfr[(DPL - 0x80) as usize] = lo;
            }
            0x92 => {
                let b = self.fetch();
                self.set_bit(x, b, self.cy());
            }
            0xA2 => {
                let b = self.fetch();
                let v = self.bit(x, b);
                self.set_cy(v);
            }
            0xA3 => {
                let [lo, hi] = self.dptr().wrapping_add(1).to_le_bytes();
                self.sfr[(DPL - 0x80) as usize] = lo;
                self.sfr[(DPH - 0x80) as usize] = hi;
            }
            0xA5 => return Err(self.fail(Error::ReservedOpcode { pc: self.op_pc })),
            0xA6 | 0xA7 => {
                let d = self.fetch();
                let v = self.direct(x, d);
                let r = self.iram[self.rn(op & 1)];
                self.set_indirect(r, v);
            }
            0xA8..=0xAF => {
                let d = self.fetch();
                let v = self.direct(x, d);
                let r = self.rn(op & 7);
                self.iram[r] = v;
            }
            0xB2 | 0xC2 | 0xD2 => {
                let b = self.fetch();
                let v = match op {
                    0xB2 => {
                        let (byte, mask) = Self::bit_loc(b);
                        self.latch(x, byte) & mask == 0
                    }
                    0xC2 => false,
                    _ => true,
                };
                self.set_bit(x, b, v);
            }
            0xB3 => self.set_cy(!self.cy()),
            0xC3 => self.set_cy(false),
            0xD3 => self.set_cy(true),
            0xB4 => {
                let v = self.fetch();
                self.cjne(self.a(), v);
            }
            0xB5 => {
                let d = self.fetch();
                let v = self.direct(x, d);
                self.cjne(self.a(), v);
            }
            0xB6 | 0xB7 => {
                let v = self.fetch();
                let x = self.indirect(self.iram[self.rn(op & 1)]);
                self.cjne(x, v);
            }
            0xB8..=0xBF => {
                let v = self.fetch();
                let x = self.iram[self.rn(op & 7)];
                self.cjne(x, v);
            }
            0xC0 => {
                // SP <- SP + 1, then ((SP)) <- (direct): `PUSH SP` stores the incremented SP.
                let d = self.fetch();
                let at = self.push_slot()?;
                let v = self.direct(x, d);
                self.iram[at] = v;
            }
            // ((SP)) is read and SP decremented before the write, so `POP SP` leaves SP at the
            // value popped (the manual's example).
            0xD0 => {
                let d = self.fetch();
                let v = self.pop();
                self.set_direct(x, d, v);
            }
            0xC4 => self.set_a(self.a().rotate_left(4)),
            0xC5 => {
                let d = self.fetch();
                let v = self.direct(x, d);
                let a = self.a();
                self.set_direct(x, d, a);
                self.set_a(v);
            }
            0xC6 | 0xC7 => {
                let r = self.iram[self.rn(op & 1)];
                let v = self.indirect(r);
                let a = self.a();
                self.set_indirect(r, a);
                self.set_a(v);
            }
            0xC8..=0xCF => {
                let r = self.rn(op & 7);
                let v = self.iram[r];
                self.iram[r] = self.a();
                self.set_a(v);
            }
            0xD4 => {
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
            0xD5 => {
                let d = self.fetch();
                let rel = self.fetch();
                let v = self.latch(x, d).wrapping_sub(1);
                self.set_direct(x, d, v);
                if v != 0 {
                    self.jump_rel(rel);
                }
            }
            0xD6 | 0xD7 => {
                let r = self.iram[self.rn(op & 1)];
                let v = self.indirect(r);
                let a = self.a();
                self.set_indirect(r, (v & 0xF0) | (a & 0x0F));
                self.set_a((a & 0xF0) | (v & 0x0F));
            }
            0xD8..=0xDF => {
                let rel = self.fetch();
                let r = self.rn(op & 7);
                self.iram[r] = self.iram[r].wrapping_sub(1);
                if self.iram[r] != 0 {
                    self.jump_rel(rel);
                }
            }
            0xE0 | 0xE2 | 0xE3 => {
                let addr = if op == 0xE0 {
                    self.dptr()
                } else {
                    self.movx_addr_ri(op)
                };
                let v = self.movx_read(x, addr);
                self.set_a(v);
            }
            0xF0 | 0xF2 | 0xF3 => {
                let addr = if op == 0xF0 {
                    self.dptr()
                } else {
                    self.movx_addr_ri(op)
                };
                self.movx_write(x, addr, self.a());
            }
            0xE4 => self.set_a(0),
            0xF4 => self.set_a(!self.a()),
            0xE5..=0xEF => {
                let v = self.src_operand(x, op);
                self.set_a(v);
            }
            0xF5 => {
                let d = self.fetch();
                self.set_direct(x, d, self.a());
            }
            0xF6 | 0xF7 => {
                let r = self.iram[self.rn(op & 1)];
                self.set_indirect(r, self.a());
            }
            0xF8..=0xFF => {
                let r = self.rn(op & 7);
                self.iram[r] = self.a();
            }
        }
        if self.cycles >= self.next_event {
            self.sync(self.cycles);
        }
        Ok(n)
    }
}
