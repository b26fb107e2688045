//! Expectations computed by hand from the AT89C51CC03 / T89C51CC01 data sheets.

use super::*;
use crate::engine::BusError;
use crate::{Frame, Id, StandardId};

/// F_CAN of a 12 MHz crystal in X1 mode.
const F_CAN: u64 = 6_000_000;

fn drain(c: &mut CanController) -> Vec<Action> {
    c.take_actions().collect()
}

fn w(c: &mut CanController, addr: u8, value: u8) {
    assert!(c.sfr_write(addr, value), "{addr:02X} is a CAN SFR");
}

fn r(c: &mut CanController, addr: u8) -> u8 {
    c.sfr_read(addr).expect("a CAN SFR")
}

/// Selects channel `ch`, index 0, auto-increment on.
fn page(c: &mut CanController, ch: u8) {
    w(c, sfr::CANPAGE, ch << 4);
}

/// Sets up channel `ch`: CANIDT, CANIDM, then CANCONCH.
fn channel(c: &mut CanController, ch: u8, idt: [u8; 4], idm: [u8; 4], conch: u8) {
    page(c, ch);
    w(c, sfr::CANSTCH, 0);
    for i in 0..4 {
        w(c, sfr::CANIDT1 + i, idt[usize::from(i)]);
        w(c, sfr::CANIDM1 + i, idm[usize::from(i)]);
    }
    w(c, sfr::CANCONCH, conch);
}

fn enabled() -> CanController {
    let mut c = CanController::new(F_CAN);
    w(&mut c, sfr::CANGCON, gcon::ENA);
    drain(&mut c);
    c
}

/// The seed's receive channel: 0x0300A0F5 shifted left by 3 is 0x1805_07A8; every mask bit set.
const A0_IDT: [u8; 4] = [0x18, 0x05, 0x07, 0xA8];
const FULL: [u8; 4] = [0xFF; 4];
/// Reception, IDE, DLC 8.
const RX_EXT8: u8 = 0x80 | 0x10 | 0x08;

#[test]
fn reset_values_and_foreign_sfrs() {
    let mut c = CanController::new(F_CAN);
    for addr in [
        sfr::CANGIT,
        sfr::CANTEC,
        sfr::CANREC,
        sfr::CANTCON,
        sfr::CANGSTA,
        sfr::CANGCON,
        sfr::CANTIML,
        sfr::CANTIMH,
        sfr::CANPAGE,
        sfr::CANSIT1,
        sfr::CANSIT2,
        sfr::CANGIE,
        sfr::CANIE1,
        sfr::CANIE2,
        sfr::CANEN1,
        sfr::CANEN2,
        sfr::CANBT1,
        sfr::CANBT2,
        sfr::CANBT3,
        sfr::CANTTCL,
        sfr::CANTTCH,
    ] {
        assert_eq!(c.sfr_peek(addr), Some(0), "reset value of {addr:02X}");
    }
    // 80C51 SFRs such as ACC, P1 and IEN1 belong to the core.
    for addr in [0xE0, 0x90, 0xE8, 0xB0, 0x9A, 0xA0, 0xC8] {
        assert_eq!(c.sfr_read(addr), None);
        assert!(!c.sfr_write(addr, 0x55));
    }
    assert!(!c.interrupt());
    assert_eq!(c.error_counters(), (0, 0, ErrorState::Active));
    assert!(drain(&mut c).is_empty());
}

#[test]
fn ena_goes_online_and_sets_enfg() {
    let mut c = CanController::new(F_CAN);
    w(&mut c, sfr::CANGCON, gcon::ENA);
    assert_eq!(
        drain(&mut c),
        vec![Action::Online {
            listen_only: false,
            self_test: false,
            filter: None
        }]
    );
    assert_eq!(r(&mut c, sfr::CANGSTA), gsta::ENFG);
    w(&mut c, sfr::CANGCON, 0);
    assert_eq!(drain(&mut c), vec![Action::Offline]);
    assert_eq!(r(&mut c, sfr::CANGSTA), 0);
}

