//! Prints an instruction trace of an Intel HEX program: `trace FILE.hex [STEPS] [8052]`.

use mcs51::{Cpu, NoXdata, Variant, disasm};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let path = args.get(1).ok_or("usage: trace FILE.hex [STEPS] [8052]")?;
    let steps: u64 = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(100);
    let variant = if args.get(3).is_some_and(|v| v == "8052") {
        Variant::I8052
    } else {
        Variant::I8051
    };
    let image = mcs51::hex::parse(&std::fs::read_to_string(path)?, 0x10000)?;
    let mut cpu = Cpu::new(variant, &image);
    for _ in 0..steps {
        let pc = cpu.pc();
        let (text, _) = disasm(&image.code, pc);
        let step = cpu.step(&mut NoXdata)?;
        let sfr = cpu.sfr();
        let what = match step.interrupt {
            Some(v) => format!("interrupt -> {v:04X}H"),
            None => text,
        };
        println!(
            "{:8} {pc:04X} {what:<24} A={:02X} PSW={:02X} SP={:02X} TL0={:02X} TH0={:02X} TCON={:02X}",
            cpu.cycles(),
            sfr[0x60],
            sfr[0x50],
            sfr[0x01],
            sfr[0x0A],
            sfr[0x0C],
            sfr[0x08]
        );
    }
    Ok(())
}
