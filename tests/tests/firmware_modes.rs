//! Every transmission mode Linux's `sja1000.c` drives, run by small 80C51 programs through the
//! SJA1000's registers: single shot (CMR = TR | AT, CAN_CTRLMODE_ONE_SHOT), self reception
//! (CMR = SRR, LOOPBACK), self test (MOD.STM, PRESUME_ACK), listen only (MOD.LOM, LISTENONLY),
//! abort (CMR.AT), sleep (MOD.SM) and the bus-off that a TXERR of 255 forces, with the recovery
//! after it.
//!
//! Each program sets its chip up in PeliCAN mode on the lab's 30 kbit/s bus (6 MHz crystal,
//! BTR0 = 03h, BTR1 = FFh: 25 quanta of 4/3 µs), accepting every frame, every interrupt flag
//! enabled (the chip sets a flag only when its enable is set; the INT pin is not wired, the
//! program polls). After each step it copies SR, IR, TXERR, RXERR, RMC, ECC, ALC and MOD into
//! internal RAM, 8 bytes a snapshot from 30h; the test reads them from the state dump at the end.
//! Expected values come from the data sheet's register descriptions (section numbers in
//! docs/SJA1000.md): SR bits RBS 01h, TBS 04h, TCS 08h, RS 10h, TS 20h, ES 40h, BS 80h; IR bits
//! RI 01h, TI 02h, EI 04h, BEI 80h; ECC for an ACK error while transmitting: "other" type (11b),
//! transmitting (bit 5 = 0), segment ACK slot 19h, so D9h.

use bus::time::BusTime;
use harvemu_e2e::{assemble, bench_file, parse_trace, run_firmware_with};

/// One snapshot: SR, IR, TXERR, RXERR, RMC, ECC, ALC, MOD.
#[derive(Debug, PartialEq, Eq, Clone, Copy)]
struct Snap {
    sr: u8,
    ir: u8,
    txerr: u8,
    rxerr: u8,
    rmc: u8,
    ecc: u8,
    alc: u8,
    mode: u8,
}

/// Builds a program for a chip at page `page` (D3h or D4h) step by step.
struct Program {
    page: u8,
    text: String,
    labels: usize,
    snaps: u8,
}

