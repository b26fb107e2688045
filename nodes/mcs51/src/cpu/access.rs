//! Operand access and ALU helpers for the instruction set: registers, direct, indirect and bit
//! addresses, the stack, and the flag arithmetic of ADD/ADDC/SUBB.

use super::{ACC, Cpu, DPH, DPL, P2, PSW, SP};
use crate::decode::Opnd;
use crate::{Error, Xdata};

/// What a direct read of a port SFR sees: its pins, or its latch (read-modify-write
/// instructions).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Port {
    Pins,
    Latch,
}

const CY: u8 = 0x80;
pub(super) const AC: u8 = 0x40;
const OV: u8 = 0x04;

impl Cpu {
    #[inline(always)]
    pub(super) fn a(&self) -> u8 {
        self.sfr[(ACC - 0x80) as usize]
    }
    #[inline(always)]
    pub(super) fn set_a(&mut self, v: u8) {
        self.sfr[(ACC - 0x80) as usize] = v;
    }
    #[inline(always)]
    pub(super) fn psw_raw(&mut self) -> &mut u8 {
        &mut self.sfr[(PSW - 0x80) as usize]
    }
    #[inline(always)]
    pub(super) fn cy(&self) -> bool {
        self.sfr[(PSW - 0x80) as usize] & CY != 0
    }
    pub(super) fn set_cy(&mut self, c: bool) {
        let p = self.psw_raw();
        *p = if c { *p | CY } else { *p & !CY };
    }
    pub(super) fn dptr(&self) -> u16 {
        u16::from_le_bytes([self.sfr[(DPL - 0x80) as usize], self.sfr[(DPH - 0x80) as usize]])
    }
    /// Internal RAM address of register Rn in the current bank.
    #[inline(always)]
    pub(super) fn rn(&self, n: u8) -> usize {
        ((self.sfr[(PSW - 0x80) as usize] & 0x18) | n) as usize
    }
    pub(super) fn direct(&mut self, x: &mut dyn Xdata, addr: u8) -> u8 {
        if addr < 0x80 {
            self.iram[addr as usize]
        } else {
            self.read_sfr(x, addr, true)
        }
    }
    pub(super) fn latch(&mut self, x: &mut dyn Xdata, addr: u8) -> u8 {
        if addr < 0x80 {
            self.iram[addr as usize]
        } else {
            self.read_sfr(x, addr, false)
        }
    }
    pub(super) fn set_direct(&mut self, x: &mut dyn Xdata, addr: u8, v: u8) {
        if addr < 0x80 {
            self.iram[addr as usize] = v;
        } else {
            self.write_sfr(x, addr, v);
        }
    }
    pub(super) fn indirect(&self, addr: u8) -> u8 {
        self.iram[addr as usize]
    }
    pub(super) fn set_indirect(&mut self, addr: u8, v: u8) {
        if addr <= self.ram_top {
            self.iram[addr as usize] = v;
        }
    }
    /// (byte address, mask) of a bit address.
    pub(super) fn bit_loc(bit: u8) -> (u8, u8) {
        let byte = if bit < 0x80 { 0x20 + (bit >> 3) } else { bit & 0xF8 };
        (byte, 1 << (bit & 7))
    }
    pub(super) fn bit(&mut self, x: &mut dyn Xdata, bit: u8) -> bool {
        let (byte, mask) = Self::bit_loc(bit);
        self.direct(x, byte) & mask != 0
    }
    /// Read-modify-write of the whole byte, so a hooked SFR sees a read and then a write.
    pub(super) fn set_bit(&mut self, x: &mut dyn Xdata, bit: u8, v: bool) {
        let (byte, mask) = Self::bit_loc(bit);
        let old = self.latch(x, byte);
        self.set_direct(x, byte, if v { old | mask } else { old & !mask });
    }
    pub(crate) fn push(&mut self, v: u8) -> Result<(), Error> {
        let at = self.push_slot()?;
        self.iram[at] = v;
        Ok(())
    }
    /// The first half of a push: SP <- SP + 1 (a fault past the top of internal RAM); returns
    /// the new SP as the address to write.
    pub(super) fn push_slot(&mut self) -> Result<usize, Error> {
        let sp = self.sfr[(SP - 0x80) as usize];
        if sp >= self.ram_top {
            return Err(self.fail(Error::StackOverflow { pc: self.op_pc, sp }));
        }
        self.sfr[(SP - 0x80) as usize] = sp + 1;
        Ok(sp as usize + 1)
    }
    pub(super) fn pop(&mut self) -> u8 {
        let sp = self.sfr[(SP - 0x80) as usize];
        self.sfr[(SP - 0x80) as usize] = sp.wrapping_sub(1);
        self.indirect(sp)
    }
    pub(super) fn jump_rel(&mut self, rel: u8) {
        self.pc = self.pc.wrapping_add(rel as i8 as u16);
    }

