//! The instruction set as one table: every opcode decoded to its operation and operands, with
//! its length and machine cycles (Intel MCS-51 User's Manual, "Instruction Set": the opcode map
//! and the instruction summary's bytes and cycles).
//!
//! The core executes from this decoded form ([`crate::cpu`]'s `execute`), counts its cycles from
//! it, and the disassembler prints it, so the three cannot disagree.

/// An operation, named by its Intel mnemonic.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Ins {
    Nop,
    Ajmp,
    Ljmp,
    Sjmp,
    Jmp,
    Acall,
    Lcall,
    Ret,
    Reti,
    Jbc,
    Jb,
    Jnb,
    Jc,
    Jnc,
    Jz,
    Jnz,
    Cjne,
    Djnz,
    Rr,
    Rrc,
    Rl,
    Rlc,
    Swap,
    Da,
    Inc,
    Dec,
    Add,
    Addc,
    Subb,
    Orl,
    Anl,
    Xrl,
    Mul,
    Div,
    Mov,
    Movc,
    Movx,
    Push,
    Pop,
    Xch,
    Xchd,
    Cpl,
    Clr,
    Setb,
    /// A5h, which the manual's opcode map leaves reserved (the core faults on it).
    Reserved,
}

impl Ins {
    pub(crate) const fn mnemonic(self) -> &'static str {
        use Ins::*;
        match self {
            Nop => "NOP",
            Ajmp => "AJMP",
            Ljmp => "LJMP",
            Sjmp => "SJMP",
            Jmp => "JMP",
            Acall => "ACALL",
            Lcall => "LCALL",
            Ret => "RET",
            Reti => "RETI",
            Jbc => "JBC",
            Jb => "JB",
            Jnb => "JNB",
            Jc => "JC",
            Jnc => "JNC",
            Jz => "JZ",
            Jnz => "JNZ",
            Cjne => "CJNE",
            Djnz => "DJNZ",
            Rr => "RR",
            Rrc => "RRC",
            Rl => "RL",
            Rlc => "RLC",
            Swap => "SWAP",
            Da => "DA",
            Inc => "INC",
            Dec => "DEC",
            Add => "ADD",
            Addc => "ADDC",
            Subb => "SUBB",
            Orl => "ORL",
            Anl => "ANL",
            Xrl => "XRL",
            Mul => "MUL",
            Div => "DIV",
            Mov => "MOV",
            Movc => "MOVC",
            Movx => "MOVX",
            Push => "PUSH",
            Pop => "POP",
            Xch => "XCH",
            Xchd => "XCHD",
            Cpl => "CPL",
            Clr => "CLR",
            Setb => "SETB",
            Reserved => "DB",
        }
    }

    /// Conditional jumps that test their operand in their last machine cycle, after all their
    /// cycles have passed (where s51 tests too). JBC is not among them: it tests and clears its
    /// bit after the first cycle, where other instructions act.
    pub(crate) const fn tests_late(self) -> bool {
        matches!(
            self,
            Ins::Jb | Ins::Jnb | Ins::Jc | Ins::Jnc | Ins::Jz | Ins::Jnz | Ins::Cjne | Ins::Djnz
        )
    }
}

/// An operand, in the manual's notation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Opnd {
    /// No operand (pads [`Decoded::opnds`]).
    Empty,
    A,
    /// The carry flag.
    C,
    /// A and B together (MUL, DIV).
    AB,
    Dptr,
    /// Register Rn of the current bank (the opcode's low 3 bits).
    Rn(u8),
    /// @Ri: internal RAM addressed by R0 or R1 (the opcode's low bit).
    AtRi(u8),
    /// @DPTR (MOVX).
    AtDptr,
    /// @A+DPTR (MOVC, JMP).
    AtADptr,
    /// @A+PC (MOVC).
    AtAPc,
    /// A direct address: internal RAM 00h–7Fh or an SFR.
    Direct,
    /// #data.
    Imm,
    /// #data16.
    Imm16,
    /// A bit address.
    Bit,
    /// /bit: the complement of a bit.
    NotBit,
    /// A signed offset from the end of the instruction.
    Rel,
    /// An 11-bit address: the page (the opcode's top 3 bits) and the low byte that follows.
    Addr11(u8),
    /// A 16-bit address, high byte first.
    Addr16,
}

impl Opnd {
    /// Bytes the operand takes after the opcode.
    pub(crate) const fn bytes(self) -> u8 {
        use Opnd::*;
        match self {
            Direct | Imm | Bit | NotBit | Rel | Addr11(_) => 1,
            Imm16 | Addr16 => 2,
            Empty | A | C | AB | Dptr | Rn(_) | AtRi(_) | AtDptr | AtADptr | AtAPc => 0,
        }
    }
}

impl Opnd {
    /// The address a code operand names: Rel from `end`, the end of the instruction; Addr11 in
    /// the 2 KB page of `end`; Addr16 as `first` (high) and `second`. `first` is the operand's
    /// first byte.
    pub(crate) fn target(self, end: u16, first: u8, second: u8) -> u16 {
        match self {
            Opnd::Rel => end.wrapping_add(first as i8 as u16),
            Opnd::Addr11(page) => (end & 0xF800) | (page as u16) << 8 | first as u16,
            _ => u16::from_be_bytes([first, second]),
        }
    }
}