impl Program {
    /// Reset mode, PeliCAN, the lab's bit timing, every frame accepted, every interrupt flag
    /// enabled, MOD = `mode` (LOM 02h, STM 04h) set in reset mode, then reset mode left.
    fn new(page: u8, mode: u8) -> Program {
        let mut p = Program {
            page,
            text: String::from(
                "        .org 4000H\n        LJMP START\n        .org 4080H\nSTART:  MOV SP, #60H\n",
            ),
            labels: 0,
            snaps: 0,
        };
        p.line(&format!("MOV DPH, #0{page:02X}H"));
        p.write(0x00, 0x01);
        p.write(0x1F, 0x80);
        p.write(0x06, 0x03);
        p.write(0x07, 0xFF);
        for amr in 0x14..=0x17 {
            p.write(amr, 0xFF);
        }
        p.write(0x04, 0xFF);
        p.write(0x00, mode | 0x01);
        p.write(0x00, mode);
        p
    }
    fn line(&mut self, s: &str) {
        self.text.push_str("        ");
        self.text.push_str(s);
        self.text.push('\n');
    }
    fn label(&mut self) -> String {
        self.labels += 1;
        format!("L{}", self.labels)
    }
    /// Writes `value` into chip register `reg`.
    fn write(&mut self, reg: u8, value: u8) -> &mut Self {
        self.line(&format!("MOV DPL, #0{reg:02X}H"));
        self.line(&format!("MOV A, #0{value:02X}H"));
        self.line("MOVX @DPTR, A");
        self
    }
    /// Loads the frame 123#5A into the transmit buffer: frame information 01h (base, DLC 1),
    /// ID10..3 = 24h, ID2..0 = 011b in bits 7:5 (60h), data 5Ah.
    fn frame(&mut self) -> &mut Self {
        self.write(0x10, 0x01)
            .write(0x11, 0x24)
            .write(0x12, 0x60)
            .write(0x13, 0x5A)
    }
    /// Waits about `ms` milliseconds (512 machine cycles of 1 µs make half of one), in loops of
    /// at most 100 ms.
    fn delay(&mut self, ms: u16) -> &mut Self {
        let mut left = ms;
        while left > 0 {
            let chunk = left.min(100);
            left -= chunk;
            let (outer, inner) = (self.label(), self.label());
            self.line(&format!("MOV R5, #{}", chunk * 2));
            self.text.push_str(&format!("{outer}:\n"));
            self.line("MOV R4, #0");
            self.text.push_str(&format!("{inner}:\n"));
            self.line(&format!("DJNZ R4, {inner}"));
            self.line(&format!("DJNZ R5, {outer}"));
        }
        self
    }
    /// Polls register `reg` until `reg AND mask` is non-zero (`set`) or zero, for at most
    /// 65,536 polls of 9 cycles (0.59 s); then goes on either way.
    fn wait(&mut self, reg: u8, mask: u8, set: bool) -> &mut Self {
        let (poll, out) = (self.label(), self.label());
        self.line("MOV R7, #0");
        self.line("MOV R6, #0");
        self.text.push_str(&format!("{poll}:\n"));
        self.line(&format!("MOV DPL, #0{reg:02X}H"));
        self.line("MOVX A, @DPTR");
        self.line(&format!("ANL A, #0{mask:02X}H"));
        self.line(&format!("{} {out}", if set { "JNZ" } else { "JZ" }));
        self.line(&format!("DJNZ R6, {poll}"));
        self.line(&format!("DJNZ R7, {poll}"));
        self.text.push_str(&format!("{out}:\n"));
        self
    }
    /// Copies SR, IR, TXERR, RXERR, RMC, ECC, ALC and MOD to the next 8 bytes from 30h.
    fn snap(&mut self) -> &mut Self {
        let base = 0x30 + 8 * self.snaps;
        self.snaps += 1;
        for (k, reg) in [0x02u8, 0x03, 0x0F, 0x0E, 0x1D, 0x0C, 0x0B, 0x00]
            .iter()
            .enumerate()
        {
            self.line(&format!("MOV DPL, #0{reg:02X}H"));
            self.line("MOVX A, @DPTR");
            self.line(&format!("MOV 0{:02X}H, A", base + k as u8));
        }
        self
    }
    /// Copies the receive window's frame information, two identifier bytes and first data
    /// byte (registers 10h to 13h) to internal RAM 70h to 73h.
    fn received(&mut self) -> &mut Self {
        for (k, reg) in [0x10u8, 0x11, 0x12, 0x13].iter().enumerate() {
            self.line(&format!("MOV DPL, #0{reg:02X}H"));
            self.line("MOVX A, @DPTR");
            self.line(&format!("MOV 0{:02X}H, A", 0x70 + k));
        }
        self
    }
    /// The program's HEX, ending in an idle loop.
    fn hex(&mut self) -> String {
        self.text.push_str("HALT:   SJMP HALT\n");
        assemble(&self.text)
    }
    /// The bench: node file and HEX.
    fn bench(&mut self, name: &str) -> (String, String) {
        let base = u16::from(self.page) << 8;
        (bench_file(name, 0x4000, base, 6_000_000, "None"), self.hex())
    }
}

/// A partner that only sets its chip up (normal mode) and idles: it acknowledges every frame.
fn partner() -> (String, String) {
    Program::new(0xD4, 0x00).bench("PARTNER")
}

struct Run {
    snaps: Vec<Snap>,
    received: Vec<u8>,
    frames: Vec<String>,
    others: Vec<Snap>,
}

