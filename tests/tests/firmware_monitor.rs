//! Firmware in the monitor's place (docs/FIRMWARE.md): the harvester with its monitor disabled
//! and an 80C51 with an SJA1000 standing in for F5, at the harvester's 250 kbit/s (16 MHz
//! crystal, BTR0 = 01h, BTR1 = 1Ch: 16 MHz / (2 · 2 · 16 quanta)). Its acceptance filter keeps
//! the flow sensors' frames to the monitor and nothing else; its INT0 handler counts them by
//! sensor.
//!
//! The filter, from the protocol's identifier (priority ID28–24, frame type ID23–16,
//! destination ID15–8, source ID7–0) and the SJA1000 data sheet's single filter for extended
//! frames (ACR0 = ID28–21, ACR1 = ID20–13, ACR2 = ID12–5, ACR3 bits 7–3 = ID4–0, bit 2 RTR;
//! a mask bit 1 is don't care):
//! - destination F5h = 1111 0101: ID15–13 = 111 (ACR1 bits 2–0, AMR1 = F8h), ID12–8 = 10101;
//! - source D0h–D7h = 1101 0xxx: ID7–5 = 110, so ACR2 = 1010 1110 = AEh (AMR2 = 00h), and
//!   ID4–3 = 10, ID2–0 don't care, RTR 0 (data frames): ACR3 = 80h, AMR3 = 0011 1011 = 3Bh;
//! - priority and frame type don't care: AMR0 = FFh, AMR1's upper five bits.

use bus::time::{BusDuration, BusTime};
use bus_runtime::hub::{GetSnapshot, RunUntil};
use harvemu_e2e::{assemble, default_harvester, drive, firmware_spec, iram, parse_trace};

/// The node: the filter above, then an idle loop; the handler adds one to 40h + n for a frame
/// from Dn (ID2–0 are bits 5–3 of the fifth byte of the receive buffer) and to R5 for every
/// frame, and releases the receive buffer.
const SOURCE: &str = "        .org    0000H
        LJMP    START
        .org    0003H
        LJMP    ISR0
        .org    0030H
START:  MOV     SP, #60H
        MOV     DPTR, #0D400H
        MOV     A, #09H         ; MOD: reset mode, single filter
        MOVX    @DPTR, A
        MOV     DPL, #1FH       ; CDR: PeliCAN
        MOV     A, #88H
        MOVX    @DPTR, A
        MOV     DPL, #04H       ; IER: receive interrupt
        MOV     A, #01H
        MOVX    @DPTR, A
        MOV     DPL, #06H       ; BTR0, BTR1: 250 kbit/s at 16 MHz
        MOV     A, #01H
        MOVX    @DPTR, A
        INC     DPTR
        MOV     A, #1CH
        MOVX    @DPTR, A
        MOV     R0, #10H        ; ACR0-ACR3, AMR0-AMR3 at 10H-17H, from the table
        MOV     R2, #08H
FILT:   MOV     DPTR, #ACCEPT
        MOV     A, R0
        CLR     C
        SUBB    A, #10H
        MOVC    A, @A+DPTR
        MOV     DPH, #0D4H
        MOV     DPL, R0
        MOVX    @DPTR, A
        INC     R0
        DJNZ    R2, FILT
        MOV     DPTR, #0D400H   ; MOD: operating mode
        MOV     A, #08H
        MOVX    @DPTR, A
        MOV     R5, #00H
        CLR     88H             ; IT0 = 0: INT0 level-triggered
        SETB    0A8H            ; EX0
        SETB    0AFH            ; EA
IDLE:   SJMP    IDLE
ISR0:   PUSH    ACC
        PUSH    PSW
        PUSH    DPL
        PUSH    DPH
        MOV     DPTR, #0D403H   ; IR
        MOVX    A, @DPTR
        MOV     DPTR, #0D414H   ; ID4-ID0 and RTR
        MOVX    A, @DPTR
        RR      A
        RR      A
        RR      A
        ANL     A, #07H
        ADD     A, #40H
        MOV     R1, A
        INC     @R1
        MOV     DPTR, #0D401H   ; CMR: release the receive buffer
        MOV     A, #04H
        MOVX    @DPTR, A
        INC     R5
        POP     DPH
        POP     DPL
        POP     PSW
        POP     ACC
        RETI
ACCEPT: .byte   0FFH, 0FFH, 0AEH, 80H, 0FFH, 0F8H, 00H, 3BH
";

#[test]
fn firmware_in_the_monitors_place_receives_the_flow_sensors_frames() {
    let hex = assemble(SOURCE);
    let text = "Firmware(name: \"F5\", image: \"f5.hex\", entry: None, cpu: I80C51(clock_hz: 12000000), \
                controllers: [Sja1000(base: 0xD400, xtal_hz: 16000000, irq: Some(Int0))])";
    let mut h = default_harvester();
    h.config.monitor.enabled = false;
    h.firmware.push(firmware_spec("f5.ron", text, "f5.hex", &hex));
    let relay = h.relay();
    let end = BusTime::from_secs(8);
    let (trace, (snap, state)) = drive(h, async move |running| {
        running.hub.send(RunUntil(end)).await.expect("hub").expect("run");
        let snap = running.hub.send(GetSnapshot).await.expect("snapshot");
        (snap, running.hardware(end).await)
    });
    let frames = parse_trace(&trace);
    assert_eq!(snap.stats.error_frames, 0);
    let (name, hw) = &state[0];
    assert_eq!(name, "F5");
    let iram = |a: usize| iram(hw, a, 1)[0];
    // Frames that ended after the chip joined the bus, a few hundred microseconds after the
    // time relay powered the node up.
    let joined = relay + BusDuration::from_millis(1);
    let to_monitor_from = |n: u32| {
        frames
            .iter()
            .filter(|f| f.at > joined && f.at <= end && f.frame.is_extended() && !f.frame.is_remote())
            .filter(|f| f.frame.raw_id() & 0xFFFF == 0xF5D0 + n)
            .count()
    };
    let mut all = 0;
    for n in 0..6 {
        let heard = to_monitor_from(n);
        assert!(heard > 0, "D{n} sent nothing to F5");
        assert_eq!(usize::from(iram(0x40 + n as usize)), heard % 256, "from D{n}");
        all += heard;
    }
    assert_eq!((iram(0x46), iram(0x47)), (0, 0), "no D6, D7");
    // R5: only those. Every other frame on the bus went to F5 too (the field nodes talk to the
    // monitor), and the filter kept them out.
    assert_eq!(usize::from(iram(0x05)), all % 256);
    let to_f5 = frames
        .iter()
        .filter(|f| f.at > joined && f.frame.raw_id() & 0xFF00 == 0xF500)
        .count();
    assert!(to_f5 > all, "{to_f5} frames to F5, {all} from flow sensors");
}
