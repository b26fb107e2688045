//! Behaviour computed by hand from the Intel MCS-51 User's Manual: external interrupts (level
//! and edge), interrupt latency rules, port pins versus latches, counters, faults, MOVX stops,
//! serial output, the idle skip (checked against plain stepping) and what coverage is told.

use mcs51::{Cpu, Error, Image, NoXdata, RunEnd, Variant, XAccess, Xdata};

/// A core with `parts` (address, bytes) loaded.
fn cpu(variant: Variant, parts: &[(u16, &[u8])]) -> Cpu {
    let mut code = vec![0xFF; 0x10000];
    for &(at, bytes) in parts {
        code[at as usize..at as usize + bytes.len()].copy_from_slice(bytes);
    }
    Cpu::new(
        variant,
        &Image {
            code,
            written: Vec::new(),
        },
    )
}

fn run(c: &mut Cpu, until: u64) {
    assert_eq!(c.run(&mut NoXdata, until), Ok(RunEnd::Reached));
}

const TCON: usize = 0x08;
const P1: usize = 0x10;

/// 0000 LJMP 0040; 0003 INC 30h; RETI; 0040 `setup`; then SJMP $.
fn int0_program(setup: &[u8]) -> Vec<u8> {
    let mut main = setup.to_vec();
    main.extend([0x80, 0xFE]);
    main
}

#[test]
fn int0_level_retriggers_while_the_pin_is_low() {
    // MOV IE,#81h (2 cycles) after LJMP (2): the pin goes low at cycle 4.
    let main = int0_program(&[0x75, 0xA8, 0x81]);
    let mut c = cpu(
        Variant::I8051,
        &[(0, &[0x02, 0x00, 0x40, 0x05, 0x30, 0x32]), (0x40, &main)],
    );
    run(&mut c, 4);
    c.set_pin(3, 2, false);
    assert_eq!(c.sfr()[TCON] & 0x02, 0x02, "IE0 follows the low pin");
    // Each round: entry 2 + INC 1 + RETI 2 + one SJMP (2) that must run after RETI = 7 cycles.
    run(&mut c, 4 + 7 * 10);
    assert_eq!(c.iram()[0x30], 10);
    c.set_pin(3, 2, true);
    assert_eq!(c.sfr()[TCON] & 0x02, 0, "level mode: IE0 is not latched");
}

#[test]
fn int0_edge_latches_once_and_vectoring_clears_it() {
    // MOV TCON,#01h (IT0); MOV IE,#81h.
    let main = int0_program(&[0x75, 0x88, 0x01, 0x75, 0xA8, 0x81]);
    let mut c = cpu(
        Variant::I8051,
        &[(0, &[0x02, 0x00, 0x40, 0x05, 0x30, 0x32]), (0x40, &main)],
    );
    run(&mut c, 6);
    c.set_pin(3, 2, false);
    c.set_pin(3, 2, true);
    assert_eq!(c.sfr()[TCON] & 0x02, 0x02, "a falling edge latches IE0");
    let after_ie_write = c.step(&mut NoXdata).unwrap();
    assert_eq!(
        after_ie_write.interrupt, None,
        "one instruction runs after a write to IE"
    );
    let entry = c.step(&mut NoXdata).unwrap();
    assert_eq!(
        (entry.interrupt, entry.cycles),
        (Some(0x03), 2),
        "the hardware LCALL takes 2 cycles"
    );
    assert_eq!(c.sfr()[TCON] & 0x02, 0, "vectoring clears an edge-triggered IE0");
    assert_eq!(
        c.iram()[0x08..0x0A],
        [0x46, 0x00],
        "return address 0046h pushed low byte first"
    );
    run(&mut c, 200);
    assert_eq!(c.iram()[0x30], 1);
}

#[test]
fn no_interrupt_right_after_a_write_to_ie() {
    // SETB TF0 (TCON.5 = bit 8Dh); MOV IE,#82h; NOP; NOP. Vector 000Bh holds FFh bytes.
    let mut c = cpu(
        Variant::I8051,
        &[(0, &[0xD2, 0x8D, 0x75, 0xA8, 0x82, 0x00, 0x00])],
    );
    for _ in 0..2 {
        c.step(&mut NoXdata).unwrap();
    }
    let nop = c.step(&mut NoXdata).unwrap();
    assert_eq!(
        (nop.interrupt, c.pc()),
        (None, 6),
        "the instruction after MOV IE runs first"
    );
    let entry = c.step(&mut NoXdata).unwrap();
    assert_eq!(entry.interrupt, Some(0x0B));
    assert_eq!(c.sfr()[TCON] & 0x20, 0, "vectoring clears TF0");
}