/// Runs the benches for `ms` of bus time; the snapshots of the first, and the first snapshot
/// of the others.
fn run(benches: &[(String, String)], ms: u64, snaps: usize) -> Run {
    let run = run_firmware_with(benches, BusTime::from_millis(ms), None);
    assert_eq!(run.crashed, [], "{}", run.trace);
    let read = |node: usize, n: usize| -> Vec<Snap> {
        let bytes = run.iram(node, 0x30, 8 * n);
        bytes
            .chunks(8)
            .map(|b| Snap {
                sr: b[0],
                ir: b[1],
                txerr: b[2],
                rxerr: b[3],
                rmc: b[4],
                ecc: b[5],
                alc: b[6],
                mode: b[7],
            })
            .collect()
    };
    let frames = parse_trace(&run.trace)
        .iter()
        .map(|f| format!("{:03X}#{}", f.frame.raw_id(), hex(f.frame.data())))
        .collect();
    Run {
        snaps: read(0, snaps),
        received: run.iram(0, 0x70, 4),
        frames,
        others: (1..benches.len()).flat_map(|n| read(n, 1)).collect(),
    }
}

fn hex(data: &[u8]) -> String {
    data.iter().map(|b| format!("{b:02X}")).collect()
}

/// ONE_SHOT alone: one attempt, an ACK error (TXERR 8), then the buffer is free without the
/// transmission complete: SR = TBS (04h), IR = TI | BEI (82h), ECC = D9h. 20 ms later TXERR is
/// still 8: nothing was retried.
#[test]
fn one_shot_alone_makes_one_attempt() {
    let mut p = Program::new(0xD3, 0x00);
    p.delay(1).frame().write(0x01, 0x03).wait(0x02, 0x04, true).snap();
    p.delay(20).snap();
    let r = run(&[p.bench("ONESHOT")], 60, 2);
    let first = r.snaps[0];
    assert_eq!(
        (first.sr, first.ir, first.txerr, first.rxerr, first.ecc),
        (0x04, 0x82, 8, 0, 0xD9),
        "{r:?}",
        r = r.snaps
    );
    assert_eq!(r.snaps[1].txerr, 8, "{:?}", r.snaps);
    assert!(r.frames.is_empty(), "{:?}", r.frames);
}

/// ONE_SHOT with a partner that acknowledges: the frame goes out once: SR = TBS | TCS (0Ch),
/// IR = TI (02h), TXERR 0, and the trace has 123#5A once.
#[test]
fn one_shot_with_a_partner_completes() {
    let mut p = Program::new(0xD3, 0x00);
    p.delay(2).frame().write(0x01, 0x03).wait(0x02, 0x04, true).snap();
    let r = run(&[p.bench("ONESHOT"), partner()], 40, 1);
    let s = r.snaps[0];
    assert_eq!((s.sr, s.ir, s.txerr), (0x0C, 0x02, 0), "{:?}", r.snaps);
    assert_eq!(r.frames, ["123#5A"]);
}

/// PRESUME_ACK (MOD.STM) alone: the frame completes with nobody to acknowledge it: SR = 0Ch,
/// IR = TI, TXERR 0, and it is on the bus.
#[test]
fn self_test_mode_completes_alone() {
    let mut p = Program::new(0xD3, 0x04);
    p.delay(1).frame().write(0x01, 0x01).wait(0x02, 0x04, true).snap();
    let r = run(&[p.bench("STM")], 40, 1);
    let s = r.snaps[0];
    assert_eq!((s.sr, s.ir, s.txerr, s.rmc), (0x0C, 0x02, 0, 0), "{:?}", r.snaps);
    assert_eq!(r.frames, ["123#5A"]);
}