    pub(super) fn add(&mut self, b: u8, carry: bool) {
        let a = self.a();
        let c = carry as u8;
        let sum = a as u16 + b as u16 + c as u16;
        let half = (a & 0x0F) + (b & 0x0F) + c > 0x0F;
        let r = sum as u8;
        let ov = (!(a ^ b) & (a ^ r)) & 0x80 != 0;
        self.set_flags(sum > 0xFF, half, ov);
        self.set_a(r);
    }
    pub(super) fn subb(&mut self, b: u8) {
        let a = self.a();
        let c = self.cy() as u8;
        let r = a.wrapping_sub(b).wrapping_sub(c);
        let borrow = (a as u16) < b as u16 + c as u16;
        let half = (a & 0x0F) < (b & 0x0F) + c;
        let ov = ((a ^ b) & (a ^ r)) & 0x80 != 0;
        self.set_flags(borrow, half, ov);
        self.set_a(r);
    }
    pub(super) fn set_flags(&mut self, cy: bool, ac: bool, ov: bool) {
        let p = self.psw_raw();
        *p = (*p & !(CY | AC | OV))
            | if cy { CY } else { 0 }
            | if ac { AC } else { 0 }
            | if ov { OV } else { 0 };
    }
    pub(super) fn set_cy_ov(&mut self, cy: bool, ov: bool) {
        let p = self.psw_raw();
        *p = (*p & !(CY | OV)) | if cy { CY } else { 0 } | if ov { OV } else { 0 };
    }
    pub(super) fn call(&mut self, target: u16) -> Result<(), Error> {
        let [lo, hi] = self.pc.to_le_bytes();
        self.push(lo)?;
        self.push(hi)?;
        self.pc = target;
        Ok(())
    }

    /// Reads a byte operand: A, Rn, @Ri, direct or #data (`b`, its byte). A direct SFR reads
    /// the port pins or the latch as `port` says.
    #[inline(always)]
    pub(super) fn load(&mut self, x: &mut dyn Xdata, o: Opnd, b: u8, port: Port) -> u8 {
        match o {
            Opnd::A => self.a(),
            Opnd::Rn(n) => self.iram[self.rn(n)],
            Opnd::AtRi(i) => self.indirect(self.iram[self.rn(i)]),
            Opnd::Direct if matches!(port, Port::Latch) => self.latch(x, b),
            Opnd::Direct => self.direct(x, b),
            Opnd::Imm => b,
            _ => unreachable!("the opcode table gives no byte source {o:?}"),
        }
    }

    /// Writes a byte operand: A, Rn, @Ri or direct (`b`, its byte).
    #[inline(always)]
    pub(super) fn store(&mut self, x: &mut dyn Xdata, o: Opnd, b: u8, v: u8) {
        match o {
            Opnd::A => self.set_a(v),
            Opnd::Rn(n) => {
                let r = self.rn(n);
                self.iram[r] = v;
            }
            Opnd::AtRi(i) => self.set_indirect(self.iram[self.rn(i)], v),
            Opnd::Direct => self.set_direct(x, b, v),
            _ => unreachable!("the opcode table gives no byte destination {o:?}"),
        }
    }

    /// The external address of MOVX: @DPTR, or @Ri with P2 as the high byte.
    #[inline(always)]
    pub(super) fn movx_addr(&self, o: Opnd) -> u16 {
        match o {
            Opnd::AtRi(i) => u16::from_le_bytes([self.iram[self.rn(i)], self.sfr[(P2 - 0x80) as usize]]),
            _ => self.dptr(),
        }
    }
}
