//! Register-level tests. Every expected value is worked out from the SJA1000 data sheet by hand
//! (the comments show how), not taken from the model's output.

use super::*;
use crate::engine::BusError;
use crate::filter::AcceptanceFilter;
use crate::time::BusDuration;

const MHZ_16: u32 = 16_000_000;
const MHZ_6: u32 = 6_000_000;

fn drain(c: &mut Sja1000) -> Vec<Action> {
    c.take_actions().collect()
}

fn base(id: u16, data: &[u8]) -> Frame {
    Frame::base(id, data).unwrap()
}

/// The example firmware's initialisation, ending in operating mode.
fn initialised() -> Sja1000 {
    let mut c = Sja1000::new(MHZ_6);
    for (addr, value) in [
        (0, 0x09),  // BasicCAN CR: RR and EIE
        (31, 0x88), // CDR: PeliCAN, clock off
        (4, 0x0D),  // IER: RIE, EIE, DOIE
        (6, 0x03),
        (7, 0xFF),
        (8, 0xAA),
        (16, 0xBB),
        (17, 0xFF),
        (18, 0xFF),
        (19, 0xFF),
        (20, 0x00),
        (21, 0xFF),
        (22, 0xFF),
        (23, 0xFF),
        (30, 0x00),
        (15, 0x00),
        (12, 0x00),
        (0, 0x08), // MOD: AFM, reset mode left
    ] {
        c.write(addr, value);
    }
    c
}

/// Writes a frame into the PeliCAN transmit window.
fn load_tx(c: &mut Sja1000, bytes: &[u8]) {
    for (i, &b) in bytes.iter().enumerate() {
        c.write(16 + i as u8, b);
    }
}

#[test]
fn basiccan_reset_values() {
    let mut c = Sja1000::new(MHZ_16);
    assert_eq!(c.mode(), Mode::BasicCan);
    assert!(c.in_reset());
    // CR: RR = 1 and reserved bit 5 reads 1 (data sheet 6.3.3 note 3) -> 21h.
    assert_eq!(c.read(0), 0x21);
    assert_eq!(c.read(1), 0xFF); // CMR reads FFh
    assert_eq!(c.read(2), 0x0C); // SR: TBS, TCS
    assert_eq!(c.read(3), 0xE0); // IR: reserved bits 7:5 read 1
    assert_eq!(c.read(31), 0x00); // CDR, Intel mode: divide by 2, BasicCAN
    assert_eq!(c.read(10), 0xFF); // transmit buffer reads FFh in reset mode
    assert!(!c.int_active());
    assert!(drain(&mut c).is_empty());
}

#[test]
fn pelican_reset_values() {
    let mut c = Sja1000::new(MHZ_16);
    c.write(31, 0x80);
    assert_eq!(c.mode(), Mode::PeliCan);
    let expect = [
        (0, 0x01),  // MOD: RM
        (1, 0x00),  // CMR reads 00h
        (2, 0x3C),  // SR: TS, RS (waiting for bus idle), TCS, TBS
        (3, 0x00),  // IR
        (11, 0x00), // ALC
        (12, 0x00), // ECC
        (13, 96),   // EWLR
        (14, 0x00), // RXERR
        (15, 0x00), // TXERR
        (29, 0x00), // RMC
        (30, 0x00), // RBSA
        (31, 0x80), // CDR
    ];
    for (addr, value) in expect {
        assert_eq!(c.read(addr), value, "address {addr}");
    }
}

#[test]
fn example_init_sequence_goes_online_with_its_filter() {
    let mut c = Sja1000::new(MHZ_6);
    c.write(0, 0x09);
    // In BasicCAN the first write lands in CR: RR (01h) and EIE (08h), plus bit 5 read as 1.
    assert_eq!(c.read(0), 0x29);
    let mut c = initialised();
    let filter = Sja1000Filter {
        mode: Sja1000Mode::Single,
        acr: [0xBB, 0xFF, 0xFF, 0xFF],
        amr: [0x00, 0xFF, 0xFF, 0xFF],
    };
    let actions = drain(&mut c);
    assert_eq!(
        actions,
        vec![
            Action::SetCounters { tec: 0, rec: 0 },
            Action::Online {
                listen_only: false,
                self_test: false,
                filter: Some(filter)
            }
        ]
    );
    assert!(!c.in_reset());
    assert_eq!(c.read(0), 0x08);
    assert_eq!(c.read(12), 0x00); // ECC is read only
    assert_eq!(c.read(8), 0xAA);
    // ID1 = BBh: identifiers BBh << 3 .. | 7 = 5D8h..5DFh pass, AAh << 3 = 550h does not.
    c.on_event(BusSide::Received(base(0x550, &[1])));
    assert_eq!(c.read(29), 0);
    assert!(!c.int_active());
    c.on_event(BusSide::Received(base(0x5DF, &[1])));
    assert_eq!(c.read(29), 1);
    assert_eq!(c.read(2) & sr::RBS, sr::RBS);
    assert!(c.int_active()); // RIE is in IER = 0Dh
    assert_eq!(c.bit_timing().bit_rate_hz(), 30_000.0);
}

