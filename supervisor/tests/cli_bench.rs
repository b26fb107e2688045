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
            "--cpu-cycles",
            "100000",
            "--lab-seconds",
            "2",
            "--campaign-runs",
            "2",
        ])
        .arg("--config")
        .arg(concat!(env!("CARGO_MANIFEST_DIR"), "/../configs/harvester.ron"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let mut rows: Vec<Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    // The campaign: runs of the built-in campaign harvest, 60 s each, on every core.
    let campaign = rows.pop().unwrap();
    assert_eq!(campaign["scenario"], "campaign", "{campaign}");
    assert_eq!(campaign["runs"], 2, "{campaign}");
    assert_eq!(campaign["virtual_seconds"], 60.0, "{campaign}");
    // A fault a second on average from 10 s to 45 s: some 35 a run, drawn with the seed.
    let faults = campaign["faults"].as_u64().unwrap();
    assert!((20..=100).contains(&faults), "{campaign}");
    assert!(campaign["jobs"].as_u64().unwrap() >= 1, "{campaign}");
    assert!(campaign["runs_per_hour"].as_f64().unwrap() > 0.0, "{campaign}");
    // The CPU alone: machine cycles, not buses. The busy loop runs whole instructions, so it
    // stops within an instruction (at most 4 cycles) past what was asked.
    let cpu = rows.pop().unwrap();
    assert_eq!(cpu["scenario"], "firmware-cpu", "{cpu}");
    let cycles = cpu["cycles"].as_u64().unwrap();
    assert!((100_000..100_004).contains(&cycles), "{cpu}");
    assert!(cpu["cycles_per_second"].as_f64().unwrap() > 0.0, "{cpu}");
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
            ("harvester", 2),
            ("firmware-lab", 1),
            ("firmware-irq", 1),
            ("firmware-irq-noskip", 1),
            ("harvester-scripts", 1),
            ("harvester-c0-fw", 1),
            ("harvester-c0-fw-cov", 1),
            ("harvester-all-fw", 1),
            ("harvester-all-fw-cov", 1),
        ]
    );
    // The harvesters with C0 as firmware and with every field node as firmware carry the same
    // traffic as the scripts: the same messages at the same periods.
    let frames = |name: &str| {
        rows.iter()
            .find(|r| r["scenario"] == name)
            .and_then(|r| r["frames"].as_f64())
            .unwrap()
    };
    let scripts = frames("harvester-scripts");
    // Counting coverage changes no frame: the same count with it as without.
    assert_eq!(frames("harvester-c0-fw-cov"), frames("harvester-c0-fw"));
    assert_eq!(frames("harvester-all-fw-cov"), frames("harvester-all-fw"));
    for row in ["harvester-c0-fw", "harvester-all-fw"] {
        let firmware = frames(row);
        assert!(
            (firmware / scripts - 1.0).abs() < 0.02,
            "{row}: {firmware} frames against {scripts}"
        );
    }
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
        if r["scenario"].as_str().unwrap().starts_with("harvester") {
            // The harvester keeps the bus partly busy: its nodes send, the monitor answers.
            let load = r["bus_load"].as_f64().unwrap();
            assert!(load > 0.05 && load < 0.9, "{r}");
            assert!(r["frames"].as_u64().unwrap() > 0 && r["wakes"].as_u64().unwrap() > 0);
            continue;
        }
        if r["scenario"].as_str().unwrap().starts_with("firmware-") {
            // The lab's sender ends a frame 4.003 ms in and then every 99.916 ms (its program's
            // loop, counted with s51): twenty end within 2 s, and the one under way at 2 s is
            // counted too; the one receiver takes each.
            assert_eq!(
                (r["frames"].as_u64(), r["deliveries"].as_u64()),
                (Some(21), Some(21)),
                "{r}"
            );
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
