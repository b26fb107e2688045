//! Scenario loading (`scenario::from_text`, which `scenario::load` uses) on the real harvester:
//! problems name the scenario, a scenario that loads carries its seed and cruise start into the
//! harvester, its frames parse, and written back to RON it loads the same.
#![no_main]

use harvemu_fuzz::harvester;
use libfuzzer_sys::fuzz_target;
use std::path::Path;
use supervisor::harvester::Harvester;
use supervisor::scenario::{self, Action, Loaded};

const FILE: &str = "configs/scenarios/fuzz.ron";

/// The real harvester for `../harvester.ron` (however it is spelled), nothing else.
fn config(path: &Path) -> Result<Harvester, nodes::Error> {
    if path.file_name().is_some_and(|n| n == "harvester.ron") {
        Ok(harvester().clone())
    } else {
        Err(nodes::Error::Io {
            path: path.display().to_string(),
            source: std::io::ErrorKind::NotFound.into(),
        })
    }
}

fuzz_target!(|input: &[u8]| {
    let Some((&seed_byte, rest)) = input.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(rest) else {
        return;
    };
    // Half the runs override the seed, as `--seed` does.
    let seed = (seed_byte & 1 == 1).then_some(u64::from(seed_byte));
    match scenario::from_text(Path::new(FILE), text, seed, config) {
        Ok(loaded) => {
            check(&loaded, seed);
            let written = ron::to_string(&loaded.scenario).expect("a scenario serializes");
            let again = scenario::from_text(Path::new(FILE), &written, seed, config)
                .unwrap_or_else(|e| panic!("a loaded scenario, written back, fails: {e}\n{written}"));
            assert_eq!(ron::to_string(&again.scenario).expect("serializes"), written);
        }
        Err(nodes::Error::Invalid(problems)) => {
            assert!(!problems.is_empty());
            assert!(problems.iter().all(|p| p.file == FILE), "{problems:?}");
        }
        Err(nodes::Error::Io { path, .. }) => assert!(!path.ends_with("harvester.ron")),
    }
});

fn check(l: &Loaded, seed: Option<u64>) {
    let s = &l.scenario;
    let h = &l.harvester;
    let want = seed.or(s.seed).unwrap_or(harvester().config.network.seed);
    assert_eq!(h.config.network.seed, want);
    if let Some(c) = s.cruise_start_s {
        assert_eq!(
            h.config.monitor.cruise.start_s.map(f64::to_bits),
            Some(c.to_bits())
        );
    }
    assert!(s.duration_s.is_finite() && s.duration_s > 0.0);
    for step in &s.timeline {
        assert!(step.at_s >= 0.0 && step.at_s <= s.duration_s);
        if let Action::Babble { frame, .. } | Action::SendFrame { frame, .. } = &step.action {
            assert!(bus::candump::parse_frame(frame).is_ok(), "{frame}");
        }
        // A disturbance that loads names a place some frame can have, for a time it can last.
        if let Action::Disturb { field, bit, bits, .. } = &step.action {
            assert!(*bit < field.max_bits(), "{field:?} bit {bit}");
            assert!((1..=4096).contains(bits), "{bits} bit times");
        }
    }
}