#[test]
fn a0_filter_accepts_its_id_only() {
    let mut c = enabled();
    channel(&mut c, 0, A0_IDT, FULL, RX_EXT8);
    assert_eq!(r(&mut c, sfr::CANEN2), 0x01);
    // One identifier bit off (0x0300A1F5), then a standard frame: both refused.
    c.on_event(BusSide::Received(Frame::extended(0x0300A1F5, &[0; 8]).unwrap()));
    c.on_event(BusSide::Received(Frame::base(0x0F5, &[0; 8]).unwrap()));
    page(&mut c, 0);
    assert_eq!(r(&mut c, sfr::CANSTCH), 0);
    assert_eq!(r(&mut c, sfr::CANEN2), 0x01);
    let data = [1, 2, 3, 4, 5, 6, 7, 8];
    c.on_event(BusSide::Received(Frame::extended(0x0300A0F5, &data).unwrap()));
    assert_eq!(r(&mut c, sfr::CANSTCH), stch::RXOK);
    assert_eq!(r(&mut c, sfr::CANEN2), 0x00); // done: the channel is free again
    assert_eq!(r(&mut c, sfr::CANCONCH), RX_EXT8); // CONCH kept, IDE and DLC 8 as received
    let got: Vec<u8> = (0..8).map(|_| r(&mut c, sfr::CANMSG)).collect();
    assert_eq!(got, data);
    assert_eq!(r(&mut c, sfr::CANIDT4), 0xA8);
}

#[test]
fn canmsg_index_auto_increments_and_wraps() {
    let mut c = CanController::new(F_CAN);
    w(&mut c, sfr::CANPAGE, 0x35); // channel 3, AINC 0, INDX 5
    for v in 0..8 {
        w(&mut c, sfr::CANMSG, 0x10 + v);
    }
    assert_eq!(r(&mut c, sfr::CANPAGE), 0x35); // 8 steps from 5 wrap back to 5
    w(&mut c, sfr::CANPAGE, 0x30);
    let got: Vec<u8> = (0..8).map(|_| r(&mut c, sfr::CANMSG)).collect();
    // Written from index 5: 10h at 5, 11h at 6, 12h at 7, 13h at 0, ...
    assert_eq!(got, [0x13, 0x14, 0x15, 0x16, 0x17, 0x10, 0x11, 0x12]);
    // AINC = 1 holds the index; peek never moves it.
    w(&mut c, sfr::CANPAGE, 0x3A); // INDX 2, AINC 1
    assert_eq!(r(&mut c, sfr::CANMSG), 0x15);
    assert_eq!(r(&mut c, sfr::CANMSG), 0x15);
    w(&mut c, sfr::CANPAGE, 0x32);
    assert_eq!(c.sfr_peek(sfr::CANMSG), Some(0x15));
    assert_eq!(c.sfr_peek(sfr::CANPAGE), Some(0x32));
    // Another channel has its own bytes.
    w(&mut c, sfr::CANPAGE, 0x40);
    assert_eq!(r(&mut c, sfr::CANMSG), 0);
}

#[test]
fn transmission_and_txok_interrupt() {
    let mut c = enabled();
    w(&mut c, sfr::CANGIE, gie::ENTX);
    w(&mut c, sfr::CANIE2, 0x04); // channel 2
    page(&mut c, 2);
    for v in 0xA0..0xA8 {
        w(&mut c, sfr::CANMSG, v);
    }
    // 0x0300F5A0 << 3 = 0x1807_AD00; transmission, IDE, DLC 8.
    channel(&mut c, 2, [0x18, 0x07, 0xAD, 0x00], [0; 4], 0x40 | 0x10 | 0x08);
    let frame = Frame::extended(0x0300F5A0, &[0xA0, 0xA1, 0xA2, 0xA3, 0xA4, 0xA5, 0xA6, 0xA7]);
    assert_eq!(
        drain(&mut c),
        vec![Action::Transmit {
            frame: frame.unwrap(),
            self_reception: false,
            single_shot: false
        }]
    );
    assert_eq!(r(&mut c, sfr::CANGSTA), gsta::ENFG | gsta::TBSY);
    assert!(!c.interrupt());
    c.on_event(BusSide::Transmitted);
    assert_eq!(r(&mut c, sfr::CANSTCH), stch::TXOK);
    assert_eq!(r(&mut c, sfr::CANSIT2), 0x04);
    assert_eq!(r(&mut c, sfr::CANGIT), git::CANIT);
    assert_eq!(r(&mut c, sfr::CANEN2), 0);
    assert!(c.interrupt());
    w(&mut c, sfr::CANSTCH, 0); // the firmware clears the flag
    assert!(!c.interrupt());
    assert_eq!(r(&mut c, sfr::CANSIT2), 0);
}

