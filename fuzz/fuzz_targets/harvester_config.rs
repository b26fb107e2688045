//! Harvester config loading (`Harvester::from_text`, which `Harvester::load` uses), with the real
//! node scripts served from memory: problems name a file, and a config that loads has one valid,
//! distinct script per entry and start-up times that can be computed.
#![no_main]

use harvemu_fuzz::{HARVESTER_PATH, script};
use libfuzzer_sys::fuzz_target;
use protocol::ident::Address;
use std::collections::BTreeSet;
use std::path::Path;
use supervisor::harvester::Harvester;

fuzz_target!(|input: &[u8]| {
    let Ok(text) = std::str::from_utf8(input) else {
        return;
    };
    match Harvester::from_text(Path::new(HARVESTER_PATH), text, script) {
        Ok(h) => {
            assert_eq!(h.scripts.len(), h.config.network.nodes.len());
            let addresses: BTreeSet<u8> = h.scripts.iter().map(|s| s.address).collect();
            assert_eq!(addresses.len(), h.scripts.len(), "distinct addresses");
            assert!(!addresses.contains(&Address::MONITOR.0));
            // The bus clock counts whole nanoseconds, so a bit must last a whole number of them.
            assert!((1..=1_000_000).contains(&h.config.network.bitrate));
            assert_eq!(3_456_000_000_000 % u64::from(h.config.network.bitrate), 0);
            assert!(h.config.monitor.calibration_samples >= 1);
            // `start` runs the bus to the time relay before the field nodes power up.
            let _ = h.relay();
        }
        Err(nodes::Error::Invalid(problems)) => {
            assert!(!problems.is_empty());
            assert!(
                problems.iter().all(|p| p.file.starts_with("configs/")),
                "{problems:?}"
            );
        }
        Err(e) => panic!("missing scripts are problems, yet {e}"),
    }
});
