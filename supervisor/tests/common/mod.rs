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

/// Copies the directory `from` into `to`, subdirectories too (the node scripts' templates).
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("create a directory");
    for e in std::fs::read_dir(from).expect("read a directory") {
        let e = e.expect("a directory entry");
        let target = to.join(e.file_name());
        if e.file_type().expect("a file type").is_dir() {
            copy_dir(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), target).expect("copy a file");
        }
    }
}

/// The repository root, where `harvemu` runs in these tests.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Starts `harvemu` with `args` from the repository root, its output piped.
pub fn spawn(args: &[&str]) -> std::process::Child {
    Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(root())
        .args(args)
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("start harvemu")
}

/// Runs `harvemu` with `args` under a file-size limit of `bytes` (RLIMIT_FSIZE): a write that
/// would make a file longer fails with EFBIG, as on a full disk.
pub fn harvemu_limited(args: &[&str], bytes: u64) -> Output {
    use std::os::unix::process::CommandExt;
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_harvemu"));
    cmd.current_dir(root()).args(args);
    // SAFETY: setrlimit is async-signal-safe, as pre_exec asks.
    unsafe {
        cmd.pre_exec(move || {
            let limit = libc::rlimit {
                rlim_cur: bytes,
                rlim_max: bytes,
            };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    cmd.output().expect("run harvemu")
}

/// Sends `signal` to a running `harvemu`.
pub fn signal(child: &std::process::Child, signal: i32) {
    let pid = i32::try_from(child.id()).expect("a pid");
    // SAFETY: kill has no memory-safety requirements.
    assert_eq!(unsafe { libc::kill(pid, signal) }, 0, "kill {pid}");
}

/// Waits for `child` to end, at most `limit`; kills it and fails when it does not.
pub fn finish_within(mut child: std::process::Child, limit: std::time::Duration) -> Output {
    let started = std::time::Instant::now();
    while child.try_wait().expect("wait for harvemu").is_none() {
        if started.elapsed() > limit {
            let _ = child.kill();
            let out = child.wait_with_output().expect("harvemu's output");
            panic!(
                "harvemu still running after {limit:?}; stderr: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    child.wait_with_output().expect("harvemu's output")
}

/// The files in `dir`, by name, sorted.
pub fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("list a directory")
        .map(|e| e.expect("an entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// Starts `harvemu run --socketcand 127.0.0.1:0` with `args` after it, and waits for the line
/// "harvemu: socketcand gateway on ADDR, ..." on its standard error: the running child, to kill
/// when done, and ADDR. The rest of standard error is read on a thread, so that the child never
/// blocks on a full pipe.
pub fn socketcand_gateway(args: &[&str]) -> (std::process::Child, String) {
    use std::io::BufRead;
    let mut child = Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(root())
        .args(["run", "--socketcand", "127.0.0.1:0"])
        .args(args)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("start harvemu");
    let stderr = child.stderr.take().expect("harvemu's standard error");
    let mut lines = std::io::BufReader::new(stderr).lines();
    let addr = lines
        .by_ref()
        .map_while(Result::ok)
        .find_map(|l| {
            l.strip_prefix("harvemu: socketcand gateway on ")
                .and_then(|rest| rest.split(',').next())
                .map(str::to_string)
        })
        .expect("the gateway's address on stderr");
    std::thread::spawn(move || lines.for_each(drop));
    (child, addr)
}
