//! `harvemu scenario` and `harvemu validate` as a user runs them.

mod common;

use common::harvemu;
use std::path::{Path, PathBuf};

fn scratch(tag: &str) -> PathBuf {
    common::scratch("cli-scenario", tag)
}

fn config() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../configs/harvester.ron")
        .display()
        .to_string()
}

#[test]
fn a_failing_expectation_gives_exit_1_the_seed_the_command_and_junit() {
    let dir = scratch("fail");
    let file = dir.join("strict.ron");
    std::fs::write(
        &file,
        format!(
            r#"Scenario(name: "too strict", config: "{}", duration_s: 3.0, seed: Some(42),
                 expect: [BusLoadBelow(1.0), ErrorFrames(min: 0, max: 0)])"#,
            config()
        ),
    )
    .unwrap();
    let junit = dir.join("report.xml");
    let out = harvemu(&[
        "scenario",
        file.to_str().unwrap(),
        "--junit",
        junit.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(1));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("FAIL BusLoadBelow(1.0)"), "{text}");
    assert!(text.contains("pass ErrorFrames"), "{text}");
    assert!(
        text.contains(&format!(
            "reproduce with: harvemu scenario {} --seed 42",
            file.display()
        )),
        "{text}"
    );
    assert!(text.contains("1 passed, 1 failed"), "{text}");
    // One test case for the scenario, failed, its failure naming the expectation that failed.
    let xml = std::fs::read_to_string(&junit).unwrap();
    assert!(
        xml.contains("<testsuite name=\"harvemu scenario\" tests=\"1\" failures=\"1\""),
        "{xml}"
    );
    assert!(
        xml.contains(&format!(
            "<testcase classname=\"harvemu.scenario\" name=\"too strict ({})\"",
            file.display()
        )),
        "{xml}"
    );
    assert_eq!(xml.matches("<testcase ").count(), 1, "{xml}");
    assert_eq!(xml.matches("<failure").count(), 1, "{xml}");
    let failure = &xml[xml.find("<failure").unwrap()..xml.find("</failure>").unwrap()];
    assert!(
        failure.starts_with("<failure message=\"1 of 2 expectations failed\">FAIL BusLoadBelow(1.0)"),
        "{failure}"
    );
    assert!(!failure.contains("ErrorFrames"), "only what failed: {failure}");
    let output = &xml[xml.find("<system-out>").unwrap()..xml.find("</system-out>").unwrap()];
    assert!(output.contains("FAIL BusLoadBelow(1.0)"), "{output}");
    assert!(output.contains("PASS ErrorFrames"), "{output}");
}