#[test]
fn transmit_standard_frame_from_the_window() {
    let mut c = initialised();
    drain(&mut c);
    // Frame info 08h: SFF, data, DLC 8. ID1 BBh, ID2 FFh: ID = BBh << 3 | FFh >> 5 = 5DFh.
    // ID2 bits 4:0 (including the bit where RX shows RTR) are ignored on transmit.
    load_tx(&mut c, &[0x08, 0xBB, 0xFF, 1, 2, 3, 4, 5, 6, 7, 8]);
    c.write(1, cmr::TR);
    let frame = base(0x5DF, &[1, 2, 3, 4, 5, 6, 7, 8]);
    assert_eq!(
        drain(&mut c),
        vec![Action::Transmit {
            frame,
            self_reception: false,
            single_shot: false
        }]
    );
    assert_eq!(c.read(2) & (sr::TBS | sr::TCS), 0);
    // The locked buffer ignores writes (TX RAM at 96 + 3 is data byte 1).
    c.write(19, 0x55);
    assert_eq!(c.peek(99), 1);
    c.write(1, cmr::TR); // a second request while one is pending is ignored
    assert!(drain(&mut c).is_empty());
    c.on_event(BusSide::Transmitted);
    assert_eq!(c.read(2) & (sr::TBS | sr::TCS), sr::TBS | sr::TCS);
    assert_eq!(c.read(3), 0); // TIE is not set in IER = 0Dh

    // RTR comes from frame info bit 6: 48h = SFF remote, DLC 8.
    load_tx(&mut c, &[0x48, 0xBB, 0x00]);
    c.write(1, cmr::TR | cmr::AT);
    let remote = Frame::new_remote(crate::standard_id(0x5D8).unwrap(), 8).unwrap();
    assert_eq!(
        drain(&mut c),
        vec![Action::Transmit {
            frame: remote,
            self_reception: false,
            single_shot: true
        }]
    );
    // Extended: frame info 85h, ID28..0 = 12345678h >> 3 ... here ID = 1ABCDEFh.
    c.on_event(BusSide::Aborted);
    assert_eq!(c.read(2) & (sr::TBS | sr::TCS), sr::TBS); // released, not complete
    let id: u32 = 0x01AB_CDEF;
    load_tx(
        &mut c,
        &[
            0x82,
            (id >> 21) as u8,
            (id >> 13) as u8,
            (id >> 5) as u8,
            (id << 3) as u8,
            9,
            10,
        ],
    );
    c.write(1, cmr::TR);
    let ext = Frame::extended(id, &[9, 10]).unwrap();
    assert_eq!(
        drain(&mut c),
        vec![Action::Transmit {
            frame: ext,
            self_reception: false,
            single_shot: false
        }]
    );
    c.write(1, cmr::AT);
    assert_eq!(drain(&mut c), vec![Action::Abort]);
}

