//! AT89C51CC03 parts, expectations computed by hand from its data sheet: the SFR hook, the four
//! interrupt levels and vectors, XRAM versus external MOVX, X2, the ADC, the watchdog and idle
//! detection while a conversion runs.

use mcs51::{Cpu, Image, NoXdata, RunEnd, Variant, Xdata, irq};

fn cpu(parts: &[(u16, &[u8])]) -> Cpu {
    let mut code = vec![0xFF; 0x10000];
    for &(at, bytes) in parts {
        code[at as usize..at as usize + bytes.len()].copy_from_slice(bytes);
    }
    Cpu::new(
        Variant::At89c51cc03,
        &Image {
            code,
            written: Vec::new(),
        },
    )
}

/// Records hooked SFR accesses; holds one register at 9Bh (as a CAN SFR would) and an
/// interrupt request level.
#[derive(Default)]
struct Hook {
    reg: u8,
    log: Vec<(char, u8, u8)>,
    irq: u8,
    ext: Vec<(char, u16, u8)>,
}

impl Xdata for Hook {
    fn read(&mut self, addr: u16) -> u8 {
        self.ext.push(('r', addr, 0x5A));
        0x5A
    }
    fn write(&mut self, addr: u16, value: u8) {
        self.ext.push(('w', addr, value));
    }
    fn sfr_read(&mut self, addr: u8) -> Option<u8> {
        self.log.push(('r', addr, self.reg));
        (addr == 0x9B).then_some(self.reg)
    }
    fn sfr_write(&mut self, addr: u8, value: u8) -> bool {
        self.log.push(('w', addr, value));
        if addr == 0x9B {
            self.reg = value;
        }
        addr == 0x9B
    }
    fn irq(&self) -> u8 {
        self.irq
    }
}

fn steps(c: &mut Cpu, x: &mut dyn Xdata, n: usize) {
    for _ in 0..n {
        c.step(x).expect("no fault");
    }
}

#[test]
fn the_hook_sees_direct_bit_and_stack_accesses() {
    // MOV 9Bh,#81h; MOV A,9Bh; PUSH 9Bh; POP 9Bh; SETB 0C0h.2 (P4.2: C0h is P4, hooked);
    // MOV A,0A1h (CANTCON, the hook returns None: 00h).
    let mut c = cpu(&[(
        0,
        &[
            0x75, 0x9B, 0x81, 0xE5, 0x9B, 0xC0, 0x9B, 0xD0, 0x9B, 0xD2, 0xC2, 0xE5, 0xA1,
        ],
    )]);
    let mut h = Hook {
        reg: 0,
        ..Hook::default()
    };
    steps(&mut c, &mut h, 2);
    assert_eq!(c.sfr()[0x60], 0x81, "A read the hooked register");
    steps(&mut c, &mut h, 2);
    assert_eq!(c.iram()[0x08], 0x81, "PUSH put the hooked value on the stack");
    steps(&mut c, &mut h, 2);
    assert_eq!(
        h.log,
        vec![
            ('w', 0x9B, 0x81),
            ('r', 0x9B, 0x81),
            ('r', 0x9B, 0x81),
            ('w', 0x9B, 0x81),
            ('r', 0xC0, 0x81),
            ('w', 0xC0, 0x04),
            ('r', 0xA1, 0x81),
        ]
    );
    assert_eq!(c.sfr()[0x60], 0, "an SFR nobody implements reads 00h");
    assert!(h.ext.is_empty());
}

/// 0000 LJMP 0100h; each vector: MOV @R1,#<vector low>; INC R1; RETI. Main: MOV R1,#40h,
/// `setup`, SJMP $.
fn vectors_program(setup: &[u8]) -> Cpu {
    let mut parts: Vec<(u16, Vec<u8>)> = vec![(0, vec![0x02, 0x01, 0x00])];
    for v in [
        0x03u16, 0x0B, 0x13, 0x1B, 0x23, 0x2B, 0x33, 0x3B, 0x43, 0x4B, 0x53,
    ] {
        // MOV @R1,#v; INC R1; RETI.
        parts.push((v, vec![0x77, v as u8, 0x09, 0x32]));
    }
    let mut main = vec![0x79, 0x40]; // MOV R1,#40h
    main.extend_from_slice(setup);
    main.extend([0x80, 0xFE]);
    parts.push((0x100, main));
    let refs: Vec<(u16, &[u8])> = parts.iter().map(|(a, b)| (*a, b.as_slice())).collect();
    cpu(&refs)
}