#[test]
fn a_bad_scenario_lists_every_problem_and_runs_nothing() {
    let dir = scratch("bad");
    let file = dir.join("bad.ron");
    std::fs::write(
        &file,
        format!(
            r#"Scenario(name: "bad", config: "{}", duration_s: 10.0,
                 timeline: [
                   (at_s: -1.0, action: Crash("D9")),
                   (at_s: 2.0, action: BitErrors(target: Priority(40), hits: Always)),
                   (at_s: 3.0, action: Plant(input: "fault.door9_open", value: 1.0)),
                   (at_s: 30.0, action: Hang("B1")),
                 ],
                 expect: [Display(field: "speeed_kmh", min: 0.0, max: 1.0)])"#,
            config()
        ),
    )
    .unwrap();
    let record = dir.join("never.log");
    let out = harvemu(&[
        "scenario",
        file.to_str().unwrap(),
        "--record",
        record.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    for needle in [
        "timeline[0].at_s: time -1 s is negative",
        "timeline[0].action: unknown node 'D9'",
        "timeline[1].action.target: priority 40 is over 31",
        "timeline[2].action.input: 'fault.door9_open' is not a plant input",
        "timeline[3].at_s: time 30 s is after the end of the run",
        "expect[0].field: the display has no field 'speeed_kmh'",
    ] {
        assert!(err.contains(needle), "missing {needle} in:\n{err}");
    }
    assert!(!record.exists());
    // Syntax and unknown fields: line and column.
    std::fs::write(&file, "Scenario(\n  name: \"x\",\n  duration: 3.0,\n)").unwrap();
    let out = harvemu(&["validate", file.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("bad.ron:3:"), "{err}");
}

#[test]
fn bad_thresholds_windows_and_fault_options_give_exit_2_with_file_index_and_field() {
    let dir = scratch("bad-thresholds");
    let file = dir.join("thresholds.ron");
    std::fs::write(
        &file,
        format!(
            r#"Scenario(name: "bad thresholds", config: "{}", duration_s: 20.0,
                 timeline: [
                   (at_s: 1.0, action: BitErrors(target: Any, hits: Once, seen_by: Nodes(["F5"]))),
                   (at_s: 2.0, action: Overload(target: Any, hits: Once, frames: 3)),
                 ],
                 expect: [
                   BusLoadBelow(1000.0),
                   NodeStateNever(node: "E0", state: BusOff, from_s: 15.0, to_s: 5.0),
                   RecMax(node: "F5", max: 16, from_s: 0.0, to_s: 25.0),
                   BusOffCount(node: "D9", min: 1, max: 1),
                 ])"#,
            config()
        ),
    )
    .unwrap();
    for command in ["validate", "scenario"] {
        let out = harvemu(&[command, file.to_str().unwrap()]);
        assert_eq!(out.status.code(), Some(2), "{command}");
        let err = String::from_utf8(out.stderr).unwrap();
        for needle in [
            "timeline[0].action.seen_by: a bit error is a bit flipped on the wire",
            "timeline[1].action.frames: 3 overload frames in a row",
            "expect[0]: a load limit of 1000 % is outside (0, 100]",
            "expect[1].to_s: the window 15 s to 5 s is empty",
            "expect[2].to_s: time 25 s is after the end of the run (20 s)",
            "expect[3].node: unknown node 'D9'",
        ] {
            assert!(
                placed(&err, &file, needle),
                "missing {needle} at a line and column in:\n{err}"
            );
        }
    }
}

#[test]
fn control_characters_in_the_name_or_description_give_exit_2_naming_the_field() {
    // JUnit XML and the HTML report could not carry them, not even escaped.
    let dir = scratch("control");
    let file = dir.join("control.ron");
    std::fs::write(
        &file,
        format!(
            "Scenario(name: \"bell\u{1}name\", description: \"tab\\tand\u{1b}escape\", config: \"{}\",\n\
             duration_s: 3.0, expect: [ErrorFrames(min: 0, max: 0)])",
            config()
        ),
    )
    .unwrap();
    let junit = dir.join("never.xml");
    for command in ["validate", "scenario"] {
        let mut args = vec![command, file.to_str().unwrap()];
        if command == "scenario" {
            args.extend(["--junit", junit.to_str().unwrap()]);
        }
        let out = harvemu(&args);
        assert_eq!(out.status.code(), Some(2), "{command}");
        let err = String::from_utf8(out.stderr).unwrap();
        for needle in [
            "name: holds the character U+0001",
            "description: holds the character U+001B",
        ] {
            assert!(
                placed(&err, &file, needle),
                "missing {needle} at a line and column in:\n{err}"
            );
        }
    }
    assert!(!junit.exists());
}

#[test]
fn validate_accepts_every_shipped_file() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs");
    let mut files = vec![root.join("harvester.ron")];
    for d in ["nodes", "nodes/templates", "scenarios", "soak"] {
        files.extend(
            std::fs::read_dir(root.join(d))
                .unwrap()
                .map(|e| e.unwrap().path())
                .filter(|p| p.is_file()),
        );
    }
    let args: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
    let mut all = vec!["validate"];
    all.extend(args.iter().map(String::as_str));
    let out = harvemu(&all);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(
        String::from_utf8(out.stdout).unwrap().matches(": ok (").count(),
        files.len()
    );
}

