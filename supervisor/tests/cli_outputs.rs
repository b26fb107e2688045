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
    let out = harvemu(&[
        "scenario",
        "configs/scenarios/bit_error_once.ron",
        "--record",
        "/dev/full",
    ]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(
        err.contains("cannot write /dev/full: No space left on device"),
        "{err}"
    );
    let out = harvemu(&[
        "soak",
        "configs/soak/soak_24h.ron",
        "--hours",
        "0.001",
        "--record",
        "/dev/full",
    ]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(3), "{err}");
    assert!(
        err.contains("cannot write /dev/full: No space left on device"),
        "{err}"
    );
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
