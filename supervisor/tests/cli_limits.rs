//! Input too large to hold: `/dev/zero` or an oversized file as a trace, a config, a node script
//! or a scenario ends at once with a short error and exit code 2. Each command runs with its
//! address space limited to 1 GiB, so that reading without a limit fails the test (the
//! allocation fails) instead of eating the machine.

mod common;

use common::scratch;
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

/// The size limit of configs, scripts and scenarios, as documented (1 MiB).
const MAX_FILE: usize = 1024 * 1024;

/// Runs `harvemu` from the repository root with at most 1 GiB of address space.
fn bounded(args: &[&str]) -> (Output, Duration) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_harvemu"));
    cmd.current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .args(args);
    // SAFETY: setrlimit is async-signal-safe and touches nothing of the parent's state.
    unsafe {
        cmd.pre_exec(|| {
            let gib = 1 << 30;
            let limit = libc::rlimit {
                rlim_cur: gib,
                rlim_max: gib,
            };
            if libc::setrlimit(libc::RLIMIT_AS, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let start = Instant::now();
    let out = cmd.output().expect("run harvemu");
    (out, start.elapsed())
}

/// Exit code 2, within `secs`, with one short error line that contains `words`.
fn refused(args: &[&str], words: &str) {
    let (out, took) = bounded(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
    assert!(took < Duration::from_secs(10), "{args:?} took {took:?}");
    assert!(err.contains(words), "{args:?}: {err}");
    let lines: Vec<&str> = err.trim_end().lines().collect();
    assert!(lines.len() <= 2, "{args:?}: {err}");
    for l in lines {
        assert!(l.chars().count() <= 200, "{args:?}: {} characters: {l}", l.len());
    }
}

/// A device or a pipe as the trace is refused before it is read: replay reads its trace twice,
/// and a pipe would be drained by the check, leaving nothing to play (it then sent no frame and
/// exited 0). An endless line in a regular file is the line limit's (below).
#[test]
fn dev_zero_or_a_pipe_as_a_trace_ends_at_once() {
    let words = "not a regular file (a pipe, a FIFO or a device): replay reads its trace twice";
    refused(&["replay", "/dev/zero", "--fast"], &format!("/dev/zero: {words}"));
    let out = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "printf '(0.000000) harv0 0300A0F5#0101\\n' | {} replay /dev/stdin --fast",
            env!("CARGO_BIN_EXE_harvemu")
        ))
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains(&format!("/dev/stdin: {words}")), "{err}");
}

#[test]
fn dev_zero_as_a_config_a_script_or_a_scenario_ends_at_once() {
    let limit = "larger than 1 MiB (1048576 bytes)";
    refused(
        &["run", "/dev/zero", "--fast", "--for", "1s"],
        &format!("/dev/zero: {limit}"),
    );
    refused(&["validate", "/dev/zero"], &format!("/dev/zero: {limit}"));
    refused(&["scenario", "/dev/zero"], &format!("/dev/zero: {limit}"));
    refused(
        &["replay", "/dev/zero", "--config", "/dev/zero"],
        &format!("/dev/zero: {limit}"),
    );
    // A harvester config naming /dev/zero as a node script.
    let dir = scratch("cli_limits", "script");
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs");
    let text = std::fs::read_to_string(root.join("harvester.ron"))
        .unwrap()
        .replace("\"nodes/e0.ron\"", "\"/dev/zero\"")
        .replace("\"nodes/", &format!("\"{}/nodes/", root.display()));
    let config = dir.join("harvester.ron");
    std::fs::write(&config, text).unwrap();
    let config = config.to_str().unwrap();
    refused(
        &["validate", config],
        &format!("nodes[0]: cannot read /dev/zero: {limit}"),
    );
    refused(
        &["run", config, "--fast", "--for", "1s"],
        &format!("nodes[0]: cannot read /dev/zero: {limit}"),
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `text` with a `//` comment added at its end so that it is exactly `len` bytes.
fn padded(text: &str, len: usize) -> String {
    let comment = "\n// ";
    let fill = len - text.len() - comment.len() - 1;
    let out = format!("{text}{comment}{}\n", "p".repeat(fill));
    assert_eq!(out.len(), len);
    out
}

#[test]
fn a_file_of_the_limit_is_read_one_byte_more_is_refused() {
    let dir = scratch("cli_limits", "sizes");
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs");
    let harvester = std::fs::read_to_string(root.join("harvester.ron"))
        .unwrap()
        .replace("\"nodes/", &format!("\"{}/nodes/", root.display()));
    let scenario = std::fs::read_to_string(root.join("scenarios/crash.ron"))
        .unwrap()
        .replace(
            "Scenario(\n",
            &format!("Scenario(\n    config: \"{}/harvester.ron\",\n", root.display()),
        );
    let script = std::fs::read_to_string(root.join("nodes/a0.ron")).unwrap();
    for (name, text, kind) in [
        ("harvester.ron", harvester, "harvester config"),
        ("scenario.ron", scenario, "scenario"),
        ("a0.ron", script, "node script"),
    ] {
        let file = dir.join(name);
        let path = file.to_str().unwrap();
        std::fs::write(&file, padded(&text, MAX_FILE)).unwrap();
        let out = common::harvemu(&["validate", path]);
        let said = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert_eq!(said.trim_end(), format!("{path}: ok ({kind})"));
        std::fs::write(&file, padded(&text, MAX_FILE + 1)).unwrap();
        refused(
            &["validate", path],
            &format!("{path}: larger than 1 MiB (1048576 bytes), the limit for an input file"),
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn an_over_long_trace_line_is_named_and_quoted_short() {
    let dir = scratch("cli_limits", "line");
    let log = dir.join("long.log");
    // One good frame, then a 100 MB line.
    let mut text = b"(1.000000) can0 123#00\n(1.000001) can0 123#".to_vec();
    text.resize(text.len() + 100_000_000, b'A');
    text.extend_from_slice(b"\n(1.000002) can0 123#01\n");
    std::fs::write(&log, text).unwrap();
    let path = log.to_str().unwrap();
    refused(
        &["replay", path, "--fast"],
        &format!(
            "{path}:2: longer than 65536 bytes, the limit for a trace line: '(1.000001) can0 123#AAAAAAAAAAAAAAAAAAAA…'"
        ),
    );
    // A token of the limit's length within a line: the error quotes 40 characters of it.
    let asc = dir.join("long.asc");
    let token = "Z".repeat(60_000);
    std::fs::write(
        &asc,
        format!("base hex  timestamps absolute\n1.0 1 {token} Rx d 1 00\n"),
    )
    .unwrap();
    let path = asc.to_str().unwrap();
    refused(
        &["replay", path, "--fast"],
        &format!("{path}:2: '1.0 1 {}…'", "Z".repeat(34)),
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn long_names_in_configs_scripts_and_scenarios_are_quoted_short() {
    let dir = scratch("cli_limits", "names");
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs");
    let long = "N".repeat(100_000);
    let scenario = std::fs::read_to_string(root.join("scenarios/crash.ron"))
        .unwrap()
        .replace(
            "Scenario(\n",
            &format!("Scenario(\n    config: \"{}/harvester.ron\",\n", root.display()),
        )
        .replace("Crash(\"D3\")", &format!("Crash(\"{long}\")"));
    let script = std::fs::read_to_string(root.join("nodes/a0.ron")).unwrap();
    let unknown_field = script.replacen("NodeScript(", &format!("NodeScript(\n    {long}: 1,"), 1);
    let cut = "N".repeat(40);
    for (name, text, words) in [
        (
            "scenario.ron",
            scenario,
            format!("unknown node '{cut}…' (nodes: "),
        ),
        ("field.ron", unknown_field, format!("`{cut}…`")),
    ] {
        let file = dir.join(name);
        std::fs::write(&file, text).unwrap();
        let out = common::harvemu(&["validate", file.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains(&words), "{name}: {err}");
        for l in err.lines() {
            assert!(l.chars().count() < 400, "{name}: {} characters: {l}", l.len());
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `campaign merge` reads at most 64 MiB of a shard's summary.json (PROMISES.md): `/dev/zero`
/// in its place is refused at once, naming the file and the limit, within the 1 GiB address
/// space (reading up to a gigabyte, as before, fails here).
#[test]
fn dev_zero_as_a_campaign_summary_ends_at_once() {
    let dir = scratch("cli_limits", "summary");
    let shard = dir.join("shard-1");
    std::fs::create_dir_all(&shard).unwrap();
    let summary = shard.join("summary.json");
    let _ = std::fs::remove_file(&summary);
    std::os::unix::fs::symlink("/dev/zero", &summary).unwrap();
    let out = dir.join("merged");
    refused(
        &[
            "campaign",
            "merge",
            shard.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        &format!(
            "{}: larger than 64 MiB (67108864 bytes), the limit for a campaign summary",
            summary.display()
        ),
    );
    assert!(!out.join("summary.json").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}