#[test]
fn fifo_fills_overruns_and_releases() {
    let mut c = initialised();
    let f = |n: u8| base(0x5DF, &[n; 8]);
    // An 8-byte base frame takes 3 + 8 = 11 bytes: 5 fit in 64 (55), the 6th would need 66.
    for n in 0..5 {
        c.on_event(BusSide::Received(f(n)));
    }
    assert_eq!(c.read(29), 5);
    assert_eq!(c.read(2) & sr::DOS, 0);
    c.on_event(BusSide::Received(f(5)));
    assert_eq!(c.read(29), 5);
    assert_eq!(c.read(2) & sr::DOS, sr::DOS);
    assert_eq!(c.read(3), ir::DOI | ir::RI);
    assert_eq!(c.read(3), ir::RI); // DOI cleared by the read, RI stays
    c.on_event(BusSide::Received(f(6))); // DOS still set: no second DOI
    assert_eq!(c.read(3), ir::RI);
    // The window shows the first frame: 08h, BBh, ID2..0 = 7 -> E0h, data 0.
    let window: Vec<u8> = (16..=26).map(|a| c.read(a)).collect();
    assert_eq!(window, vec![0x08, 0xBB, 0xE0, 0, 0, 0, 0, 0, 0, 0, 0]);
    c.write(1, cmr::RRB);
    assert_eq!(c.read(29), 4);
    assert_eq!(c.read(30), 11); // RBSA moved past the 11-byte message
    assert_eq!(c.read(19), 1); // the second frame's data
    // Now 44 bytes are used: one more 11-byte frame fits, wrapping from 55 to 1.
    c.on_event(BusSide::Received(f(7)));
    assert_eq!(c.read(29), 5);
    for _ in 0..4 {
        c.write(1, cmr::RRB);
    }
    assert_eq!(c.read(30), 55);
    let window: Vec<u8> = (16..=26).map(|a| c.read(a)).collect();
    assert_eq!(window, vec![0x08, 0xBB, 0xE0, 7, 7, 7, 7, 7, 7, 7, 7]);
    c.write(1, cmr::CDO);
    assert_eq!(c.read(2) & sr::DOS, 0);
    c.write(1, cmr::RRB);
    assert_eq!(c.read(29), 0);
    assert_eq!(c.read(3), 0);
    assert!(!c.int_active());
    // In reset mode the FIFO RAM is readable: the last frame wrapped, its data byte 8 at 1.
    c.write(0, 0x09);
    assert_eq!(c.read(32 + 55), 0x08);
    assert_eq!(c.read(32 + 1), 7);
    assert_eq!(c.read(32 + 2), 0xE0); // RAM still holds the first frame's ID2 byte here
}

#[test]
fn interrupt_register_read_clears_all_but_ri() {
    let mut c = initialised();
    c.write(4, ir::RI | ir::TI); // IER
    c.on_event(BusSide::Received(base(0x5DF, &[])));
    load_tx(&mut c, &[0x00, 0xBB, 0x00]);
    c.write(1, cmr::TR);
    c.on_event(BusSide::Transmitted);
    assert_eq!(c.peek(3), ir::RI | ir::TI);
    assert_eq!(c.read(3), ir::RI | ir::TI);
    assert_eq!(c.read(3), ir::RI);
    assert!(c.int_active());
    c.write(4, ir::TI); // RIE cleared: RI and INT follow at once (data sheet 6.4.7 note 1)
    assert_eq!(c.read(3), 0);
    assert!(!c.int_active());
    c.write(4, ir::RI);
    assert!(c.int_active());
    c.write(1, cmr::RRB);
    assert!(!c.int_active());
}