#[test]
fn lowest_channel_transmits_first() {
    let mut c = CanController::new(F_CAN);
    channel(&mut c, 5, [0x20, 0, 0, 0], [0; 4], 0x40); // standard 0x100, DLC 0
    channel(&mut c, 1, [0x40, 0, 0, 0], [0; 4], 0x40); // standard 0x200, DLC 0
    w(&mut c, sfr::CANGCON, gcon::ENA);
    let first = Frame::base(0x200, &[]).unwrap();
    let second = Frame::base(0x100, &[]).unwrap();
    let tx = |frame| Action::Transmit {
        frame,
        self_reception: false,
        single_shot: false,
    };
    assert_eq!(drain(&mut c)[1..], [tx(first)]);
    c.on_event(BusSide::Transmitted);
    assert_eq!(drain(&mut c), [tx(second)]);
}

#[test]
fn lowest_matching_channel_receives_and_disabled_one_does_not() {
    let mut c = enabled();
    // Channels 1 and 4 accept any standard frame (masks 0, IDEMSK 1); channel 0 is disabled
    // with the same filter.
    let open_std = [0, 0, 0, 0x01];
    channel(&mut c, 0, [0; 4], open_std, 0x00);
    channel(&mut c, 4, [0; 4], open_std, 0x80 | 2);
    channel(&mut c, 1, [0; 4], open_std, 0x80 | 2);
    c.on_event(BusSide::Received(Frame::base(0x123, &[9, 8]).unwrap()));
    assert_eq!(r(&mut c, sfr::CANEN2), 0x10);
    page(&mut c, 1);
    assert_eq!(r(&mut c, sfr::CANSTCH), stch::RXOK);
    // 0x123 left-aligned: ID10..3 = 0x24, ID2..0 = 011 in bits 7:5.
    assert_eq!((r(&mut c, sfr::CANIDT1), r(&mut c, 0xBD)), (0x24, 0x60));
    page(&mut c, 0);
    assert_eq!(r(&mut c, sfr::CANSTCH), 0);
    c.on_event(BusSide::Received(Frame::base(0x321, &[1, 2, 3]).unwrap()));
    page(&mut c, 4);
    assert_eq!(r(&mut c, sfr::CANSTCH), stch::RXOK | stch::DLCW); // expected 2, got 3
    assert_eq!(r(&mut c, sfr::CANCONCH), 0x80 | 3);
}

#[test]
fn buffer_fills_then_overruns() {
    let mut c = enabled();
    w(&mut c, sfr::CANGIE, gie::ENBUF);
    let any = [0, 0, 0, 0];
    channel(&mut c, 6, [0; 4], any, 0xC0 | 8);
    channel(&mut c, 3, [0; 4], any, 0xC0 | 8);
    let f = |id| Frame::extended(id, &[id as u8; 8]).unwrap();
    c.on_event(BusSide::Received(f(0x11)));
    assert_eq!(r(&mut c, sfr::CANGIT) & git::OVRBUF, 0);
    c.on_event(BusSide::Received(f(0x22)));
    assert_eq!(r(&mut c, sfr::CANGIT), git::CANIT | git::OVRBUF);
    assert!(c.interrupt());
    c.on_event(BusSide::Received(f(0x33))); // nowhere to go
    page(&mut c, 3);
    assert_eq!(r(&mut c, sfr::CANMSG), 0x11);
    page(&mut c, 6);
    assert_eq!(r(&mut c, sfr::CANMSG), 0x22);
    w(&mut c, sfr::CANGIT, 0);
    assert!(!c.interrupt());
}

#[test]
fn errors_set_flags_and_counters() {
    let mut c = enabled();
    w(&mut c, sfr::CANGIE, gie::ENERG | gie::ENERCH);
    w(&mut c, sfr::CANIE2, 0x01);
    channel(&mut c, 0, [0x20, 0, 0, 0], [0; 4], 0x40);
    drain(&mut c);
    c.on_event(BusSide::BusError {
        error: BusError::Ack,
        transmitting: true,
        segment: 0x19,
    });
    c.on_event(BusSide::BusError {
        error: BusError::Bit,
        transmitting: true,
        segment: 0x19,
    });
    c.on_event(BusSide::BusError {
        error: BusError::Crc,
        transmitting: false,
        segment: 0x08,
    });
    page(&mut c, 0);
    assert_eq!(r(&mut c, sfr::CANSTCH), stch::AERR | stch::BERR);
    // The acknowledgement error went to the channel only; the CRC error, met while receiving,
    // to the general flags.
    assert_eq!(r(&mut c, sfr::CANGIT), git::CANIT | git::CERG);
    assert_eq!(r(&mut c, sfr::CANSIT2), 0x01);
    let passive = BusSide::Counters {
        tec: 136,
        rec: 3,
        state: ErrorState::Passive,
    };
    c.on_event(passive);
    assert_eq!((r(&mut c, sfr::CANTEC), r(&mut c, sfr::CANREC)), (136, 3));
    assert_eq!(r(&mut c, sfr::CANGSTA), gsta::ENFG | gsta::TBSY | gsta::ERRP);
}

