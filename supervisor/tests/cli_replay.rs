//! `harvemu replay` and `--record FILE.asc` as a user runs them: the skip filter, loops, the ASC
//! recording of a run against its candump recording, an interrupted recording, and bad input.

use std::io::{BufRead, BufReader};
mod common;

use common::harvemu;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::OnceLock;

fn ok(out: Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(out.status.success(), "{err}");
    err
}

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("harvemu-cli-replay-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn path(name: &str) -> String {
    dir().join(name).to_str().unwrap().to_string()
}

/// One frame of a candump log, read here without the crate's reader: (µs, id digits, data).
fn lines(text: &str) -> Vec<(u64, String, String)> {
    text.lines()
        .map(|l| {
            let (time, rest) = l.strip_prefix('(').unwrap().split_once(") harv0 ").unwrap();
            let (secs, us) = time.split_once('.').unwrap();
            let (id, data) = rest.split_once('#').unwrap();
            let at = secs.parse::<u64>().unwrap() * 1_000_000 + us.parse::<u64>().unwrap();
            (at, id.to_string(), data.to_string())
        })
        .collect()
}

/// The source address of a frame (low byte of an extended identifier).
fn source(id: &str) -> Option<&str> {
    (id.len() == 8).then(|| &id[6..])
}

/// A trace file and its lines.
type Recorded = (String, Vec<(u64, String, String)>);

/// 6 s of the default harvester, recorded once for every test here.
fn recorded() -> &'static Recorded {
    static TRACE: OnceLock<Recorded> = OnceLock::new();
    TRACE.get_or_init(|| {
        let log = path("full.log");
        ok(harvemu(&["run", "--fast", "--for", "6s", "--record", &log]));
        let text = std::fs::read_to_string(&log).unwrap();
        let parsed = lines(&text);
        (log, parsed)
    })
}

fn count(err: &str, what: &str) -> u64 {
    // "... 5984 frames skipped (emulated sources), 716 replayed, ..."
    let at = err.find(what).unwrap_or_else(|| panic!("no '{what}' in {err}"));
    err[..at].split_whitespace().last().unwrap().parse().unwrap()
}

#[test]
fn the_skip_filter_drops_exactly_the_emulated_sources() {
    let (log, original) = recorded();
    let out = path("skip.log");
    let err = ok(harvemu(&[
        "replay",
        log,
        "--fast",
        "--without",
        "B3",
        "--without",
        "D3",
        "--skip-emulated",
        "--record",
        &out,
    ]));
    let missing = ["B3", "D3"];
    let kept: Vec<&(u64, String, String)> = original
        .iter()
        .filter(|(_, id, _)| source(id).is_none_or(|s| missing.contains(&s)))
        .collect();
    assert!(kept.len() > 300, "{}", kept.len());
    assert_eq!(count(&err, "replayed"), kept.len() as u64, "{err}");
    assert_eq!(
        count(&err, "frames skipped"),
        (original.len() - kept.len()) as u64,
        "{err}"
    );
    let again = lines(&std::fs::read_to_string(&out).unwrap());
    let from_missing = |l: &[(u64, String, String)]| -> Vec<(String, String)> {
        l.iter()
            .filter(|(_, id, _)| source(id).is_some_and(|s| missing.contains(&s)))
            .map(|(_, id, data)| (id.clone(), data.clone()))
            .collect()
    };
    let want: Vec<(String, String)> = kept.iter().map(|(_, id, d)| (id.clone(), d.clone())).collect();
    assert_eq!(
        from_missing(&again),
        want,
        "B3's and D3's frames, as recorded, in order"
    );
}