#[test]
fn error_interrupts_and_captures() {
    let mut c = initialised();
    c.write(4, 0xFF);
    let counters = |tec, rec, state| BusSide::Counters { tec, rec, state };
    c.on_event(counters(95, 0, ErrorState::Active));
    assert_eq!(c.read(3), 0);
    c.on_event(counters(96, 0, ErrorState::Active)); // reaches EWLR 96: ES, EI
    assert_eq!(c.read(2) & sr::ES, sr::ES);
    assert_eq!(c.read(3), ir::EI);
    c.on_event(counters(128, 0, ErrorState::Passive)); // passive: EPI; ES unchanged
    assert_eq!(c.read(3), ir::EPI);
    assert_eq!(c.read(15), 128);
    c.on_event(counters(127, 0, ErrorState::Active)); // active again: EPI
    assert_eq!(c.read(3), ir::EPI);
    c.on_event(counters(90, 0, ErrorState::Active)); // below EWLR: ES cleared, EI
    assert_eq!(c.read(3), ir::EI);
    assert_eq!(c.read(2) & sr::ES, 0);

    // Stuff error while transmitting in the data field: ECC = 10 0 01010 = 8Ah.
    let data = ecc_segment(Location::Data);
    c.on_event(BusSide::BusError {
        error: BusError::Stuff,
        transmitting: true,
        segment: data,
    });
    assert_eq!(c.read(3), ir::BEI);
    // Held until ECC is read: the next error neither overwrites it nor interrupts.
    let ack_del = ecc_segment(Location::AckDel);
    c.on_event(BusSide::BusError {
        error: BusError::Form,
        transmitting: false,
        segment: ack_del,
    });
    assert_eq!(c.read(3), 0);
    assert_eq!(c.peek(12), 0x8A);
    assert_eq!(c.read(12), 0x8A);
    // Form error while receiving at the ACK delimiter: 01 1 11011 = 7Bh.
    c.on_event(BusSide::BusError {
        error: BusError::Form,
        transmitting: false,
        segment: ack_del,
    });
    assert_eq!(c.read(3), ir::BEI);
    assert_eq!(c.read(12), 0x7B);
    // ACK error: "other" (11), transmitting, ACK slot 19h -> D9h.
    let ack = ecc_segment(Location::Ack);
    c.on_event(BusSide::BusError {
        error: BusError::Ack,
        transmitting: true,
        segment: ack,
    });
    assert_eq!(c.read(12), 0xD9);

    c.on_event(BusSide::ArbitrationLost { bit: 12 }); // lost at IDE
    c.on_event(BusSide::ArbitrationLost { bit: 3 });
    assert_eq!(c.read(3), ir::ALI | ir::BEI);
    assert_eq!(c.read(11), 12);
    c.on_event(BusSide::ArbitrationLost { bit: 31 });
    assert_eq!(c.read(3), ir::ALI);
    assert_eq!(c.read(11), 31);
}

#[test]
fn bus_off_and_recovery() {
    let mut c = initialised();
    c.write(4, 0xFF);
    drain(&mut c);
    load_tx(&mut c, &[0x00, 0xBB, 0x00]);
    c.write(1, cmr::TR);
    drain(&mut c);
    c.on_event(BusSide::Counters {
        tec: 256,
        rec: 5,
        state: ErrorState::BusOff,
    });
    assert_eq!(drain(&mut c), vec![Action::Offline]);
    assert!(c.in_reset());
    assert_eq!(c.read(0) & mod_bits::RM, mod_bits::RM);
    // BS; ES since TXERR = 127 >= 96; TBS released; TCS still 0; RS/TS waiting.
    assert_eq!(c.read(2), sr::BS | sr::ES | sr::TS | sr::RS | sr::TBS);
    assert_eq!(c.read(15), 127);
    assert_eq!(c.read(14), 0);
    assert_eq!(c.read(3), ir::EI);
    c.write(14, 50); // RXERR cannot be written while bus-off
    assert_eq!(c.read(14), 0);
    c.write(0, 0x08);
    assert_eq!(
        drain(&mut c),
        vec![Action::StartRecovery {
            listen_only: false,
            self_test: false
        }]
    );
    assert!(!c.in_reset());
    c.on_event(BusSide::Counters {
        tec: 100,
        rec: 0,
        state: ErrorState::BusOff,
    });
    assert_eq!(c.read(15), 100);
    assert_eq!(c.read(2) & sr::BS, sr::BS);
    c.write(15, 3); // operating mode: TXERR is read only
    assert_eq!(c.read(15), 100);
    c.on_event(BusSide::RecoveryDone);
    assert_eq!(c.read(2), sr::TBS);
    assert_eq!(c.read(15), 0);
    assert_eq!(c.read(3), ir::EI);
    assert!(drain(&mut c).is_empty());
}

#[test]
fn txerr_writes_in_reset_mode() {
    // 0..254 while bus-off clears bus-off: leaving reset joins the bus normally.
    let mut c = initialised();
    c.write(4, 0xFF);
    c.on_event(BusSide::Counters {
        tec: 260,
        rec: 0,
        state: ErrorState::BusOff,
    });
    c.read(3);
    drain(&mut c);
    c.write(15, 0);
    assert_eq!(drain(&mut c), vec![Action::SetCounters { tec: 0, rec: 0 }]);
    assert_eq!(c.read(2) & sr::BS, sr::BS); // status changes wait for reset mode to end
    c.write(0, 0x08);
    assert!(matches!(drain(&mut c)[..], [Action::Online { .. }]));
    assert_eq!(c.read(2) & (sr::BS | sr::ES), 0);
    assert_eq!(c.read(3), ir::EI);

    // 255 asks for a CPU-driven bus-off when reset mode is left.
    c.write(0, 0x09);
    c.write(15, 255);
    assert_eq!(
        drain(&mut c),
        vec![Action::Offline, Action::SetCounters { tec: 255, rec: 0 }]
    );
    c.write(0, 0x08);
    assert_eq!(drain(&mut c), vec![Action::SetCounters { tec: 256, rec: 0 }]);
    assert!(c.in_reset());
    assert_eq!(c.read(15), 127);
    assert_eq!(c.read(2) & sr::BS, sr::BS);
    assert_eq!(c.read(3), ir::EI);
    c.write(0, 0x08);
    assert_eq!(
        drain(&mut c),
        vec![Action::StartRecovery {
            listen_only: false,
            self_test: false
        }]
    );
}

