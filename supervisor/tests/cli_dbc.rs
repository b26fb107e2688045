//! `harvemu dbc` as a user runs it: standard output or a file, the config's cycle times, and
//! clear errors for paths that do not work.

mod common;

use common::harvemu;
use std::path::{Path, PathBuf};

fn scratch(tag: &str) -> PathBuf {
    common::scratch("cli-dbc", tag)
}

#[test]
fn the_file_holds_what_standard_output_shows() {
    let stdout = harvemu(&["dbc"]);
    assert!(
        stdout.status.success(),
        "{}",
        String::from_utf8_lossy(&stdout.stderr)
    );
    let text = String::from_utf8(stdout.stdout).unwrap();
    assert!(text.starts_with("VERSION \"\""));
    assert!(text.contains("\nBO_ 2197856501 row_command_A0: 2 F5\n"));

    let file = scratch("out").join("harvester.dbc");
    let out = harvemu(&["dbc", "-o", file.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.stdout.is_empty(), "nothing on standard output with -o");
    assert_eq!(std::fs::read_to_string(&file).unwrap(), text);
}

#[test]
fn cycle_times_come_from_the_config_given() {
    let dir = scratch("config");
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs");
    std::fs::create_dir_all(dir.join("nodes")).unwrap();
    std::fs::copy(src.join("harvester.ron"), dir.join("harvester.ron")).unwrap();
    common::copy_dir(&src.join("nodes"), &dir.join("nodes"));
    let b0 = dir.join("nodes/b0.ron");
    let script = std::fs::read_to_string(&b0).unwrap();
    assert!(script.contains(r#""period_ms": 100"#));
    std::fs::write(&b0, script.replace(r#""period_ms": 100"#, r#""period_ms": 40"#)).unwrap();
    let out = harvemu(&["dbc", "--config", dir.join("harvester.ron").to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    // B0 -> F5: 0x0500F5B0 with bit 31 set.
    assert!(text.contains("BA_ \"GenMsgCycleTime\" BO_ 2231432624 40;"));
}

#[test]
fn bad_paths_name_the_file_an_output_with_3_a_config_with_2() {
    let missing_dir = scratch("bad").join("no-such-dir").join("x.dbc");
    let out = harvemu(&["dbc", "-o", missing_dir.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(3));
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains(missing_dir.to_str().unwrap()), "{err}");
    assert!(!missing_dir.exists());

    let out = harvemu(&["dbc", "--config", "configs/no-such-harvester.ron"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("configs/no-such-harvester.ron"), "{err}");
    assert!(out.stdout.is_empty());
}
