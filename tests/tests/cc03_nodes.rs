//! The AT89C51CC03's CAN controller as a firmware node on a real bus: small as31 programs run
//! on the `mcs51` core with the on-chip controller, as harvemu runs every firmware node
//! (`harvemu_e2e::run_firmware_specs`: 30 kbit/s, virtual time). Where the bench of
//! cc03_registers.rs and cc03_interrupts.rs plays the bus by hand, these tests let the engine
//! answer: aborts of a frame on the wire, the automatic reply to a remote frame, and the CAN
//! timer overflow interrupt of a program that idles.
//!
//! Expectations are worked out by hand from the AT89C51CC03 data sheet (Atmel 4182), the
//! T89C51CC01 data sheet (Atmel 4129) and, where docs/AT89C51CC03.md says so, the AT90CAN32/64/128
//! data sheet (Atmel 7679) of the same controller design; cycle counts from the Intel MCS-51
//! User's Manual. Each program stores what it reads into internal RAM from 30h; the tests read
//! it from the state dump at the end.
//!
//! Bit timing of every node: a 12 MHz crystal in X1 mode gives F_CAN = 6 MHz (T89C51CC01, "Bit
//! Timing and Baud Rate"); 30 kbit/s is 200 F_CAN periods a bit: BRP = 9 (a quantum of 10
//! periods, CANBT1 = 12h) and 20 quanta = SYNS 1 + PRS 6 + PHS1 7 + PHS2 6 (CANBT2 = PRS 5 << 1
//! = 0Ah, CANBT3 = PHS2 5 << 4 | PHS1 6 << 1 = 5Ch), SJW 1 quantum.

use bus::time::BusTime;
use bus::{Frame, Id, StandardId};
use harvemu_e2e::cc03::firmware::PRELUDE;
use harvemu_e2e::{FirmwareRun, assemble, bench_specs, parse_trace, run_firmware_specs};

/// CANBT1–3 for 30 kbit/s from F_CAN = 6 MHz (see the module docs).
const BIT_TIMING: &str = "
	mov CANBT1,#12h
	mov CANBT2,#0Ah
	mov CANBT3,#5Ch
";

/// About `ms` milliseconds of machine cycles (1 µs each): `ms` × 2 × (1 + 250 × 2 + 2) cycles.
fn delay(label: &str, ms: u32) -> String {
    format!(
        "
	mov R6,#{n}
{label}_o:	mov R7,#250
{label}_i:	djnz R7,{label}_i
	djnz R6,{label}_o
",
        n = 2 * ms
    )
}

/// A node file for an AT89C51CC03 at 12 MHz with its own controller.
fn node(name: &str) -> String {
    format!(
        "Firmware(name: \"{name}\", image: \"lab.hex\", \
         cpu: At89c51cc03(clock_hz: 12000000), controllers: [OnChip])"
    )
}

/// The image of `main` with the CAN and CAN timer handlers (the bench's prelude: vectors, CAN
/// SFR names, `main` at 0100h after `mov SP,#0C0h`).
fn image(main: &str, can_isr: &str, tim_isr: &str) -> String {
    assemble(&format!(
        "{PRELUDE}{main}\ncan_isr:\n{can_isr}\ntim_isr:\n{tim_isr}\n"
    ))
}

/// A node that waits `ms` milliseconds, then joins the bus with the lab's bit timing and
/// nothing else: it acknowledges what it receives.
fn partner(ms: u32) -> (String, String) {
    let main = format!(
        "{}{BIT_TIMING}
	mov CANGCON,#02h
stop:	sjmp stop
",
        delay("w", ms)
    );
    (node("PARTNER"), image(&main, "reti", "reti"))
}

fn sid(id: u16) -> Id {
    Id::Standard(StandardId::new(id).expect("an 11-bit identifier"))
}

fn frames(run: &FirmwareRun) -> Vec<Frame> {
    parse_trace(&run.trace).into_iter().map(|l| l.frame).collect()
}

fn run(benches: &[(String, String)], ms: u64) -> FirmwareRun {
    let run = run_firmware_specs(bench_specs(benches), BusTime::from_millis(ms), None);
    assert!(run.crashed.is_empty(), "{:?}", run.crashed);
    run
}

