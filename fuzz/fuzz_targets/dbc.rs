//! A DBC file's text (`protocol::database::Database::parse`, as `harvemu import` reads it): no
//! panic; an error names the file with a line and column inside the text (or none); what
//! parses, written back with `to_dbc` and parsed again, gives as many messages. Inputs over
//! 4 KiB are left out.
#![no_main]

use libfuzzer_sys::fuzz_target;
use protocol::database::{Database, Written};
use std::collections::BTreeMap;

/// Longer inputs are left out: the parser's time grows with the text, and a few messages say
/// all a longer file would.
const MAX_INPUT: usize = 4096;

fuzz_target!(|input: &[u8]| {
    if input.len() > MAX_INPUT {
        return;
    }
    let text = protocol::database::text_of(input);
    match Database::parse("f.dbc", &text) {
        Err(e) => {
            let e = e.to_string();
            assert!(e.starts_with("f.dbc:"), "{e}");
            if let Some((line, _)) = e["f.dbc:".len()..].split_once(':')
                && let Ok(line) = line.parse::<usize>()
            {
                assert!(line <= text.lines().count() + 1, "{e}");
            }
        }
        Ok(db) => {
            // What every message says it holds runs without a panic.
            for m in &db.messages {
                let _ = m.encode(&BTreeMap::new());
            }
            let cycles: BTreeMap<String, u32> = db
                .messages
                .iter()
                .filter_map(|m| Some((m.name.clone(), m.cycle_ms?)))
                .collect();
            let written = db.to_dbc(&Written {
                name: "f",
                bitrate: 250_000,
                cycles: &cycles,
            });
            // Names the writer cannot say again (a value table's quote, a unit's) may stop a
            // second reading; when it reads, it is the same.
            if let Ok(again) = Database::parse("f.dbc", &written) {
                assert_eq!(again.messages.len(), db.messages.len(), "{written}");
            }
        }
    }
});
