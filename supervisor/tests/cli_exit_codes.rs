//! Exit codes that say what happened, and what a run stopped by a signal leaves: real signals
//! sent to the running binary. A signal is sent only after a wide margin (seconds), so that it
//! never arrives before harvemu handles signals; every wait has a generous limit.

mod common;

use common::{finish_within, harvemu, root, scratch, signal, spawn};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Far longer than any of these runs needs after its signal, even on a slow, loaded machine.
const LIMIT: Duration = Duration::from_secs(90);

/// A copy of the default harvester config in `dir`, with node scripts named by absolute path and
/// `edit` applied to its text.
fn config(dir: &Path, edit: impl Fn(String) -> String) -> PathBuf {
    let text = std::fs::read_to_string(root().join("configs/harvester.ron")).unwrap();
    let nodes = root().join("configs/nodes");
    let text = edit(text.replace("\"nodes/", &format!("\"{}/", nodes.display())));
    let path = dir.join("harvester.ron");
    std::fs::write(&path, text).unwrap();
    path
}

/// A scenario in `dir` far longer than the tests wait.
fn long_scenario(dir: &Path) -> PathBuf {
    let path = dir.join("long.ron");
    let config = root().join("configs/harvester.ron");
    std::fs::write(
        &path,
        format!(
            r#"Scenario(name: "a long run", config: "{}", duration_s: 36000.0, expect: [NoFrameLost])"#,
            config.display()
        ),
    )
    .unwrap();
    path
}

fn text(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The last two lines of an ASC: the interruption comment, then the footer.
fn assert_interrupted_asc(path: &Path, name: &str) {
    let asc = text(path);
    let lines: Vec<&str> = asc.lines().collect();
    assert!(lines[0].starts_with("date "), "an ASC header: {:?}", &lines[..2]);
    assert_eq!(lines.last(), Some(&"End TriggerBlock"), "the footer ends it");
    let comment = lines[lines.len() - 2];
    assert!(
        comment.starts_with(&format!("// harvemu: interrupted by {name}")),
        "{comment:?}"
    );
    assert!(asc.ends_with("End TriggerBlock\n"));
}

#[test]
fn sigterm_mid_scenario_finishes_trace_junit_and_report_and_exits_143() {
    let dir = scratch("cli-exit-codes", "term");
    let scenario = long_scenario(&dir);
    let (asc, xml, html) = (dir.join("t.asc"), dir.join("j.xml"), dir.join("r.html"));
    let child = spawn(&[
        "scenario",
        scenario.to_str().unwrap(),
        "--record",
        asc.to_str().unwrap(),
        "--junit",
        xml.to_str().unwrap(),
        "--report",
        html.to_str().unwrap(),
    ]);
    std::thread::sleep(Duration::from_secs(4));
    signal(&child, libc::SIGTERM);
    let out = finish_within(child, LIMIT);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(143), "{err}");
    assert!(err.contains("interrupted by SIGTERM"), "{err}");
    assert_interrupted_asc(&asc, "SIGTERM");
    let xml = text(&xml);
    assert!(xml.ends_with("</testsuites>\n"), "complete JUnit: {xml}");
    assert!(xml.contains("interrupted by SIGTERM"), "{xml}");
    let html = text(&html);
    assert!(html.trim_end().ends_with("</html>"), "a complete report");
    assert!(html.contains("(interrupted)"), "the report says so");
}

#[test]
fn sighup_stops_a_fast_run_with_129_and_a_finished_trace() {
    let dir = scratch("cli-exit-codes", "hup");
    let asc = dir.join("t.asc");
    let child = spawn(&["run", "--fast", "--for", "10h", "--record", asc.to_str().unwrap()]);
    std::thread::sleep(Duration::from_secs(3));
    signal(&child, libc::SIGHUP);
    let out = finish_within(child, LIMIT);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(129), "{err}");
    assert!(err.contains("harvemu: interrupted by SIGHUP"), "{err}");
    assert_interrupted_asc(&asc, "SIGHUP");
}

