//! `harvemu bench --json` prints one object per scenario with the documented keys.

use serde_json::Value;
use std::process::Command;

#[test]
fn bench_json_reports_every_scenario() {
    let out = Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .args(["bench", "--json", "--seconds", "0.5", "--buses", "1,3"])
        .args([
            "--harvester-seconds",
            "3",
            "--harvesters",
            "2",
            "--many-seconds",
            "2",
        ])
        .arg("--config")
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/../configs/harvester.ron"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let rows: Vec<Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let shape: Vec<(&str, u64)> = rows
        .iter()
        .map(|r| (r["scenario"].as_str().unwrap(), r["buses"].as_u64().unwrap()))
        .collect();
    assert_eq!(
        shape,
        [
            ("saturated", 1),
            ("saturated-multi", 1),
            ("saturated-multi", 3),
            ("harvester", 1),
            ("harvester", 2)
        ]
    );
    for r in &rows {
        for key in [
            "virtual_seconds",
            "wall_seconds",
            "frames",
            "frames_per_second",
            "deliveries_per_second",
            "peak_rss_bytes",
            "wakes",
            "speedup",
            "bus_load",
        ] {
            assert!(r[key].is_number(), "{key} in {r}");
        }
        if r["scenario"] == "harvester" {
            // The harvester keeps the bus partly busy: its nodes send, the monitor answers.
            let load = r["bus_load"].as_f64().unwrap();
            assert!(load > 0.05 && load < 0.9, "{r}");
            assert!(r["frames"].as_u64().unwrap() > 0 && r["wakes"].as_u64().unwrap() > 0);
            continue;
        }
        // A saturated bus is busy all the time: 0.5 s at 250 kbit/s is 125,000 bits, and a frame
        // of this bench is at most 160 bits long (8 data bytes, worst-case stuffing).
        let per_bus = r["frames"].as_u64().unwrap() / r["buses"].as_u64().unwrap();
        assert!(per_bus >= 125_000 / 160, "{r}");
        assert!(r["bus_load"].as_f64().unwrap() > 0.99);
        assert_eq!(
            r["deliveries"], r["frames"],
            "each frame goes to exactly one receiver"
        );
    }
}

#[test]
fn bench_rejects_a_bad_duration() {
    let out = Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .args(["bench", "--seconds", "-1"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
}