#[test]
fn bus_off_and_automatic_recovery() {
    let mut c = enabled();
    c.on_event(BusSide::Counters {
        tec: 256,
        rec: 0,
        state: ErrorState::BusOff,
    });
    assert_eq!(r(&mut c, sfr::CANGSTA), gsta::ENFG | gsta::BOFF);
    assert_eq!(r(&mut c, sfr::CANTEC), 255);
    assert_eq!(c.error_counters(), (256, 0, ErrorState::BusOff));
    assert!(drain(&mut c).is_empty()); // no Offline, no StartRecovery: the bus recovers
    c.on_event(BusSide::RecoveryDone);
    assert_eq!(r(&mut c, sfr::CANGSTA), gsta::ENFG);
    assert_eq!(r(&mut c, sfr::CANTEC), 0);
}

#[test]
fn abort_request_and_general_reset() {
    let mut c = enabled();
    channel(&mut c, 0, [0x20, 0, 0, 0], [0; 4], 0x40);
    drain(&mut c);
    w(&mut c, sfr::CANGCON, gcon::ENA | gcon::ABRQ);
    assert_eq!(drain(&mut c), [Action::Abort]);
    assert_eq!(r(&mut c, sfr::CANEN2), 0);
    c.on_event(BusSide::Aborted);
    assert_eq!(r(&mut c, sfr::CANGSTA), gsta::ENFG);
    c.on_event(BusSide::Counters {
        tec: 8,
        rec: 0,
        state: ErrorState::Active,
    });
    w(&mut c, sfr::CANGCON, gcon::GRES);
    assert_eq!(
        drain(&mut c),
        [Action::Offline, Action::SetCounters { tec: 0, rec: 0 }]
    );
    assert_eq!(r(&mut c, sfr::CANGCON), 0);
    assert_eq!(r(&mut c, sfr::CANTEC), 0);
    page(&mut c, 0);
    assert_eq!(r(&mut c, sfr::CANIDT1), 0x20); // message objects keep their contents
}

#[test]
fn timer_and_time_stamp() {
    let mut c = enabled();
    w(&mut c, sfr::CANTCON, 9); // one tick every 6 · 10 = 60 CAN clocks
    c.set_time(60 * 0x1234 + 59);
    assert_eq!((r(&mut c, sfr::CANTIMH), r(&mut c, sfr::CANTIML)), (0x12, 0x34));
    channel(&mut c, 2, [0; 4], [0; 4], 0x80);
    c.on_event(BusSide::Received(Frame::base(1, &[]).unwrap()));
    page(&mut c, 2);
    assert_eq!((r(&mut c, sfr::CANSTMPH), r(&mut c, sfr::CANSTMPL)), (0x12, 0x34));
    c.set_time(60 * 0x1_0000 + 59); // past 0xFFFF
    assert!(c.timer_interrupt());
    assert_eq!((r(&mut c, sfr::CANTIMH), r(&mut c, sfr::CANTIML)), (0, 0));
}