#[test]
fn for_and_sigint_are_honoured_before_the_field_nodes_start() {
    let dir = scratch("cli-exit-codes", "relay");
    // The time relay starts the field nodes after 100 s of bus time.
    let cfg = config(&dir, |t| {
        t.replace("time_relay_ms: 500,", "time_relay_ms: 100000,")
    });
    assert!(text(&cfg).contains("time_relay_ms: 100000,"));
    let cfg = cfg.to_str().unwrap();
    let out = finish_within(spawn(&["run", cfg, "--fast", "--for", "2s"]), LIMIT);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(err.contains("t=2.0 s"), "stopped at 2 s: {err}");
    // In real time, 1.5 s into a start-up of 100 s.
    let child = spawn(&["run", cfg, "--for", "20s"]);
    std::thread::sleep(Duration::from_millis(1500));
    let sent = std::time::Instant::now();
    signal(&child, libc::SIGINT);
    let out = finish_within(child, LIMIT);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(err.contains("harvemu: interrupted by SIGINT"), "{err}");
    // At once: well before the 20 s of --for, let alone the 100 s of the relay.
    assert!(sent.elapsed() < Duration::from_secs(15), "{:?}", sent.elapsed());
}

#[test]
fn bad_input_is_2_and_an_absurd_scenario_length_is_refused() {
    let dir = scratch("cli-exit-codes", "bad");
    let file = dir.join("forever.ron");
    std::fs::write(
        &file,
        format!(
            r#"Scenario(name: "forever", config: "{}", duration_s: 1e30, expect: [NoFrameLost])"#,
            root().join("configs/harvester.ron").display()
        ),
    )
    .unwrap();
    for command in ["validate", "scenario"] {
        let out = finish_within(spawn(&[command, file.to_str().unwrap()]), LIMIT);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{command}: {err}");
        assert!(err.contains(&file.display().to_string()), "{err}");
        assert!(err.contains("duration_s"), "{err}");
        assert!(err.contains("2592000"), "the maximum is given: {err}");
    }
    let out = finish_within(spawn(&["run", "--fast"]), LIMIT);
    assert_eq!(out.status.code(), Some(2), "usage: --fast needs --for");
    let out = finish_within(
        spawn(&["run", "no-such-config.ron", "--fast", "--for", "1s"]),
        LIMIT,
    );
    assert_eq!(out.status.code(), Some(2), "a config that is not there");
}

/// A socketcand address that cannot be listened on (taken here by another listener) is the
/// user's input: exit 2, naming the address and the reason, before the run starts.
#[test]
fn a_gateway_address_in_use_is_exit_2_with_the_address_and_the_reason() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").expect("a free port");
    let addr = taken.local_addr().unwrap().to_string();
    let out = harvemu(&["run", "--fast", "--for", "1s", "--socketcand", &addr]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains(&format!("cannot listen on {addr}")), "{err}");
    assert!(err.contains("in use"), "{err}");
}

/// `harvemu ARGS` with standard output and standard error each either discarded or `/dev/full`.
fn with_full(args: &[&str], stdout_full: bool, stderr_full: bool) -> std::process::Output {
    let sink = |full: bool| {
        let path = if full { "/dev/full" } else { "/dev/null" };
        std::process::Stdio::from(std::fs::OpenOptions::new().write(true).open(path).unwrap())
    };
    std::process::Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(root())
        .args(args)
        .stdout(sink(stdout_full))
        .stderr(sink(stderr_full))
        .output()
        .unwrap()
}

/// A standard error that takes nothing is no panic (exit 101): the run goes on, its trace is
/// whole, and the exit code is 3 (an output failed); help and the version on a full standard
/// output are 3 as well.
#[test]
fn a_full_standard_error_or_help_output_is_exit_3_not_a_panic() {
    let dir = scratch("exit-codes", "stderr-full");
    let trace = dir.join("t.log");
    let out = with_full(
        &[
            "run",
            "--fast",
            "--for",
            "1s",
            "--record",
            trace.to_str().unwrap(),
        ],
        false,
        true,
    );
    assert_eq!(out.status.code(), Some(3));
    let text = std::fs::read_to_string(&trace).unwrap();
    assert!(
        text.lines().count() > 100,
        "the trace is written: {} lines",
        text.lines().count()
    );
    assert!(text.ends_with('\n'), "and whole");
    for args in [&["--help"][..], &["--version"], &["run", "--help"]] {
        let out = with_full(args, true, false);
        assert_eq!(out.status.code(), Some(3), "{args:?}");
    }
    // Nothing to say and nothing refused: a clean exit.
    let out = with_full(&["validate", "configs/scenarios/bus_off.ron"], false, true);
    assert_eq!(out.status.code(), Some(0));
    std::fs::remove_dir_all(&dir).unwrap();
}
