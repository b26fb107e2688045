//! The C firmware of the alarm module C0 (`configs/firmware/c0/c0_alarm.c`): the shipped
//! `configs/firmware/c0_alarm.hex` is what Debian's SDCC makes of the source with the command
//! the source's opening comment gives (with `--debug`: its debug files `c0_alarm.cdb` and
//! `c0_alarm.ihx` lie beside it, and are that build's too), so the HEX never drifts from the C; and the image, run on
//! the AT89C51CC03 core with its CAN controller, sends what the script node `configs/nodes/c0.ron`
//! would: expectations from the script's rules (boot delay, check period, heartbeat, Quantize)
//! and docs/PROTOCOL.md, worked out here rather than read from the firmware.

use bus::at89c51cc::{Action, BusSide};
use bus::fault::ErrorState;
use harvemu_e2e::cc03::Cc03;
use harvemu_e2e::root;
use std::process::Command;

/// Code memory of the AT89C51CC03: 64 KB of flash.
const CODE_BYTES: usize = 0x1_0000;

fn image(text: &str, what: &str) -> mcs51::Image {
    mcs51::hex::parse(text, CODE_BYTES).unwrap_or_else(|e| panic!("{what}: {e}"))
}

#[test]
fn sdcc_makes_the_shipped_hex_from_the_source() {
    let dir = std::env::temp_dir().join(format!("harvemu-c0-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    for file in ["c0_alarm.c", "at89c51cc03.h"] {
        let from = root().join("configs/firmware/c0").join(file);
        std::fs::copy(&from, dir.join(file)).unwrap_or_else(|e| panic!("{}: {e}", from.display()));
    }
    // The build command of c0_alarm.c's opening comment (packihx only regroups the records).
    let out = Command::new("sdcc")
        .current_dir(&dir)
        .args([
            "-mmcs51",
            "--model-small",
            "--debug",
            "-o",
            "c0_alarm.ihx",
            "c0_alarm.c",
        ])
        .output()
        .unwrap_or_else(|e| panic!("cannot run sdcc ({e}): install the Debian package sdcc"));
    assert!(
        out.status.success(),
        "sdcc failed on c0_alarm.c:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let made = std::fs::read_to_string(dir.join("c0_alarm.ihx")).unwrap();
    // The debug files beside the shipped image are this build's, byte for byte.
    for file in ["c0_alarm.ihx", "c0_alarm.cdb"] {
        let shipped = root().join("configs/firmware").join(file);
        let shipped = std::fs::read(&shipped).unwrap_or_else(|e| panic!("{}: {e}", shipped.display()));
        let built = std::fs::read(dir.join(file)).unwrap();
        assert!(
            shipped == built,
            "the shipped {file} is not what sdcc --debug makes of c0_alarm.c"
        );
    }
    let made = image(&made, "c0_alarm.ihx made by sdcc");
    std::fs::remove_dir_all(&dir).unwrap();

    let path = root().join("configs/firmware/c0_alarm.hex");
    let shipped = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let shipped = image(&shipped, "configs/firmware/c0_alarm.hex");

    assert_eq!(
        made.written, shipped.written,
        "sdcc writes other addresses than the shipped HEX"
    );
    let differ: Vec<String> = (0..CODE_BYTES)
        .filter(|&a| made.code[a] != shipped.code[a])
        .take(8)
        .map(|a| {
            format!(
                "{a:04X}H: sdcc {:02X}, shipped {:02X}",
                made.code[a], shipped.code[a]
            )
        })
        .collect();
    assert!(
        differ.is_empty(),
        "the shipped c0_alarm.hex is not what sdcc makes of c0_alarm.c: {differ:?}"
    );
    // Something was built at all: the reset vector jumps somewhere (LJMP, 02h).
    assert_eq!(shipped.code[0], 0x02, "no LJMP at the reset vector");
}

/// The shipped image on the shared AT89C51CC03 bench ([`Cc03`]: 12 MHz in X1 mode, a machine
/// cycle is 1 µs) and a bus that confirms each frame 520 machine cycles (130 bits at 4 µs) after
/// it is asked to send it.
struct Bench {
    chip: Cc03,
    done_at: Option<u64>,
    /// Frames handed to the bus, with the cycle of the request.
    frames: Vec<(u64, bus::Frame)>,
    /// Every other action of the controller, with its cycle.
    actions: Vec<(u64, Action)>,
}

const MS: u64 = 1000;

impl Bench {
    /// Doors closed, the vacuum input at `code`.
    fn new(code: u16) -> Bench {
        let path = root().join("configs/firmware/c0_alarm.hex");
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut chip = Cc03::new(&text).unwrap_or_else(|e| panic!("c0_alarm.hex: {e}"));
        for bit in 0..6 {
            chip.set_pin(2, bit, false);
        }
        chip.set_analog(0, code);
        Bench {
            chip,
            done_at: None,
            frames: Vec::new(),
            actions: Vec::new(),
        }
    }

    fn run_to(&mut self, cycle: u64) {
        while self.chip.cycles() < cycle {
            if self.done_at.is_some_and(|t| self.chip.cycles() >= t) {
                self.done_at = None;
                self.chip.deliver(BusSide::Transmitted);
            }
            // Exactly one instruction (`run` stops at the first boundary at or past one more
            // cycle), so each request is stamped with the cycle of the instruction that made it.
            self.chip.run(1).unwrap();
            let now = self.chip.cycles();
            for action in self.chip.take_actions() {
                match action {
                    Action::Transmit { frame, .. } => {
                        self.frames.push((now, frame));
                        self.done_at = Some(now + 520);
                    }
                    other => self.actions.push((now, other)),
                }
            }
        }
    }

    /// The frames requested from `cycle` on.
    fn frames_since(&self, cycle: u64) -> Vec<(u64, bus::Frame)> {
        self.frames.iter().filter(|f| f.0 >= cycle).cloned().collect()
    }
}

/// alarm.suction_doors from C0 (docs/PROTOCOL.md): 0400F5C0, DLC 4, 30h, the doors, the vacuum
/// in mV little-endian.
fn expected(doors: u8, mv: u16) -> bus::Frame {
    let id = bus::ExtendedId::new(0x0400_F5C0).unwrap();
    let [lo, hi] = mv.to_le_bytes();
    bus::Frame::new_data(id, &[0x30, doors, lo, hi]).unwrap()
}

/// What the script's `Quantize(…, 100)` makes of the centre of the ADC code's bin.
fn quantized_mv(code: u16) -> u16 {
    let centre = (f64::from(code) + 0.5) * 5000.0 / 1024.0;
    ((centre / 100.0).round() * 100.0) as u16
}

/// Boot delay 60 ms, then a check every 10 ms and a heartbeat every 1000 ms after the last
/// send: with nothing changing, frames at 60, 1060, 2060 and 3060 ms. The firmware decides at
/// its tick and needs well under a millisecond to hand the frame over.
#[test]
fn the_first_frame_comes_after_the_boot_delay_and_then_one_a_second() {
    let mut b = Bench::new(512);
    b.run_to(3500 * MS);
    let frame = expected(0, quantized_mv(512));
    assert_eq!(quantized_mv(512), 2500);
    assert_eq!(b.frames.len(), 4, "{:?}", b.frames);
    for (k, (at, f)) in b.frames.iter().enumerate() {
        let due = (60 + 1000 * k as u64) * MS;
        assert!(
            (due..due + MS).contains(at),
            "frame {k} at {at} µs, due at {due} µs"
        );
        assert_eq!(*f, frame);
    }
    let (tec, rec, _) = b.chip.can().error_counters();
    assert_eq!((tec, rec), (0, 0));
    let timing = b.chip.can().bit_timing();
    assert_eq!(timing.bit_rate_hz(), 250_000.0, "{timing:?}");
}

/// A door that opens between two checks is sent at the next check, and the heartbeat restarts
/// from that frame.
#[test]
fn a_door_change_goes_out_at_the_next_check() {
    let mut b = Bench::new(512);
    b.run_to(3503 * MS);
    b.chip.set_pin(2, 2, true);
    b.run_to(4600 * MS);
    let after = b.frames_since(3503 * MS);
    let times: Vec<u64> = after.iter().map(|f| f.0).collect();
    assert_eq!(after.len(), 2, "{times:?}");
    assert!((3510 * MS..3511 * MS).contains(&after[0].0), "{times:?}");
    assert!((4510 * MS..4511 * MS).contains(&after[1].0), "{times:?}");
    for (_, f) in &after {
        assert_eq!(*f, expected(0x04, 2500));
    }
}

/// The vacuum is the code's bin centre quantized to 100 mV; a new code that quantizes to the
/// same value sends nothing.
#[test]
fn the_vacuum_is_quantized_to_100_mv() {
    let mut b = Bench::new(0);
    b.run_to(100 * MS);
    assert_eq!(b.frames.last().map(|f| f.1), Some(expected(0, 0)));
    let mut t = 100 * MS;
    // 20: centre 100.1 mV; 30: 148.9 mV, still 100; 31: 153.8 mV; 1023: 4997.6 mV.
    for (code, mv) in [
        (20, 100),
        (30, 100),
        (31, 200),
        (205, 1000),
        (300, 1500),
        (1023, 5000),
    ] {
        assert_eq!(quantized_mv(code), mv, "code {code}");
        let before = b.frames.last().map(|f| f.1);
        b.chip.set_analog(0, code);
        t += 50 * MS;
        b.run_to(t);
        let sent = b.frames_since(t - 50 * MS);
        if Some(expected(0, mv)) == before {
            assert!(sent.is_empty(), "code {code}: {sent:?}");
        } else {
            let got: Vec<bus::Frame> = sent.iter().map(|f| f.1).collect();
            assert_eq!(got, [expected(0, mv)], "code {code}");
        }
    }
}

/// Bus-off seen in CANGSTA: the firmware resets the controller (GRES: offline, counters 0) and
/// sets it up again (online at 250 kbit/s); the heartbeat goes on.
#[test]
fn bus_off_restarts_the_controller() {
    let mut b = Bench::new(512);
    // Halfway between two ticks, where the main loop idles and polls CANGSTA (at a tick it
    // first does the tick's work, the ADC conversion included).
    b.run_to(505 * MS);
    let before = b.actions.len();
    b.chip.deliver(BusSide::Counters {
        tec: 256,
        rec: 0,
        state: ErrorState::BusOff,
    });
    b.run_to(1500 * MS);
    let restart: Vec<&Action> = b.actions[before..].iter().map(|a| &a.1).collect();
    assert!(
        matches!(
            restart[..],
            [
                Action::Offline,
                Action::SetCounters { tec: 0, rec: 0 },
                Action::Online {
                    listen_only: false,
                    ..
                }
            ]
        ),
        "{restart:?}"
    );
    assert!(
        b.actions[before].0 < 505 * MS + 100,
        "restart at {} µs",
        b.actions[before].0
    );
    assert!(b.chip.can().enabled());
    assert_eq!(b.chip.can().bit_timing().bit_rate_hz(), 250_000.0);
    let after = b.frames_since(500 * MS);
    assert_eq!(after.len(), 1, "{after:?}");
    assert!((1060 * MS..1061 * MS).contains(&after[0].0));
}