#[test]
fn bit_timing_250_kbit_at_12_mhz_x1() {
    // 12 MHz in X1 mode: F_CAN = 6 MHz. 250 kbit/s needs 6 MHz / 250 kHz = 24 clocks a bit:
    // BRP = 1 (quantum 2 / 6 MHz = 1/3 µs) and 12 quanta = SYNC 1 + PRS 3 + PHS1 4 + PHS2 4,
    // SJW 1. CANBT1 = BRP << 1 = 02h; CANBT2 = SJW 0 << 5 | PRS 2 << 1 = 04h;
    // CANBT3 = PHS2 3 << 4 | PHS1 3 << 1 = 36h (the data sheet's 500 kbit/s example with BRP 0).
    let mut c = CanController::new(F_CAN);
    w(&mut c, sfr::CANBT1, 0x02);
    w(&mut c, sfr::CANBT2, 0x04);
    w(&mut c, sfr::CANBT3, 0x36);
    let t = c.bit_timing();
    assert_eq!(t.quanta_per_bit(), 12);
    assert_eq!(t.clocks_per_bit(), 24);
    assert_eq!(t.bit_rate_hz(), 250_000.0);
    assert_eq!(
        t.bit_time(),
        Some(crate::time::BusDuration::from_ticks(13_824_000))
    ); // 4 µs
    // Tolerance: min(SJW / (20 · NBT), min(PS1, PS2) / (2 · (13 · NBT − PS2)))
    //          = min(1 / 240, 4 / 304) = 1 / 240 ≈ 0.4167 %.
    assert!((t.tolerance() - 1.0 / 240.0).abs() < 1e-12);
    assert!(t.samples_correctly(250_000.0 * 1.004));
    assert!(!t.samples_correctly(250_000.0 * 1.005));
    assert!(!t.samples_correctly(500_000.0));
}

/// Standard identifier `id` left-aligned in CANIDT1..4 (ID10..3 in CANIDT1, ID2..0 in CANIDT2
/// 7:5), with RTRTAG (CANIDT4 bit 2) when `rtr`.
fn std_idt(id: u16, rtr: bool) -> [u8; 4] {
    [(id >> 3) as u8, (id << 5) as u8, 0, if rtr { 0x04 } else { 0 }]
}

fn tx(frame: Frame) -> Action {
    Action::Transmit {
        frame,
        self_reception: false,
        single_shot: false,
    }
}

/// Writes `bytes` into channel `ch`'s buffer from index 0.
fn fill(c: &mut CanController, ch: u8, bytes: &[u8]) {
    page(c, ch);
    for &b in bytes {
        w(c, sfr::CANMSG, b);
    }
}

// The bus holds at most one frame of the controller, from its `Transmit` until it answers:
// `Transmitted`, or `Aborted` when it dropped the frame (docs/CAN.md, "Controller modes": an
// abort drops a frame not yet started at once; an attempt on the wire runs to its end, and is
// answered `Transmitted` if it succeeded). The AT89C51CC03 data sheet (CANGCON table, ABRQ):
// pending communications are disabled at once, the one under way ends normally and sets its
// status flags.

#[test]
fn an_abort_answered_transmitted_sets_txok_and_frees_the_bus() {
    let mut c = enabled();
    channel(&mut c, 0, std_idt(0x100, false), [0; 4], conch::TX);
    channel(&mut c, 1, std_idt(0x200, false), [0; 4], conch::TX);
    assert_eq!(drain(&mut c), [tx(Frame::base(0x100, &[]).unwrap())]);
    page(&mut c, 0);
    w(&mut c, sfr::CANCONCH, 0x00);
    assert_eq!(drain(&mut c), [Action::Abort]);
    // Channel 0 is disabled at once, but its frame is on the wire until the bus answers.
    assert_eq!(r(&mut c, sfr::CANEN2), 0x02);
    assert_eq!(r(&mut c, sfr::CANGSTA), gsta::ENFG | gsta::TBSY);
    c.on_event(BusSide::Transmitted);
    assert_eq!(
        r(&mut c, sfr::CANSTCH),
        stch::TXOK,
        "the attempt under way ends normally"
    );
    assert_eq!(drain(&mut c), [tx(Frame::base(0x200, &[]).unwrap())]);
    c.on_event(BusSide::Transmitted);
    page(&mut c, 1);
    assert_eq!(r(&mut c, sfr::CANSTCH), stch::TXOK);
    assert_eq!(r(&mut c, sfr::CANEN2), 0);
}

#[test]
fn an_abort_answered_aborted_offers_the_next_channel() {
    let mut c = enabled();
    channel(&mut c, 0, std_idt(0x100, false), [0; 4], conch::TX);
    drain(&mut c);
    // ABRQ clears every CANEN bit; channel 1, enabled after ABRQ is cleared, waits for the bus
    // to let go of channel 0's frame.
    w(&mut c, sfr::CANGCON, gcon::ENA | gcon::ABRQ);
    assert_eq!(drain(&mut c), [Action::Abort]);
    w(&mut c, sfr::CANGCON, gcon::ENA);
    channel(&mut c, 1, std_idt(0x200, false), [0; 4], conch::TX);
    assert!(drain(&mut c).is_empty());
    c.on_event(BusSide::Aborted);
    assert_eq!(drain(&mut c), [tx(Frame::base(0x200, &[]).unwrap())]);
    page(&mut c, 0);
    assert_eq!(r(&mut c, sfr::CANSTCH), 0, "an abort sets no flag");
}

