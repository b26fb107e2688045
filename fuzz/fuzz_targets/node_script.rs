//! Node script loading (`nodes::script::from_text`, which `load` uses): every problem names the
//! file, and a script that loads writes back to RON that loads to the same script.
#![no_main]

use libfuzzer_sys::fuzz_target;
use nodes::environment::PlantSignals;
use nodes::script::from_text;

const FILE: &str = "configs/nodes/fuzz.ron";

fuzz_target!(|input: &[u8]| {
    let Ok(text) = std::str::from_utf8(input) else {
        return;
    };
    match from_text(FILE, text, &PlantSignals) {
        Ok(script) => {
            let written = ron::to_string(&script).expect("a script serializes");
            let again = from_text(FILE, &written, &PlantSignals)
                .unwrap_or_else(|e| panic!("a loaded script, written back, fails: {e}\n{written}"));
            // Compared as text: NaN is not equal to itself.
            assert_eq!(ron::to_string(&again).expect("a script serializes"), written);
        }
        Err(nodes::Error::Invalid(problems)) => {
            assert!(!problems.is_empty());
            assert!(problems.iter().all(|p| p.file == FILE), "{problems:?}");
        }
        Err(e) => panic!("no file is read, yet {e}"),
    }
});
