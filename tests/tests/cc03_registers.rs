//! The AT89C51CC03's CAN controller at register level, driven by real 8051 code: one test
//! firmware per feature (this file: pages, transmission, reception filters, error flags, CANGCON,
//! CANGSTA and the counters; cc03_interrupts.rs: interrupts, the timer, priority, the buffer and
//! bit timing), assembled with as31, run on the `mcs51` core with the controller on its SFR hooks
//! (`harvemu_e2e::cc03`). Each firmware stores what it reads into internal RAM; the test plays
//! the bus and checks those bytes.
//!
//! Expected values are worked out by hand from the AT89C51CC03 data sheet (Atmel 4182: SFR map,
//! CAN register tables) and the T89C51CC01 data sheet (Atmel 4129: "Bit Timing and Baud Rate"),
//! as docs/AT89C51CC03.md lists them, and from the Intel MCS-51 User's Manual for cycle counts.
//! Where a firmware waits for the test, it polls a pin of port 1 that the test pulls low.

use bus::at89c51cc::{Action, BusSide};
use bus::engine::BusError;
use bus::fault::ErrorState;
use harvemu_e2e::cc03::firmware::*;

#[test]
fn canpage_index_auto_increment_into_canmsg() {
    let mut c = chip(
        "
	mov CANPAGE,#20h
	mov CANMSG,#11h
	mov CANMSG,#22h
	mov CANMSG,#33h
	mov CANMSG,#44h
	mov CANMSG,#55h
	mov CANMSG,#66h
	mov CANMSG,#77h
	mov CANMSG,#88h
	mov 30h,CANPAGE
	mov CANPAGE,#25h
	mov 31h,CANMSG
	mov 32h,CANMSG
	mov 33h,CANMSG
	mov 34h,CANMSG
	mov 35h,CANPAGE
	mov CANPAGE,#2Bh
	mov 36h,CANMSG
	mov 37h,CANMSG
	mov CANMSG,#0AAh
	mov 38h,CANPAGE
	mov 39h,CANMSG
	mov CANPAGE,#30h
	mov CANMSG,#0EEh
	mov CANIDT1,#56h
	mov CANPAGE,#20h
	mov CANIDT1,#12h
	mov CANIDM1,#34h
	mov CANPAGE,#23h
	mov 3Ah,CANMSG
	mov CANPAGE,#30h
	mov 3Bh,CANMSG
	mov 3Ch,CANIDT1
	mov CANPAGE,#20h
	mov 3Dh,CANIDT1
	mov 3Eh,CANIDM1
stop:	sjmp stop
",
        "reti",
        "reti",
    );
    run(&mut c, 300);
    let expected = [
        0x20, // eight accesses bring INDX round to 0
        0x66, 0x77, 0x88, 0x11, // reads from INDX 5 on, wrapping after 7
        0x21, // four reads from 5: INDX 1
        0x44, 0x44, // AINC = 1: INDX stays 3
        0x2B, 0xAA, // the write went to INDX 3, which did not move
        0xAA, // channel 3's byte did not touch channel 2's
        0xEE, 0x56, // channel 3's own CANMSG and CANIDT1
        0x12, 0x34, // channel 2's CANIDT1 and CANIDM1
    ];
    assert_eq!(ram(&c, 0x30, 15), expected);
}

