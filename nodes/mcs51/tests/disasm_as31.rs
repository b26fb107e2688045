//! The disassembler's text, assembled again by as31 (Debian package `as31`), gives back the
//! same bytes, for every defined opcode.

mod support;

use mcs51::disasm;

#[test]
fn disassembly_reassembles_to_the_same_bytes() {
    let mut code = vec![0xFFu8; 0x10000];
    let mut src = String::new();
    let mut at: u16 = 0x1000;
    for op in (0..=255u8).filter(|&op| op != 0xA5) {
        // Operand bytes vary with the opcode so that SFR names, bits and both jump directions
        // appear.
        let bytes = [op, op ^ 0x5A, op.wrapping_mul(7).wrapping_add(0x81)];
        code[at as usize..at as usize + 3].copy_from_slice(&bytes);
        let (text, len) = disasm(&code, at);
        assert!((1..=3).contains(&len), "{op:02X}: length {len}");
        code[at as usize + len as usize..at as usize + 3].fill(0xFF);
        src.push_str(&format!("\t.org {at}\n\t{text}\n"));
        at += len;
    }
    src.push_str("done:\tnop\n");
    let p = support::assemble(&src);
    let image = mcs51::hex::parse(&p.hex, 0x10000).expect("as31 writes valid HEX");
    let listing = || {
        src.lines()
            .filter(|l| !l.contains(".org"))
            .collect::<Vec<_>>()
            .join("\n")
    };
    let range = 0x1000..at as usize;
    for (addr, (ours, as31)) in range
        .clone()
        .zip(code[range.clone()].iter().zip(&image.code[range]))
    {
        assert_eq!(
            as31,
            ours,
            "byte at {addr:04X}h differs; the text:\n{}",
            listing()
        );
    }
}