#[test]
fn outside_sources_take_their_vectors_in_polling_order() {
    // IEN1 = 0Fh (SPI, overrun, ADC, CAN); IEN0 = C0h (EA, EC/PCA). All at level 0.
    let mut c = vectors_program(&[0x75, 0xE8, 0x0F, 0x75, 0xA8, 0xC0]);
    let mut h = Hook::default();
    // LJMP, MOV R1, two MOVs, and the SJMP that runs after an IEN0 write.
    steps(&mut c, &mut h, 5);
    h.irq = irq::PCA | irq::CAN | irq::CAN_TIMER | irq::SPI;
    // Levels stay up: each handler runs, RETI, one instruction, then the first in polling
    // order again. Drop each source after its first entry by hand.
    let mut seen = Vec::new();
    for _ in 0..4 {
        let s = c.step(&mut h).expect("no fault");
        let v = s.interrupt.expect("an interrupt entry");
        seen.push(v);
        h.irq &= !match v {
            0x33 => irq::PCA,
            0x3B => irq::CAN,
            0x4B => irq::CAN_TIMER,
            _ => irq::SPI,
        };
        // MOV @R1, INC R1, RETI, and the SJMP that runs after RETI.
        steps(&mut c, &mut h, 4);
    }
    assert_eq!(seen, vec![0x33, 0x3B, 0x4B, 0x53]);
}

#[test]
fn four_priority_levels_nest() {
    // SPI at level 1 (IPL1.3), CAN at level 2 (IPH1.0), PCA at level 3 (IPH0.6 + IPL0.6).
    // MOV IPL1,#08h; MOV IPH1,#01h; MOV IPH0,#40h; MOV IPL0,#40h; MOV IEN1,#09h; MOV IEN0,#0C0h
    let setup = [
        0x75, 0xF8, 0x08, 0x75, 0xF7, 0x01, 0x75, 0xB7, 0x40, 0x75, 0xB8, 0x40, 0x75, 0xE8, 0x09, 0x75, 0xA8,
        0xC0,
    ];
    let mut c = vectors_program(&setup);
    let mut h = Hook::default();
    // LJMP, MOV R1, six MOVs, and the SJMP that runs after an IEN0 write.
    steps(&mut c, &mut h, 9);
    // Only SPI: taken (level 1 over nothing).
    h.irq = irq::SPI;
    assert_eq!(c.step(&mut h).unwrap().interrupt, Some(0x53));
    // CAN (level 2) interrupts the SPI handler at once.
    h.irq = irq::SPI | irq::CAN;
    assert_eq!(c.step(&mut h).unwrap().interrupt, Some(0x3B));
    // PCA (level 3) interrupts the CAN handler.
    h.irq |= irq::PCA;
    assert_eq!(c.step(&mut h).unwrap().interrupt, Some(0x33));
    // Nothing interrupts level 3: the PCA handler's MOV @R1 runs.
    assert_eq!(c.step(&mut h).unwrap().interrupt, None);
    assert_eq!(c.snapshot().in_service, 0b1110);
    // A second level-1 source cannot interrupt level 1's own handler once PCA and CAN end.
    h.irq = irq::SPI;
    steps(&mut c, &mut h, 2); // INC R1; RETI (PCA)
    assert_eq!(c.snapshot().in_service, 0b0110);
}

