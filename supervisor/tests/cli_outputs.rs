//! Outputs that cannot be written completely: every command says so, naming the file, with exit
//! code 3, and a regular file is then left as it was (no torn trace, report or DBC). A full disk
//! is played by a file-size limit (writes past it fail with EFBIG), a full stream by /dev/full
//! (ENOSPC).

mod common;

use common::{harvemu, harvemu_limited, listing, scratch};

/// A file-size limit far below any trace, report or DBC harvemu writes, above nothing.
const LIMIT: u64 = 2000;

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn scenario_and_soak_report_a_trace_that_cannot_be_written() {
    for args in [
        vec!["scenario", "configs/scenarios/bit_error_once.ron"],
        vec!["soak", "configs/soak/soak_24h.ron", "--hours", "0.001"],
    ] {
        let out = harvemu(&[&args[..], &["--record", "/dev/full"]].concat());
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(3), "{args:?}: {err}");
        assert!(
            err.contains("cannot write /dev/full: No space left on device"),
            "{args:?}: {err}"
        );
    }
}

#[test]
fn a_trace_cut_short_by_a_full_disk_is_not_left_behind() {
    let dir = scratch("cli-outputs", "trace");
    for (name, args) in [
        ("run.log", vec!["run", "--fast", "--for", "5s"]),
        ("run.asc", vec!["run", "--fast", "--for", "5s"]),
        (
            "scenario.asc",
            vec!["scenario", "configs/scenarios/bit_error_once.ron"],
        ),
    ] {
        let path = dir.join(name);
        // An older file of the same name stays as it was.
        std::fs::write(&path, "old\n").unwrap();
        let mut args = args.clone();
        args.extend(["--record", path.to_str().unwrap()]);
        let out = harvemu_limited(&args, LIMIT);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(3), "{name}: {err}");
        assert!(
            err.contains(&format!("cannot write {}: File too large", path.display())),
            "{name}: {err}"
        );
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old\n", "{name}");
        assert_eq!(listing(&dir), [name], "no temporary file left beside {name}");
        std::fs::remove_file(&path).unwrap();
    }
}

