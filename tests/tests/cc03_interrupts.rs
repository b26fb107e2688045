//! The AT89C51CC03's CAN controller at register level, driven by real 8051 code: one test
//! firmware per feature (this file: the CAN and CAN timer interrupts, the timer and time stamps,
//! channel priority, the reception buffer and bit timing; cc03_registers.rs: the rest), assembled with as31, run on the `mcs51` core with the controller on its SFR hooks
//! (`harvemu_e2e::cc03`). Each firmware stores what it reads into internal RAM; the test plays
//! the bus and checks those bytes.
//!
//! Expected values are worked out by hand from the AT89C51CC03 data sheet (Atmel 4182: SFR map,
//! CAN register tables) and the T89C51CC01 data sheet (Atmel 4129: "Bit Timing and Baud Rate"),
//! as docs/AT89C51CC03.md lists them, and from the Intel MCS-51 User's Manual for cycle counts.
//! Where a firmware waits for the test, it polls a pin of port 1 that the test pulls low.

use bus::at89c51cc::BusSide;
use harvemu_e2e::cc03::firmware::*;

#[test]
fn can_interrupt_only_when_ecan_ea_canie_and_cangie_allow() {
    let mut c = chip(
        "
	mov 50h,#00h
	mov CANPAGE,#30h
	mov CANSTCH,#00h
	mov CANIDM1,#00h
	mov CANIDM2,#00h
	mov CANIDM3,#00h
	mov CANIDM4,#00h
	mov CANCONCH,#80h
	mov CANIE2,#08h
	mov CANGIE,#20h
	setb ECAN
	mov CANGCON,#02h
w0:	jb P1.0,w0
	mov 30h,CANSIT2
	mov 31h,CANGIT
	nop
	nop
	mov 32h,50h
	clr ECAN
	setb EA
	nop
	nop
	mov 33h,50h
	mov CANIE2,#00h
	setb ECAN
	nop
	nop
	mov 34h,50h
	mov 35h,CANSIT2
	mov 36h,CANGIT
	mov CANIE2,#08h
	nop
	nop
	mov 37h,50h
	mov CANGIE,#10h
	setb ECAN
	nop
	nop
	mov 38h,50h
	mov CANGIE,#20h
	nop
	nop
	mov 39h,50h
stop:	sjmp stop
",
        // The handler counts and masks ECAN, leaving RXOK set for the next case.
        "	inc 50h
	clr ECAN
	reti",
        "	mov 7Fh,#0EEh
	reti",
    );
    run(&mut c, 200);
    c.deliver(BusSide::Received(data(sid(0x42), &[])));
    go(&mut c, 0);
    let expected = [
        0x08, 0x80, // channel 3 in CANSIT2, CANIT: the request is up
        0,    // EA = 0: not taken
        0,    // ECAN = 0: not taken
        0, 0x00, 0x00, // CANIE2 = 0: no CANSIT, no CANIT, not taken
        1,    // all four allow: taken once
        1,    // CANGIE with ENTX but not ENRX: not taken
        2,    // ENRX again: taken
    ];
    assert_eq!(ram(&c, 0x30, 10), expected);
}

#[test]
fn can_timer_counts_while_enabled_and_stamps_a_reception() {
    // Cycles (Intel MCS-51 User's Manual): LJMP 2, MOV direct,#data 2, MOV Rn,#data 1,
    // DJNZ Rn 2, MOV direct,direct 2. The ENA write starts at cycle 2 + 2 + 2 + 1 + 200 + 2
    // + 2 = 211. With CANTCON = 4 a tick is 6 · 5 F_CAN periods: 60 oscillator periods, 5
    // machine cycles.
    let mut c = chip(
        "
	mov CANTCON,#04h
	mov R7,#100
d0:	djnz R7,d0
	mov 30h,CANTIML
	mov 31h,CANTIMH
	mov CANGCON,#02h
	mov 32h,CANTIML
	mov R7,#51
d1:	djnz R7,d1
	mov 33h,CANTIML
	mov 34h,CANTIMH
	mov CANPAGE,#10h
	mov CANSTCH,#00h
	mov CANIDM1,#00h
	mov CANIDM2,#00h
	mov CANIDM3,#00h
	mov CANIDM4,#00h
	mov CANCONCH,#80h
w0:	mov A,CANSTCH
	jnb ACC.5,w0
	mov 35h,CANSTMPL
	mov 36h,CANSTMPH
	mov CANSTCH,#00h
	mov CANCONCH,#80h
w1:	mov A,CANSTCH
	jnb ACC.5,w1
	mov 37h,CANSTMPL
	mov 38h,CANSTMPH
stop:	sjmp stop
",
        "reti",
        "reti",
    );
    const ENABLED_AT: u64 = 211;
    run(&mut c, 2000);
    // Not counting before ENA; 2 cycles after it, no tick yet; 105 cycles later (MOV 2, MOV
    // Rn 1, 51 DJNZ 102), exactly 21 ticks more.
    assert_eq!(ram(&c, 0x30, 5), [0, 0, 0, 21, 0]);
    let first = c.cycles();
    c.deliver(BusSide::Received(data(sid(0x10), &[1])));
    run(&mut c, 1000);
    let second = c.cycles();
    c.deliver(BusSide::Received(data(sid(0x11), &[2])));
    run(&mut c, 200);
    let stamp = |at: u64| ((at - ENABLED_AT) / 5) as u16;
    let got = ram(&c, 0x35, 4);
    assert_eq!(u16::from_le_bytes([got[0], got[1]]), stamp(first));
    assert_eq!(u16::from_le_bytes([got[2], got[3]]), stamp(second));
    assert!(stamp(first) > 255, "the test reaches CANSTMPH");
}