#[test]
fn loops_multiply_the_frames_and_keep_time_going_forward() {
    let (log, original) = recorded();
    let out = path("loop.log");
    let err = ok(harvemu(&[
        "replay",
        log,
        "--fast",
        "--without",
        "D3",
        "--skip-emulated",
        "--loop",
        "3",
        "--record",
        &out,
    ]));
    let d3 = |l: &[(u64, String, String)]| -> Vec<(u64, String)> {
        l.iter()
            .filter(|(_, id, _)| source(id) == Some("D3"))
            .map(|(t, _, d)| (*t, d.clone()))
            .collect()
    };
    let once = d3(original);
    let thrice = d3(&lines(&std::fs::read_to_string(&out).unwrap()));
    assert_eq!(thrice.len(), 3 * once.len());
    assert_eq!(count(&err, "replayed"), 3 * once.len() as u64);
    assert!(err.contains("3 passes"), "{err}");
    for pass in thrice.chunks(once.len()) {
        let payloads: Vec<&String> = pass.iter().map(|(_, d)| d).collect();
        assert_eq!(payloads, once.iter().map(|(_, d)| d).collect::<Vec<_>>());
    }
    assert!(
        thrice.windows(2).all(|w| w[0].0 < w[1].0),
        "times keep increasing"
    );
}

#[test]
fn an_asc_recording_holds_the_same_frames_as_a_candump_recording() {
    let (_, original) = recorded();
    let asc = path("full.asc");
    ok(harvemu(&["run", "--fast", "--for", "6s", "--record", &asc]));
    let text = std::fs::read_to_string(&asc).unwrap();
    let all: Vec<&str> = text.lines().collect();
    // The date header is the run's epoch, 2024-01-01T00:00:00Z in virtual time, and the ASC's
    // times count from it, while the candump log carries seconds since 1970.
    assert_eq!(all[0], "date Mon Jan 01 12:00:00.000 am 2024");
    const EPOCH_US: u64 = 1_704_067_200_000_000;
    assert_eq!(all[1], "base hex  timestamps absolute");
    assert_eq!(*all.last().unwrap(), "End TriggerBlock");
    // Frame lines, read here: "   0.551520 1  0200F5E0x       Rx   d 7 10 78 00 F4 01 00 00".
    let frames: Vec<(u64, String, String)> = all
        .iter()
        .filter(|l| l.contains(" Rx "))
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            let (secs, us) = f[0].split_once('.').unwrap();
            let id = f[2].trim_end_matches('x').to_string();
            let data: String = f[6..].concat();
            (
                EPOCH_US + secs.parse::<u64>().unwrap() * 1_000_000 + us.parse::<u64>().unwrap(),
                id,
                data,
            )
        })
        .collect();
    assert_eq!(
        &frames, original,
        "the same run, the same frames at the same times"
    );
}

#[test]
fn replaying_an_asc_trace_works_as_replaying_its_candump_twin() {
    let (log, _) = recorded();
    let asc = path("twin.asc");
    ok(harvemu(&["run", "--fast", "--for", "6s", "--record", &asc]));
    let (a, b) = (path("from-log.log"), path("from-asc.log"));
    let args = ["--fast", "--without", "D3", "--skip-emulated", "--record"];
    let e1 = ok(harvemu(
        &[&["replay", log.as_str()], &args[..], &[a.as_str()]].concat(),
    ));
    let e2 = ok(harvemu(
        &[&["replay", asc.as_str()], &args[..], &[b.as_str()]].concat(),
    ));
    assert_eq!(count(&e1, "replayed"), count(&e2, "replayed"));
    // The same run in either format: the same timing, the same bus.
    assert_eq!(
        std::fs::read_to_string(a).unwrap(),
        std::fs::read_to_string(b).unwrap()
    );
}

