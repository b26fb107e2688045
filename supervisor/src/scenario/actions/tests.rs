//! Faults reach nodes through the node interface: a node whose logic cannot take one refuses it,
//! and the run ends with an error naming the step, the node and the fault.

use crate::harvester::Harvester;
use crate::scenario::{Act, Loaded, Todo, from_text, run};
use bus::engine::NodeId;
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
        // The resolved form is changed, past the validation.
        match &mut l.plan.todo[step].1 {
            Todo::Act {
                act: Act::Inject { node, .. },
                index,
                ..
            } if *index == step => *node = "F5".into(),
            other => panic!("{other:?}"),
        }
        let Err(e) = run(&l, None, |_| {}) else {
            panic!("timeline[{step}] on F5 ran without an error");
        };
        assert!(matches!(e, crate::Error::BadInput(_)), "not bad input: {e:?}");
        assert_eq!(e.to_string(), *expected);
    }
}

/// Scenarios are resolved against the ids the harvester's nodes are planned to take on the bus
/// ([`Harvester::node_ids`]): they must be the ids assembly gives them, for scripts, the monitor
/// and firmware nodes with several chips alike.
#[test]
fn nodes_take_the_ids_the_plan_gives_them() {
    use crate::configs::Source;
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    for config in [
        "configs/harvester.ron",
        "configs/harvester-firmware-c0.ron",
        "configs/firmware/irq_lab.ron",
    ] {
        let h = Harvester::open(&Source::file(root.join(config))).unwrap();
        let system = actix::System::with_tokio_rt(|| bus_runtime::hub::runtime(true).unwrap());
        let running = system
            .block_on(crate::harvester::start(&h, false, Vec::new()))
            .unwrap();
        assert_eq!(running.node_ids(), h.node_ids(), "{config}");
        assert!(h.node_ids().len() > 1, "{config}");
    }
    // A node with two chips takes two ids: the node after it takes the third.
    let dir = std::env::temp_dir().join(format!("harvemu-ids-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(
        root.join("configs/firmware/can_seed.hex"),
        dir.join("can_seed.hex"),
    )
    .unwrap();
    std::fs::copy(root.join("configs/firmware/sender.ron"), dir.join("sender.ron")).unwrap();
    let two = r#"Firmware(name: "TWO", image: "can_seed.hex", entry: Some(0x4000),
        cpu: I80C51(clock_hz: 12000000),
        controllers: [Sja1000(base: 0xD300, xtal_hz: 6000000, irq: None),
                      Sja1000(base: 0xD400, xtal_hz: 6000000, irq: None)])"#;
    std::fs::write(dir.join("two.ron"), two).unwrap();
    let lab = r#"Network(name: "ids", bitrate: 30000, nodes: ["two.ron", "sender.ron"])"#;
    std::fs::write(dir.join("lab.ron"), lab).unwrap();
    let h = Harvester::open(&Source::file(dir.join("lab.ron"))).unwrap();
    let system = actix::System::with_tokio_rt(|| bus_runtime::hub::runtime(true).unwrap());
    let running = system
        .block_on(crate::harvester::start(&h, false, Vec::new()))
        .unwrap();
    let expected = vec![("TWO".to_string(), NodeId(0)), ("SENDER".to_string(), NodeId(2))];
    assert_eq!((running.node_ids(), h.node_ids()), (expected.clone(), expected));
    std::fs::remove_dir_all(&dir).unwrap();
}
