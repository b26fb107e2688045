//! `harvemu run` as a user runs it: the default harvester in virtual time, a recorded trace, and
//! configs with mistakes.

mod common;

use common::harvemu;
use std::path::{Path, PathBuf};

/// A private copy of `configs/` to break.
fn configs_copy(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("harvemu-cli-run-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("nodes")).unwrap();
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs");
    std::fs::copy(src.join("harvester.ron"), dir.join("harvester.ron")).unwrap();
    common::copy_dir(&src.join("nodes"), &dir.join("nodes"));
    dir
}

#[test]
fn runs_the_default_harvester_and_records_it() {
    let dir = configs_copy("record");
    let log = dir.join("run.log");
    let out = harvemu(&["run", "--fast", "--for", "5s", "--record", log.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let trace = std::fs::read_to_string(&log).unwrap();
    let lines: Vec<&str> = trace.lines().collect();
    assert!(lines.len() > 1000, "{} lines", lines.len());
    // Every line is a candump log line on harv0 with a time inside the run.
    for l in &lines {
        let (time, rest) = l
            .strip_prefix('(')
            .and_then(|l| l.split_once(") harv0 "))
            .expect(l);
        // Virtual time is stamped from 2024-01-01T00:00:00Z, 1704067200 s after 1970.
        let t: f64 = time.parse::<f64>().unwrap() - 1_704_067_200.0;
        assert!((0.5..=5.0).contains(&t), "{l}");
        assert!(bus::candump::parse_frame(rest).is_ok(), "{l}");
    }
    assert!(
        trace.contains(" harv0 0601F5D0#200D0002FFBFFF00"),
        "D0's flow marker is there"
    );
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("harvested"), "a closing summary: {err}");
}

#[test]
fn every_problem_of_a_bad_config_is_listed_and_nothing_runs() {
    let dir = configs_copy("bad");
    let b1 = dir.join("nodes/b1.ron");
    let text = std::fs::read_to_string(&b1)
        .unwrap()
        .replace("engine.rpm", "engine.rmp")
        .replace(r#""period_ms": 100"#, r#""period_ms": 0"#);
    std::fs::write(&b1, text).unwrap();
    let c2 = dir.join("nodes/c2.ron");
    std::fs::write(
        &c2,
        std::fs::read_to_string(&c2)
            .unwrap()
            .replace(r#""address": 0xC2"#, r#""address": 0xC9"#),
    )
    .unwrap();
    let log = dir.join("never.log");
    let out = harvemu(&[
        "run",
        dir.join("harvester.ron").to_str().unwrap(),
        "--fast",
        "--for",
        "1s",
        "--record",
        log.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    for needle in [
        "b1.ron: node B1: messages[0] (parameters).frames[0].fields.engine_rpm: unknown plant signal 'engine.rmp'",
        "b1.ron: node B1: messages[0] (parameters).when: period 0",
        "c2.ron: node C2: address: 0xC9 is not a harvester address",
    ] {
        assert!(err.contains(needle), "missing {needle} in:\n{err}");
    }
    assert!(!log.exists(), "nothing was started");
    // A syntax error has its line and column.
    std::fs::write(
        dir.join("harvester.ron"),
        "Harvester(\n  name: \"x\",\n  bitrat: 250000,\n)",
    )
    .unwrap();
    let out = harvemu(&[
        "run",
        dir.join("harvester.ron").to_str().unwrap(),
        "--fast",
        "--for",
        "1s",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("harvester.ron:3:"), "{err}");
}

#[test]
fn bad_durations_are_refused() {
    for bad in ["abc", "-5s", "10x"] {
        let out = harvemu(&["run", "--fast", "--for", bad]);
        assert_eq!(out.status.code(), Some(2), "{bad}");
    }
}

#[test]
fn a_config_given_by_its_path_works_from_anywhere() {
    let dir = common::scratch("cli-run", "elsewhere");
    let run = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_harvemu"))
            .current_dir(&dir)
            .args(args)
            .output()
            .unwrap()
    };
    // Node scripts are relative to the config, not to the working directory.
    let config = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/harvester.ron");
    let out = run(&["run", config.to_str().unwrap(), "--fast", "--for", "1s"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains(&format!("from {},", config.display())), "{err}");
    assert!(!err.contains("built in"), "{err}");
}