#[test]
fn auxr_selects_xram_or_the_external_bus() {
    // MOV DPTR,#07FFh; MOV A,#33h; MOVX @DPTR,A; MOVX A,@DPTR -> XRAM (2048 bytes at reset).
    // MOV DPTR,#0800h; MOVX @DPTR,A -> external. ORL AUXR,#02h (EXTRAM); MOV DPTR,#0010h;
    // MOVX @DPTR,A -> external. ANL AUXR,#0E3h (XRS = 000: 256 bytes); ANL AUXR,#0FDh;
    // MOV DPTR,#0100h; MOVX @DPTR,A -> external; MOV DPTR,#00FFh; MOVX @DPTR,A -> XRAM.
    let prog = [
        0x90, 0x07, 0xFF, 0x74, 0x33, 0xF0, 0xE0, 0x90, 0x08, 0x00, 0xF0, 0x43, 0x8E, 0x02, 0x90, 0x00, 0x10,
        0xF0, 0x53, 0x8E, 0xE3, 0x53, 0x8E, 0xFD, 0x90, 0x01, 0x00, 0xF0, 0x90, 0x00, 0xFF, 0xF0,
    ];
    let mut c = cpu(&[(0, &prog)]);
    let mut h = Hook::default();
    steps(&mut c, &mut h, 15);
    assert_eq!(c.xram()[0x7FF], 0x33);
    assert_eq!(c.xram()[0xFF], 0x33);
    assert_eq!(c.xram().len(), 2048);
    assert_eq!(
        h.ext,
        vec![('w', 0x0800, 0x33), ('w', 0x0010, 0x33), ('w', 0x0100, 0x33)]
    );
}

#[test]
fn x2_halves_the_clocks_per_machine_cycle() {
    // NOP; ORL CKCON,#01h (2 cycles); NOP; NOP; SJMP $.
    let mut c = cpu(&[(0, &[0x00, 0x43, 0x8F, 0x01, 0x00, 0x00, 0x80, 0xFE])]);
    assert_eq!(c.clocks_per_cycle(), 12);
    assert_eq!(c.run(&mut NoXdata, 100), Ok(RunEnd::ClockChanged));
    assert_eq!((c.cycles(), c.clocks()), (3, 36));
    assert_eq!(c.clocks_per_cycle(), 6);
    assert_eq!(c.run(&mut NoXdata, 5), Ok(RunEnd::Reached));
    assert_eq!(c.clocks(), 36 + 2 * 6);
}

#[test]
fn adc_conversion_time_result_and_interrupt() {
    // MOV ADCLK,#03h; MOV ADCON,#2Dh (ADEN, ADSST, channel 5); wait: MOV A,ADCON;
    // JNB ACC.4,wait; MOV R6,ADDH; MOV R5,ADDL; SJMP $.
    let mut c = cpu(&[(
        0,
        &[
            0x75, 0xF2, 0x03, 0x75, 0xF3, 0x2D, 0xE5, 0xF3, 0x30, 0xE4, 0xFB, 0xAE, 0xF5, 0xAD, 0xF4, 0x80,
            0xFE,
        ],
    )]);
    c.set_analog_millivolts(5, 3000, 5000); // 1024 * 3000 / 5000 = 614.4 -> 614 = 266h
    // PRS 3: 11 ADC clocks of 12 peripheral clocks = 132 = 22 machine cycles, from the cycle
    // the MOV ADCON takes effect (cycle 2 + 1 = 3): done at cycle 25.
    // The wait loop takes 3 cycles a turn from cycle 4 (MOV A at 4, 7, …, 22; JNB at 23).
    while c.cycles() < 23 {
        c.step(&mut NoXdata).unwrap();
    }
    assert_eq!(c.cycles(), 23);
    assert_eq!(c.adc_conversion_cycles(), 22);
    assert_eq!(
        c.sfr()[0x73] & 0x18,
        0x08,
        "ADSST still set, no ADEOC at cycle 23"
    );
    c.step(&mut NoXdata).unwrap(); // the JNB of cycles 23–25
    assert_eq!(c.cycles(), 25);
    assert_eq!(c.sfr()[0x73] & 0x18, 0x10, "ADEOC at cycle 25");
    c.run(&mut NoXdata, 60).unwrap();
    assert_eq!(c.sfr()[0x73] & 0x18, 0x10);
    assert_eq!((c.iram()[6], c.iram()[5]), (0x99, 0x02), "614 = 10 0110 0110b");
}