#[test]
fn pins_for_reads_latches_for_read_modify_write() {
    // MOV A,P1; ANL P1,#0FFh; MOV C,P1.0; MOV 20h,C... as MOV 00h,C
    let mut c = cpu(
        Variant::I8051,
        &[(0, &[0xE5, 0x90, 0x53, 0x90, 0xFF, 0xA2, 0x90, 0x92, 0x00])],
    );
    c.set_pin(1, 0, false);
    for _ in 0..4 {
        c.step(&mut NoXdata).unwrap();
    }
    assert_eq!(c.sfr()[0x60], 0xFE, "MOV A,P1 reads the pins");
    assert_eq!(c.sfr()[P1], 0xFF, "ANL P1 read the latch, so it wrote FFh back");
    assert_eq!(c.iram()[0x20] & 1, 0, "MOV C,P1.0 read the low pin");
}

#[test]
fn counter_counts_falling_edges_and_gate_waits_for_int0() {
    // MOV TMOD,#0Dh (timer 0: GATE, C/T, mode 1); SETB TR0; NOPs.
    let mut code = vec![0x75, 0x89, 0x0D, 0xD2, 0x8C];
    code.extend([0x00; 20]);
    let mut c = cpu(Variant::I8051, &[(0, &code)]);
    c.step(&mut NoXdata).unwrap();
    c.step(&mut NoXdata).unwrap();
    c.set_pin(3, 2, false); // INT0 low: the gate holds the counter
    for _ in 0..3 {
        c.set_pin(3, 4, false);
        c.set_pin(3, 4, true);
        c.step(&mut NoXdata).unwrap();
    }
    assert_eq!(c.sfr()[0x0A], 0, "gated off while INT0 is low");
    c.set_pin(3, 2, true);
    for _ in 0..3 {
        c.set_pin(3, 4, false);
        c.set_pin(3, 4, true);
        c.step(&mut NoXdata).unwrap();
    }
    assert_eq!(c.sfr()[0x0A], 3, "three falling edges on T0");
}

#[test]
fn faults_stop_the_core() {
    let mut c = cpu(Variant::I8051, &[(0, &[0x00, 0xA5])]);
    c.step(&mut NoXdata).unwrap();
    assert_eq!(c.step(&mut NoXdata), Err(Error::ReservedOpcode { pc: 1 }));
    assert_eq!(c.step(&mut NoXdata), Err(Error::Stopped { pc: 1 }));
    // MOV SP,#7Fh; PUSH ACC: past the 80C51's 128 bytes, fine on the 8052.
    let prog: &[u8] = &[0x75, 0x81, 0x7F, 0xC0, 0xE0];
    let mut c = cpu(Variant::I8051, &[(0, prog)]);
    c.step(&mut NoXdata).unwrap();
    assert_eq!(
        c.step(&mut NoXdata),
        Err(Error::StackOverflow { pc: 3, sp: 0x7F })
    );
    assert_eq!(c.run(&mut NoXdata, 100), Err(Error::Stopped { pc: 3 }));
    let mut c = cpu(Variant::I8052, &[(0, prog)]);
    c.step(&mut NoXdata).unwrap();
    c.step(&mut NoXdata).unwrap();
    assert_eq!(c.sfr()[0x01], 0x80);
}

#[test]
fn upper_ram_absent_on_the_80c51() {
    // MOV R0,#90h; MOV @R0,#5Ah; MOV A,@R0
    let prog: &[u8] = &[0x78, 0x90, 0x76, 0x5A, 0xE6];
    for (variant, a) in [(Variant::I8051, 0x00), (Variant::I8052, 0x5A)] {
        let mut c = cpu(variant, &[(0, prog)]);
        for _ in 0..3 {
            c.step(&mut NoXdata).unwrap();
        }
        assert_eq!(c.sfr()[0x60], a, "{variant:?}");
    }
}

struct Log(Vec<(u16, u8)>);

