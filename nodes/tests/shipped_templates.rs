//! The shipped node files that are template instances make exactly the scripts the files they
//! replaced held: `tests/data/before_templates/` keeps those files as they were, byte for byte.

use nodes::environment::PlantSignals;
use nodes::script::{load, parse};
use std::path::Path;

#[test]
fn every_instance_expands_to_the_script_it_replaced() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let before = root.join("tests/data/before_templates");
    let mut names: Vec<_> = std::fs::read_dir(&before)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    let expected: Vec<String> = ["b", "c", "d"]
        .iter()
        .zip([8, 4, 6])
        .flat_map(|(family, n)| (0..n).map(move |i| format!("{family}{i}.ron")))
        .collect();
    assert_eq!(names, expected, "one old file per rewritten node");
    for name in names {
        let path = root.join("../configs/nodes").join(&name);
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            text.contains("Instance(\n"),
            "{name} is an instance of a template"
        );
        let new = load(&path, &PlantSignals).unwrap_or_else(|e| panic!("{name}: {e}"));
        let old_text = std::fs::read_to_string(before.join(&name)).unwrap();
        assert!(old_text.contains("NodeScript(\n"), "{name} was a whole script");
        let old = parse(&name, &old_text).unwrap();
        assert_eq!(new, old, "{name}");
    }
}
