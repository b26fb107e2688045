//! Node script loading (`nodes::script::from_text`, which `load` uses): every problem names the
//! file; a script that loads writes back to RON that loads to the same script, and runs for a
//! few steps sending only frames that the catalogue decodes as its own.
#![no_main]

use bus::node::NodeLogic;
use bus::time::BusTime;
use libfuzzer_sys::fuzz_target;
use nodes::environment::PlantSignals;
use nodes::script::{Environment, NodeScript, Port, ScriptedNode, SharedEnv, from_text};
use std::cell::RefCell;
use std::rc::Rc;

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
            run(script);
        }
        Err(nodes::Error::Invalid(problems)) => {
            assert!(!problems.is_empty());
            assert!(problems.iter().all(|p| p.file == FILE), "{problems:?}");
        }
        Err(e) => panic!("no file is read, yet {e}"),
    }
});

/// Every signal reads 1; writes are taken. (The real plant integrates in 10 ms steps, too slow
/// for times that a fuzzed script may jump to.)
struct Constant;

impl Environment for Constant {
    fn advance_to(&mut self, _: BusTime) {}
    fn port(&self, _: &str) -> Option<Port> {
        Some(Port(0))
    }
    fn read(&self, _: Port) -> Option<f64> {
        Some(1.0)
    }
    fn write(&mut self, _: Port, _: f64) -> bool {
        true
    }
}

fn run(script: NodeScript) {
    let address = script.address;
    let env: SharedEnv = Rc::new(RefCell::new(Constant));
    let mut node = ScriptedNode::new(script, env, BusTime::from_millis(500), 1);
    for _ in 0..50 {
        let Some(now) = node.poll_timeout() else {
            break;
        };
        node.handle_timeout(now);
        while let Some(frame) = node.poll_transmit() {
            let decoded = protocol::catalogue::decode(&frame)
                .unwrap_or_else(|e| panic!("{frame:?} does not decode: {e}"))
                .unwrap_or_else(|| panic!("{frame:?} is not a catalogue message"));
            assert_eq!(decoded.node.0, address);
        }
    }
}
