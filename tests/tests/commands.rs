//! Monitor commands reaching the row alignment module and the speed controller, sent through the
//! monitor's controller as an external monitor would.

use bus::time::BusTime;
use bus_runtime::hub::Submit;
use harvemu_e2e::{run_to, traffic_of};
use protocol::catalogue::{self, by_name};
use protocol::ident::Address;

fn command(name: &str, node: Address, values: &'static [(&'static str, f64)]) -> bus::Frame {
    by_name(name)
        .unwrap()
        .encode(node, |f| values.iter().find(|(n, _)| *n == f).map(|(_, v)| *v))
        .unwrap()
}

/// Runs the harvester, sending `(time, frame)` from the monitor's controller; returns the decoded
/// traffic of `node` as (ms, decoded).
fn run_with(
    commands: Vec<(u64, bus::Frame)>,
    until_ms: u64,
    node: Address,
) -> Vec<(u64, catalogue::Decoded)> {
    let traffic = traffic_of(node, async |running| {
        let monitor = running.nodes[0].1;
        for (at, frame) in commands {
            run_to(running, BusTime::from_millis(at)).await;
            assert!(
                running
                    .hub
                    .send(Submit { node: monitor, frame })
                    .await
                    .unwrap()
                    .unwrap()
            );
        }
        run_to(running, BusTime::from_millis(until_ms)).await;
    });
    traffic
        .into_iter()
        .map(|(t, d)| (t.as_nanos() / 1_000_000, d))
        .collect()
}

#[test]
fn row_alignment_starts_on_command_and_holds_the_rows() {
    let start = command("row.command", Address::ROW_ALIGNMENT, &[("command", 1.0)]);
    let traffic = run_with(vec![(5000, start)], 20_000, Address::ROW_ALIGNMENT);
    let status: Vec<(u64, String, f64)> = traffic
        .iter()
        .filter(|(_, d)| d.message.name == "row.status")
        .map(|(t, d)| {
            (
                *t,
                d.get("state").unwrap().label().unwrap_or("?").to_string(),
                d.get("offset").unwrap().physical,
            )
        })
        .collect();
    assert!(status.iter().filter(|s| s.0 < 5000).all(|s| s.1 == "idle"));
    let seeking = status.iter().find(|s| s.1 == "seeking row").unwrap().0;
    assert!((5000..5300).contains(&seeking), "{seeking}");
    let locked = status.iter().find(|s| s.1 == "locked").unwrap().0;
    assert!(
        (7000..7300).contains(&locked),
        "locked two seconds later: {locked}"
    );
    // Steering keeps the heads close to the rows.
    let late: Vec<f64> = status
        .iter()
        .filter(|s| s.0 > 10_000)
        .map(|s| s.2.abs())
        .collect();
    let mean = late.iter().sum::<f64>() / late.len() as f64;
    assert!(mean < 60.0, "mean |offset| {mean} mm");
}

#[test]
fn cruise_follows_the_set_point_and_falls_back_without_one() {
    let e0 = Address::SPEED_CONTROL;
    let cruise = command("speed.mode", e0, &[("mode", 1.0)]);
    let mut commands = vec![(3000, cruise)];
    // Set-points of 7 km/h every 200 ms from 3 s to 9 s, then silence.
    for k in 0..30u64 {
        commands.push((
            3000 + 200 * k + 10,
            command("speed.setpoint", e0, &[("setpoint", 7.0)]),
        ));
    }
    let traffic = run_with(commands, 12_000, e0);
    let status: Vec<(u64, i64, f64, i64)> = traffic
        .iter()
        .filter(|(_, d)| d.message.name == "speed.status")
        .map(|(t, d)| {
            (
                *t,
                d.get("mode").unwrap().raw,
                d.get("actual").unwrap().physical,
                d.get("setpoint_timeout").unwrap().raw,
            )
        })
        .collect();
    let at = |ms: u64| *status.iter().rev().find(|s| s.0 <= ms).unwrap();
    assert_eq!(at(2900).1, 0, "manual before");
    assert_eq!(at(8900).1, 1, "cruise while set-points come");
    assert!(
        (at(8900).2 - 7.0).abs() < 0.3,
        "speed follows the set-point: {:?}",
        at(8900)
    );
    // The last set-point came at 8810 ms: the watchdog falls back at 9810 ms.
    assert_eq!(at(9800).1, 1);
    assert_eq!((at(9900).1, at(9900).3), (0, 1), "manual again, and it says why");
}
