//! An AT89C51CC03 firmware node in the harvester, in C1's place, wired to the plant: its door
//! switches on P2.0–P2.5 and the duct vacuum sensor on ADC channel 0. The program (assembled in
//! the test) runs in X2 mode (CKCON = 81h: X2, and CANX2 so the CAN clock stays F_OSC / 2),
//! sets its on-chip controller to 250 kbit/s (CANBT1–3 = 02h, 04h, 36h: 6 MHz / 2 / 12 quanta),
//! and every 10 ms of timer 0 (20 000 counts of 0.5 µs in X2) reads P2, converts channel 0 and
//! sends 0x0400F5C1 with 31h, P2 & 3Fh and the 10-bit code (little-endian) on channel 1.
//!
//! It also drives P3.5 low at once, and P3.5 is wired, active low, to the plant's door 6 fault:
//! the plant opens door 6, and the firmware reads it back on P2.5.
//!
//! What the test knows independently: the plant's doors (a fault input it sets itself), the
//! duct vacuum the plant reports, the ideal converter's code ⌊1024 · mV / 5000⌋, and that a
//! 10 ms period proves the X2 time base (at X1 the same counts take 20 ms).

use actix::prelude::*;
use bus::time::{BusDuration, BusTime};
use bus_runtime::hub::{GetSnapshot, RunUntil, runtime};
use harvemu_e2e::{Shared, assemble, candump, default_harvester, parse_trace};
use std::path::Path;
use std::sync::Arc;
use supervisor::harvester;

const PROGRAM: &str = "
        .org    0000H
        LJMP    START
        .org    0040H
START:  MOV     SP, #60H
        CLR     0B5H            ; P3.5 low: opens door 6 through the plant
        MOV     8FH, #81H       ; CKCON: X2, CANX2
        MOV     0ABH, #01H      ; CANGCON: general reset
        MOV     0B4H, #02H      ; CANBT1..3: 250 kbit/s from F_CAN = 6 MHz
        MOV     0B5H, #04H
        MOV     0B6H, #36H
        MOV     0ABH, #02H      ; CANGCON: ENA
        MOV     0F6H, #01H      ; ADCF: P1.0 analog
        MOV     89H, #01H       ; TMOD: timer 0 mode 1
LOOP:   CLR     8CH             ; TR0 off, 10 ms: 65536 - 20000 = B1E0H
        MOV     8CH, #0B1H
        MOV     8AH, #0E0H
        CLR     8DH             ; TF0
        SETB    8CH             ; TR0
WAIT:   JNB     8DH, WAIT
        MOV     A, 0A0H         ; P2: the doors
        ANL     A, #3FH
        MOV     R2, A
        MOV     0F3H, #28H      ; ADCON: ADEN, ADSST, channel 0
CONV:   MOV     A, 0F3H
        JNB     0E4H, CONV      ; ACC.4 = ADEOC
        MOV     0F3H, #20H      ; clear ADEOC
        MOV     A, 0F5H         ; low byte of the code: ADDH << 2 | ADDL
        RL      A
        RL      A
        ANL     A, #0FCH
        ORL     A, 0F4H
        MOV     R3, A
        MOV     A, 0F5H         ; high byte: ADDH >> 6
        SWAP    A
        RR      A
        RR      A
        ANL     A, #03H
        MOV     R4, A
        MOV     0B1H, #10H      ; CANPAGE: channel 1, auto-increment, index 0
        MOV     0B2H, #00H      ; CANSTCH
        MOV     0BCH, #20H      ; CANIDT: 0400F5C1 << 3 = 2007AE08
        MOV     0BDH, #07H
        MOV     0BEH, #0AEH
        MOV     0BFH, #08H
        MOV     0A3H, #31H      ; CANMSG x4
        MOV     0A3H, R2
        MOV     0A3H, R3
        MOV     0A3H, R4
        MOV     0B3H, #54H      ; CANCONCH: transmit, IDE, DLC 4
SENT:   MOV     A, 0B2H
        JNB     0E6H, SENT      ; CANSTCH.6 = TXOK
        MOV     0B2H, #00H
        INC     R5              ; frames sent
        SJMP    LOOP
";