#[test]
fn transmission_ide_dlc_txok_canen_and_disable() {
    let mut c = chip(
        "
	mov CANPAGE,#00h
	mov CANSTCH,#00h
	mov CANIDT1,#18h
	mov CANIDT2,#05h
	mov CANIDT3,#07h
	mov CANIDT4,#0A8h
	mov CANMSG,#01h
	mov CANMSG,#02h
	mov CANMSG,#03h
	mov CANCONCH,#53h
	mov CANPAGE,#10h
	mov CANSTCH,#00h
	mov CANIDT1,#24h
	mov CANIDT2,#60h
	mov CANIDT3,#00h
	mov CANIDT4,#04h
	mov CANCONCH,#42h
	mov 30h,CANEN2
	mov 31h,CANGSTA
	mov CANGCON,#02h
	mov 32h,CANGSTA
w0:	mov CANPAGE,#00h
	mov A,CANSTCH
	jnb ACC.6,w0
	mov 33h,A
	mov 34h,CANCONCH
	mov 35h,CANEN2
w1:	mov CANPAGE,#10h
	mov A,CANSTCH
	jnb ACC.6,w1
	mov 36h,CANEN2
	mov 37h,CANGSTA
	mov CANPAGE,#20h
	mov CANSTCH,#00h
	mov CANIDT1,#0FFh
	mov CANIDT2,#0E0h
	mov CANIDT4,#00h
	mov CANCONCH,#40h
	mov 38h,CANEN2
	mov CANCONCH,#00h
	mov 39h,CANEN2
w2:	jb P1.0,w2
	mov 3Ah,CANSTCH
	mov 3Bh,CANGSTA
stop:	sjmp stop
",
        "reti",
        "reti",
    );
    run(&mut c, 300);
    // Channel 0: IDE, DLC 3, 0x0300A0F5 left-aligned as 18 05 07 A8; channel 1: standard
    // 0x123 (CANIDT1 = ID10..3 = 24h, CANIDT2 = ID2..0 in 7:5 = 60h) with RTRTAG, DLC 2.
    let first = transmit(data(eid(0x0300_A0F5), &[1, 2, 3]));
    assert_eq!(c.take_actions(), [ONLINE, first]);
    // Both channels enabled; before ENA nothing is busy; after it ENFG and TBSY.
    assert_eq!(ram(&c, 0x30, 3), [0x03, 0x00, 0x14]);
    c.deliver(BusSide::Transmitted);
    run(&mut c, 300);
    assert_eq!(c.take_actions(), [transmit(remote(sid(0x123), 2))]);
    // TXOK; CONCH stays as written; channel 0's CANEN bit cleared, channel 1's still set.
    assert_eq!(ram(&c, 0x33, 3), [0x40, 0x53, 0x02]);
    c.deliver(BusSide::Transmitted);
    run(&mut c, 300);
    // Channel 2 (0x7FF, no data) is offered, then withdrawn by CONCH = 00.
    let third = transmit(data(sid(0x7FF), &[]));
    assert_eq!(c.take_actions(), [third, Action::Abort]);
    assert_eq!(ram(&c, 0x36, 4), [0x00, 0x04, 0x04, 0x00]);
    c.deliver(BusSide::Aborted);
    go(&mut c, 0);
    // An aborted channel sets no status flag; the transmitter is no longer busy.
    assert_eq!(ram(&c, 0x3A, 2), [0x00, 0x04]);
    assert!(c.take_actions().is_empty());
}

/// The dump of one channel: CANSTCH, CANCONCH, CANIDT1–4, four CANMSG bytes (from INDX 0).
const DUMP: &str = "
dump:	mov @R0,CANSTCH
	inc R0
	mov @R0,CANCONCH
	inc R0
	mov @R0,CANIDT1
	inc R0
	mov @R0,CANIDT2
	inc R0
	mov @R0,CANIDT3
	inc R0
	mov @R0,CANIDT4
	inc R0
	mov @R0,CANMSG
	inc R0
	mov @R0,CANMSG
	inc R0
	mov @R0,CANMSG
	inc R0
	mov @R0,CANMSG
	ret
";