#[test]
fn can_timer_overflow_enters_its_own_vector() {
    // SETB bit is 1 cycle: the ENA write starts at 2 + 2 + 2 + 1 + 1 = 8. CANTCON = 0: a tick
    // every 6 F_CAN periods, one machine cycle, so 0xFFFF to 0 comes 65536 cycles later.
    let mut c = chip(
        "
	mov 51h,#00h
	setb ETIM
	setb EA
	mov CANGCON,#02h
stop:	sjmp stop
",
        "	mov 7Eh,#0EEh
	reti",
        "	inc 51h
	mov 52h,CANGIT
	anl CANGIT,#0DFh
	reti",
    );
    let overflow = 8 + 65_536;
    run(&mut c, overflow - 20);
    assert_eq!(c.iram(0x51), 0, "no overflow yet");
    run(&mut c, 40);
    // OVRTIM (20h) without CANIT: the CAN vector 003Bh is not taken.
    assert_eq!(ram(&c, 0x51, 2), [1, 0x20]);
    assert_ne!(c.iram(0x7E), 0xEE, "the CAN vector was taken");
}

#[test]
fn lower_channel_first_for_transmission_and_reception() {
    let main = format!(
        "
	mov CANPAGE,#50h
	mov CANSTCH,#00h
	mov CANIDT1,#0A0h
	mov CANIDT2,#00h
	mov CANIDT4,#00h
	mov CANCONCH,#40h
	mov CANPAGE,#20h
	mov CANSTCH,#00h
	mov CANIDT1,#0C0h
	mov CANIDT2,#00h
	mov CANIDT4,#00h
	mov CANCONCH,#40h
	mov CANPAGE,#70h
	mov CANSTCH,#00h
	{ANY}
	mov CANCONCH,#81h
	mov CANPAGE,#90h
	mov CANSTCH,#00h
	{ANY}
	mov CANCONCH,#81h
	mov CANIE1,#02h
	mov CANGIE,#20h
	mov CANGCON,#02h
w0:	jb P1.0,w0
	mov CANPAGE,#70h
	mov 30h,CANSTCH
	mov 31h,CANMSG
	mov CANPAGE,#90h
	mov 32h,CANSTCH
	mov 33h,CANEN1
	mov 34h,CANEN2
w1:	jb P1.1,w1
	mov 35h,CANSTCH
	mov 36h,CANMSG
	mov 37h,CANEN1
	mov 38h,CANSIT1
	mov 39h,CANSIT2
stop:	sjmp stop
"
    );
    let mut c = chip(&main, "reti", "reti");
    run(&mut c, 300);
    // Channel 2 goes before channel 5 although its identifier (600h) loses arbitration to
    // channel 5's (500h): the controller offers the lowest channel number first.
    let (two, five) = (data(sid(0x600), &[]), data(sid(0x500), &[]));
    assert_eq!(c.take_actions(), [ONLINE, transmit(two)]);
    c.deliver(BusSide::Transmitted);
    run(&mut c, 100);
    assert_eq!(c.take_actions(), [transmit(five)]);
    c.deliver(BusSide::Transmitted);
    // Channels 7 and 9 both accept every frame: channel 7 takes the first.
    c.deliver(BusSide::Received(data(sid(0x1), &[0x11])));
    go(&mut c, 0);
    assert_eq!(ram(&c, 0x30, 5), [0x20, 0x11, 0x00, 0x02, 0x00]);
    c.deliver(BusSide::Received(data(sid(0x2), &[0x22])));
    go(&mut c, 1);
    // Channel 9 takes the second; only it has CANIE (CANIE1 bit 1), so only it is in CANSIT.
    assert_eq!(ram(&c, 0x35, 5), [0x20, 0x22, 0x00, 0x02, 0x00]);
}

