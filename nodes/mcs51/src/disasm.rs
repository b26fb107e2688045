//! A disassembler in Intel/as31 syntax, for instruction traces: it prints the decoded form the
//! core executes ([`crate::decode`]).

use crate::cpu::SFRS;
use crate::decode::{Ins, OPS, Opnd};

/// The name of the 80C51 SFR at `addr`, for direct operands.
fn sfr_name(addr: u8) -> Option<&'static str> {
    SFRS.iter().find(|&&(a, _)| a == addr).map(|&(_, name)| name)
}

/// A number in Intel syntax: hex with an H suffix, a leading 0 before a letter digit.
fn hex(v: u32, digits: usize) -> String {
    let s = format!("{v:0digits$X}H");
    if s.starts_with(|c: char| c.is_ascii_alphabetic()) {
        format!("0{s}")
    } else {
        s
    }
}

fn direct(a: u8) -> String {
    sfr_name(a)
        .map(str::to_string)
        .unwrap_or_else(|| hex(a as u32, 2))
}

fn bit(b: u8) -> String {
    if let Some(name) = sfr_name(b & 0xF8).filter(|_| b >= 0x80) {
        return format!("{name}.{}", b & 7);
    }
    hex(b as u32, 2)
}

/// Disassembles the instruction at `pc` (its bytes from `code[pc]`, wrapping at 64 KB; missing
/// bytes read FFh); returns the text and the instruction's length in bytes.
pub fn disasm(code: &[u8], pc: u16) -> (String, u16) {
    let byte = |i: u16| code.get(pc.wrapping_add(i) as usize).copied().unwrap_or(0xFF);
    let op = byte(0);
    let d = OPS[op as usize];
    let len = d.len as u16;
    if d.ins == Ins::Reserved {
        return (format!("{} {}", d.ins.mnemonic(), hex(op as u32, 2)), len);
    }
    let end = pc.wrapping_add(len);
    let mut text = d.ins.mnemonic().to_string();
    for (n, (&o, &at)) in d.opnds.iter().zip(&d.at).enumerate() {
        let b = byte(at as u16);
        let operand = match o {
            Opnd::Empty => break,
            Opnd::A => "A".to_string(),
            Opnd::C => "C".to_string(),
            Opnd::AB => "AB".to_string(),
            Opnd::Dptr => "DPTR".to_string(),
            Opnd::Rn(r) => format!("R{r}"),
            Opnd::AtRi(i) => format!("@R{i}"),
            Opnd::AtDptr => "@DPTR".to_string(),
            Opnd::AtADptr => "@A+DPTR".to_string(),
            Opnd::AtAPc => "@A+PC".to_string(),
            Opnd::Direct => direct(b),
            Opnd::Imm => format!("#{}", hex(b as u32, 2)),
            Opnd::Imm16 => format!("#{}", hex(u16::from_be_bytes([b, byte(at as u16 + 1)]) as u32, 4)),
            Opnd::Bit => bit(b),
            Opnd::NotBit => format!("/{}", bit(b)),
            Opnd::Rel | Opnd::Addr11(_) | Opnd::Addr16 => {
                hex(o.target(end, b, byte(at as u16 + 1)) as u32, 4)
            }
        };
        text.push(if n == 0 { ' ' } else { ',' });
        text.push_str(&operand);
    }
    (text, len)
}

#[cfg(test)]
mod tests {
    use super::disasm;

    #[test]
    fn intel_syntax() {
        let cases: &[(&[u8], u16, &str, u16)] = &[
            (&[0xF0], 0, "MOVX @DPTR,A", 1),
            (&[0x80, 0x7E], 0x4000, "SJMP 4080H", 2),
            (&[0x74, 0xFF], 0, "MOV A,#0FFH", 2),
            (&[0x85, 0x30, 0x90], 0, "MOV P1,30H", 3),
            (&[0x26], 0, "ADD A,@R0", 1),
            (&[0x9B], 0, "SUBB A,R3", 1),
            (&[0x43, 0x90, 0x01], 0, "ORL P1,#01H", 3),
            (&[0xB9, 0x05, 0xFD], 0x10, "CJNE R1,#05H,0010H", 3),
            (&[0xD2, 0xE7], 0, "SETB ACC.7", 2),
            (&[0x31, 0x23], 0x0800, "ACALL 0923H", 2),
            (&[0x90, 0x12, 0x34], 0, "MOV DPTR,#1234H", 3),
            (&[0xF8], 0, "MOV R0,A", 1),
            (&[0x86, 0x40], 0, "MOV 40H,@R0", 2),
            (&[0xA7, 0x40], 0, "MOV @R1,40H", 2),
            (&[0xDA, 0xFE], 0, "DJNZ R2,0000H", 2),
            (&[0x42, 0x20], 0, "ORL 20H,A", 2),
        ];
        for &(bytes, pc, text, len) in cases {
            let mut code = vec![0u8; 0x10000];
            code[pc as usize..pc as usize + bytes.len()].copy_from_slice(bytes);
            assert_eq!(disasm(&code, pc), (text.to_string(), len), "{bytes:02X?}");
        }
    }
}
