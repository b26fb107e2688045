//! Test helper: assembles a program with as31, runs it in our core and in s51 (uCsim), and
//! compares internal RAM, SFRs and the machine-cycle count.
//!
//! Each program must contain a label `done:` (conventionally `done: sjmp done`); both runs stop
//! when the PC reaches it, before executing it. s51 counts oscillator clocks ("ticks"), 12 per
//! machine cycle. s51 fills internal RAM, external RAM and ROM with noise at start; the script
//! sets them to 00h, 00h and FFh, which is our core's reset picture (with a zeroed external RAM).

#![allow(dead_code)]

use mcs51::{Cpu, Variant, Xdata};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The SFRs both simulators implement and the tests compare (SBUF excluded: s51 shows the
/// transmitted byte, we the receive buffer).
pub const SFRS: [(u8, &str); 20] = [
    (0x80, "P0"),
    (0x81, "SP"),
    (0x82, "DPL"),
    (0x83, "DPH"),
    (0x87, "PCON"),
    (0x88, "TCON"),
    (0x89, "TMOD"),
    (0x8A, "TL0"),
    (0x8B, "TL1"),
    (0x8C, "TH0"),
    (0x8D, "TH1"),
    (0x90, "P1"),
    (0x98, "SCON"),
    (0xA0, "P2"),
    (0xA8, "IE"),
    (0xB0, "P3"),
    (0xB8, "IP"),
    (0xD0, "PSW"),
    (0xE0, "ACC"),
    (0xF0, "B"),
];

/// Final state of a run.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Outcome {
    pub iram: Vec<u8>,
    pub sfr: [u8; 128],
    pub cycles: u64,
}

/// An assembled program.
pub struct Program {
    _dir: tempfile::TempDir,
    pub hex_path: PathBuf,
    pub hex: String,
    pub done: u16,
}

fn run_tool(cmd: &mut Command, name: &str, package: &str) -> std::process::Output {
    match cmd.output() {
        Ok(out) => out,
        Err(e) => panic!("cannot run `{name}` ({e}): install the Debian package `{package}`"),
    }
}

/// Assembles `src` with as31 into Intel HEX.
pub fn assemble(src: &str) -> Program {
    let dir = tempfile::tempdir().expect("temporary directory");
    let asm = dir.path().join("prog.asm");
    std::fs::write(&asm, src).expect("write the source");
    let out = run_tool(
        Command::new("as31")
            .arg("-l")
            .arg("-Fhex")
            .arg("prog.asm")
            .current_dir(dir.path()),
        "as31",
        "as31",
    );
    let log = String::from_utf8_lossy(&out.stderr).to_string() + &String::from_utf8_lossy(&out.stdout);
    let hex_path = dir.path().join("prog.hex");
    assert!(
        !log.contains("Error") && !log.contains("rror,") && hex_path.exists(),
        "as31 failed:\n{log}\n{src}"
    );
    let hex = std::fs::read_to_string(&hex_path).expect("read the HEX file");
    let listing = std::fs::read_to_string(dir.path().join("prog.lst")).expect("read the listing");
    let done = listing
        .lines()
        .find(|l| l.contains("done:"))
        .and_then(|l| u16::from_str_radix(l.split(':').next()?.trim(), 16).ok())
        .expect("the program has a `done:` label");
    Program {
        _dir: dir,
        hex_path,
        hex,
        done,
    }
}

/// 64 KB of external RAM, zeroed.
pub struct Ram(pub Vec<u8>);

impl Xdata for Ram {
    fn read(&mut self, addr: u16) -> u8 {
        self.0[addr as usize]
    }
    fn write(&mut self, addr: u16, value: u8) {
        self.0[addr as usize] = value;
    }
}

fn top(variant: Variant) -> usize {
    if variant == Variant::I8051 { 0x80 } else { 0x100 }
}

/// Our final state; a driven port shows its pins (latch AND level), as s51's dump does, where
/// [`Cpu::sfr`] shows the latch.
fn outcome(cpu: &Cpu, variant: Variant, pins: &[(u8, u8)]) -> Outcome {
    let mut sfr = cpu.sfr();
    for &(port, levels) in pins {
        sfr[0x10 * port as usize] &= levels;
    }
    Outcome {
        iram: cpu.iram()[..top(variant)].to_vec(),
        sfr,
        cycles: cpu.cycles(),
    }
}

/// Drives external pin levels `(port, levels)` before the program starts.
fn drive(cpu: &mut Cpu, pins: &[(u8, u8)]) {
    for &(port, levels) in pins {
        for bit in 0..8 {
            cpu.set_pin(port, bit, levels >> bit & 1 != 0);
        }
    }
}

/// Runs `p` in our core until PC reaches `done` (at most `limit` cycles).
pub fn run_ours(p: &Program, variant: Variant, limit: u64, pins: &[(u8, u8)]) -> Outcome {
    let image = mcs51::hex::parse(&p.hex, 0x10000).expect("as31 writes valid HEX");
    let mut cpu = Cpu::new(variant, &image);
    drive(&mut cpu, pins);
    // s51 enters an interrupt in 1 machine cycle, the manual's hardware LCALL takes 2.
    cpu.set_interrupt_entry_cycles(1);
    let mut ram = Ram(vec![0; 0x10000]);
    while cpu.pc() != p.done {
        assert!(
            cpu.cycles() < limit,
            "our core did not reach done within {limit} cycles"
        );
        cpu.step(&mut ram).expect("no fault");
    }
    outcome(&cpu, variant, pins)
}

