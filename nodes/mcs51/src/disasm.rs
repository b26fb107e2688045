//! A disassembler in Intel/as31 syntax, for instruction traces.

/// SFR names by address, for direct operands.
fn sfr_name(addr: u8) -> Option<&'static str> {
    Some(match addr {
        0x80 => "P0",
        0x81 => "SP",
        0x82 => "DPL",
        0x83 => "DPH",
        0x87 => "PCON",
        0x88 => "TCON",
        0x89 => "TMOD",
        0x8A => "TL0",
        0x8B => "TL1",
        0x8C => "TH0",
        0x8D => "TH1",
        0x90 => "P1",
        0x98 => "SCON",
        0x99 => "SBUF",
        0xA0 => "P2",
        0xA8 => "IE",
        0xB0 => "P3",
        0xB8 => "IP",
        0xD0 => "PSW",
        0xE0 => "ACC",
        0xF0 => "B",
        _ => return None,
    })
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

/// Template of each opcode: operands in `{}` are filled from the following bytes in order:
/// `d` direct, `i` #data, `b` bit, `r` relative, `p` 11-bit page address, `l` 16-bit address,
/// `w` #data16. `Rn` and `@i` (@Ri) take the register from the opcode's low bits.
fn template(op: u8) -> &'static str {
    match op {
        0x00 => "NOP",
        0x02 => "LJMP {l}",
        0x03 => "RR A",
        0x04 => "INC A",
        0x05 => "INC {d}",
        0x06 | 0x07 => "INC @i",
        0x08..=0x0F => "INC Rn",
        0x10 => "JBC {b},{r}",
        0x12 => "LCALL {l}",
        0x13 => "RRC A",
        0x14 => "DEC A",
        0x15 => "DEC {d}",
        0x16 | 0x17 => "DEC @i",
        0x18..=0x1F => "DEC Rn",
        0x20 => "JB {b},{r}",
        0x22 => "RET",
        0x23 => "RL A",
        0x30 => "JNB {b},{r}",
        0x32 => "RETI",
        0x33 => "RLC A",
        0x40 => "JC {r}",
        0x42 | 0x52 | 0x62 => "{d},A",
        0x43 | 0x53 | 0x63 => "{d},{i}",
        0x50 => "JNC {r}",
        0x60 => "JZ {r}",
        0x70 => "JNZ {r}",
        0x72 => "ORL C,{b}",
        0x73 => "JMP @A+DPTR",
        0x74 => "MOV A,{i}",
        0x75 => "MOV {d},{i}",
        0x76 | 0x77 => "MOV @i,{i}",
        0x78..=0x7F => "MOV Rn,{i}",
        0x80 => "SJMP {r}",
        0x82 => "ANL C,{b}",
        0x83 => "MOVC A,@A+PC",
        0x84 => "DIV AB",
        0x85 => "MOV {d},{d}",
        0x86 | 0x87 => "MOV {d},@i",
        0x88..=0x8F => "MOV {d},Rn",
        0x90 => "MOV DPTR,{w}",
        0x92 => "MOV {b},C",
        0x93 => "MOVC A,@A+DPTR",
        0xA0 => "ORL C,/{b}",
        0xA2 => "MOV C,{b}",
        0xA3 => "INC DPTR",
        0xA4 => "MUL AB",
        0xA5 => "DB 0A5H",
        0xA6 | 0xA7 => "MOV @i,{d}",
        0xA8..=0xAF => "MOV Rn,{d}",
        0xB0 => "ANL C,/{b}",
        0xB2 => "CPL {b}",
        0xB3 => "CPL C",
        0xB4 => "CJNE A,{i},{r}",
        0xB5 => "CJNE A,{d},{r}",
        0xB6 | 0xB7 => "CJNE @i,{i},{r}",
        0xB8..=0xBF => "CJNE Rn,{i},{r}",
        0xC0 => "PUSH {d}",
        0xC2 => "CLR {b}",
        0xC3 => "CLR C",
        0xC4 => "SWAP A",
        0xC5 => "XCH A,{d}",
        0xC6 | 0xC7 => "XCH A,@i",
        0xC8..=0xCF => "XCH A,Rn",
        0xD0 => "POP {d}",
        0xD2 => "SETB {b}",
        0xD3 => "SETB C",
        0xD4 => "DA A",
        0xD5 => "DJNZ {d},{r}",
        0xD6 | 0xD7 => "XCHD A,@i",
        0xD8..=0xDF => "DJNZ Rn,{r}",
        0xE0 => "MOVX A,@DPTR",
        0xE2 | 0xE3 => "MOVX A,@i",
        0xE4 => "CLR A",
        0xE5 => "MOV A,{d}",
        0xE6 | 0xE7 => "MOV A,@i",
        0xE8..=0xEF => "MOV A,Rn",
        0xF0 => "MOVX @DPTR,A",
        0xF2 | 0xF3 => "MOVX @i,A",
        0xF4 => "CPL A",
        0xF5 => "MOV {d},A",
        0xF6 | 0xF7 => "MOV @i,A",
        0xF8..=0xFF => "MOV Rn,A",
        _ if op & 0x1F == 0x01 => "AJMP {p}",
        _ if op & 0x1F == 0x11 => "ACALL {p}",
        _ => match op & 0x0F {
            4 => "A,{i}",
            5 => "A,{d}",
            6 | 7 => "A,@i",
            _ => "A,Rn",
        },
    }
}