/// Channel 0 set up to transmit the base frame 100#AA (CANIDT1 = ID10..3 = 20h, DLC 1) and the
/// controller enabled (ENA).
const CHANNEL0_SENDS_AA: &str = "\tmov CANPAGE,#00h
\tmov CANSTCH,#00h
\tmov CANIDT1,#20h
\tmov CANIDT2,#00h
\tmov CANIDT3,#00h
\tmov CANIDT4,#00h
\tmov CANMSG,#0AAh
\tmov CANCONCH,#41h
\tmov CANGCON,#02h
";

/// Channel 0 (0x100, one byte AAh) is alone on the bus: nobody acknowledges it and it is sent
/// again and again (ACK errors, AERR). After 10 ms the program launches channel 1 (0x200, BBh),
/// which must wait for channel 0, then writes CONCH = 00 to channel 0. The partner joins at
/// 15 ms. Channel 0's attempt ends without acknowledge and is not retried (the engine's abort);
/// the bus then holds nothing of the node, so channel 1 goes next and is sent once the partner
/// acknowledges it.
#[test]
fn aborting_a_channel_that_is_retried_lets_the_next_channel_go() {
    let main = format!(
        "{BIT_TIMING}
{CHANNEL0_SENDS_AA}{}
	mov CANPAGE,#10h
	mov CANSTCH,#00h
	mov CANIDT1,#40h
	mov CANIDT2,#00h
	mov CANIDT3,#00h
	mov CANIDT4,#00h
	mov CANMSG,#0BBh
	mov CANCONCH,#41h
	mov 30h,CANEN2
	mov 31h,CANGSTA
	mov CANPAGE,#00h
	mov CANCONCH,#00h
	mov 32h,CANEN2
	mov CANPAGE,#10h
w0:	mov A,CANSTCH
	jnb ACC.6,w0
	mov 33h,A
	mov 34h,CANEN2
	mov CANPAGE,#00h
	mov 35h,CANSTCH
	mov 36h,CANGSTA
stop:	sjmp stop
",
        delay("d", 10)
    );
    let sender = (node("SENDER"), image(&main, "reti", "reti"));
    let run = run(&[sender, partner(15)], 60);
    // Only channel 1's frame completes: channel 0 was never acknowledged.
    assert_eq!(frames(&run), [Frame::new_data(sid(0x200), &[0xBB]).unwrap()]);
    let expected = [
        0x03, // channels 0 and 1 enabled (CANEN2)
        0x14, // ENFG and TBSY: the bus holds channel 0's frame (CANGSTA)
        0x02, // CONCH = 00 clears channel 0's CANEN bit at once
        0x41, // channel 1: TXOK, and AERR from its attempts before the partner joined
        0x00, // both channels free
        0x01, // channel 0: AERR from its attempts; an abort sets no flag
        0x04, // ENFG, no TBSY: the bus holds nothing (TEC below 128: error active)
    ];
    assert_eq!(run.iram(0, 0x30, 7), expected);
}

/// Channel 0 (0x100, AAh) alone on the bus again. The program waits for its first ACK error
/// (CANTEC = 8, at that attempt's ACK slot), then 1 ms: the next attempt starts 17 bits
/// (567 µs: error flag 6, delimiter 8, intermission 3) after the error and its frame runs
/// 44 bits (1467 µs) to its ACK slot, so 1 ms later that attempt is on the wire. The program
/// clears ENA and sets it again at once, and launches channel 1 (0x200, BBh). The attempt on
/// the wire runs to its end and is dropped (the engine's `Offline` is an abort); only then is
/// channel 0, still enabled, offered again. When the partner joins at 15 ms, channel 0's frame
/// is sent once, then channel 1's.
#[test]
fn ena_cleared_and_set_during_an_attempt_sends_the_frame_once() {
    let main = format!(
        "{BIT_TIMING}
{CHANNEL0_SENDS_AA}w0:	mov A,CANTEC
	jz w0
{}
	mov CANGCON,#00h
	mov CANGCON,#02h
	mov CANPAGE,#10h
	mov CANSTCH,#00h
	mov CANIDT1,#40h
	mov CANIDT2,#00h
	mov CANIDT3,#00h
	mov CANIDT4,#00h
	mov CANMSG,#0BBh
	mov CANCONCH,#41h
w1:	mov A,CANSTCH
	jnb ACC.6,w1
	mov 30h,A
	mov CANPAGE,#00h
	mov 31h,CANSTCH
	mov 32h,CANEN2
stop:	sjmp stop
",
        delay("d", 1)
    );
    let sender = (node("SENDER"), image(&main, "reti", "reti"));
    let run = run(&[sender, partner(15)], 60);
    let expected = [
        Frame::new_data(sid(0x100), &[0xAA]).unwrap(),
        Frame::new_data(sid(0x200), &[0xBB]).unwrap(),
    ];
    assert_eq!(frames(&run), expected, "{}", run.trace);
    // Channel 1 was offered only after channel 0 was sent, and the partner was there by then:
    // TXOK alone. Channel 0: TXOK and AERR (its attempts before the partner joined).
    assert_eq!(run.iram(0, 0x30, 3), [0x40, 0x41, 0x00]);
}

