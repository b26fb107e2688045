//! `harvemu scenario FILE --config configs/harvester-firmware.ron`: every shipped scenario whose
//! harvester is the default one holds against the harvester whose twenty field nodes are
//! firmware, but for the expectations listed in [`NOT_FOR_FIRMWARE`], each of which the scenario
//! file explains and each of which must fail (so that the list says what is true). A fault
//! campaign runs against it too.
//!
//! The optimised phase of `scripts/test` runs this by name: a debug build takes minutes.

use harvemu_e2e::root;
use std::path::{Path, PathBuf};
use supervisor::campaign::{Campaign, Shard, play};
use supervisor::scenario;

/// Expectations that do not hold for firmware: (scenario file, index in its `expect`, the
/// reason, which the scenario file gives in these words).
const NOT_FOR_FIRMWARE: &[(&str, usize, &str)] = &[
    (
        "power_cycle.ron",
        1,
        "a firmware node's CAN controller stays in reset until its firmware sets it up",
    ),
    (
        "sensor_faults.ron",
        0,
        "the firmware reads a stuck 0 rpm as the centre of its ADC's first bin",
    ),
    (
        "sensor_faults.ron",
        2,
        "a firmware node whose sensor is gone reads a cut wire and goes on sending",
    ),
    (
        "sensor_faults.ron",
        3,
        "a firmware node whose sensor is gone reads a cut wire and goes on sending",
    ),
];

fn firmware_config() -> PathBuf {
    root().join("configs/harvester-firmware.ron")
}

/// The shipped scenarios that run the default harvester.
fn on_the_default_harvester() -> Vec<String> {
    let default = root().join("configs/harvester.ron").canonicalize().unwrap();
    let mut files: Vec<String> = std::fs::read_dir(root().join("configs/scenarios"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".ron"))
        .filter(|n| {
            let loaded = scenario::load(&root().join("configs/scenarios").join(n), None)
                .unwrap_or_else(|e| panic!("{n}: {e}"));
            Path::new(&loaded.harvester.source.path).canonicalize().unwrap() == default
        })
        .collect();
    files.sort();
    files
}

/// The words of a text, comment marks left out, one space between them: a reason reads the
/// same however the comment that gives it is wrapped.
fn words(text: &str) -> String {
    text.split_whitespace()
        .filter(|w| *w != "//")
        .collect::<Vec<_>>()
        .join(" ")
}

#[test]
fn every_default_harvester_scenario_holds_against_the_firmware_harvester() {
    let files = on_the_default_harvester();
    assert!(files.len() >= 16, "the default harvester's scenarios: {files:?}");
    let mut wrong = Vec::new();
    for file in &files {
        let path = root().join("configs/scenarios").join(file);
        let loaded = scenario::load_with(&path, None, None, Some(&firmware_config()))
            .unwrap_or_else(|e| panic!("{file} against the firmware harvester: {e}"));
        assert_eq!(
            loaded.harvester.firmware.len(),
            20,
            "{file}: every field node is firmware"
        );
        let text = words(&std::fs::read_to_string(&path).unwrap());
        let outcome = scenario::run(&loaded, None, |_| {}).unwrap_or_else(|e| panic!("{file}: {e}"));
        for (k, v) in outcome.verdicts.iter().enumerate() {
            let excepted = NOT_FOR_FIRMWARE.iter().find(|(f, i, _)| f == file && *i == k);
            match (excepted, v.passed) {
                (None, false) => wrong.push(format!("{file} #{k}: {} -> {}", v.expectation, v.observed)),
                (Some(_), true) => wrong.push(format!(
                    "{file} #{k} is listed as not holding for firmware, but holds: {}",
                    v.expectation
                )),
                (Some((_, _, why)), false) => assert!(
                    text.contains(&words(why)),
                    "{file} does not say why #{k} does not hold for firmware: \"{why}\""
                ),
                (None, true) => {}
            }
        }
    }
    assert!(wrong.is_empty(), "{wrong:#?}");
}

/// `harvemu campaign harvest --config configs/harvester-firmware.ron`: random faults against
/// the firmware harvester, every run passing.
#[test]
fn the_harvest_campaign_runs_against_the_firmware_harvester() {
    let c = Campaign::open(
        &root().join("configs/campaigns/harvest.ron"),
        None,
        Some(&firmware_config()),
    )
    .unwrap();
    assert_eq!(c.base.harvester.firmware.len(), 20);
    let mut failed = Vec::new();
    let done = play(&c, Shard { k: 1, m: 1 }, 4, 2, 0, |r| {
        if let Some(f) = &r.failure {
            failed.push(format!("run {} (seed {}): {}", r.run, r.seed, f.expectation));
        }
        true
    })
    .unwrap();
    assert_eq!(done, 4);
    assert!(failed.is_empty(), "{failed:#?}");
}
