//! What the command-line tests share: running the binary from the repository root, and a
//! private scratch directory per test.

#![allow(dead_code)] // each test file uses what it needs

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `harvemu` with `args` from the repository root (so `configs/...` paths work).
pub fn harvemu(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .args(args)
        .output()
        .expect("run harvemu")
}

/// A private, empty directory named after the test file (`suite`), the test (`tag`) and the
/// process, so that parallel tests and runs never share one.
pub fn scratch(suite: &str, tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("harvemu-{suite}-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create a scratch directory");
    dir
}