impl Xdata for Log {
    fn read(&mut self, addr: u16) -> u8 {
        addr as u8 ^ 0x55
    }
    fn write(&mut self, addr: u16, value: u8) {
        self.0.push((addr, value));
    }
}

#[test]
fn movx_is_reported_and_run_stops_after_a_write() {
    // MOV DPTR,#1234h; MOVX A,@DPTR; MOVX @DPTR,A; MOV P2,#0A0h; MOV R1,#05h; MOVX @R1,A; SJMP $
    let prog: &[u8] = &[
        0x90, 0x12, 0x34, 0xE0, 0xF0, 0x75, 0xA0, 0xA0, 0x79, 0x05, 0xF3, 0x80, 0xFE,
    ];
    let mut c = cpu(Variant::I8051, &[(0, prog)]);
    let mut log = Log(Vec::new());
    c.step(&mut log).unwrap();
    assert_eq!(
        c.step(&mut log).unwrap().xdata,
        Some(XAccess::Read { addr: 0x1234 })
    );
    assert_eq!(
        c.run(&mut log, 1000),
        Ok(RunEnd::XdataWrite {
            addr: 0x1234,
            value: 0x61
        })
    );
    assert_eq!((c.pc(), c.cycles()), (5, 6));
    assert_eq!(
        c.run(&mut log, 1000),
        Ok(RunEnd::XdataWrite {
            addr: 0xA005,
            value: 0x61
        })
    );
    assert_eq!(log.0, vec![(0x1234, 0x61), (0xA005, 0x61)]);
    assert_eq!(c.run(&mut log, 1000), Ok(RunEnd::Reached));
}

#[test]
fn serial_bytes_reach_the_caller() {
    // MOV SCON,#40h (mode 1, timer 1 stopped: TI at once); MOV SBUF,#'H'; MOV SBUF,#'i'
    let prog: &[u8] = &[0x75, 0x98, 0x40, 0x75, 0x99, b'H', 0x75, 0x99, b'i'];
    let mut c = cpu(Variant::I8051, &[(0, prog)]);
    run(&mut c, 6);
    assert_eq!(c.take_serial(), b"Hi");
    assert_eq!(c.sfr()[0x18] & 0x02, 0x02, "TI");
    assert!(c.take_serial().is_empty());
}

#[test]
fn serial_mode2_ti_after_eleven_bits_at_fosc_64() {
    // MOV SCON,#80h; MOV SBUF,#0AAh (written at cycle 3); NOPs. 11 bits × 64 clocks / 12 =
    // 58.7 machine cycles: TI at cycle 3 + 59 = 62 (Intel manual: mode 2 baud = fosc/64).
    let mut code = vec![0x75, 0x98, 0x80, 0x75, 0x99, 0xAA];
    code.extend([0x00; 100]);
    let mut c = cpu(Variant::I8051, &[(0, &code)]);
    run(&mut c, 61);
    assert_eq!((c.cycles(), c.sfr()[0x18] & 0x02), (61, 0));
    c.step(&mut NoXdata).unwrap();
    assert_eq!((c.cycles(), c.sfr()[0x18] & 0x02), (62, 0x02));
}

/// A delay-loop program with a timer 0 interrupt (mode 2, every 100 cycles) whose handler
/// counts: the idle skip must give exactly the state that stepping gives.
fn delay_program(ie: u8) -> Cpu {
    let main: &[u8] = &[
        0x75, 0x89, 0x02, // MOV TMOD,#02h
        0x75, 0x8C, 0x9C, // MOV TH0,#9Ch
        0x75, 0x8A, 0x9C, // MOV TL0,#9Ch
        0x75, 0xA8, ie, // MOV IE,#ie
        0xD2, 0x8C, // SETB TR0
        0x7F, 0x00, // loop: MOV R7,#0
        0xDF, 0xFE, // DJNZ R7,$
        0x75, 0x40, 0x37, // MOV 40h,#37h
        0xD5, 0x40, 0xFD, // DJNZ 40h,$
        0x05, 0x31, // INC 31h
        0x80, 0xF1, // SJMP loop
    ];
    cpu(
        Variant::I8051,
        &[
            (0, &[0x02, 0x00, 0x40]),
            (0x0B, &[0x05, 0x30, 0x32]),
            (0x40, main),
        ],
    )
}

