//! Connection-oriented flow sensor traffic when the monitor stops acknowledging, and when it
//! comes back.

use bus::time::BusTime;
use bus_runtime::hub::Control;
use harvemu_e2e::{run_to, traffic_of};
use protocol::ident::Address;

#[test]
fn sensors_give_up_without_acknowledgements_and_resume() {
    let decoded = traffic_of(Address::flow_sensor(0), async |running| {
        let monitor = running.nodes[0].1;
        run_to(running, BusTime::from_secs(5)).await;
        // The monitor hangs: alive on the bus (it still acknowledges at the CAN level), silent.
        running
            .hub
            .send(Control::SetHung(monitor, true))
            .await
            .unwrap()
            .unwrap();
        run_to(running, BusTime::from_secs(8)).await;
        running
            .hub
            .send(Control::SetHung(monitor, false))
            .await
            .unwrap()
            .unwrap();
        run_to(running, BusTime::from_secs(12)).await;
    });
    let markers = |from: u64, to: u64| {
        decoded
            .iter()
            .filter(|(t, d)| {
                d.message.name == "flow.marker_flow" && (from..to).contains(&(t.as_nanos() / 1_000_000))
            })
            .count()
    };
    // Streaming (10 groups a second) before; a sensor gives up once a third group in a row is
    // overdue, 50 ms after the next cycle's first group; silence after.
    assert_eq!(markers(4000, 5000), 10);
    let around: Vec<(u64, &str)> = decoded
        .iter()
        .filter(|(t, _)| (4900..5600).contains(&(t.as_nanos() / 1_000_000)))
        .map(|(t, d)| (t.as_nanos() / 1_000_000, d.message.name))
        .collect();
    assert!(markers(5000, 5300) <= 2, "{around:?}");
    assert_eq!(markers(5300, 8000), 0);
    let states: Vec<(u64, &str)> = decoded
        .iter()
        .filter(|(_, d)| d.message.name == "flow.status")
        .map(|(t, d)| {
            (
                t.as_nanos() / 1_000_000,
                d.get("state").unwrap().label().unwrap_or("?"),
            )
        })
        .collect();
    let no_ack: Vec<u64> = states
        .iter()
        .filter(|(_, s)| *s == "no acknowledgement")
        .map(|(t, _)| *t)
        .collect();
    assert!(
        !no_ack.is_empty() && no_ack[0] > 5000 && no_ack[0] < 5400,
        "{no_ack:?}"
    );
    // While it waits it says so at least every 250 ms.
    assert!(
        no_ack
            .windows(2)
            .filter(|w| w[1] < 8000)
            .all(|w| w[1] - w[0] <= 250),
        "{no_ack:?}"
    );
    // The monitor back: it sees the status, accepts the sensor again, and the stream resumes.
    assert_eq!(markers(9000, 12000), 30);
    assert_eq!(states.last().unwrap().1, "running");
}
