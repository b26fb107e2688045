//! A firmware node file's configuration block, a 16-bit DAC and an analog multiplexer, on an
//! AT89C51CC03 in C1's place in the harvester. The program (assembled in the test):
//!
//! - reads the two bytes the node file places at FF00h (MOVC) and writes them to P0 (low) and
//!   P2 (high): the DAC on those ports drives the plant's `speed.setpoint` at 0.01 km/h a step;
//! - every 10 ms of timer 0 converts ADC channel 0 twice, with P3.4 low and then high: the
//!   multiplexer in front of the channel passes the duct vacuum, then half the clutch pressure;
//!   it keeps the last codes in internal RAM 30h–33h (low byte first) and counts the loops in 34h.
//!
//! What the test knows independently: the set-point the block's bytes mean (01F4h = 500 steps of
//! 0.01 km/h), the plant's signals at the end, and the ideal converter's code
//! ⌊1024 · mV / 5000⌋. A second test cuts and sticks the wires with sensor faults.

use actix::prelude::*;
use bus::time::BusTime;
use bus_runtime::hub::{RunUntil, runtime};
use harvemu_e2e::{assemble, default_harvester};
use std::path::Path;
use std::sync::Arc;
use supervisor::harvester;

const PROGRAM: &str = "
        .org    0000H
        LJMP    START
        .org    0040H
START:  MOV     SP, #60H
        MOV     DPTR, #0FF00H   ; the node file's block: the set-point, low byte first
        CLR     A
        MOVC    A, @A+DPTR
        MOV     80H, A          ; P0: the DAC's low byte
        MOV     A, #1
        MOVC    A, @A+DPTR
        MOV     0A0H, A         ; P2: its high byte
        MOV     0F6H, #01H      ; ADCF: P1.0 analog
        MOV     0F2H, #03H      ; ADCLK
        MOV     89H, #01H       ; TMOD: timer 0 mode 1
LOOP:   CLR     8CH             ; 10 ms: 65536 - 10000 = D8F0H
        MOV     8CH, #0D8H
        MOV     8AH, #0F0H
        CLR     8DH
        SETB    8CH
WAIT:   JNB     8DH, WAIT
        CLR     0B4H            ; P3.4 low: the multiplexer passes its low input
        MOV     R0, #30H
        ACALL   CONV
        SETB    0B4H            ; P3.4 high: its other input
        ACALL   CONV
        INC     34H
        SJMP    LOOP
CONV:   MOV     0F3H, #28H      ; ADCON: ADEN, ADSST, channel 0
BUSY:   MOV     A, 0F3H
        JNB     0E4H, BUSY
        MOV     0F3H, #20H
        MOV     A, 0F5H         ; ADDH << 2 | ADDL, low byte
        RL      A
        RL      A
        ANL     A, #0FCH
        ORL     A, 0F4H
        MOV     @R0, A
        INC     R0
        MOV     A, 0F5H         ; ADDH >> 6, high byte
        SWAP    A
        RR      A
        RR      A
        ANL     A, #03H
        MOV     @R0, A
        INC     R0
        RET
";