/// One opcode decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Decoded {
    pub(crate) ins: Ins,
    /// Operands in the order the manual writes them, [`Opnd::Empty`] past the last.
    pub(crate) opnds: [Opnd; 3],
    /// Offset from the opcode of each operand's first byte (0 for an operand without bytes).
    pub(crate) at: [u8; 3],
    /// Bytes, opcode included: 1 plus the operands' bytes.
    pub(crate) len: u8,
    pub(crate) cycles: u8,
}

impl Decoded {
    const fn new(ins: Ins, opnds: &[Opnd], cycles: u8) -> Decoded {
        let mut d = Decoded {
            ins,
            opnds: [Opnd::Empty; 3],
            at: [0; 3],
            len: 1,
            cycles,
        };
        let mut i = 0;
        while i < opnds.len() {
            d.opnds[i] = opnds[i];
            if opnds[i].bytes() > 0 {
                d.at[i] = d.len;
            }
            d.len += opnds[i].bytes();
            i += 1;
        }
        // MOV direct,direct is the one instruction encoded source first.
        if matches!(ins, Ins::Mov) && matches!(opnds, [Opnd::Direct, Opnd::Direct]) {
            d.at = [2, 1, 0];
        }
        d
    }
}

/// Source operand of the ALU rows x4–xF: #data, direct, @Ri, Rn.
const fn alu_src(op: u8) -> Opnd {
    match op & 0x0F {
        4 => Opnd::Imm,
        5 => Opnd::Direct,
        6 | 7 => Opnd::AtRi(op & 1),
        _ => Opnd::Rn(op & 7),
    }
}