const NODE: &str = "Firmware(
    name: \"C1\",
    image: \"fw.hex\",
    cpu: At89c51cc03(clock_hz: 12000000, vref_mv: 5000),
    controllers: [OnChip],
    analog: [(channel: 0, signal: \"duct.vacuum\", scale: 1.0)],
    pins: [
        Input(pin: \"P2.0\", signal: \"door1.open\"),
        Input(pin: \"P2.1\", signal: \"door2.open\"),
        Input(pin: \"P2.2\", signal: \"door3.open\"),
        Input(pin: \"P2.3\", signal: \"door4.open\"),
        Input(pin: \"P2.4\", signal: \"door5.open\"),
        Input(pin: \"P2.5\", signal: \"door6.open\"),
        Output(pin: \"P3.5\", input: \"fault.door6_open\", active_low: true),
    ],
)";

#[test]
fn an_at89c51cc03_node_reads_the_plant_and_sends_with_its_own_controller() {
    let hex = assemble(PROGRAM);
    let read = move |_: &Path| Ok(("fw.hex".to_string(), hex.clone()));
    let spec = nodes::firmware::load("c1.ron", Path::new("c1.ron"), NODE, &read).expect("the node file");
    let mut h = default_harvester();
    h.scripts.retain(|s| s.name != "C1");
    h.firmware.push(Arc::new(spec));
    let trace = Shared::default();
    let t = trace.clone();
    let door_at = BusTime::from_secs(5);
    let end = BusTime::from_secs(8);
    let (snap, hw, vacuum) = System::with_tokio_rt(|| runtime(true).expect("runtime")).block_on(async move {
        let running = harvester::start(&h, false, vec![candump(t, &h)])
            .await
            .expect("start");
        running
            .hub
            .send(RunUntil(door_at))
            .await
            .expect("hub")
            .expect("run");
        running
            .plant
            .borrow_mut()
            .set_input("fault.door3_open", 1.0)
            .expect("a plant input");
        running.hub.send(RunUntil(end)).await.expect("hub").expect("run");
        let snap = running.hub.send(GetSnapshot).await.expect("snapshot");
        let hw = running.hardware(end).await;
        let vacuum = running.plant.borrow().signal("duct.vacuum").expect("duct.vacuum");
        (snap, hw, vacuum)
    });
    let frames: Vec<_> = parse_trace(&String::from_utf8(trace.0.take()).expect("utf-8"))
        .into_iter()
        .filter(|l| l.frame.raw_id() == 0x0400_F5C1)
        .map(|l| (l.at, l.frame.data().to_vec()))
        .collect();
    assert_eq!(snap.stats.error_frames, 0);
    assert!(frames.len() > 600, "{} frames from the firmware", frames.len());
    // Every 10 ms and a little: the conversion (235 cycles of 0.5 µs), the frame itself (about
    // 130 bits of 4 µs), and at times a wait for the bus, which other nodes hold.
    let mut gaps: Vec<BusDuration> = frames.windows(2).map(|w| w[1].0.since(w[0].0)).collect();
    for (w, gap) in frames.windows(2).zip(&gaps) {
        assert!(
            *gap >= BusDuration::from_millis(10) && *gap < BusDuration::from_millis(13),
            "{gap} between frames at {} and {}",
            w[0].0,
            w[1].0
        );
    }
    gaps.sort();
    let median = gaps[gaps.len() / 2];
    assert!(
        median > BusDuration::from_micros(10_500) && median < BusDuration::from_micros(10_800),
        "median gap {median}"
    );
    for (at, data) in &frames {
        assert_eq!((data.len(), data[0]), (4, 0x31), "at {at}: {data:02X?}");
        // The pins are read at most a sample (1 ms) and a loop (10.8 ms) after the door opens;
        // door 6 is open from the start, by the firmware's own output.
        if *at < door_at {
            assert_eq!(data[1], 0b0010_0000, "at {at}: {data:02X?}");
        } else if *at > door_at + BusDuration::from_millis(12) {
            assert_eq!(data[1], 0b0010_0100, "at {at}: {data:02X?}");
        }
    }
    // The last code is the ideal converter's for the plant's vacuum, within the vacuum's
    // change over the last loop (a few millivolts) and one code.
    let last = frames.last().expect("frames");
    let code = u16::from_le_bytes([last.1[2], last.1[3]]);
    let want = (1024.0 * vacuum / 5000.0).floor();
    assert!(
        (f64::from(code) - want).abs() <= 3.0,
        "code {code}, plant {vacuum:.1} mV gives {want}"
    );
    let (name, hw) = &hw[0];
    assert_eq!(name, "C1");
    assert_eq!(hw.controllers[0].kind, "AT89C51CC03");
    // R5 counted the frames it saw sent (modulo 256).
    let r5 = u8::from_str_radix(&hw.cpu.iram[10..12], 16).expect("hex");
    assert_eq!(r5, (frames.len() % 256) as u8);
}