#[test]
fn reception_identifier_tags_and_masks_rxok_dlcw() {
    let main = format!(
        "
	mov CANPAGE,#40h
	mov CANSTCH,#00h
	mov CANIDT1,#18h
	mov CANIDT2,#05h
	mov CANIDT3,#07h
	mov CANIDT4,#0A8h
	mov CANIDM1,#0FFh
	mov CANIDM2,#0FFh
	mov CANIDM3,#0FFh
	mov CANIDM4,#0FFh
	mov CANCONCH,#98h
	mov CANPAGE,#50h
	mov CANSTCH,#00h
	mov CANIDT1,#24h
	mov CANIDT2,#00h
	mov CANIDT3,#00h
	mov CANIDT4,#00h
	mov CANIDM1,#0FFh
	mov CANIDM2,#00h
	mov CANIDM3,#00h
	mov CANIDM4,#05h
	mov CANCONCH,#82h
	mov CANPAGE,#60h
	mov CANSTCH,#00h
	mov CANIDT1,#0AAh
	mov CANIDT2,#0A0h
	mov CANIDT3,#00h
	mov CANIDT4,#04h
	mov CANIDM1,#0FFh
	mov CANIDM2,#0E0h
	mov CANIDM3,#00h
	mov CANIDM4,#05h
	mov CANCONCH,#81h
	mov CANGCON,#02h
w0:	jb P1.0,w0
	mov 30h,CANEN2
	mov CANPAGE,#40h
	mov 31h,CANSTCH
	mov CANPAGE,#50h
	mov 32h,CANSTCH
	mov CANPAGE,#60h
	mov 33h,CANSTCH
w1:	jb P1.1,w1
	mov 34h,CANEN2
	mov R0,#40h
	mov CANPAGE,#40h
	lcall dump
	mov R0,#50h
	mov CANPAGE,#50h
	lcall dump
	mov R0,#60h
	mov CANPAGE,#60h
	lcall dump
stop:	sjmp stop
{DUMP}"
    );
    let mut c = chip(&main, "reti", "reti");
    run(&mut c, 300);
    // Channel 4: the harvester's A0, only extended data frame 0x0300A0F5 (every mask bit set,
    // RTRMSK and IDEMSK included), DLC 8 expected. Channel 5: standard data frames 120h–127h
    // (CANIDM1 = FFh compares ID10..3, CANIDM2 = 00h ignores ID2..0), DLC 2. Channel 6:
    // standard remote frame 555h only, DLC 1. None of these frames fits any of them.
    for frame in [
        data(eid(0x0300_A0F4), &[9]),
        remote(eid(0x0300_A0F5), 8),
        data(sid(0x128), &[1, 2]),
        remote(sid(0x120), 2),
        data(sid(0x555), &[]),
        data(sid(0x0A0), &[5]),
    ] {
        c.deliver(BusSide::Received(frame));
    }
    go(&mut c, 0);
    assert_eq!(ram(&c, 0x30, 4), [0x70, 0, 0, 0], "a rejected frame was taken");
    for frame in [
        data(eid(0x0300_A0F5), &[0xA1, 0xA2, 0xA3, 0xA4]),
        data(sid(0x127), &[0xB1, 0xB2]),
        remote(sid(0x555), 1),
    ] {
        c.deliver(BusSide::Received(frame));
    }
    go(&mut c, 1);
    assert_eq!(c.iram(0x34), 0x00, "CANEN2: every receiver done");
    // DLCW and RXOK: 4 bytes came where 8 were expected; CANCONCH keeps CONCH = 10 and IDE
    // and takes the DLC received, 4.
    assert_eq!(
        ram(&c, 0x40, 10),
        [0xA0, 0x94, 0x18, 0x05, 0x07, 0xA8, 0xA1, 0xA2, 0xA3, 0xA4]
    );
    // RXOK; CANIDT1/2 hold the identifier received (127h: 24h, E0h), RTRTAG 0.
    let ch5 = ram(&c, 0x50, 8);
    assert_eq!([ch5[0], ch5[1], ch5[2], ch5[3]], [0x20, 0x82, 0x24, 0xE0]);
    assert_eq!(ch5[5] & 0x04, 0, "RTRTAG of a data frame");
    assert_eq!([ch5[6], ch5[7]], [0xB1, 0xB2]);
    // The remote frame: RXOK, DLC 1 as expected (no DLCW), RTRTAG 1.
    let ch6 = ram(&c, 0x60, 6);
    assert_eq!([ch6[0], ch6[1], ch6[2], ch6[3]], [0x20, 0x81, 0xAA, 0xA0]);
    assert_eq!(ch6[5] & 0x04, 0x04, "RTRTAG of a remote frame");
}

#[test]
fn channel_and_general_error_flags() {
    let mut c = chip(
        "
	mov CANPAGE,#00h
	mov CANSTCH,#00h
	mov CANIDT1,#20h
	mov CANIDT2,#00h
	mov CANIDT4,#00h
	mov CANCONCH,#40h
	mov CANGCON,#02h
w0:	jb P1.0,w0
	mov 30h,CANSTCH
	mov 31h,CANGIT
	mov CANIE2,#01h
	mov CANGIE,#08h
	mov 32h,CANSIT2
	mov 33h,CANGIT
	mov CANGIE,#00h
	mov CANSTCH,#00h
	mov CANGIT,#00h
w1:	jb P1.1,w1
	mov 34h,CANSTCH
	mov 35h,CANGIT
	mov CANGIE,#02h
	mov 36h,CANGIT
	mov 37h,CANSIT2
stop:	sjmp stop
",
        "reti",
        "reti",
    );
    run(&mut c, 200);
    assert_eq!(c.take_actions(), [ONLINE, transmit(data(sid(0x100), &[]))]);
    let error = |error, transmitting| BusSide::BusError {
        error,
        transmitting,
        segment: 0,
    };
    c.deliver(error(BusError::Ack, true));
    c.deliver(error(BusError::Bit, true));
    go(&mut c, 0);
    // While transmitting: the channel's AERR and BERR, and no general flag (an error set in a
    // channel sets none). With ENERCH and the channel's CANIE bit: CANSIT and CANIT.
    assert_eq!(ram(&c, 0x30, 4), [0x11, 0x00, 0x01, 0x80]);
    c.deliver(error(BusError::Stuff, false));
    c.deliver(error(BusError::Crc, false));
    c.deliver(error(BusError::Form, false));
    go(&mut c, 1);
    // While receiving: no channel is blamed; SERG, CERG, FERG; with ENERG, CANIT.
    assert_eq!(ram(&c, 0x34, 4), [0x00, 0x0E, 0x8E, 0x00]);
}