const NODE: &str = "Firmware(
    name: \"C1\",
    address: 0xC1,
    image: \"fw.hex\",
    cpu: At89c51cc03(clock_hz: 12000000, vref_mv: 5000),
    controllers: [OnChip],
    // The set-point, 500 steps of 0.01 km/h, low byte first.
    config: (at: 0xFF00, bytes: [0xF4, 0x01]),
    // One select line to both multiplexers (channel 1 is not read).
    analog: [(channel: 0, signal: \"duct.vacuum\", scale: 1.0,
              while_high: Some((pin: \"P3.4\", signal: \"clutch.pressure\", scale: 0.5, offset_mv: 100.0))),
             (channel: 1, signal: \"basket.level\",
              while_high: Some((pin: \"P3.4\", signal: \"supply.voltage\", scale: 0.1)))],
    dacs: [(low: \"P0\", high: Some(\"P2\"), input: \"speed.setpoint\", scale: 0.01)],
)";

fn code(mv: f64) -> f64 {
    (1024.0 * mv / 5000.0).floor()
}

/// The default harvester with the program and node file above in C1's place.
fn with_c1() -> harvester::Harvester {
    let hex = assemble(PROGRAM);
    let read = move |_: &Path| Ok(("fw.hex".to_string(), hex.clone()));
    let spec = nodes::firmware::load("c1.ron", Path::new("c1.ron"), NODE, &read).expect("the node file");
    assert_eq!(spec.address, Some(0xC1));
    let mut h = default_harvester();
    h.scripts.retain(|s| s.name != "C1");
    h.firmware.push(Arc::new(spec));
    h
}

/// The program's last codes of the low and high inputs, and its loop count, from C1's state.
fn converted(hw: &[(String, bus::node::HardwareState)]) -> (f64, f64, u8) {
    let (_, hw) = &hw[0];
    let iram: Vec<u8> = (0..256)
        .map(|i| u8::from_str_radix(&hw.cpu.iram[2 * i..2 * i + 2], 16).expect("hex"))
        .collect();
    let low = f64::from(u16::from_le_bytes([iram[0x30], iram[0x31]]));
    let high = f64::from(u16::from_le_bytes([iram[0x32], iram[0x33]]));
    (low, high, iram[0x34])
}

#[test]
fn the_block_the_dac_and_the_multiplexer_reach_the_firmware_and_the_plant() {
    let h = with_c1();
    let end = BusTime::from_secs(6);
    let (hw, setpoint, vacuum, pressure) = System::with_tokio_rt(|| runtime(true).expect("runtime"))
        .block_on(async move {
            let running = harvester::start(&h, false, Vec::new()).await.expect("start");
            running.hub.send(RunUntil(end)).await.expect("hub").expect("run");
            let hw = running.hardware(end).await;
            let plant = running.plant.borrow();
            let signal = |n: &str| plant.signal(n).expect("a plant signal");
            (
                hw,
                signal("speed.setpoint"),
                signal("duct.vacuum"),
                signal("clutch.pressure"),
            )
        });
    assert!((setpoint - 5.0).abs() < 1e-9, "the DAC set {setpoint} km/h");
    let (low, high, loops) = converted(&hw);
    assert_ne!(loops, 0, "the loop ran");
    // The signals move little over the last loop: within two codes of the end's.
    assert!(
        (low - code(vacuum)).abs() <= 2.0,
        "low input {low}, vacuum {vacuum:.1} mV"
    );
    let want = code(100.0 + 0.5 * pressure);
    assert!(
        (high - want).abs() <= 2.0,
        "high input {high}, pressure {pressure:.1} mV gives {want}"
    );
    assert!((low - high).abs() > 50.0, "the two inputs differ: {low} {high}");
}

/// Sensor faults act on the wires (docs/FIRMWARE.md, "Sensor faults on wires"): at 2 s the duct
/// vacuum's wire is stuck at 1000 mV and the clutch pressure's cut. From the plant's next step
/// the program converts 1000 mV on the low input (the ideal converter: code 204) and 0 V on the
/// high one (a cut wire reads 0 V, whatever the multiplexer's offset). A signal no input of the
/// node reads is refused.
#[test]
fn sensor_faults_act_on_the_wires() {
    use bus::node::{NodeFault, SensorFault};
    use bus_runtime::node::Inject;
    let h = with_c1();
    let (hw, refused) = System::with_tokio_rt(|| runtime(true).expect("runtime")).block_on(async move {
        let running = harvester::start(&h, false, Vec::new()).await.expect("start");
        let fault_at = BusTime::from_secs(2);
        running
            .hub
            .send(RunUntil(fault_at))
            .await
            .expect("hub")
            .expect("run");
        let c1 = running.actor("C1").expect("C1");
        let inject = |signal: &str, reads| Inject {
            fault: NodeFault::Sensor {
                signal: signal.into(),
                reads,
            },
            now: fault_at,
        };
        c1.send(inject("duct.vacuum", SensorFault::Stuck(1000.0)))
            .await
            .expect("C1")
            .expect("the vacuum's wire");
        c1.send(inject("clutch.pressure", SensorFault::Dropout))
            .await
            .expect("C1")
            .expect("the pressure's wire");
        let refused = c1
            .send(inject("engine.rpm", SensorFault::Stuck(0.0)))
            .await
            .expect("C1");
        let end = BusTime::from_secs(3);
        running.hub.send(RunUntil(end)).await.expect("hub").expect("run");
        (running.hardware(end).await, refused)
    });
    let refused = refused.expect_err("no input of C1 reads engine.rpm");
    assert!(refused.0.contains("engine.rpm"), "{refused}");
    let (low, high, _) = converted(&hw);
    assert_eq!(low, code(1000.0), "the stuck wire");
    assert_eq!(high, 0.0, "the cut wire");
}
