//! `harvemu run --tui` refuses to draw into something that is not a terminal.

use std::path::Path;
use std::process::Command;

#[test]
fn tui_without_a_terminal_is_bad_input() {
    // `output()` gives the child pipes, not a terminal.
    let out = Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .args(["run", "--tui", "--fast", "--for", "1s"])
        .output()
        .expect("run harvemu");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("--tui needs a terminal"), "{err}");
    assert_eq!(err.lines().count(), 1, "one line, before anything runs: {err}");
    assert!(out.stdout.is_empty());
}