#[test]
fn a_channel_written_again_during_its_abort_keeps_its_new_request() {
    let mut c = enabled();
    fill(&mut c, 0, &[0x01]);
    channel(&mut c, 0, std_idt(0x100, false), [0; 4], conch::TX | 1);
    drain(&mut c);
    w(&mut c, sfr::CANCONCH, 0x00);
    assert_eq!(drain(&mut c), [Action::Abort]);
    // The firmware loads a new byte and launches the channel again before the bus answers.
    fill(&mut c, 0, &[0x02]);
    w(&mut c, sfr::CANCONCH, conch::TX | 1);
    assert!(drain(&mut c).is_empty(), "the bus still holds the first frame");
    // The first frame was on the wire and went out: TXOK for it; the new request stands.
    c.on_event(BusSide::Transmitted);
    assert_eq!(r(&mut c, sfr::CANSTCH), stch::TXOK);
    assert_eq!(r(&mut c, sfr::CANEN2), 0x01);
    assert_eq!(drain(&mut c), [tx(Frame::base(0x100, &[0x02]).unwrap())]);
}

#[test]
fn ena_cleared_the_bus_still_answers_for_the_frame_it_held() {
    // Dropped: the channel stays enabled and is offered again once the bus answered and ENA is
    // set, once only.
    let mut c = enabled();
    channel(&mut c, 0, std_idt(0x100, false), [0; 4], conch::TX);
    let frame = tx(Frame::base(0x100, &[]).unwrap());
    assert_eq!(drain(&mut c), [frame]);
    w(&mut c, sfr::CANGCON, 0);
    w(&mut c, sfr::CANGCON, gcon::ENA);
    let online = Action::Online {
        listen_only: false,
        self_test: false,
        filter: None,
    };
    assert_eq!(drain(&mut c), [Action::Offline, online]);
    c.on_event(BusSide::Aborted);
    assert_eq!(drain(&mut c), [frame]);
    c.on_event(BusSide::Transmitted);
    page(&mut c, 0);
    assert_eq!(r(&mut c, sfr::CANSTCH), stch::TXOK);
    assert!(drain(&mut c).is_empty());

    // Sent: the attempt on the wire when ENA was cleared succeeded. TXOK, and the frame is not
    // sent a second time.
    let mut c = enabled();
    channel(&mut c, 0, std_idt(0x100, false), [0; 4], conch::TX);
    drain(&mut c);
    w(&mut c, sfr::CANGCON, 0);
    c.on_event(BusSide::Transmitted);
    assert_eq!(r(&mut c, sfr::CANSTCH), stch::TXOK);
    assert_eq!(r(&mut c, sfr::CANEN2), 0);
    w(&mut c, sfr::CANGCON, gcon::ENA);
    assert_eq!(drain(&mut c), [Action::Offline, online]);
}

#[test]
fn a_general_reset_leaves_the_bus_answer_to_the_frame_it_held() {
    let mut c = enabled();
    channel(&mut c, 0, std_idt(0x100, false), [0; 4], conch::TX);
    drain(&mut c);
    w(&mut c, sfr::CANGCON, gcon::GRES);
    assert_eq!(drain(&mut c), [Action::Offline]);
    // Enabled again with channel 1 launched before the bus answered for channel 0's frame.
    w(&mut c, sfr::CANGCON, gcon::ENA);
    channel(&mut c, 1, std_idt(0x200, false), [0; 4], conch::TX);
    assert_eq!(drain(&mut c).len(), 1, "Online only: the bus still holds a frame");
    c.on_event(BusSide::Aborted);
    assert_eq!(drain(&mut c), [tx(Frame::base(0x200, &[]).unwrap())]);
    c.on_event(BusSide::Transmitted);
    page(&mut c, 1);
    assert_eq!(r(&mut c, sfr::CANSTCH), stch::TXOK);
    page(&mut c, 0);
    assert_eq!(r(&mut c, sfr::CANSTCH), 0);
}

