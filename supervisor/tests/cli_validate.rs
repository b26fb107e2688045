//! `harvemu validate` (and the loading of `run`) on configs and scripts that used to pass and
//! then break the run: exit code 2, every problem with file, node and field, nothing started.

mod common;

use common::harvemu;
use std::path::{Path, PathBuf};

fn nodes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/nodes")
}

/// B1's script with its engine speed bound to `expr` and its name set to `name`.
fn b1(expr: &str, name: &str) -> String {
    let text = std::fs::read_to_string(nodes_dir().join("b1.ron")).unwrap();
    let text = text.replace(
        r#""engine_rpm": Signal("engine.rpm")"#,
        &format!(r#""engine_rpm": {expr}"#),
    );
    let text = text.replace(r#""name": "B1""#, &format!(r#""name": {name:?}"#));
    assert!(text.contains(expr));
    text
}

#[test]
fn a_bad_script_gives_exit_2_naming_file_node_and_field() {
    let dir = common::scratch("cli-validate", "script");
    common::copy_dir(&nodes_dir().join("templates"), &dir.join("templates"));
    let file = dir.join("b1.ron");
    std::fs::write(
        &file,
        b1(
            r#"Clamp(Scaled(Signal("engine.rpm"), NaN, 0.0), 3000.0, 0.0)"#,
            "B1",
        ),
    )
    .unwrap();
    let out = harvemu(&["validate", file.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    let at = format!(
        "{}: node B1: messages[0] (parameters).frames[0].fields.engine_rpm: ",
        file.display()
    );
    for needle in [
        "Clamp min 3000 is above its max 0",
        "Scaled gain is NaN, not a finite number",
    ] {
        assert!(
            err.contains(&format!("{at}{needle}")),
            "missing {at}{needle} in:\n{err}"
        );
    }
}

/// Two nodes named B1 (the second at B2's address), a NUL in a name and a reaction time of
/// 2^64 − 1 µs: `validate` and `run` both refuse the config before anything runs.
#[test]
fn a_bad_harvester_config_gives_exit_2_for_validate_and_run() {
    let dir = common::scratch("cli-validate", "config");
    common::copy_dir(&nodes_dir().join("templates"), &dir.join("templates"));
    std::fs::write(dir.join("b2.ron"), {
        let text = std::fs::read_to_string(nodes_dir().join("b2.ron")).unwrap();
        text.replace(r#""name": "B2""#, r#""name": "B1""#)
    })
    .unwrap();
    std::fs::write(dir.join("b3.ron"), {
        let text = std::fs::read_to_string(nodes_dir().join("b3.ron")).unwrap();
        text.replace(r#""name": "B3""#, r#""name": "B\u{0}3""#)
    })
    .unwrap();
    let b1 = nodes_dir().join("b1.ron");
    let config = dir.join("harvester.ron");
    std::fs::write(
        &config,
        format!(
            r#"Harvester(name: "x", bitrate: 33300, seed: 1, time_relay_ms: 500,
                reaction_us: 18446744073709551615, nodes: [{:?}, "b2.ron", "b3.ron"])"#,
            b1.display().to_string()
        ),
    )
    .unwrap();
    let c = config.display();
    let expected = [
        format!(
            "{c}: bitrate: 33300 bit/s: a bit rate must be 10000 to 1000000 bit/s with a bit time the bus clock holds exactly"
        ),
        format!("{c}: reaction_us: 18446744073709551615 µs is over 1000000 µs (one second)"),
        format!(
            "{c}: node B1: nodes[1] (b2.ron): nodes[0] ({}) has the same name: every node needs a name of its own",
            b1.display()
        ),
        format!(
            "{}: node B\\03: name: \"B\\03\" holds the control character '\\0'",
            dir.join("b3.ron").display()
        ),
    ];
    for args in [
        vec!["validate", config.to_str().unwrap()],
        vec!["run", config.to_str().unwrap(), "--fast", "--for", "1s"],
    ] {
        let out = harvemu(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8(out.stderr).unwrap();
        for e in &expected {
            assert!(err.contains(e.as_str()), "{args:?}: missing {e} in:\n{err}");
        }
        // A message reads as one line of words: no runs of blanks from a broken continuation.
        for line in err.lines() {
            assert!(!line.trim_start().contains("  "), "{args:?}: {line}");
        }
    }
}

#[test]
fn one_problem_is_a_problem_and_two_are_problems() {
    let dir = common::scratch("cli-validate", "plural");
    let scenario = |name: &str, duration: &str| {
        let file = dir.join(name);
        std::fs::write(
            &file,
            format!("Scenario(name: \"x\", description: \"y\", duration_s: {duration}, expect: [])\n"),
        )
        .unwrap();
        file
    };
    let one = scenario("one.ron", "-1.0");
    let two = scenario("two.ron", "NaN");
    let err = |files: &[&Path]| {
        let mut args = vec!["validate"];
        args.extend(files.iter().map(|f| f.to_str().unwrap()));
        let out = harvemu(&args);
        assert_eq!(out.status.code(), Some(2));
        String::from_utf8(out.stderr).unwrap()
    };
    let text = err(&[&one]);
    assert!(text.starts_with("harvemu: error: 1 problem:\n"), "{text}");
    let text = err(&[&one, &two]);
    assert!(text.starts_with("harvemu: error: 2 problems:\n"), "{text}");
}