/// A board self test, MOD.STM with CMR = SRR, alone: the chip sends the frame without an
/// acknowledge and receives it itself: SR = RBS | TBS | TCS (0Dh), IR = RI | TI (03h), RMC 1,
/// and the receive window holds 01h 24h 60h 5Ah.
#[test]
fn self_test_with_self_reception_receives_its_own_frame() {
    let mut p = Program::new(0xD3, 0x04);
    p.delay(1)
        .frame()
        .write(0x01, 0x10)
        .wait(0x02, 0x04, true)
        .snap()
        .received();
    let r = run(&[p.bench("SELFTEST")], 40, 1);
    let s = r.snaps[0];
    assert_eq!((s.sr, s.ir, s.txerr, s.rmc), (0x0D, 0x03, 0, 1), "{:?}", r.snaps);
    assert_eq!(r.received, [0x01, 0x24, 0x60, 0x5A]);
}

/// LOOPBACK (CMR = SRR, normal mode) with a partner: acknowledged, sent and received by its own
/// chip: SR 0Dh, IR 03h, RMC 1.
#[test]
fn self_reception_with_a_partner() {
    let mut p = Program::new(0xD3, 0x00);
    p.delay(2)
        .frame()
        .write(0x01, 0x10)
        .wait(0x02, 0x04, true)
        .snap()
        .received();
    let r = run(&[p.bench("LOOPBACK"), partner()], 40, 1);
    let s = r.snaps[0];
    assert_eq!((s.sr, s.ir, s.txerr, s.rmc), (0x0D, 0x03, 0, 1), "{:?}", r.snaps);
    assert_eq!(r.received, [0x01, 0x24, 0x60, 0x5A]);
    assert_eq!(r.frames, ["123#5A"]);
}

/// LISTENONLY: the listener (MOD.LOM) is the only other node while a sender requests 123#5A
/// once. The listener drives nothing: no ACK, so the sender's attempts fail with ACK errors until
/// it is error passive at TXERR 128, where exception 3a keeps it; the listener sends no error
/// flag and its counters stay 0. Once the sender's flags are passive, nothing destroys the frame
/// for the listener, which receives it (RMC at least 1).
#[test]
fn listen_only_receives_and_drives_nothing() {
    let mut listener = Program::new(0xD3, 0x02);
    listener.delay(150).snap();
    let mut sender = Program::new(0xD4, 0x00);
    sender.delay(2).frame().write(0x01, 0x01).delay(140).snap();
    let r = run(&[listener.bench("LISTENER"), sender.bench("SENDER")], 200, 1);
    let l = r.snaps[0];
    assert_eq!((l.txerr, l.rxerr, l.mode), (0, 0, 0x02), "{:?}", r.snaps);
    assert!(l.rmc >= 1, "{:?}", r.snaps);
    assert_eq!(r.others[0].txerr, 128, "the sender: {:?}", r.others);
}

/// Restart after a forced bus-off: in reset mode TXERR = 255, then clearing RM performs the
/// bus-off (data sheet 6.4.12): reset mode again, TXERR 127, RXERR 0, SR = BS | ES | RS | TS |
/// TCS | TBS (FCh: in PeliCAN reset mode RS and TS read 1; TCS is still the 1 of the hardware
/// reset, no transmission having been requested), IR = EI. Clearing RM again runs the
/// recovery, 128 × 11 recessive bits (46.9 ms at 30 kbit/s); polled until BS is 0, the chip is
/// in operating mode with both counters 0, SR = TBS | TCS (0Ch) and IR = EI for BS's change.
#[test]
fn forced_bus_off_recovers_when_reset_mode_is_left_again() {
    let mut p = Program::new(0xD3, 0x00);
    p.delay(1)
        .write(0x00, 0x01)
        .write(0x0F, 0xFF)
        .write(0x00, 0x00)
        .snap();
    p.write(0x00, 0x00).wait(0x02, 0x80, false).snap();
    let r = run(&[p.bench("FORCED")], 200, 2);
    let (off, on) = (r.snaps[0], r.snaps[1]);
    assert_eq!(
        (off.mode & 1, off.sr, off.ir, off.txerr, off.rxerr),
        (1, 0xFC, 0x04, 127, 0),
        "{:?}",
        r.snaps
    );
    assert_eq!(
        (on.mode, on.sr, on.ir, on.txerr, on.rxerr),
        (0x00, 0x0C, 0x04, 0, 0),
        "{:?}",
        r.snaps
    );
}