#[test]
fn idle_skip_waits_for_a_request_held_off_by_an_ie_write() {
    // SETB TF0; MOV IE,#82h; DJNZ R7,$; SJMP $. Handler: INC 30h; RETI.
    let main: &[u8] = &[0xD2, 0x8D, 0x75, 0xA8, 0x82, 0xDF, 0xFE, 0x80, 0xFE];
    let make = || {
        cpu(
            Variant::I8051,
            &[
                (0, &[0x02, 0x00, 0x40]),
                (0x0B, &[0x05, 0x30, 0x32]),
                (0x40, main),
            ],
        )
    };
    let mut skipped = make();
    run(&mut skipped, 20);
    let mut stepped = make();
    while stepped.cycles() < 20 {
        stepped.step(&mut NoXdata).unwrap();
    }
    assert_eq!(skipped.snapshot(), stepped.snapshot());
    // LJMP 2, SETB 1, MOV IE 2, one DJNZ 2 (R7 = FFh), entry 2, INC 1, RETI 2, DJNZ 2 = 14.
    assert_eq!((skipped.iram()[0x30], skipped.iram()[7]), (1, 0xFB));
}

#[test]
fn idle_skip_matches_stepping() {
    for (ie, until) in [0x82, 0x00]
        .into_iter()
        .flat_map(|ie| [1, 17, 100, 517, 1000, 4321, 20_000].map(|u| (ie, u)))
    {
        let mut skipped = delay_program(ie);
        run(&mut skipped, until);
        let mut stepped = delay_program(ie);
        while stepped.cycles() < until {
            stepped.step(&mut NoXdata).unwrap();
        }
        assert_eq!(
            skipped.snapshot(),
            stepped.snapshot(),
            "IE {ie:02X}h, until {until}"
        );
        assert_eq!(skipped.cycles(), stepped.cycles(), "IE {ie:02X}h, until {until}");
        assert_eq!(stepped.skipped_cycles(), 0);
        if until >= 1000 {
            assert!(
                skipped.skipped_cycles() > until / 2,
                "IE {ie:02X}h, until {until}: skipped"
            );
        }
    }
    let mut c = delay_program(0x82);
    run(&mut c, 20_000);
    assert!(
        c.iram()[0x30] >= 190,
        "the timer interrupt kept running: {}",
        c.iram()[0x30]
    );
}

/// Every instruction told, by address: (runs, jumped, fell through).
#[derive(Default)]
struct Told(std::collections::BTreeMap<u16, (u64, u64, u64)>);

impl mcs51::Cover for Told {
    fn ran(&mut self, pc: u16) {
        self.0.entry(pc).or_default().0 += 1;
    }
    fn jumped(&mut self, pc: u16, taken: bool) {
        let e = self.0.entry(pc).or_default();
        e.0 += 1;
        if taken {
            e.1 += 1;
        } else {
            e.2 += 1;
        }
    }
    fn looped(&mut self, pc: u16, times: u32, ended: bool) {
        let e = self.0.entry(pc).or_default();
        e.0 += u64::from(times);
        e.1 += u64::from(times) - u64::from(ended);
        e.2 += u64::from(ended);
    }
}

#[test]
fn coverage_is_told_of_every_instruction_a_delay_loop_s_too() {
    // 0000 MOV R7,#10 (1 cycle); 0002 DJNZ R7,$ (2 cycles, ten times: passed in closed form);
    // 0004 CJNE R7,#0,$+3 (2: R7 is 0, it falls through); 0007 SJMP $ (2 cycles each).
    let program: &[u8] = &[0x7F, 0x0A, 0xDF, 0xFE, 0xBF, 0x00, 0x00, 0x80, 0xFE];
    for stepped in [false, true] {
        let mut c = cpu(Variant::I8051, &[(0, program)]);
        let mut told = Told::default();
        if stepped {
            while c.cycles() < 100 {
                c.step_covered(&mut NoXdata, &mut told).unwrap();
            }
        } else {
            c.run_covered(&mut NoXdata, 100, &mut told).unwrap();
        }
        // 1 + 20 + 2 = 23 cycles before the SJMPs; the ones that start before cycle 100: 39.
        let want = [
            (0x0000, (1, 0, 0)),
            (0x0002, (10, 9, 1)),
            (0x0004, (1, 0, 1)),
            (0x0007, (39, 0, 0)),
        ];
        assert_eq!(told.0.into_iter().collect::<Vec<_>>(), want, "stepped {stepped}");
    }
}