/// Channel 3 set for automatic reply to remote frames of 0x123: RTRTAG and every mask bit set
/// (RTRMSK and IDEMSK included: a remote frame with a standard identifier only), CONCH 10
/// (reception) with RPLV and DLC `dlc`; its buffer holds 11h..18h.
fn reply_channel(c: &mut CanController, dlc: u8) {
    fill(c, 3, &[0x11, 0x12, 0x13, 0x14, 0x15, 0x16, 0x17, 0x18]);
    channel(c, 3, std_idt(0x123, true), FULL, conch::RX | conch::RPLV | dlc);
}

#[test]
fn automatic_reply_answers_a_matching_remote_frame() {
    let mut c = enabled();
    w(&mut c, sfr::CANGIE, gie::ENRX | gie::ENTX);
    w(&mut c, sfr::CANIE2, 0x08);
    reply_channel(&mut c, 2);
    assert!(drain(&mut c).is_empty());
    // A data frame with the identifier does not match RTRTAG (RTRMSK set): not taken.
    let data = Frame::base(0x123, &[9, 9]).unwrap();
    assert!(!c.takes(&data));
    let remote = Frame::new_remote(Id::Standard(StandardId::new(0x123).unwrap()), 2).unwrap();
    assert!(c.takes(&remote));
    c.on_event(BusSide::Received(remote));
    // The reply: a data frame with the remote frame's identifier and DLC, from the buffer.
    assert_eq!(drain(&mut c), [tx(Frame::base(0x123, &[0x11, 0x12]).unwrap())]);
    page(&mut c, 3);
    // No flag yet; RPLV and RTRTAG cleared; the channel stays enabled, now a producer, and
    // takes no frame meanwhile.
    assert_eq!(r(&mut c, sfr::CANSTCH), 0);
    assert_eq!(r(&mut c, sfr::CANCONCH), conch::RX | 2);
    assert_eq!(r(&mut c, sfr::CANIDT4), 0x00);
    assert_eq!(r(&mut c, sfr::CANEN2), 0x08);
    assert!(!c.interrupt());
    assert!(!c.takes(&remote));
    c.on_event(BusSide::Transmitted);
    assert_eq!(r(&mut c, sfr::CANSTCH), stch::TXOK);
    assert_eq!(r(&mut c, sfr::CANEN2), 0);
    assert_eq!(r(&mut c, sfr::CANSIT2), 0x08);
    assert!(c.interrupt());
}

#[test]
fn automatic_reply_takes_the_remote_frames_dlc_and_waits_its_turn() {
    let mut c = enabled();
    // Channel 0 holds the bus with a frame of its own.
    channel(&mut c, 0, std_idt(0x050, false), [0; 4], conch::TX);
    drain(&mut c);
    reply_channel(&mut c, 2);
    let remote = Frame::new_remote(Id::Standard(StandardId::new(0x123).unwrap()), 4).unwrap();
    c.on_event(BusSide::Received(remote));
    assert!(drain(&mut c).is_empty(), "one frame at a time");
    page(&mut c, 3);
    // DLC 4 received where 2 was expected: DLCW, and CANCONCH takes the received DLC.
    assert_eq!(r(&mut c, sfr::CANSTCH), stch::DLCW);
    assert_eq!(r(&mut c, sfr::CANCONCH), conch::RX | 4);
    c.on_event(BusSide::Transmitted);
    let reply = Frame::base(0x123, &[0x11, 0x12, 0x13, 0x14]).unwrap();
    assert_eq!(drain(&mut c), [tx(reply)]);
}

