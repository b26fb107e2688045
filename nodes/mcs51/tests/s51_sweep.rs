//! Whole-instruction-set sweep against s51: programs of random instructions (every opcode but
//! the jumps, calls and returns that would leave the straight line, and A5h) with random
//! operands, branches taken or not to the next instruction; final RAM, SFRs and cycles compared.

mod support;

use mcs51::Variant;

/// xorshift64*: a fixed generator so every run tests the same programs.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn byte(&mut self) -> u8 {
        (self.next() >> 32) as u8
    }
    fn pick<T: Copy>(&mut self, xs: &[T]) -> T {
        xs[(self.next() >> 33) as usize % xs.len()]
    }
}

/// Direct addresses the programs may touch: RAM and the SFRs without side effects on control
/// (no SP, IE, IP, TCON, TMOD, SCON, SBUF, PCON, P0, P3).
fn direct(r: &mut Rng) -> u8 {
    if r.byte() < 200 {
        r.byte() & 0x7F
    } else {
        r.pick(&[0xE0, 0xF0, 0xD0, 0x82, 0x83, 0x90, 0xA0])
    }
}

fn bit(r: &mut Rng) -> u8 {
    if r.byte() < 160 {
        r.byte() & 0x7F
    } else {
        r.pick(&[0xE0, 0xF0, 0xD0, 0x90]) | (r.byte() & 7)
    }
}

fn imm(r: &mut Rng) -> u8 {
    if r.byte() < 100 {
        r.pick(&[0, 1, 0x0F, 0x10, 0x7F, 0x80, 0x99, 0xFE, 0xFF])
    } else {
        r.byte()
    }
}

/// Opcodes that leave the straight line or are reserved.
fn excluded(op: u8) -> bool {
    op & 0x0F == 0x01 || matches!(op, 0x02 | 0x12 | 0x22 | 0x32 | 0x73 | 0xA5 | 0x81)
}

/// The bytes of one instruction with opcode `op`; branches get offset 0 (fall through either
/// way, so both outcomes meet again), PUSH is followed by a POP so the stack stays in bounds.
fn instruction(op: u8, r: &mut Rng) -> Vec<u8> {
    match op {
        0x05
        | 0x15
        | 0x25
        | 0x35
        | 0x42
        | 0x45
        | 0x52
        | 0x55
        | 0x62
        | 0x65
        | 0x95
        | 0xC5
        | 0xE5
        | 0xF5
        | 0x86
        | 0x87
        | 0x88..=0x8F
        | 0xA6
        | 0xA7
        | 0xA8..=0xAF
        | 0xD0 => {
            vec![op, direct(r)]
        }
        0xC0 => vec![0xC0, direct(r), 0xD0, direct(r)],
        0x24 | 0x34 | 0x44 | 0x54 | 0x64 | 0x94 | 0x74 | 0x76 | 0x77 | 0x78..=0x7F => {
            vec![op, imm(r)]
        }
        0x43 | 0x53 | 0x63 | 0x75 => vec![op, direct(r), imm(r)],
        0x85 => vec![op, direct(r), direct(r)],
        0x90 => vec![op, r.byte(), r.byte()],
        0x72 | 0x82 | 0xA0 | 0xB0 | 0x92 | 0xA2 | 0xB2 | 0xC2 | 0xD2 => vec![op, bit(r)],
        0x10 | 0x20 | 0x30 => vec![op, bit(r), 0],
        0x40 | 0x50 | 0x60 | 0x70 | 0x80 => vec![op, 0],
        0xB4 | 0xB6 | 0xB7 | 0xB8..=0xBF => vec![op, imm(r), 0],
        0xB5 | 0xD5 => vec![op, direct(r), 0],
        0xD8..=0xDF => vec![op, 0],
        _ => vec![op],
    }
}

fn program(seed: u64) -> String {
    let mut r = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let mut ops: Vec<u8> = (0..=255u8).filter(|&op| !excluded(op)).collect();
    // Shuffle, then add random extra picks.
    for i in (1..ops.len()).rev() {
        ops.swap(i, (r.next() % (i as u64 + 1)) as usize);
    }
    for _ in 0..150 {
        let op = r.byte();
        if !excluded(op) {
            ops.push(op);
        }
    }
    let mut src = String::from("\t.org 0\n\tmov sp,#0C0h\n");
    for op in ops {
        let bytes: Vec<String> = instruction(op, &mut r).iter().map(|b| format!("{b}")).collect();
        src.push_str(&format!("\t.db {}\n", bytes.join(", ")));
    }
    src.push_str("done:\tsjmp done\n");
    src
}

#[test]
fn random_programs_cover_every_opcode() {
    for seed in 1..=24 {
        support::check(&program(seed), Variant::I8052);
    }
}