/// The opcode map, with each instruction's machine cycles. Exhaustive without a wildcard, so
/// the compiler checks that every opcode has one row.
pub(crate) const fn decode(op: u8) -> Decoded {
    use Ins::*;
    use Opnd::*;
    let e = Decoded::new;
    let r = Rn(op & 7);
    let i = AtRi(op & 1);
    match op {
        0x00 => e(Nop, &[], 1),
        0x01 | 0x21 | 0x41 | 0x61 | 0x81 | 0xA1 | 0xC1 | 0xE1 => e(Ajmp, &[Addr11(op >> 5)], 2),
        0x11 | 0x31 | 0x51 | 0x71 | 0x91 | 0xB1 | 0xD1 | 0xF1 => e(Acall, &[Addr11(op >> 5)], 2),
        0x02 => e(Ljmp, &[Addr16], 2),
        0x03 => e(Rr, &[A], 1),
        0x04 => e(Inc, &[A], 1),
        0x05 => e(Inc, &[Direct], 1),
        0x06 | 0x07 => e(Inc, &[i], 1),
        0x08..=0x0F => e(Inc, &[r], 1),
        0x10 => e(Jbc, &[Bit, Rel], 2),
        0x12 => e(Lcall, &[Addr16], 2),
        0x13 => e(Rrc, &[A], 1),
        0x14 => e(Dec, &[A], 1),
        0x15 => e(Dec, &[Direct], 1),
        0x16 | 0x17 => e(Dec, &[i], 1),
        0x18..=0x1F => e(Dec, &[r], 1),
        0x20 => e(Jb, &[Bit, Rel], 2),
        0x22 => e(Ret, &[], 2),
        0x23 => e(Rl, &[A], 1),
        0x24..=0x2F => e(Add, &[A, alu_src(op)], 1),
        0x30 => e(Jnb, &[Bit, Rel], 2),
        0x32 => e(Reti, &[], 2),
        0x33 => e(Rlc, &[A], 1),
        0x34..=0x3F => e(Addc, &[A, alu_src(op)], 1),
        0x40 => e(Jc, &[Rel], 2),
        0x42 => e(Orl, &[Direct, A], 1),
        0x43 => e(Orl, &[Direct, Imm], 2),
        0x44..=0x4F => e(Orl, &[A, alu_src(op)], 1),
        0x50 => e(Jnc, &[Rel], 2),
        0x52 => e(Anl, &[Direct, A], 1),
        0x53 => e(Anl, &[Direct, Imm], 2),
        0x54..=0x5F => e(Anl, &[A, alu_src(op)], 1),
        0x60 => e(Jz, &[Rel], 2),
        0x62 => e(Xrl, &[Direct, A], 1),
        0x63 => e(Xrl, &[Direct, Imm], 2),
        0x64..=0x6F => e(Xrl, &[A, alu_src(op)], 1),
        0x70 => e(Jnz, &[Rel], 2),
        0x72 => e(Orl, &[C, Bit], 2),
        0x73 => e(Jmp, &[AtADptr], 2),
        0x74 => e(Mov, &[A, Imm], 1),
        0x75 => e(Mov, &[Direct, Imm], 2),
        0x76 | 0x77 => e(Mov, &[i, Imm], 1),
        0x78..=0x7F => e(Mov, &[r, Imm], 1),
        0x80 => e(Sjmp, &[Rel], 2),
        0x82 => e(Anl, &[C, Bit], 2),
        0x83 => e(Movc, &[A, AtAPc], 2),
        0x84 => e(Div, &[AB], 4),
        0x85 => e(Mov, &[Direct, Direct], 2),
        0x86 | 0x87 => e(Mov, &[Direct, i], 2),
        0x88..=0x8F => e(Mov, &[Direct, r], 2),
        0x90 => e(Mov, &[Dptr, Imm16], 2),
        0x92 => e(Mov, &[Bit, C], 2),
        0x93 => e(Movc, &[A, AtADptr], 2),
        0x94..=0x9F => e(Subb, &[A, alu_src(op)], 1),
        0xA0 => e(Orl, &[C, NotBit], 2),
        0xA2 => e(Mov, &[C, Bit], 1),
        0xA3 => e(Inc, &[Dptr], 2),
        0xA4 => e(Mul, &[AB], 4),
        0xA5 => e(Reserved, &[], 1),
        0xA6 | 0xA7 => e(Mov, &[i, Direct], 2),
        0xA8..=0xAF => e(Mov, &[r, Direct], 2),
        0xB0 => e(Anl, &[C, NotBit], 2),
        0xB2 => e(Cpl, &[Bit], 1),
        0xB3 => e(Cpl, &[C], 1),
        0xB4 => e(Cjne, &[A, Imm, Rel], 2),
        0xB5 => e(Cjne, &[A, Direct, Rel], 2),
        0xB6 | 0xB7 => e(Cjne, &[i, Imm, Rel], 2),
        0xB8..=0xBF => e(Cjne, &[r, Imm, Rel], 2),
        0xC0 => e(Push, &[Direct], 2),
        0xC2 => e(Clr, &[Bit], 1),
        0xC3 => e(Clr, &[C], 1),
        0xC4 => e(Swap, &[A], 1),
        0xC5 => e(Xch, &[A, Direct], 1),
        0xC6 | 0xC7 => e(Xch, &[A, i], 1),
        0xC8..=0xCF => e(Xch, &[A, r], 1),
        0xD0 => e(Pop, &[Direct], 2),
        0xD2 => e(Setb, &[Bit], 1),
        0xD3 => e(Setb, &[C], 1),
        0xD4 => e(Da, &[A], 1),
        0xD5 => e(Djnz, &[Direct, Rel], 2),
        0xD6 | 0xD7 => e(Xchd, &[A, i], 1),
        0xD8..=0xDF => e(Djnz, &[r, Rel], 2),
        0xE0 => e(Movx, &[A, AtDptr], 2),
        0xE2 | 0xE3 => e(Movx, &[A, i], 2),
        0xE4 => e(Clr, &[A], 1),
        0xE5 => e(Mov, &[A, Direct], 1),
        0xE6 | 0xE7 => e(Mov, &[A, i], 1),
        0xE8..=0xEF => e(Mov, &[A, r], 1),
        0xF0 => e(Movx, &[AtDptr, A], 2),
        0xF2 | 0xF3 => e(Movx, &[i, A], 2),
        0xF4 => e(Cpl, &[A], 1),
        0xF5 => e(Mov, &[Direct, A], 1),
        0xF6 | 0xF7 => e(Mov, &[i, A], 1),
        0xF8..=0xFF => e(Mov, &[r, A], 1),
    }
}

/// Every opcode decoded, indexed by the opcode byte, for look-ups at run time. A `static`: an
/// unoptimised build copies a `const` array whole at every index.
pub(crate) static OPS: [Decoded; 256] = {
    let mut t = [Decoded::new(Ins::Nop, &[], 1); 256];
    let mut op = 0;
    while op < 256 {
        t[op] = decode(op as u8);
        op += 1;
    }
    t
};

#[cfg(test)]
mod tests {
    use super::{Ins, OPS, Opnd};

    #[test]
    fn lengths_and_cycles_are_the_manuals() {
        for (op, d) in OPS.iter().enumerate() {
            assert!((1..=3).contains(&d.len), "{op:02X}");
            // Every 3-byte instruction takes 2 cycles; only MUL and DIV take 4.
            let expected = match d.len {
                3 => &[2][..],
                _ if matches!(d.ins, Ins::Mul | Ins::Div) => &[4],
                _ => &[1, 2],
            };
            assert!(expected.contains(&d.cycles), "{op:02X}: {} cycles", d.cycles);
        }
        // The operand bytes of MOV direct,direct: source first.
        assert_eq!((OPS[0x85].opnds[0], OPS[0x85].at), (Opnd::Direct, [2, 1, 0]));
        assert_eq!(OPS[0xB8].at, [0, 1, 2]);
        // A change to any row's cycles shows here: the manual's cycle column adds up to 354.
        assert_eq!(OPS.iter().map(|d| d.cycles as u32).sum::<u32>(), 354);
    }
}