/// Disassembles the instruction at `pc` (its bytes from `code[pc]`, wrapping at 64 KB; missing
/// bytes read FFh); returns the text and the instruction's length in bytes.
pub fn disasm(code: &[u8], pc: u16) -> (String, u16) {
    let byte = |i: u16| code.get(pc.wrapping_add(i) as usize).copied().unwrap_or(0xFF);
    let op = byte(0);
    let mut t = template(op).to_string();
    // The ALU groups and ORL/ANL/XRL direct share templates without a mnemonic.
    let prefix = match op >> 4 {
        0x2 => "ADD ",
        0x3 => "ADDC ",
        0x4 => "ORL ",
        0x5 => "ANL ",
        0x6 => "XRL ",
        0x9 => "SUBB ",
        _ => "",
    };
    if t.starts_with('{') || t.starts_with("A,") {
        t = format!("{prefix}{t}");
    }
    let mut out = String::new();
    let mut len: u16 = 1;
    let mut rest = t.as_str();
    let mut dirs: Vec<u8> = Vec::new();
    while let Some(open) = rest.find('{') {
        out.push_str(&rest[..open]);
        let kind = rest.as_bytes()[open + 1];
        rest = &rest[open + 3..];
        let text = match kind {
            b'd' => {
                let d = byte(len);
                dirs.push(d);
                direct(d)
            }
            b'i' => format!("#{}", hex(byte(len) as u32, 2)),
            b'b' => bit(byte(len)),
            b'r' => {
                let end = pc.wrapping_add(len + 1);
                hex(end.wrapping_add(byte(len) as i8 as u16) as u32, 4)
            }
            b'p' => {
                let end = pc.wrapping_add(2);
                hex(
                    ((end & 0xF800) | (op as u16 >> 5) << 8 | byte(len) as u16) as u32,
                    4,
                )
            }
            b'l' => {
                len += 1;
                hex(u16::from_be_bytes([byte(len - 1), byte(len)]) as u32, 4)
            }
            _ => {
                len += 1;
                format!(
                    "#{}",
                    hex(u16::from_be_bytes([byte(len - 1), byte(len)]) as u32, 4)
                )
            }
        };
        len += 1;
        out.push_str(&text);
    }
    out.push_str(rest);
    if op == 0x85 {
        // MOV direct,direct is encoded source first.
        out = format!("MOV {},{}", direct(dirs[1]), direct(dirs[0]));
    }
    let out = out
        .replace("@i", &format!("@R{}", op & 1))
        .replace("Rn", &format!("R{}", op & 7));
    (out, len)
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