#[test]
fn a_loop_waiting_for_adeoc_turns_the_same_until_the_conversion_ends() {
    // MOV ADCON,#28h; wait: MOV A,ADCON; JNB ACC.4,wait; SJMP $.
    let mut c = cpu(&[(0, &[0x75, 0xF3, 0x28, 0xE5, 0xF3, 0x30, 0xE4, 0xFB, 0x80, 0xFE])]);
    // The start, then a first turn (which loads A).
    steps(&mut c, &mut NoXdata, 3);
    let head = c.clone();
    steps(&mut c, &mut NoXdata, 2);
    assert_eq!(c.pc(), head.pc());
    // One turn is 3 cycles, and the same as 3 cycles passing idle: the conversion's end
    // (PRS 0: 11 * 4 * 32 / 6 = 235 cycles after the start, which the write makes after the
    // first of its two cycles) is the next event.
    let mut idle = head.clone();
    idle.idle(3);
    assert!(c.same_but_time(&idle));
    assert_eq!(head.next_event(), 1 + 235);
    // Passing whole turns up to the event and stepping on gives what stepping all the way does.
    let mut skipped = c.clone();
    skipped.idle(3 * 75);
    while skipped.cycles() < 260 {
        skipped.step(&mut NoXdata).unwrap();
    }
    while c.cycles() < skipped.cycles() {
        c.step(&mut NoXdata).unwrap();
    }
    assert_eq!(c.snapshot(), skipped.snapshot());
    assert_eq!(c.pc(), 8, "out of the loop at SJMP $");
    // After the end the SJMP $ loop turns with nothing under way.
    let head = c.clone();
    c.step(&mut NoXdata).unwrap();
    let mut idle = head.clone();
    idle.idle(2);
    assert!(c.same_but_time(&idle));
    assert_eq!(c.next_event(), u64::MAX);
}

#[test]
fn the_adc_interrupt_vectors_to_43h() {
    // MOV IEN1,#02h; MOV IEN0,#80h; MOV ADCLK,#06h; MOV ADCON,#28h; SJMP $. 43h: SJMP $.
    let mut c = cpu(&[
        (
            0,
            &[
                0x75, 0xE8, 0x02, 0x75, 0xA8, 0x80, 0x75, 0xF2, 0x06, 0x75, 0xF3, 0x28, 0x80, 0xFE,
            ],
        ),
        (0x43, &[0x80, 0xFE]),
    ]);
    // Start effective at cycle 7; PRS 6: 44 cycles; ADEOC at 51, polled at the end of the
    // SJMP that covers it (cycles 50–52), entry at 52.
    let mut entry = None;
    while c.cycles() < 100 {
        let at = c.cycles();
        if c.step(&mut NoXdata).unwrap().interrupt == Some(0x43) {
            entry = Some(at);
        }
    }
    assert_eq!(entry, Some(52));
}

#[test]
fn the_watchdog_resets_a_core_that_does_not_feed_it() {
    // MOV WDTPRG,#00h; MOV WDTRST,#1Eh; MOV WDTRST,#0E1h; INC 30h; SJMP $.
    let mut c = cpu(&[(
        0,
        &[
            0x75, 0xA7, 0x00, 0x75, 0xA6, 0x1E, 0x75, 0xA6, 0xE1, 0x05, 0x30, 0x80, 0xFE,
        ],
    )]);
    // Started when the third MOV takes effect (cycle 5): time-out 2^14 - 1 cycles later.
    assert_eq!(c.run(&mut NoXdata, 100_000), Ok(RunEnd::WatchdogReset));
    assert!(
        c.cycles() >= 5 + 16383 && c.cycles() <= 5 + 16383 + 2,
        "{}",
        c.cycles()
    );
    assert_eq!((c.pc(), c.watchdog_resets(), c.iram()[0x30]), (0, 1, 1));
}