/// Automatic reply (docs/AT89C51CC03.md, "Automatic reply"): the replier's channel 3 is enabled
/// for reception (CONCH 10) of remote frames of 0x123 (CANIDT 24h 60h 00h 04h: RTRTAG; every
/// mask bit set, RTRMSK and IDEMSK included), with RPLV and DLC 2, its buffer 11h 12h. The
/// requester receives data frames of 0x123 on channel 1 (RTRTAG 0, RTRMSK 1) and after 2 ms
/// sends the remote frame 0x123, DLC 2, on channel 0. The replier's CPU does nothing but wait:
/// the controller answers with the data frame 0x123 11 12 and sets TXOK when it is sent, RXOK
/// never; RPLV and RTRTAG read 0 after the remote frame.
#[test]
fn a_channel_with_rplv_answers_a_remote_frame_by_itself() {
    let replier = format!(
        "{BIT_TIMING}
	mov CANPAGE,#30h
	mov CANSTCH,#00h
	mov CANIDT1,#24h
	mov CANIDT2,#60h
	mov CANIDT3,#00h
	mov CANIDT4,#04h
	mov CANIDM1,#0FFh
	mov CANIDM2,#0FFh
	mov CANIDM3,#0FFh
	mov CANIDM4,#05h
	mov CANMSG,#11h
	mov CANMSG,#12h
	mov CANCONCH,#0A2h
	mov CANGCON,#02h
w0:	mov A,CANSTCH
	jnb ACC.6,w0
	mov 30h,A
	mov 31h,CANCONCH
	mov 32h,CANIDT4
	mov 33h,CANEN2
stop:	sjmp stop
"
    );
    let requester = format!(
        "{BIT_TIMING}
	mov CANPAGE,#10h
	mov CANSTCH,#00h
	mov CANIDT1,#24h
	mov CANIDT2,#60h
	mov CANIDT3,#00h
	mov CANIDT4,#00h
	mov CANIDM1,#0FFh
	mov CANIDM2,#0FFh
	mov CANIDM3,#0FFh
	mov CANIDM4,#05h
	mov CANCONCH,#82h
	mov CANGCON,#02h
{}
	mov CANPAGE,#00h
	mov CANSTCH,#00h
	mov CANIDT1,#24h
	mov CANIDT2,#60h
	mov CANIDT3,#00h
	mov CANIDT4,#04h
	mov CANCONCH,#42h
	mov CANPAGE,#10h
w0:	mov A,CANSTCH
	jnb ACC.5,w0
	mov 30h,A
	mov 31h,CANMSG
	mov 32h,CANMSG
	mov CANPAGE,#00h
	mov 33h,CANSTCH
stop:	sjmp stop
",
        delay("d", 2)
    );
    let benches = [
        (node("REPLIER"), image(&replier, "reti", "reti")),
        (node("REQUESTER"), image(&requester, "reti", "reti")),
    ];
    let run = run(&benches, 40);
    let expected = [
        Frame::new_remote(sid(0x123), 2).unwrap(),
        Frame::new_data(sid(0x123), &[0x11, 0x12]).unwrap(),
    ];
    assert_eq!(frames(&run), expected, "{}", run.trace);
    // Replier: TXOK only; CANCONCH 82h (reception, DLC 2, RPLV cleared); RTRTAG cleared; the
    // channel free once its reply is sent.
    assert_eq!(run.iram(0, 0x30, 4), [0x40, 0x82, 0x00, 0x00]);
    // Requester: the reply in channel 1 (RXOK, 11h 12h); its remote frame sent (TXOK).
    assert_eq!(run.iram(1, 0x30, 4), [0x20, 0x11, 0x12, 0x40]);
}