#[test]
fn reset_only_registers_ignore_operating_writes() {
    let mut c = initialised();
    let before: Vec<u8> = [0u8, 6, 7, 8, 13, 14, 15, 30, 31]
        .iter()
        .map(|&a| c.peek(a))
        .collect();
    for addr in [6, 7, 8, 13, 14, 15, 30] {
        c.write(addr, 0x5A);
    }
    c.write(0, 0x0E); // LOM, STM, AFM changes need reset mode
    c.write(31, 0x08); // CAN mode bit: reset mode only; clock bits may change
    let after: Vec<u8> = [0u8, 6, 7, 8, 13, 14, 15, 30, 31]
        .iter()
        .map(|&a| c.peek(a))
        .collect();
    assert_eq!(after, before);
    assert_eq!(c.mode(), Mode::PeliCan);
    // 16 is the transmit buffer now, not ACR0.
    c.write(16, 0x11);
    c.write(0, 0x09);
    assert_eq!(c.read(16), 0xBB);
    assert_eq!(c.read(96), 0x11);
    c.write(13, 0x20); // in reset mode it takes
    assert_eq!(c.read(13), 0x20);
}

#[test]
fn basiccan_receive_and_transmit() {
    let mut c = Sja1000::new(MHZ_16);
    for (addr, value) in [(4, 0xBB), (5, 0x00), (6, 0x01), (7, 0x1C)] {
        c.write(addr, value);
    }
    c.write(0, 0x06); // RIE, TIE; RR cleared
    let filter = Sja1000Filter {
        mode: Sja1000Mode::Single,
        acr: [0xBB, 0, 0, 0],
        amr: [0x00, 0xFF, 0xFF, 0xFF],
    };
    assert_eq!(
        drain(&mut c),
        vec![Action::Online {
            listen_only: false,
            self_test: false,
            filter: Some(filter)
        }]
    );
    assert_eq!(c.read(4), 0xFF); // ACR reads FFh in operating mode
    assert_eq!(c.read(0), 0x26);
    c.on_event(BusSide::Received(Frame::extended(0x5DF << 18, &[]).unwrap()));
    c.on_event(BusSide::Received(base(0x123, &[9])));
    assert_eq!(c.read(2) & sr::RBS, 0); // neither the extended nor the filtered frame
    c.on_event(BusSide::Received(base(0x5DF, &[1, 2])));
    // Receive buffer: BBh, ID2..0 = 111 | RTR 0 | DLC 2 = E2h, data.
    let rx: Vec<u8> = (20..=23).map(|a| c.read(a)).collect();
    assert_eq!(rx, vec![0xBB, 0xE2, 1, 2]);
    assert_eq!(c.read(3), 0xE1); // RI with reserved bits
    // Transmit a remote frame: BBh, F2h = ID2..0 111, RTR, DLC 2.
    c.write(10, 0xBB);
    c.write(11, 0xF2);
    c.write(1, cmr::TR);
    let remote = Frame::new_remote(crate::standard_id(0x5DF).unwrap(), 2).unwrap();
    assert_eq!(
        drain(&mut c),
        vec![Action::Transmit {
            frame: remote,
            self_reception: false,
            single_shot: false
        }]
    );
    c.on_event(BusSide::Transmitted);
    assert_eq!(c.read(3), 0xE3); // TI and RI
    assert_eq!(c.read(3), 0xE1);
}

