//! What the trace-format tests against python-can and asammdf share: the python to run them
//! with, and small conversions of their output.

#![allow(dead_code)] // each test file uses what it needs

use bus::{Id, extended_id, standard_id};
use serde_json::Value;
use std::process::Command;

/// `$HARVEMU_PYTHON`, else `python3`.
pub fn python() -> String {
    std::env::var("HARVEMU_PYTHON").unwrap_or_else(|_| "python3".to_string())
}

/// Runs `script` with `args` (in UTC, so that python-can's local start times are UTC); its
/// standard output. The python must import `modules` (`"can"`, `"can, asammdf"`): the test fails
/// naming HARVEMU_PYTHON when it cannot, never skips.
pub fn run_python(modules: &str, script: &str, args: &[&str]) -> String {
    let py = python();
    let check = Command::new(&py)
        .args(["-c", &format!("import {modules}")])
        .output();
    assert!(
        check.as_ref().is_ok_and(|o| o.status.success()),
        "`{py}` cannot `import {modules}` ({}): set HARVEMU_PYTHON to a python that has them",
        match &check {
            Ok(o) => String::from_utf8_lossy(&o.stderr)
                .lines()
                .last()
                .unwrap_or_default()
                .to_string(),
            Err(e) => e.to_string(),
        }
    );
    let out = Command::new(&py)
        .env("TZ", "UTC")
        .arg("-c")
        .arg(script)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run `{py}`: {e}"));
    assert!(
        out.status.success(),
        "the python script failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("UTF-8 output")
}

/// One JSON value per line.
pub fn json_lines(text: &str) -> Vec<Value> {
    text.lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{l}: {e}")))
        .collect()
}

/// An identifier from its raw value.
pub fn id(raw: u32, extended: bool) -> Id {
    if extended {
        extended_id(raw).unwrap().into()
    } else {
        standard_id(raw as u16).unwrap().into()
    }
}

/// Bytes as lower-case hex, as python's `bytes.hex()` writes them.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}