#[test]
fn an_interrupted_asc_recording_is_complete() {
    let asc = path("interrupted.asc");
    let mut child = Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .args(["run", "--record", &asc])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Once the run has started (its startup lines), give it a few seconds of bus time to record.
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut startup = String::new();
    while !startup.contains("real time (Ctrl-C stops)") {
        assert!(err.read_line(&mut startup).unwrap() > 0, "{startup}");
    }
    std::thread::sleep(std::time::Duration::from_millis(2500));
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut err, &mut rest).unwrap();
    assert_eq!(child.wait().unwrap().code(), Some(130), "{rest}");
    assert!(rest.contains("interrupted"), "{rest}");
    let text = std::fs::read_to_string(&asc).unwrap();
    assert!(text.ends_with("End TriggerBlock\n"), "{text}");
    let records = bus::tracefile::read_str(&text, bus::tracefile::ErrorFrames::Keep).unwrap();
    assert!(records.len() > 100, "{} frames", records.len());
}

#[test]
fn bad_input_is_one_line_and_exit_code_2() {
    let bad = path("bad.log");
    std::fs::write(&bad, "(1.000000) can0 123#00\n(1.5) can0 123#0G\n").unwrap();
    let asc = path("bad.asc");
    std::fs::write(
        &asc,
        "date Wed Jun 12 02:47:38.610 pm 2024\nbase hex  timestamps absolute\n1.0 1 123 Rx d 3 01\n",
    )
    .unwrap();
    let backwards = path("backwards.log");
    std::fs::write(
        &backwards,
        "(1.000000) can0 123#00\n(2.000000) harv0.D2 20000288#0000010A00000800\n(1.500000) can0 123#01\n",
    )
    .unwrap();
    let backwards_asc = path("backwards.asc");
    std::fs::write(
        &backwards_asc,
        "base hex  timestamps absolute\n2.0 1 123 Rx d 1 01\n1.0 1 123 Rx d 1 02\n",
    )
    .unwrap();
    let empty = path("empty.log");
    std::fs::write(&empty, "\n").unwrap();
    let missing = path("missing.log");
    let (log, _) = recorded();
    for (args, words) in [
        (vec!["replay", &bad, "--fast"], format!("{bad}:2: frame '123#0G'")),
        (vec!["replay", &asc, "--fast"], format!("{asc}:3: ")),
        (
            vec!["replay", &backwards, "--fast"],
            format!("{backwards}:3: time 1.500000 goes backwards"),
        ),
        (
            vec!["replay", &backwards_asc, "--fast"],
            format!("{backwards_asc}:3: time 1.000000 goes backwards"),
        ),
        (vec!["replay", &empty, "--fast"], "no frames".to_string()),
        (
            vec!["replay", &missing, "--fast"],
            format!("cannot open {missing}"),
        ),
        (
            vec!["replay", log, "--fast", "--loop", "0"],
            "at least 1".to_string(),
        ),
        (vec!["replay", log, "--fast", "--loop"], "needs --for".to_string()),
        (
            vec!["replay", log, "--iface", "harvemu-none"],
            "cannot open CAN interface harvemu-none".to_string(),
        ),
        (
            vec!["replay", log, "--fast", "--iface", "vcan0"],
            "real time".to_string(),
        ),
        (vec!["replay", log, "--without", "Z9"], "no such node".to_string()),
    ] {
        let out = harvemu(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(&words), "{args:?}: {err}");
        if !args.contains(&"Z9") {
            // Config problems are listed one a line; everything else is one line.
            assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
        }
    }
}