#[test]
fn self_reception_stores_own_frame_when_the_filter_passes() {
    let mut c = initialised();
    drain(&mut c);
    c.write(4, ir::RI | ir::TI);
    load_tx(&mut c, &[0x01, 0xBB, 0xE0, 0x42]);
    c.write(1, cmr::SRR);
    let frame = base(0x5DF, &[0x42]);
    assert_eq!(
        drain(&mut c),
        vec![Action::Transmit {
            frame,
            self_reception: true,
            single_shot: false
        }]
    );
    c.on_event(BusSide::Transmitted);
    assert_eq!(c.read(3), ir::RI | ir::TI);
    assert_eq!(c.read(19), 0x42);
    // A frame the filter rejects is not self-received.
    c.write(1, cmr::RRB);
    load_tx(&mut c, &[0x01, 0xAA, 0x00, 0x42]);
    c.write(1, cmr::SRR | cmr::AT);
    c.on_event(BusSide::Transmitted);
    assert_eq!(c.read(29), 0);
}

#[test]
fn bit_timing_examples() {
    // 6 MHz, BTR0 03h (SJW 1, BRP 3), BTR1 FFh (SAM, TSEG2 8, TSEG1 16): t_scl = 2 * 4 / 6 MHz,
    // NBT = 1 + 16 + 8 = 25, bit = 200 crystal periods = 33.3 us -> 30 000 bit/s;
    // 200 / 6 MHz * 3.456e12 ticks/s = 115 200 000 ticks.
    let t = BitTiming::from_registers(0x03, 0xFF, MHZ_6);
    assert_eq!(t.quanta_per_bit(), 25);
    assert_eq!(t.bit_rate_hz(), 30_000.0);
    assert_eq!(t.bit_time(), Some(BusDuration::from_ticks(115_200_000)));
    assert!(t.sam);
    // df = min(1 / (20 * 25), min(16, 8) / (2 * (13 * 25 - 8))) = min(0.002, 8/634) = 0.002.
    assert!((t.tolerance() - 0.002).abs() < 1e-12);
    // 16 MHz, BTR0 01h (SJW 1, BRP 1), BTR1 1Ch (TSEG2 2, TSEG1 13): t_scl = 250 ns, NBT 16,
    // bit = 4 us -> 250 000 bit/s; 4 us = 13 824 000 ticks.
    let t = BitTiming::from_registers(0x01, 0x1C, MHZ_16);
    assert_eq!(t.bit_rate_hz(), 250_000.0);
    assert_eq!(t.bit_time(), Some(BusDuration::from_ticks(13_824_000)));
    // df = min(1 / (20 * 16), min(13, 2) / (2 * (13 * 16 - 2))) = min(1/320, 2/412)
    //    = min(0.003125, 0.004854) = 0.003125.
    assert!((t.tolerance() - 0.003125).abs() < 1e-12);
    assert!(t.samples_correctly(250_000.0));
    assert!(t.samples_correctly(250_000.0 * 1.003));
    assert!(!t.samples_correctly(250_000.0 * 1.004));
    // 7 MHz: 200 / 7e6 s is not a whole number of ticks.
    assert_eq!(BitTiming::from_registers(0x03, 0xFF, 7_000_000).bit_time(), None);
}

#[test]
fn ecc_segment_codes() {
    // Data sheet Table 21.
    let table = [
        (Location::Sof, 0x03),
        (Location::Id28To21, 0x02),
        (Location::Id20To18, 0x06),
        (Location::Srtr, 0x04),
        (Location::Ide, 0x05),
        (Location::Id17To13, 0x07),
        (Location::Id12To05, 0x0F),
        (Location::Id04To00, 0x0E),
        (Location::Rtr, 0x0C),
        (Location::Res1, 0x0D),
        (Location::Res0, 0x09),
        (Location::Dlc, 0x0B),
        (Location::Data, 0x0A),
        (Location::CrcSeq, 0x08),
        (Location::CrcDel, 0x18),
        (Location::Ack, 0x19),
        (Location::AckDel, 0x1B),
        (Location::Eof, 0x1A),
        (Location::Intermission, 0x12),
        (Location::Flag, 0x11),
        (Location::Delimiter, 0x17),
    ];
    for (location, code) in table {
        assert_eq!(ecc_segment(location), code, "{location:?}");
    }
}

#[test]
fn filter_in_force_matches_registers() {
    let c = initialised();
    let f = c.filter();
    assert!(f.accepts(&base(0x5D8, &[])));
    assert!(!f.accepts(&base(0x550, &[])));
}
