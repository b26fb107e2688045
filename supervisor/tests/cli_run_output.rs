//! What `harvemu run` prints when stderr is not a terminal (a pipe here, as in a log file or CI):
//! plain lines at a steady pace, no carriage returns or escape sequences, the closing summary
//! once, also after Ctrl-C; and `--seed`.

mod common;

use common::{harvemu, scratch};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The summary lines of a run's stderr (they start with the bus time).
fn summaries(stderr: &str) -> Vec<&str> {
    stderr.lines().filter(|l| l.starts_with("t=")).collect()
}

/// The bus time a summary line starts with, in seconds.
fn time_of(line: &str) -> f64 {
    line.strip_prefix("t=")
        .and_then(|l| l.split_once(" s"))
        .and_then(|(t, _)| t.parse().ok())
        .unwrap_or_else(|| panic!("no time in {line:?}"))
}

#[test]
fn piped_output_is_plain_lines_every_ten_seconds_and_one_closing_summary() {
    let out = harvemu(&["run", "--fast", "--for", "35s"]);
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(out.status.success(), "{err}");
    assert!(!err.contains('\r'), "no carriage return in a pipe: {err:?}");
    assert!(!err.contains('\x1b'), "no escape sequence in a pipe: {err:?}");
    let lines = summaries(&err);
    let times: Vec<f64> = lines.iter().map(|l| time_of(l)).collect();
    assert_eq!(times, [10.0, 20.0, 30.0, 35.0], "{err}");
    for l in &lines {
        assert!(l.len() < 200, "a line of {} characters: {l}", l.len());
        for field in ["frames ", "load ", "harvested ", "not active "] {
            assert!(l.contains(field), "{field:?} in {l}");
        }
    }
}

#[test]
fn ctrl_c_ends_a_real_time_run_with_one_summary() {
    let child = Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .args(["run", "--for", "60s"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start harvemu");
    std::thread::sleep(Duration::from_millis(2500));
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("run kill");
    assert!(kill.success());
    let started = Instant::now();
    let out = child.wait_with_output().unwrap();
    assert!(
        started.elapsed() < Duration::from_secs(20),
        "harvemu stopped on SIGINT"
    );
    let err = String::from_utf8(out.stderr).unwrap();
    assert_eq!(out.status.code(), Some(130), "exit code 130 after SIGINT: {err}");
    assert_eq!(err.matches("harvemu: interrupted").count(), 1, "{err}");
    let lines = summaries(&err);
    assert_eq!(lines.len(), 1, "one summary, after the interruption: {err}");
    assert!(err.find("harvemu: interrupted") < err.find(lines[0]), "{err}");
    let t = time_of(lines[0]);
    assert!((1.0..10.0).contains(&t), "{err}");
    assert!(!err.contains('\r'), "{err:?}");
}

#[test]
fn seed_overrides_the_configs_seed() {
    let dir = scratch("cli-run-output", "seed");
    let record = |name: &str, seed: Option<&str>| {
        let path = dir.join(name);
        let mut args = vec!["run", "--fast", "--for", "3s", "--record", path.to_str().unwrap()];
        if let Some(seed) = seed {
            args.extend(["--seed", seed]);
        }
        let out = harvemu(&args);
        let err = String::from_utf8(out.stderr).unwrap();
        assert!(out.status.success(), "{err}");
        let said = format!("seed {}", seed.unwrap_or("2011"));
        (std::fs::read_to_string(path).unwrap(), err.contains(&said))
    };
    let config_seed =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/harvester.ron"))
            .unwrap();
    assert!(
        config_seed.contains("seed: 2011,"),
        "the default config's seed is 2011"
    );
    let (a, a_said) = record("a.log", Some("7"));
    let (b, _) = record("b.log", Some("7"));
    let (c, c_said) = record("c.log", Some("8"));
    let (default, default_said) = record("default.log", None);
    assert!(a_said && c_said && default_said, "the seed in use is printed");
    assert_eq!(a, b, "the same seed, the same bus");
    assert_ne!(a, c, "another seed, another bus");
    assert_ne!(a, default, "--seed replaces the config's seed");
    let bad = harvemu(&["run", "--seed", "x"]);
    assert_eq!(bad.status.code(), Some(2));
}

/// Diagnostics (`RUST_LOG`) on a stderr that is not a terminal are plain text: a log file or a
/// CI job's output gets no colour escape sequences (tracing's default wrote them everywhere).
#[test]
fn diagnostics_in_a_log_carry_no_escape_sequences() {
    let out = Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .args(["run", "--fast", "--for", "0.3s"])
        .env("RUST_LOG", "trace")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(
        err.lines().any(|l| l.contains(" TRACE ")),
        "no diagnostics at all"
    );
    assert!(
        !err.contains('\u{1b}'),
        "escape sequences in: {}",
        &err[..err.len().min(500)]
    );
}