/// With `--iface`, replay emulates nothing unless asked: the interface carries only the trace.
#[test]
fn onto_an_interface_only_the_trace_goes_unless_emulated_nodes_are_asked_for() {
    use supervisor::harvester::Harvester;
    use supervisor::replay::{emulated, for_interface};
    let config = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/harvester.ron");
    let full = Harvester::load(&config).unwrap();
    // The default harvester: 20 field nodes and the monitor.
    assert_eq!(emulated(&full).len(), 21);

    let mut alone = full.clone();
    for_interface(&mut alone, false);
    assert!(emulated(&alone).is_empty(), "{:?}", emulated(&alone));
    assert_eq!(
        alone.relay(),
        bus::time::BusTime::ZERO,
        "the trace starts at once"
    );

    let mut with = full.clone();
    for_interface(&mut with, true);
    assert_eq!(emulated(&with), emulated(&full));
    assert_eq!(with.relay(), full.relay());

    // --with-emulated means nothing without --iface: refused like other bad usage.
    let (log, _) = recorded();
    let out = harvemu(&["replay", log, "--fast", "--with-emulated"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--iface"), "{err}");
}

/// A real-time replay that is frozen (SIGSTOP) for 400 ms says so when it ends, as `run` does:
/// bus time slipped instead of bursting, and the closing line counts the overrun. Lower bounds
/// only: a loaded machine adds overruns, it cannot remove the freeze.
#[test]
fn a_frozen_real_time_replay_reports_its_overrun() {
    let dir = common::scratch("cli-replay", "overrun");
    let trace = dir.join("three.log");
    let mut text = String::new();
    for i in 0..30 {
        text += &format!("({}.{:06}) harv0 0300A0F5#0101\n", i / 10, (i % 10) * 100_000);
    }
    std::fs::write(&trace, text).unwrap();
    let child = common::spawn(&["replay", trace.to_str().unwrap(), "--for", "4s"]);
    std::thread::sleep(std::time::Duration::from_millis(1500));
    common::signal(&child, libc::SIGSTOP);
    std::thread::sleep(std::time::Duration::from_millis(400));
    common::signal(&child, libc::SIGCONT);
    let out = common::finish_within(child, std::time::Duration::from_secs(60));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    let line = err
        .lines()
        .find(|l| l.starts_with("harvemu: real time: "))
        .unwrap_or_else(|| panic!("no overrun line in:\n{err}"));
    // "harvemu: real time: N overruns, bus time S s behind the wall clock (longest M ms)"
    let longest: u64 = line
        .rsplit("(longest ")
        .next()
        .and_then(|t| t.strip_suffix(" ms)"))
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("cannot read: {line}"));
    assert!(longest >= 300, "{line}");
}

#[test]
fn a_long_pause_in_the_trace_is_warned_about_once_or_refused_with_max_gap() {
    // Two hours between the frames on lines 8 and 9 (line numbers of the file, header and all),
    // and another after line 9.
    let asc = path("gap.asc");
    std::fs::write(
        &asc,
        "date Mon Jan 01 12:00:00.000 am 2024\n\
         base hex  timestamps absolute\n\
         internal events logged\n\
         // version 9.0.0\n\
         Begin Triggerblock Mon Jan 01 12:00:00.000 am 2024\n\
         \x20  0.000000 Start of measurement\n\
         \x20  0.001000 1  123             Rx   d 1 01\n\
         \x20  0.002000 1  123             Rx   d 1 02\n\
         \x20  7200.002000 1  123             Rx   d 1 03\n\
         \x20  14400.002000 1  123             Rx   d 1 04\n\
         End TriggerBlock\n",
    )
    .unwrap();
    let out = harvemu(&["replay", &asc, "--fast", "--for", "1s"]);
    let err = ok(out);
    let warnings: Vec<&str> = err.lines().filter(|l| l.contains("warning")).collect();
    assert_eq!(warnings.len(), 1, "{err}");
    assert!(
        warnings[0].contains(&format!("{asc}:9: 2.0 h after the record before")),
        "{err}"
    );
    assert!(warnings[0].contains("--max-gap"), "{err}");
    // Under the limit: no word.
    let out = harvemu(&["replay", &asc, "--fast", "--for", "1s", "--max-gap", "3h"]);
    assert!(!ok(out).contains("warning"));
    // Over it: refused at that line, before anything runs.
    let out = harvemu(&["replay", &asc, "--fast", "--for", "1s", "--max-gap", "10m"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert_eq!(
        err.trim(),
        format!("harvemu: error: {asc}:9: 2.0 h after the record before, longer than --max-gap 10.0 min")
    );
}