/// Runs `p` in our core with [`Cpu::run`] (lazy timers, idle skipping) to `cycles`; the PC must
/// then be at `done`.
pub fn run_ours_to(p: &Program, variant: Variant, cycles: u64, pins: &[(u8, u8)]) -> Outcome {
    let image = mcs51::hex::parse(&p.hex, 0x10000).expect("as31 writes valid HEX");
    let mut cpu = Cpu::new(variant, &image);
    drive(&mut cpu, pins);
    cpu.set_interrupt_entry_cycles(1);
    let mut ram = Ram(vec![0; 0x10000]);
    while cpu.run(&mut ram, cycles).expect("no fault") != mcs51::RunEnd::Reached {}
    assert_eq!(cpu.pc(), p.done, "run to cycle {cycles} ends at `done`");
    outcome(&cpu, variant, pins)
}

/// Runs `p` in s51 until PC reaches `done`; `setup` are extra commands before `run`.
pub fn run_s51(p: &Program, variant: Variant, setup: &str) -> Outcome {
    let t = top(variant);
    let script = format!(
        "fill rom 0 0xffff 0xff\nload \"{}\"\nfill iram 0 {:#x} 0\nfill xram 0 0xffff 0\n{setup}\n\
         break {:#x}\nrun\ndump /h iram 0 {:#x} 16\ndump /h sfr 0x80 0xff 16\nquit\n",
        p.hex_path.display(),
        t - 1,
        p.done,
        t - 1
    );
    let dir = p.hex_path.parent().unwrap_or(Path::new("."));
    let cmd_file = dir.join("cmds");
    std::fs::write(&cmd_file, &script).expect("write the s51 script");
    let cpu = if variant == Variant::I8051 { "8051" } else { "8052" };
    let out = run_tool(
        Command::new("timeout")
            .args(["30", "s51", "-t", cpu, "-b"])
            .stdin(std::fs::File::open(&cmd_file).expect("open the script")),
        "s51",
        "sdcc-ucsim",
    );
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    parse_s51(&text, t).unwrap_or_else(|| panic!("cannot read s51's output:\n{text}"))
}

fn parse_s51(text: &str, top: usize) -> Option<Outcome> {
    let ticks: u64 = text.lines().find_map(|l| {
        l.strip_prefix("Simulated ")?
            .split_whitespace()
            .next()?
            .parse()
            .ok()
    })?;
    if !text.contains("Breakpoint") {
        return None;
    }
    let mut iram = vec![0u8; 0x100];
    let mut sfr = [0u8; 128];
    let mut seen = 0;
    // Lines "0xNN b0 b1 ... b15 ascii": iram rows come first, then the sfr rows from 0x80.
    for line in text.lines().filter(|l| l.starts_with("0x")) {
        let mut words = line.split_whitespace();
        let addr = usize::from_str_radix(words.next()?.trim_start_matches("0x"), 16).ok()?;
        let bytes: Vec<u8> = words
            .take(16)
            .map_while(|w| u8::from_str_radix(w, 16).ok())
            .collect();
        if bytes.len() != 16 {
            continue;
        }
        let in_sfr = seen >= top;
        for (i, b) in bytes.into_iter().enumerate() {
            if in_sfr {
                sfr[addr - 0x80 + i] = b;
            } else {
                iram[addr + i] = b;
            }
        }
        seen += 16;
    }
    if seen != top + 128 {
        return None;
    }
    iram.truncate(top);
    Some(Outcome {
        iram,
        sfr,
        cycles: ticks / 12,
    })
}

/// Asserts that two runs agree on RAM, the compared SFRs and cycles, listing every difference.
pub fn compare(ours: &Outcome, s51: &Outcome, src: &str) {
    let mut diffs = Vec::new();
    for (a, (x, y)) in ours.iram.iter().zip(&s51.iram).enumerate() {
        if x != y {
            diffs.push(format!("iram {a:02X}h: ours {x:02X} s51 {y:02X}"));
        }
    }
    for (addr, name) in SFRS {
        let (x, y) = (ours.sfr[addr as usize - 0x80], s51.sfr[addr as usize - 0x80]);
        if x != y {
            diffs.push(format!("{name}: ours {x:02X} s51 {y:02X}"));
        }
    }
    if ours.cycles != s51.cycles {
        diffs.push(format!("cycles: ours {} s51 {}", ours.cycles, s51.cycles));
    }
    assert!(
        diffs.is_empty(),
        "differences from s51:\n{}\nprogram:\n{src}",
        diffs.join("\n")
    );
}

/// Assembles `src`, runs it in both simulators and compares.
pub fn check(src: &str, variant: Variant) -> Outcome {
    check_with_pins(src, variant, &[])
}

/// As [`check`], with external pin levels `(port, levels)` driven from the start (in s51 by
/// `set hardware port[n]`).
pub fn check_with_pins(src: &str, variant: Variant, pins: &[(u8, u8)]) -> Outcome {
    let p = assemble(src);
    let setup: String = pins
        .iter()
        .map(|(port, levels)| format!("set hardware port[{port}] {levels:#x}\n"))
        .collect();
    let ours = run_ours(&p, variant, 50_000_000, pins);
    let theirs = run_s51(&p, variant, &setup);
    compare(&ours, &theirs, src);
    let by_run = run_ours_to(&p, variant, theirs.cycles, pins);
    compare(&by_run, &theirs, src);
    ours
}