#[test]
fn a_report_junit_or_dbc_cut_short_is_not_left_behind() {
    let dir = scratch("cli-outputs", "report");
    let html = dir.join("r.html");
    let xml = dir.join("j.xml");
    let dbc = dir.join("h.dbc");
    let scenario = "configs/scenarios/bit_error_once.ron";
    let out = harvemu_limited(&["scenario", scenario, "--report", html.to_str().unwrap()], LIMIT);
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    assert!(
        stderr(&out).contains(&format!("cannot write {}", html.display())),
        "{}",
        stderr(&out)
    );
    let out = harvemu_limited(&["dbc", "-o", dbc.to_str().unwrap()], LIMIT);
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    assert!(
        stderr(&out).contains(&format!("cannot write {}: File too large", dbc.display())),
        "{}",
        stderr(&out)
    );
    // The JUnit XML of one scenario is short: a limit of 200 bytes cuts it.
    let out = harvemu_limited(&["scenario", scenario, "--junit", xml.to_str().unwrap()], 200);
    assert_eq!(out.status.code(), Some(3), "{}", stderr(&out));
    assert!(
        stderr(&out).contains(&format!("cannot write {}", xml.display())),
        "{}",
        stderr(&out)
    );
    assert!(listing(&dir).is_empty(), "nothing left: {:?}", listing(&dir));
    // Without the limit each is written whole.
    let out = harvemu(&[
        "scenario",
        scenario,
        "--report",
        html.to_str().unwrap(),
        "--junit",
        xml.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(
        std::fs::read_to_string(&html)
            .unwrap()
            .trim_end()
            .ends_with("</html>")
    );
    assert!(
        std::fs::read_to_string(&xml)
            .unwrap()
            .ends_with("</testsuites>\n")
    );
    let out = harvemu(&["dbc", "-o", dbc.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(std::fs::read_to_string(&dbc).unwrap().contains("BO_ "));
}

#[test]
fn an_output_that_cannot_be_created_is_exit_code_3_before_anything_runs() {
    for args in [
        vec![
            "run",
            "--fast",
            "--for",
            "1s",
            "--record",
            "/nonexistent-folder/t.log",
        ],
        vec![
            "scenario",
            "configs/scenarios/bit_error_once.ron",
            "--report",
            "/nonexistent-folder/r.html",
        ],
        vec![
            "scenario",
            "configs/scenarios/bit_error_once.ron",
            "--junit",
            "/nonexistent-folder/j.xml",
        ],
        vec!["dbc", "-o", "/nonexistent-folder/h.dbc"],
    ] {
        let out = harvemu(&args);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(3), "{args:?}: {err}");
        assert!(
            err.contains("cannot create /nonexistent-folder/"),
            "{args:?}: {err}"
        );
        assert!(out.stdout.is_empty(), "nothing ran: {args:?}");
    }
}

#[test]
fn a_trace_to_standard_output_streams_whole_lines() {
    let out = harvemu(&["run", "--fast", "--for", "2s", "--record", "/dev/stdout"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.lines().count() > 100, "{} lines", text.lines().count());
    assert!(text.ends_with('\n'));
    assert!(
        text.lines().all(|l| l.starts_with('(') && l.contains(" harv0")),
        "candump lines only"
    );
}

/// Runs `harvemu` with `args` from the repository root, standard output going to `stdout`.
fn harvemu_to(args: &[&str], stdout: std::process::Stdio) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(common::root())
        .args(args)
        .stdout(stdout)
        .stderr(std::process::Stdio::piped())
        .output()
        .expect("run harvemu")
}

/// What commands print on standard output is an output too: `> /dev/full` is exit code 3 naming
/// standard output (it was a panic from `println!`, or exit 0 with nothing written).
#[test]
fn standard_output_that_takes_no_writes_is_exit_code_3() {
    for args in [
        vec!["protocol"],
        vec!["inspect", "0300A0F5#0101"],
        vec!["validate", "configs/harvester.ron"],
        vec!["dbc"],
        vec!["scenario", "configs/scenarios/bit_error_once.ron"],
    ] {
        let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
        let out = harvemu_to(&args, full.into());
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(3), "{args:?}: {err}");
        assert!(
            err.contains("cannot write standard output: No space left on device"),
            "{args:?}: {err}"
        );
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

/// A reader that goes away (`harvemu protocol | head -1`) ends the output quietly, as with any
/// Unix filter: exit 0 and nothing on standard error.
#[test]
fn a_reader_that_goes_away_ends_standard_output_quietly() {
    for args in [vec!["protocol", "--markdown"], vec!["inspect", "0300A0F5#0101"]] {
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_harvemu"))
            .current_dir(common::root())
            .args(&args)
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("start harvemu");
        // Close the read end before harvemu writes: every write it makes meets a broken pipe.
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(0), "{args:?}: {err}");
        assert_eq!(err, "", "{args:?}");
    }
}

/// A trace that fails in the middle of a batch stops the batch with exit code 3, and the JUnit
/// and the HTML report are still written whole (they were not written at all). The trace is
/// played against a file-size limit it passes while the JUnit and the report fit under it.
#[test]
fn a_failed_trace_in_a_batch_still_leaves_the_report_and_junit() {
    let dir = scratch("cli-outputs", "batch");
    let junit = dir.join("junit.xml");
    let report = dir.join("report.html");
    let trace = dir.join("trace.log");
    let out = harvemu_limited(
        &[
            "scenario",
            "configs/scenarios/bit_error_once.ron",
            "--record",
            trace.to_str().unwrap(),
            "--junit",
            junit.to_str().unwrap(),
            "--report",
            report.to_str().unwrap(),
        ],
        // The JUnit and the report are far smaller than this; the scenario's trace is about
        // 210 kB, so its write fails.
        100_000,
    );
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(err.contains(&format!("{}", trace.display())), "{err}");
    assert!(!trace.exists(), "a torn trace was left: {:?}", listing(&dir));
    let xml = std::fs::read_to_string(&junit).expect("the JUnit is written");
    assert!(xml.ends_with("</testsuites>\n"), "{xml}");
    let html = std::fs::read_to_string(&report).expect("the report is written");
    assert!(
        html.trim_end().ends_with("</html>"),
        "{}",
        &html[html.len().saturating_sub(200)..]
    );
}

#[test]
fn two_outputs_on_one_file_or_an_output_on_an_input_are_refused_before_anything_runs() {
    let dir = scratch("cli-outputs", "same");
    let p = |name: &str| dir.join(name).to_str().unwrap().to_string();
    // A trace to replay, whose bytes must survive.
    let trace = p("t.log");
    std::fs::write(&trace, "(1.000000) harv0 123#01\n").unwrap();
    let config = p("h.ron");
    assert!(harvemu(&["config", "export", &p("cfg")]).status.success());
    std::fs::copy(dir.join("cfg/harvester.ron"), &config).ok();
    let same = p("x");
    let dotted = format!("{}/./x", dir.display());
    // A folder a merge reads (empty: the refusal comes before it is read).
    let shard = p("m");
    std::fs::create_dir(&shard).unwrap();
    let shard_too = format!("{}/m/", dir.display());
    let soak = p("s.ron");
    let original = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/soak/soak_24h.ron");
    std::fs::copy(&original, &soak).unwrap();
    let cases: Vec<(Vec<&str>, &str, &str)> = vec![
        (
            vec![
                "run",
                "--fast",
                "--for",
                "1s",
                "--record",
                &same,
                "--dump-state",
                &dotted,
            ],
            "--record",
            "--dump-state",
        ),
        (
            vec!["scenario", "bit_error_once", "--junit", &same, "--report", &same],
            "--junit",
            "--report",
        ),
        (
            vec!["scenario", "bit_error_once", "--record", &same, "--report", &same],
            "--record",
            "--report",
        ),
        (
            vec!["replay", &trace, "--fast", "--record", &trace],
            "--record",
            "TRACE",
        ),
        (
            vec!["soak", &soak, "--hours", "0.001", "--record", &soak],
            "--record",
            "SCENARIO",
        ),
        (
            vec![
                "campaign",
                "harvest",
                "--runs",
                "1",
                "--out",
                &same,
                "--coverage",
                &same,
            ],
            "--out",
            "--coverage",
        ),
        (
            vec!["campaign", "merge", &shard, "--out", &shard_too],
            "--out",
            "DIR",
        ),
        (vec!["coverage", "merge", &shard, "--out", &shard], "--out", "DIR"),
    ];
    for (args, first, second) in cases {
        let out = harvemu(&args);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(first) && err.contains(second), "{args:?}: {err}");
        // Nothing ran: no output was made, and what is read is as it was.
        assert!(!dir.join("x").exists(), "{args:?} wrote x");
        assert_eq!(
            std::fs::read_to_string(&trace).unwrap(),
            "(1.000000) harv0 123#01\n"
        );
        assert_eq!(
            std::fs::read_dir(&shard).unwrap().count(),
            0,
            "{args:?} wrote into m"
        );
        assert_eq!(std::fs::read(&soak).unwrap(), std::fs::read(&original).unwrap());
    }
    // A config is an input too; streams may be shared.
    std::fs::write(&same, "").unwrap();
    let out = harvemu(&["dbc", "--config", &config, "--output", &config]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("--output") && stderr(&out).contains("--config"),
        "{}",
        stderr(&out)
    );
    let out = harvemu(&[
        "run",
        "--fast",
        "--for",
        "1s",
        "--record",
        "/dev/null",
        "--dump-state",
        "/dev/null",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let _ = std::fs::remove_dir_all(&dir);
}