#[test]
fn cangcon_listening_enable_abort_and_general_reset() {
    let mut c = chip(
        "
	mov CANPAGE,#00h
	mov CANSTCH,#00h
	mov CANIDT1,#20h
	mov CANIDT2,#00h
	mov CANIDT4,#00h
	mov CANCONCH,#40h
	mov CANGCON,#0Ah
	mov 30h,CANGSTA
	mov 31h,CANEN2
w0:	jb P1.0,w0
	mov CANGCON,#00h
	mov 32h,CANGSTA
	mov CANGCON,#02h
	mov 33h,CANGSTA
	mov CANGCON,#82h
	mov 34h,CANEN2
w1:	jb P1.1,w1
	mov 35h,CANSTCH
	mov 36h,CANGSTA
	mov CANGCON,#02h
	mov CANGIE,#3Eh
	mov CANIE2,#0FFh
	mov CANPAGE,#35h
w2:	jb P1.2,w2
	mov 3Fh,CANTEC
	mov CANGCON,#01h
	mov 37h,CANGCON
	mov 38h,CANGSTA
	mov 39h,CANGIE
	mov 3Ah,CANIE2
	mov 3Bh,CANREC
	mov 3Ch,CANTEC
	mov 3Dh,CANPAGE
	mov CANPAGE,#00h
	mov 3Eh,CANIDT1
stop:	sjmp stop
",
        "reti",
        "reti",
    );
    run(&mut c, 200);
    // ENA with AUTBAUD: listening mode; the channel stays enabled but nothing is sent.
    let listening = Action::Online {
        listen_only: true,
        self_test: false,
        filter: None,
    };
    assert_eq!(c.take_actions(), [listening]);
    assert_eq!(ram(&c, 0x30, 2), [0x04, 0x01]);
    go(&mut c, 0);
    // Off the bus, back on in normal mode (the frame goes out), then ABRQ.
    let frame = transmit(data(sid(0x100), &[]));
    assert_eq!(c.take_actions(), [Action::Offline, ONLINE, frame, Action::Abort]);
    assert_eq!(ram(&c, 0x32, 3), [0x00, 0x14, 0x00]);
    c.deliver(BusSide::Aborted);
    go(&mut c, 1);
    assert_eq!(ram(&c, 0x35, 2), [0x00, 0x04], "abort sets no flag; not busy");
    c.deliver(BusSide::Counters {
        tec: 5,
        rec: 3,
        state: ErrorState::Active,
    });
    go(&mut c, 2);
    assert_eq!(c.iram(0x3F), 5, "CANTEC before the general reset");
    assert_eq!(
        c.take_actions(),
        [Action::Offline, Action::SetCounters { tec: 0, rec: 0 }]
    );
    // GRES: CANGCON, CANGSTA, CANGIE, CANIE2, the counters and CANPAGE at their reset value
    // 00h; the message objects keep theirs (channel 0's CANIDT1).
    assert_eq!(ram(&c, 0x37, 8), [0, 0, 0, 0, 0, 0, 0, 0x20]);
}

#[test]
fn cangsta_cantec_canrec_follow_the_counters() {
    // Five rounds: wait for P1.0, then P1.1, … P1.4 to go low, and store CANTEC, CANREC and
    // CANGSTA each time.
    let mut c = chip(
        "
	mov CANGCON,#02h
	mov R0,#30h
	mov R7,#5
	mov R6,#01h
next:	mov A,P1
	anl A,R6
	jnz next
	mov @R0,CANTEC
	inc R0
	mov @R0,CANREC
	inc R0
	mov @R0,CANGSTA
	inc R0
	mov A,R6
	rl A
	mov R6,A
	djnz R7,next
stop:	sjmp stop
",
        "reti",
        "reti",
    );
    run(&mut c, 100);
    let counters = |tec, rec, state| BusSide::Counters { tec, rec, state };
    let steps = [
        (counters(96, 12, ErrorState::Active), [96, 12, 0x04]),
        (counters(128, 0, ErrorState::Passive), [128, 0, 0x05]),
        (counters(0, 130, ErrorState::Passive), [0, 130, 0x05]),
        // Bus off: TEC above 255 shows as FFh; the controller stays enabled (ENFG).
        (counters(256, 0, ErrorState::BusOff), [0xFF, 0, 0x06]),
        (BusSide::RecoveryDone, [0, 0, 0x04]),
    ];
    for (i, (event, _)) in steps.iter().enumerate() {
        c.deliver(*event);
        go(&mut c, i as u8);
    }
    let expected: Vec<u8> = steps.iter().flat_map(|(_, e)| *e).collect();
    assert_eq!(ram(&c, 0x30, 15), expected);
}
