//! Speed of the core in machine cycles per host second:
//! `cargo run --release -p mcs51 --example speed`.
//!
//! Busy: a loop of ALU, MOV, MOVC and CJNE instructions with timer 0 interrupting every 256
//! cycles, nothing skipped. Idle: nested DJNZ delay loops, run with skipping and stepped.

use mcs51::{Cpu, Image, NoXdata, Variant};
use std::time::Instant;

fn image(parts: &[(u16, &[u8])]) -> Image {
    let mut code = vec![0xFF; 0x10000];
    for &(at, bytes) in parts {
        code[at as usize..at as usize + bytes.len()].copy_from_slice(bytes);
    }
    Image {
        code,
        written: Vec::new(),
    }
}

fn busy() -> Image {
    let main: &[u8] = &[
        0x75, 0x89, 0x02, // MOV TMOD,#02h
        0xD2, 0x8C, // SETB TR0
        0x75, 0xA8, 0x82, // MOV IE,#82h
        0xE8, // loop: MOV A,R0
        0x24, 0x03, // ADD A,#3
        0xF8, // MOV R0,A
        0x65, 0x31, // XRL A,31h
        0xF5, 0x31, // MOV 31h,A
        0x23, // RL A
        0x54, 0x7F, // ANL A,#7Fh
        0xB4, 0x40, 0x00, // CJNE A,#40h,+0
        0xA3, // INC DPTR
        0x93, // MOVC A,@A+DPTR
        0x09, // INC R1
        0x80, 0xEE, // SJMP loop
    ];
    image(&[
        (0, &[0x02, 0x00, 0x40]),
        (0x0B, &[0x05, 0x30, 0x32]),
        (0x40, main),
    ])
}

fn idle() -> Image {
    // loop: MOV R6,#0; outer: MOV R7,#0; DJNZ R7,$; DJNZ R6,outer; INC 30h; SJMP loop
    let main: &[u8] = &[
        0x7E, 0x00, 0x7F, 0x00, 0xDF, 0xFE, 0xDE, 0xFA, 0x05, 0x30, 0x80, 0xF4,
    ];
    image(&[(0, main)])
}

fn rate(cycles: u64, seconds: f64) -> String {
    format!(
        "{:.1} million machine cycles per second",
        cycles as f64 / seconds / 1e6
    )
}

fn main() -> Result<(), mcs51::Error> {
    let mut cpu = Cpu::new(Variant::I8051, &busy());
    let t = Instant::now();
    cpu.run(&mut NoXdata, 500_000_000)?;
    let s = t.elapsed().as_secs_f64();
    println!("busy, run:         {}", rate(cpu.cycles(), s));

    let mut cpu = Cpu::new(Variant::I8051, &idle());
    let t = Instant::now();
    while cpu.cycles() < 200_000_000 {
        cpu.step(&mut NoXdata)?;
    }
    println!(
        "idle, stepped:     {}",
        rate(cpu.cycles(), t.elapsed().as_secs_f64())
    );

    let mut cpu = Cpu::new(Variant::I8051, &idle());
    let t = Instant::now();
    cpu.run(&mut NoXdata, 20_000_000_000)?;
    let s = t.elapsed().as_secs_f64();
    println!(
        "idle, run (skips): {} ({:.1} % of cycles skipped)",
        rate(cpu.cycles(), s),
        100.0 * cpu.skipped_cycles() as f64 / cpu.cycles() as f64
    );
    Ok(())
}