/// Abort (CMR = AT) while a frame alone on the bus is retried after ACK errors: the attempt on
/// the bus ends, and the buffer is free without the transmission complete: SR = TBS (04h), TI
/// raised. Nothing is retried afterwards (TXERR the same 20 ms later), and the next request
/// (TR | AT) works: one more attempt, TXERR + 8, the buffer free again.
#[test]
fn abort_frees_the_buffer_and_the_next_request_works() {
    let mut p = Program::new(0xD3, 0x00);
    p.delay(1).frame().write(0x01, 0x01).delay(5).write(0x01, 0x02);
    p.wait(0x02, 0x04, true).snap().delay(20).snap();
    p.write(0x01, 0x03).wait(0x02, 0x04, true).snap();
    let r = run(&[p.bench("ABORT")], 100, 3);
    let (aborted, later, again) = (r.snaps[0], r.snaps[1], r.snaps[2]);
    assert_eq!((aborted.sr, aborted.ir & 0x02), (0x04, 0x02), "{:?}", r.snaps);
    assert!(
        aborted.txerr % 8 == 0 && (8..=32).contains(&aborted.txerr),
        "{:?}",
        r.snaps
    );
    assert_eq!(later.txerr, aborted.txerr, "{:?}", r.snaps);
    assert_eq!((again.sr, again.ir & 0x02), (0x04, 0x02), "{:?}", r.snaps);
    assert_eq!(again.txerr, aborted.txerr + 8, "{:?}", r.snaps);
}

/// Sleep (MOD.SM) with a sender: the sleeping chip is off the bus, so the sender's first attempt
/// has nobody to acknowledge it (an ACK error, TXERR 8). Its start of frame wakes the sleeper:
/// MOD.SM reads 0 and IR = WUI (10h), but the chip does not receive that frame: it integrates
/// first, 11 recessive bits after the sender's 6-bit error flag (error delimiter 8 + intermission
/// 3), which is exactly when the sender retries (data sheet 6.4.3: the waking message is lost
/// until 11 recessive bits). So the retry is acknowledged by the woken chip (the sender's TXERR
/// 8 − 1 = 7, SR 0Ch) and received by it once (RMC 1, RBS, RXERR 0). The trace has the frame
/// once.
#[test]
fn sleeping_chip_is_off_the_bus_and_bus_activity_wakes_it() {
    let mut sleeper = Program::new(0xD3, 0x00);
    sleeper.delay(1).write(0x00, 0x10).snap();
    sleeper.wait(0x00, 0x10, false).snap().delay(20).snap();
    let mut sender = Program::new(0xD4, 0x00);
    sender
        .delay(5)
        .frame()
        .write(0x01, 0x01)
        .wait(0x02, 0x08, true)
        .snap();
    let r = run(&[sleeper.bench("SLEEPER"), sender.bench("SENDER")], 60, 3);
    let (asleep, woken, later) = (r.snaps[0], r.snaps[1], r.snaps[2]);
    assert_eq!((asleep.mode, asleep.ir), (0x10, 0x00), "{:?}", r.snaps);
    assert_eq!(
        (woken.mode, woken.ir, woken.rmc, woken.rxerr),
        (0x00, 0x10, 0, 0),
        "{:?}",
        r.snaps
    );
    assert_eq!(
        (later.rmc, later.sr & 0x01, later.rxerr),
        (1, 0x01, 0),
        "{:?}",
        r.snaps
    );
    let s = r.others[0];
    assert_eq!((s.sr, s.txerr), (0x0C, 7), "the sender: {:?}", r.others);
    assert_eq!(r.frames, ["123#5A"]);
}