/// The CAN timer overflow interrupt of a program that idles in `SJMP $`.
///
/// Cycles (Intel MCS-51 User's Manual; 1 µs each at 12 MHz in X1 mode): LJMP 0–2, MOV SP 2–4,
/// MOV R0 4–5, MOV TMOD 5–7, MOV CANTCON 7–9, SETB ETIM 9–10, SETB EA 10–11, SETB TR0 11–12
/// (timer 0 counts from cycle 12: the core counts no cycle of the SETB itself), MOV CANGCON
/// 12–14, whose write takes effect at cycle 13 (after its first machine cycle), when the CAN
/// timer starts. CANTCON = 1: a tick every 6 · (1 + 1) = 12 F_CAN periods (the divider of 6:
/// docs/AT89C51CC03.md), 24 oscillator periods, 2 machine cycles; 65 536 ticks to the overflow:
/// overflow k at cycle O(k) = 13 + 131 072 k. The CPU sees OVRTIM at the first instruction
/// boundary at or after it and enters the handler: LCALL 2 cycles to 004Bh, LJMP 2, INC 1, then
/// `MOV @R0,TL0` reads timer 0 at its second cycle, 6 cycles after the boundary; `MOV @R0,TH0`
/// three cycles later. The handler clears OVRTIM by writing 0 (`ANL CANGIT,#0DFh`) and takes 15
/// cycles in all (2 + 2 + 1 + 2 + 1 + 2 + 1 + 2 + RETI 2).
///
/// - k = 1: `SJMP $` runs from cycle 14 in steps of 2; O(1) = 131 085 is odd, so the boundary is
///   131 086: TL0 read at 131 092, 131 080 counts, TL0 = 131 080 mod 256 = 08h, TH0 (3 cycles
///   later, 131 083 mod 65 536 = 11) = 00h. The handler ends at 131 101: the loop's boundaries
///   are odd from then on.
/// - k = 2: O(2) = 262 157 is such a boundary: TL0 read at 262 163, 262 151 counts: 07h, 00h.
///   The handler ends at 262 172: even boundaries again.
/// - k = 3: as k = 1, O(3) = 393 229, boundary 393 230: 08h, 00h.
///
/// In 400 ms (400 000 cycles) the overflows at 131 085, 262 157 and 393 229 come: three entries.
/// The same with idle loops skipped and without.
#[test]
fn the_can_timer_overflow_interrupts_an_idle_loop_on_time() {
    let main = "
	mov R0,#40h
	mov TMOD,#01h
	mov CANTCON,#01h
	setb ETIM
	setb EA
	setb TR0
	mov CANGCON,#02h
stop:	sjmp stop
";
    let tim_isr = "	inc 30h
	mov @R0,TL0
	inc R0
	mov @R0,TH0
	inc R0
	anl CANGIT,#0DFh
	reti";
    let benches = [(node("TIMER"), image(main, "reti", tim_isr))];
    let end = BusTime::from_millis(400);
    let skipping = run_firmware_specs(bench_specs(&benches), end, None);
    let mut specs = bench_specs(&benches);
    for s in &mut specs {
        std::sync::Arc::make_mut(s).skip_idle_loops = false;
    }
    let working = run_firmware_specs(specs, end, None);
    assert_eq!(skipping.iram(0, 0x7F, 1), [0x00], "no stray vector");
    assert_eq!(skipping.iram(0, 0x30, 1), [3], "three overflows in 400 ms");
    assert_eq!(
        skipping.iram(0, 0x40, 8),
        [0x08, 0x00, 0x07, 0x00, 0x08, 0x00, 0x00, 0x00]
    );
    assert_eq!(skipping.states, working.states);
}
