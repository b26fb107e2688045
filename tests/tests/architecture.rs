//! docs/ARCHITECTURE.md stays true: every path it names (in backticks, under one of the
//! workspace's top-level folders) exists, every `Type::function` it names is a function defined
//! in the workspace's sources, and a function named right after a file (`` `file.rs`, `name` ``)
//! is defined in that file.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The text between backticks, in order.
fn quoted(text: &str) -> Vec<&str> {
    text.split('`').skip(1).step_by(2).collect()
}

const TOP: [&str; 6] = ["bus/", "nodes/", "supervisor/", "tests/", "configs/", "fuzz/"];

fn sources(dir: &Path, out: &mut String) {
    for e in std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let path = e.expect("a directory entry").path();
        if path.is_dir() {
            if path.file_name().is_some_and(|n| n == "target") {
                continue;
            }
            sources(&path, out);
        } else if path.extension().is_some_and(|x| x == "rs") {
            out.push_str(&std::fs::read_to_string(&path).expect("a source file"));
        }
    }
}

#[test]
fn every_path_and_function_the_architecture_names_exists() {
    let doc = std::fs::read_to_string(root().join("docs/ARCHITECTURE.md")).unwrap();
    let names = quoted(&doc);
    let paths: Vec<&str> = names
        .iter()
        .copied()
        .filter(|n| TOP.iter().any(|t| n.starts_with(t)) && !n.contains(' '))
        .collect();
    assert!(paths.len() >= 30, "the architecture names few paths: {paths:?}");
    let missing: Vec<&&str> = paths.iter().filter(|p| !root().join(p).exists()).collect();
    assert!(
        missing.is_empty(),
        "docs/ARCHITECTURE.md names paths that do not exist: {missing:?}"
    );

    let mut code = String::new();
    for top in ["bus", "nodes", "supervisor"] {
        sources(&root().join(top), &mut code);
    }
    let functions: Vec<&str> = names
        .iter()
        .copied()
        .filter(|n| n.contains("::") && !n.contains('/'))
        .collect();
    assert!(functions.len() >= 4, "{functions:?}");
    let unknown: Vec<&&str> = functions
        .iter()
        .filter(|f| {
            let name = f.rsplit("::").next().unwrap_or_default();
            !code.contains(&format!("fn {name}(")) && !code.contains(&format!("fn {name}<"))
        })
        .collect();
    assert!(
        unknown.is_empty(),
        "docs/ARCHITECTURE.md names functions nobody defines: {unknown:?}"
    );

    let mut in_file = Vec::new();
    for pair in doc.split("`, `").collect::<Vec<_>>().windows(2) {
        let file = pair[0].rsplit('`').next().unwrap_or_default();
        let name = pair[1].split('`').next().unwrap_or_default();
        if file.ends_with(".rs") && name.chars().all(|c| c.is_ascii_lowercase() || c == '_') {
            in_file.push((file, name));
        }
    }
    assert!(in_file.len() >= 3, "{in_file:?}");
    for (file, name) in in_file {
        let text = std::fs::read_to_string(root().join(file)).unwrap_or_default();
        assert!(
            text.contains(&format!("fn {name}(")),
            "docs/ARCHITECTURE.md says {file} has `{name}`, which it does not define"
        );
    }
}

#[test]
fn a_missing_path_would_be_seen() {
    let names = quoted("see `bus/src/nowhere.rs` and `Bus::submit`");
    assert_eq!(names, ["bus/src/nowhere.rs", "Bus::submit"]);
    assert!(!root().join(names[0]).exists());
}