/// `--config` runs a scenario against another harvester: C0's bus-off scenario passes with C0
/// as firmware (the config it names) and fails against the all-script harvester, whose C0
/// waits out the chip's recovery; the summary and the command to reproduce name the config.
/// A config that cannot be read is exit 2 and runs nothing.
#[test]
fn config_runs_a_scenario_against_another_harvester() {
    let out = harvemu(&["scenario", "c0_bus_off"]);
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert!(text.contains("pass BusOffLongest"), "{text}");

    let out = harvemu(&["scenario", "c0_bus_off", "--config", "configs/harvester.ron"]);
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(text.contains("against configs/harvester.ron"), "{text}");
    assert!(text.contains("FAIL BusOffLongest"), "{text}");
    assert!(
        text.contains("reproduce with: harvemu scenario configs/scenarios/c0_bus_off.ron --seed 2011 --config configs/harvester.ron"),
        "{text}"
    );

    let missing = scratch("config").join("nothing.ron");
    let out = harvemu(&["scenario", "suction_door", "--config", missing.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("nothing.ron"), "{err}");
    assert!(out.stdout.is_empty(), "nothing ran");
}

#[test]
fn a_crash_of_a_node_that_is_down_is_noted_not_an_error() {
    // Found by a campaign: the second crash came while B1 was down, waiting out the restart
    // policy's 100 ms back-off, and harvemu ended with "Mailbox has closed" (exit 70).
    let dir = scratch("crash-twice");
    let file = dir.join("twice.ron");
    std::fs::write(
        &file,
        format!(
            r#"Scenario(name: "crash twice", config: "{}", duration_s: 8.0, seed: Some(1),
                 timeline: [(at_s: 5.0, action: Crash("B1")), (at_s: 5.15, action: Crash("B1"))],
                 expect: [Restarts(node: "B1", count: 1), NoCrashes])"#,
            config()
        ),
    )
    .unwrap();
    let out = harvemu(&["scenario", file.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let events: Vec<&str> = text.lines().filter(|l| l.contains(" event ")).collect();
    assert_eq!(events.len(), 3, "{text}");
    assert!(events[0].ends_with("B1 crashed: injected crash"), "{text}");
    assert!(
        events[1].starts_with("  event 5.150000 B1 not crashed: it is down"),
        "{text}"
    );
    assert!(events[2].ends_with("B1 restarted"), "{text}");
}

/// True when `err` has a line `FILE:LINE:COLUMN: needle` for `file`.
fn placed(err: &str, file: &std::path::Path, needle: &str) -> bool {
    let prefix = format!("{}:", file.display());
    err.lines().any(|l| {
        let Some(rest) = l.trim_start().strip_prefix(&prefix) else {
            return false;
        };
        let mut parts = rest.splitn(3, ':');
        let numbers = parts.next().is_some_and(|x| x.parse::<u32>().is_ok())
            && parts.next().is_some_and(|x| x.parse::<u32>().is_ok());
        numbers
            && parts
                .next()
                .is_some_and(|m| m.strip_prefix(' ') == Some(needle) || m.trim_start().starts_with(needle))
    })
}

/// The terminal tells each `Disturb` step's hits and misses: an error flag in an attempt without
/// error is a miss, a data bit of the frame a hit (it makes the flag that the next attempt's rule
/// would find, but that rule is spent on the first attempt).
#[test]
fn disturb_hits_and_misses_are_printed() {
    let dir = scratch("disturb-counts");
    let file = dir.join("counts.ron");
    let bench =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/scenarios/conformance/bench/network.ron");
    std::fs::write(
        &file,
        format!(
            "Scenario(name: \"counts\", config: {:?}, duration_s: 0.05, timeline: [\n\
             (at_s: 0.01, action: Disturb(target: Node(\"TX\"), hits: Once, field: ErrorFlag, bit: 0, level: Recessive)),\n\
             (at_s: 0.01, action: SendFrame(node: \"TX\", frame: \"012#80\")),\n\
             (at_s: 0.02, action: Disturb(target: Node(\"TX\"), hits: Always, field: Data, bit: 1, level: Recessive)),\n\
             (at_s: 0.02, action: Disturb(target: Any, hits: Always, until_s: Some(0.03), field: Data, bit: 8, level: Recessive)),\n\
             (at_s: 0.02, action: SendFrame(node: \"TX\", frame: \"012#80\")),\n\
             ], expect: [ErrorFrames(min: 1, max: 100)])",
            bench.display().to_string()
        ),
    )
    .unwrap();
    let out = harvemu(&["scenario", file.to_str().unwrap()]);
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(
        stdout.contains("  timeline[0] Disturb: 0 hits, 1 miss\n"),
        "{stdout}"
    );
    // Every attempt from 0.02 s on meets the data-bit error until TX is bus off: 32 attempts.
    assert!(
        stdout.contains("  timeline[2] Disturb: 32 hits, 0 misses\n"),
        "{stdout}"
    );
    // A one-byte frame has no data bit 8 (with target Any the frames are not known at load):
    // each of those attempts is a miss.
    assert!(
        stdout.contains("  timeline[3] Disturb: 0 hits, 32 misses\n"),
        "{stdout}"
    );
}

#[test]
fn a_node_never_heard_is_missing_on_the_summary_line_and_in_the_report() {
    let dir = scratch("missing");
    // run --without D3: the machine still has D3, so the monitor misses it; alarms are no
    // failure, so the exit code stays 0.
    let out = harvemu(&["run", "--fast", "--for", "5s", "--without", "D3"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let last = err.lines().last().unwrap_or_default();
    assert!(last.ends_with("1 alarm (missing D3)"), "{err}");
    // Without a node left out: no alarm at all.
    let out = harvemu(&["run", "--fast", "--for", "5s"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.lines().last().unwrap_or_default().ends_with("  0 alarms"),
        "{err}"
    );
    // The shipped scenario, with its report: D3 raised at 0.5 s + 141 ms + 3 s, on the 10 ms
    // loop after it, and never cleared.
    let report = dir.join("r.html");
    let out = harvemu(&[
        "scenario",
        "dead_from_power_on",
        "--report",
        report.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let page = std::fs::read_to_string(&report).unwrap();
    assert!(page.contains("<h3>Monitor alarms</h3>"), "{page}");
    assert!(
        page.contains("<tr><td class=\"num\">3.650000</td><td>D3</td><td>missing</td><td class=\"num\">still active</td></tr>"),
        "{page}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
