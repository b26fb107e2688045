//! The flow sensors' `flow.status` on a healthy bus: at its heartbeat rate, with no group ever
//! reported as missing its acknowledgement.

use bus::time::BusTime;
use harvemu_e2e::{default_harvester, run_virtual};
use protocol::catalogue::{self, Trigger};
use protocol::ident::Address;

const SECONDS: u64 = 30;
/// Calibration is over well before this (the nodes power on at 0.5 s and stream within 1.5 s);
/// from here on nothing of a healthy sensor's state changes.
const SETTLED_S: u64 = 5;

#[test]
fn flow_status_keeps_to_its_heartbeat_and_reports_no_missed_acknowledgements() {
    // The documented rate: on change, at least every `heartbeat` (250 ms), so 4 a second once
    // nothing changes.
    let status = catalogue::by_name("flow.status").expect("in the catalogue");
    let Trigger::OnChange { heartbeat_ms } = status.trigger else {
        panic!("flow.status is sent on change: {:?}", status.trigger);
    };
    let expected = 1000.0 / f64::from(heartbeat_ms);

    let (lines, _) = run_virtual(
        default_harvester(),
        BusTime::from_secs(SECONDS),
        |_| {},
        |_, _| (),
    );
    let mut rates = Vec::new();
    let mut missed_by_sensor = Vec::new();
    for n in 0..6u8 {
        let d = Address::flow_sensor(n);
        let sent: Vec<(BusTime, catalogue::Decoded)> = lines
            .iter()
            .filter_map(|l| catalogue::decode(&l.frame).ok().flatten().map(|x| (l.at, x)))
            .filter(|(_, x)| x.node == d && x.message.name == "flow.status")
            .collect();
        let missed: Vec<(u64, i64)> = sent
            .iter()
            .map(|(t, x)| {
                (
                    t.as_nanos() / 1_000_000,
                    x.get("missed_acks").map_or(-1, |v| v.raw),
                )
            })
            .filter(|&(_, m)| m != 0)
            .collect();
        missed_by_sensor.push((d, missed));
        let settled = sent
            .iter()
            .filter(|(t, _)| t.as_nanos() >= SETTLED_S * 1_000_000_000)
            .count();
        let rate = settled as f64 / (SECONDS - SETTLED_S) as f64;
        rates.push((d, rate));
    }
    println!("flow.status per second: {rates:?} (documented {expected})");
    // A healthy bus acknowledges every group in time: never a missed acknowledgement, from the
    // first status to the last.
    for (d, missed) in missed_by_sensor {
        let head: Vec<_> = missed.iter().take(8).collect();
        assert!(
            missed.is_empty(),
            "{d}: {} statuses with missed_acks != 0, first (ms, value): {head:?}",
            missed.len()
        );
    }
    for (d, rate) in rates {
        assert!(
            (rate - expected).abs() <= 0.25 * expected,
            "{d}: {rate:.2} flow.status a second, documented {expected}"
        );
    }
}