#[test]
fn reception_buffer_fills_in_channel_order_then_ovrbuf() {
    let main = format!(
        "
	mov CANPAGE,#80h
	mov CANSTCH,#00h
	{ANY}
	mov CANCONCH,#0C1h
	mov CANPAGE,#90h
	mov CANSTCH,#00h
	{ANY}
	mov CANCONCH,#0C1h
	mov CANPAGE,#0A0h
	mov CANSTCH,#00h
	{ANY}
	mov CANCONCH,#0C1h
	mov CANGIE,#04h
	mov 30h,CANEN1
	mov CANGCON,#02h
w0:	jb P1.0,w0
	mov 31h,CANEN1
	mov 32h,CANGIT
w1:	jb P1.1,w1
	mov 33h,CANEN1
	mov 34h,CANGIT
	mov CANPAGE,#80h
	mov 35h,CANSTCH
	mov 36h,CANMSG
	mov CANPAGE,#90h
	mov 37h,CANSTCH
	mov 38h,CANMSG
	mov CANPAGE,#0A0h
	mov 39h,CANSTCH
	mov 3Ah,CANMSG
stop:	sjmp stop
"
    );
    let mut c = chip(&main, "reti", "reti");
    run(&mut c, 300);
    let frame = |b: u8| BusSide::Received(data(sid(0x300 + u16::from(b)), &[b]));
    c.deliver(frame(1));
    c.deliver(frame(2));
    go(&mut c, 0);
    c.deliver(frame(3));
    c.deliver(frame(4));
    go(&mut c, 1);
    let expected = [
        0x07, // channels 8, 9, 10 (CANEN1 bits 0–2) enabled into the buffer
        0x04, 0x00, // two frames: 8 and 9 filled, no OVRBUF yet
        0x00, 0x90, // the third fills the buffer: OVRBUF, and CANIT as ENBUF is set
        0x20, 1, 0x20, 2, 0x20, 3, // in channel order; the fourth frame is lost
    ];
    assert_eq!(ram(&c, 0x30, 11), expected);
}

#[test]
fn canbt_registers_give_the_bit_rate_of_the_data_sheet_formula() {
    let mut c = chip(
        "
	mov CANBT1,#02h
	mov CANBT2,#04h
	mov CANBT3,#36h
	mov 30h,CANBT1
	mov 31h,CANBT2
	mov 32h,CANBT3
w0:	jb P1.0,w0
	mov CANBT3,#38h
w1:	jb P1.1,w1
	mov CANBT1,#0FFh
	mov CANBT2,#0FFh
	mov CANBT3,#0FFh
	mov 33h,CANBT1
	mov 34h,CANBT2
	mov 35h,CANBT3
stop:	sjmp stop
",
        "reti",
        "reti",
    );
    run(&mut c, 100);
    assert_eq!(ram(&c, 0x30, 3), [0x02, 0x04, 0x36]);
    // 12 MHz in X1 mode: F_CAN = 6 MHz. BRP = 1: a quantum is 2 / 6 MHz. PRS = 2, PHS1 = 3,
    // PHS2 = 3: 1 + 3 + 4 + 4 = 12 quanta, 24 F_CAN periods, 4 µs: 250 kbit/s. SJW = 0: 1
    // quantum. ISO 11898-1 tolerance: min(4, 4) / (2 · (13 · 12 − 4)) = 1/76 and
    // 1 / (20 · 12) = 1/240; the smaller holds.
    let t = c.can().bit_timing();
    assert_eq!(
        (t.brp, t.sjw, t.prs, t.phs1, t.phs2, t.smp),
        (1, 0, 2, 3, 3, false)
    );
    assert_eq!(t.quanta_per_bit(), 12);
    assert_eq!(t.clocks_per_bit(), 24);
    assert_eq!(t.bit_rate_hz(), 250_000.0);
    assert_eq!(t.bit_time(), Some(bus::time::BusDuration::from_micros(4)));
    assert!((t.tolerance() - 1.0 / 240.0).abs() < 1e-12);
    assert!(t.samples_correctly(250_000.0));
    go(&mut c, 0);
    // PHS1 = 4 instead: 13 quanta, 26 periods, 230 769 bit/s, 7.7 % slow; the tolerance is
    // 1 / (20 · 13) = 0.38 %, so the bus's 250 kbit/s cannot be sampled.
    let t = c.can().bit_timing();
    assert_eq!(t.quanta_per_bit(), 13);
    assert!((t.bit_rate_hz() - 6_000_000.0 / 26.0).abs() < 1e-6);
    assert!((t.tolerance() - 1.0 / 260.0).abs() < 1e-12);
    assert!(!t.samples_correctly(250_000.0));
    go(&mut c, 1);
    // Reserved bits read 0: CANBT1 bits 7 and 0, CANBT2 bits 7, 4 and 0, CANBT3 bit 7.
    assert_eq!(ram(&c, 0x33, 3), [0x7E, 0x6E, 0x7F]);
}
