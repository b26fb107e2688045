//! Faults reach nodes through the node interface: a node whose logic cannot take one refuses it,
//! and the run ends with an error naming the step, the node and the fault.

use crate::harvester::Harvester;
use crate::scenario::{Action, Loaded, from_text, run};
use nodes::Error;
use std::path::Path;

fn harvester(_: &Path) -> Result<Harvester, Error> {
    Harvester::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/harvester.ron"))
}

/// A short run with one sensor fault on a script node, B1.
fn loaded() -> Loaded {
    let text = r#"Scenario(name: "t", duration_s: 2.0, expect: [NoFrameLost], timeline: [
        (at_s: 1.0, action: SensorFault(node: "B1", signal: "engine.rpm", fault: Stuck(0.0))),
        (at_s: 1.5, action: SensorRepaired(node: "B1", signal: "engine.rpm")),
    ])"#;
    from_text(Path::new("t.ron"), text, None, harvester).unwrap()
}

#[test]
fn a_script_node_takes_sensor_faults() {
    let outcome = run(&loaded(), None, |_| {}).unwrap();
    assert_eq!(outcome.applied.values().sum::<u64>(), 2);
}

/// Validation keeps sensor faults off the monitor; past it, the monitor's logic still refuses
/// them, where a downcast to a script would have done nothing without a word.
#[test]
fn a_node_that_takes_no_faults_refuses_them_by_name() {
    let expected = [
        "t.ron: timeline[0]: node F5 refused the sensor fault Stuck(0.0) on engine.rpm: \
         its logic takes no injected faults",
        "t.ron: timeline[1]: node F5 refused the repair of the sensor of engine.rpm: \
         its logic takes no injected faults",
    ];
    for (step, expected) in expected.iter().enumerate() {
        let mut l = loaded();
        // Only this step reaches the monitor; the one before it (if any) goes to B1 as loaded.
        match &mut l.scenario.timeline[step].action {
            Action::SensorFault { node, .. } | Action::SensorRepaired { node, .. } => *node = "F5".into(),
            other => panic!("{other:?}"),
        }
        let Err(e) = run(&l, None, |_| {}) else {
            panic!("timeline[{step}] on F5 ran without an error");
        };
        assert!(matches!(e, crate::Error::BadInput(_)), "not bad input: {e:?}");
        assert_eq!(e.to_string(), *expected);
    }
}