#[test]
fn without_rplv_or_rtrtag_a_remote_frame_is_received_and_not_answered() {
    let remote = Frame::new_remote(Id::Standard(StandardId::new(0x123).unwrap()), 2).unwrap();
    // RPLV clear: a plain reception of the remote frame.
    let mut c = enabled();
    fill(&mut c, 3, &[0x11, 0x12]);
    channel(&mut c, 3, std_idt(0x123, true), FULL, conch::RX | 2);
    c.on_event(BusSide::Received(remote));
    assert!(drain(&mut c).is_empty());
    page(&mut c, 3);
    assert_eq!(r(&mut c, sfr::CANSTCH), stch::RXOK);
    assert_eq!(r(&mut c, sfr::CANIDT4), 0x04, "RTRTAG as received");
    assert_eq!(r(&mut c, sfr::CANEN2), 0);
    // RPLV set but RTRTAG clear, the RTR bit not compared (RTRMSK 0): the remote frame is
    // received, not answered.
    let mut c = enabled();
    channel(
        &mut c,
        3,
        std_idt(0x123, false),
        [0xFF, 0xFF, 0xFF, 0x01],
        conch::RX | conch::RPLV | 2,
    );
    c.on_event(BusSide::Received(remote));
    assert!(drain(&mut c).is_empty());
    page(&mut c, 3);
    assert_eq!(r(&mut c, sfr::CANSTCH), stch::RXOK);
    // Buffer mode (CONCH 11) does not reply either.
    let mut c = enabled();
    channel(
        &mut c,
        3,
        std_idt(0x123, true),
        FULL,
        conch::RX_BUFFER | conch::RPLV | 2,
    );
    c.on_event(BusSide::Received(remote));
    assert!(drain(&mut c).is_empty());
    page(&mut c, 3);
    assert_eq!(r(&mut c, sfr::CANSTCH), stch::RXOK);
}

#[test]
fn a_reply_not_yet_sent_ends_with_a_conch_write() {
    let mut c = enabled();
    channel(&mut c, 0, std_idt(0x050, false), [0; 4], conch::TX);
    drain(&mut c);
    reply_channel(&mut c, 2);
    let remote = Frame::new_remote(Id::Standard(StandardId::new(0x123).unwrap()), 2).unwrap();
    c.on_event(BusSide::Received(remote));
    page(&mut c, 3);
    w(&mut c, sfr::CANCONCH, 0x00);
    assert_eq!(r(&mut c, sfr::CANEN2), 0x01);
    c.on_event(BusSide::Transmitted);
    assert!(drain(&mut c).is_empty(), "no reply once the channel was disabled");
}

#[test]
fn next_timer_overflow_is_when_set_time_sets_ovrtim() {
    let mut c = CanController::new(F_CAN);
    w(&mut c, sfr::CANTCON, 9); // one tick every 6 · 10 = 60 CAN clocks
    assert_eq!(c.next_timer_overflow(), None, "disabled: the timer stands still");
    c.set_time(100);
    w(&mut c, sfr::CANGCON, gcon::ENA);
    // Enabled at 100 with the timer at 0: 65 536 ticks of 60 periods.
    let first = 100 + 65_536 * 60;
    assert_eq!(c.next_timer_overflow(), Some(first));
    c.set_time(1_000); // 15 ticks and 0 left over, still the same overflow
    assert_eq!(c.next_timer_overflow(), Some(first));
    c.set_time(first - 1);
    assert!(!c.timer_interrupt());
    assert_eq!((r(&mut c, sfr::CANTIMH), r(&mut c, sfr::CANTIML)), (0xFF, 0xFF));
    c.set_time(first);
    assert!(c.timer_interrupt());
    assert_eq!(c.next_timer_overflow(), Some(first + 65_536 * 60));
    w(&mut c, sfr::CANGCON, 0);
    assert_eq!(c.next_timer_overflow(), None);
}

#[test]
fn flags_are_cleared_by_writing_zero() {
    // AT89C51CC03 data sheet, "CAN Controller" interrupts and the CANGIT and CANSTCH tables:
    // the software clears the flags (as Atmel's 8051 CAN library does, by writing 0); writing 1
    // clears nothing (that is the AVR parts' CANGIT rule, not this one's).
    let mut c = enabled();
    c.set_time(6 * 0x1_0000); // CANTCON 0: the overflow
    channel(&mut c, 0, std_idt(0x100, false), [0; 4], conch::TX);
    c.on_event(BusSide::Transmitted);
    assert_eq!(r(&mut c, sfr::CANGIT), git::OVRTIM);
    w(&mut c, sfr::CANGIT, git::OVRTIM);
    assert!(c.timer_interrupt(), "writing 1 keeps OVRTIM");
    w(&mut c, sfr::CANGIT, !git::OVRTIM);
    assert!(!c.timer_interrupt(), "writing 0 clears OVRTIM");
    page(&mut c, 0);
    w(&mut c, sfr::CANSTCH, stch::TXOK);
    assert_eq!(r(&mut c, sfr::CANSTCH), stch::TXOK, "writing 1 keeps TXOK");
    w(&mut c, sfr::CANSTCH, 0);
    assert_eq!(r(&mut c, sfr::CANSTCH), 0, "writing 0 clears TXOK");
}
