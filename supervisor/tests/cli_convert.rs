//! `harvemu convert` and the binary formats on the command line: a trace with error frames goes
//! candump log -> BLF -> pcapng -> MF4 -> candump log and comes back byte for byte; replay reads
//! every format as its candump twin; `--format` overrides the name; a file whose name denies its
//! bytes, a cut-off file and a stream for BLF or MF4 are bad input (exit 2) naming what and
//! where; a run stopped by SIGTERM leaves BLF and MF4 that read to their end, python-can agreeing;
//! asammdf decodes the MF4 with `harvemu dbc`'s DBC as cantools decodes the candump log.

mod common;

use common::{harvemu, scratch, spawn};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

fn ok(out: Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{err}");
    err
}

fn bad(out: Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A scenario's trace with error frames on the controllers' interfaces (D2 bus off), recorded
/// once: its folder and the candump log.
fn recorded() -> &'static (PathBuf, PathBuf) {
    static R: OnceLock<(PathBuf, PathBuf)> = OnceLock::new();
    R.get_or_init(|| {
        let dir = scratch("convert", "shared");
        let log = dir.join("bus_off.log");
        ok(harvemu(&[
            "scenario",
            "configs/scenarios/bus_off.ron",
            "--seed",
            "3",
            "--record",
            s(&log),
        ]));
        (dir, log)
    })
}

/// Error frames of a candump log, counted from its text: an 8-digit id with CAN_ERR_FLAG.
fn error_lines(log: &str) -> usize {
    log.lines()
        .filter(|l| {
            let id = l
                .split_whitespace()
                .nth(2)
                .and_then(|f| f.split_once('#'))
                .map(|(id, _)| id);
            id.is_some_and(|id| {
                id.len() == 8 && u32::from_str_radix(id, 16).is_ok_and(|v| v & 0x2000_0000 != 0)
            })
        })
        .count()
}

#[test]
fn a_log_through_blf_pcapng_and_mf4_comes_back_byte_for_byte() {
    let (dir, log) = recorded();
    let original = std::fs::read_to_string(log).unwrap();
    let errors = error_lines(&original);
    assert!(errors > 100, "the trace must have error frames: {errors}");
    let interfaces: std::collections::BTreeSet<&str> = original
        .lines()
        .filter_map(|l| l.split_whitespace().nth(1))
        .collect();
    assert!(interfaces.len() > 1, "{interfaces:?}");
    let chain = ["rt.blf", "rt.pcapng", "rt.mf4", "rt.log"];
    let mut from = log.clone();
    for name in chain {
        let to = dir.join(name);
        let err = ok(harvemu(&["convert", s(&from), s(&to)]));
        let records = original.lines().count();
        assert!(err.contains(&format!("{records} records")), "{name}: {err}");
        from = to;
    }
    let back = std::fs::read_to_string(&from).unwrap();
    assert!(back == original, "the round trip changed the trace");
}

#[test]
fn asc_is_told_what_it_cannot_carry() {
    let (dir, log) = recorded();
    let original = std::fs::read_to_string(log).unwrap();
    let asc = dir.join("lossy.asc");
    let err = ok(harvemu(&["convert", s(log), s(&asc)]));
    let errors = error_lines(&original);
    assert!(
        err.contains(&format!("keeps no error-frame details: {errors} error frames")),
        "{err}"
    );
    assert!(err.contains("keeps no interface names"), "{err}");
    // The frames themselves are all there, at their times, on channel 1 (can0).
    let back = dir.join("from-asc.log");
    ok(harvemu(&["convert", s(&asc), s(&back)]));
    let frames = |t: &str, iface: &str| -> Vec<String> {
        t.lines()
            .filter(|l| error_lines(l) == 0)
            .map(|l| {
                let f: Vec<&str> = l.split_whitespace().collect();
                assert_eq!(f[1], iface, "{l}");
                format!("{} {}", f[0], f[2])
            })
            .collect()
    };
    same(
        &frames(&std::fs::read_to_string(back).unwrap(), "can0"),
        &frames(&original, "harv0"),
    );
}

/// Equal lists, or the first place they differ.
fn same(a: &[String], b: &[String]) {
    if let Some(i) = (0..a.len().min(b.len())).find(|&i| a[i] != b[i]) {
        panic!("entry {i}: {} but {}", a[i], b[i]);
    }
    assert_eq!(a.len(), b.len(), "one list is a prefix of the other");
}

#[test]
fn replay_reads_every_format_as_its_candump_twin() {
    let dir = scratch("convert", "replay");
    let log = dir.join("run.log");
    ok(harvemu(&["run", "--fast", "--for", "6s", "--record", s(&log)]));
    let mut played = Vec::new();
    for ext in ["log", "blf", "pcapng", "mf4"] {
        let trace = dir.join(format!("twin.{ext}"));
        ok(harvemu(&["convert", s(&log), s(&trace)]));
        let out = dir.join(format!("played-{ext}.log"));
        let args = [
            "--fast",
            "--without",
            "D3",
            "--skip-emulated",
            "--record",
            s(&out),
        ];
        ok(harvemu(&[&["replay", s(&trace)], &args[..]].concat()));
        played.push((ext, std::fs::read_to_string(out).unwrap()));
    }
    for (ext, text) in &played[1..] {
        assert!(text == &played[0].1, "replaying the {ext} twin gave another bus");
    }
}

#[test]
fn format_overrides_the_name_and_blf_or_mf4_on_a_stream_is_refused() {
    let dir = scratch("convert", "format");
    let dat = dir.join("run.dat");
    ok(harvemu(&[
        "run",
        "--fast",
        "--for",
        "1s",
        "--record",
        s(&dat),
        "--format",
        "pcapng",
    ]));
    let bytes = std::fs::read(&dat).unwrap();
    assert_eq!(
        &bytes[..4],
        &[0x0A, 0x0D, 0x0D, 0x0A],
        "a pcapng Section Header Block"
    );
    for format in ["blf", "mf4"] {
        let err = bad(harvemu(&[
            "run",
            "--fast",
            "--for",
            "1s",
            "--record",
            "/dev/stdout",
            "--format",
            format,
        ]));
        assert!(
            err.contains("/dev/stdout") && err.contains("record to a file"),
            "{err}"
        );
    }
    let err = bad(harvemu(&[
        "run",
        "--fast",
        "--for",
        "1s",
        "--record",
        s(&dat),
        "--format",
        "xlsx",
    ]));
    assert!(err.contains("xlsx") && err.contains("blf"), "{err}");
}

#[test]
fn a_file_whose_name_denies_its_bytes_is_refused_naming_both() {
    let (dir, log) = recorded();
    for (name, says) in [
        ("log.blf", "Vector BLF"),
        ("log.mf4", "MF4"),
        ("log.pcapng", "pcapng"),
    ] {
        let wrong = dir.join(name);
        std::fs::copy(log, &wrong).unwrap();
        let err = bad(harvemu(&["convert", s(&wrong), s(&dir.join("x.log"))]));
        assert!(
            err.contains("this is text") && err.contains(&format!("its name says {says}")),
            "{err}"
        );
        let err = bad(harvemu(&["replay", s(&wrong), "--fast"]));
        assert!(err.contains("its name says"), "{err}");
    }
    let blf = dir.join("real.blf");
    ok(harvemu(&["convert", s(log), s(&blf)]));
    let as_log = dir.join("blf.log");
    std::fs::copy(&blf, &as_log).unwrap();
    let err = bad(harvemu(&["convert", s(&as_log), s(&dir.join("y.asc"))]));
    assert!(
        err.contains("this is Vector BLF") && err.contains("rename it to .blf"),
        "{err}"
    );
    let zeros = dir.join("zeros.mf4");
    std::fs::write(&zeros, [0u8; 4096]).unwrap();
    let err = bad(harvemu(&["convert", s(&zeros), s(&dir.join("z.log"))]));
    assert!(err.contains("its name says MF4"), "{err}");
}

#[test]
fn a_cut_off_binary_file_is_refused_at_its_record_and_byte() {
    let (dir, log) = recorded();
    for ext in ["blf", "pcapng", "mf4"] {
        let whole = dir.join(format!("whole.{ext}"));
        ok(harvemu(&["convert", s(log), s(&whole)]));
        let bytes = std::fs::read(&whole).unwrap();
        for cut in [bytes.len() * 2 / 3 + 1, bytes.len() - 3] {
            let part = dir.join(format!("cut.{ext}"));
            std::fs::write(&part, &bytes[..cut]).unwrap();
            let out = dir.join("cut.log");
            let err = bad(harvemu(&["convert", s(&part), s(&out)]));
            assert!(
                err.contains("record ") && err.contains(" at byte "),
                "{ext} cut at {cut}: {err}"
            );
            assert!(!out.exists(), "{ext}: nothing written from a bad input");
        }
    }
}

/// The python with python-can: HARVEMU_PYTHON, else python3.
fn python() -> PathBuf {
    std::env::var_os("HARVEMU_PYTHON").map_or_else(|| "python3".into(), PathBuf::from)
}

/// Messages python-can reads from `path` (BLFReader or MF4Reader).
fn python_can_count(path: &Path) -> usize {
    let script = "import sys, can\n\
        r = can.BLFReader(sys.argv[1]) if sys.argv[1].endswith('.blf') else can.MF4Reader(sys.argv[1])\n\
        print(sum(1 for _ in r))";
    let out = Command::new(python()).args(["-c", script]).arg(path).output();
    let out =
        out.unwrap_or_else(|e| panic!("{e}: set HARVEMU_PYTHON to a python with python-can and asammdf"));
    assert!(
        out.status.success(),
        "python-can could not read {} (set HARVEMU_PYTHON to a python with python-can and asammdf): {}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).trim().parse().unwrap()
}

#[test]
fn a_run_stopped_by_sigterm_leaves_blf_and_mf4_that_read_to_their_end() {
    let dir = scratch("convert", "sigterm");
    for ext in ["blf", "mf4"] {
        let trace = dir.join(format!("cut.{ext}"));
        let mut child = spawn(&["run", "--record", s(&trace)]);
        let mut err = BufReader::new(child.stderr.take().unwrap());
        let mut startup = String::new();
        while !startup.contains("real time (Ctrl-C stops)") {
            assert!(err.read_line(&mut startup).unwrap() > 0, "{startup}");
        }
        std::thread::sleep(std::time::Duration::from_millis(2000));
        common::signal(&child, libc::SIGTERM);
        let mut rest = String::new();
        std::io::Read::read_to_string(&mut err, &mut rest).unwrap();
        assert_eq!(child.wait().unwrap().code(), Some(143), "{rest}");
        let log = dir.join(format!("cut-{ext}.log"));
        let said = ok(harvemu(&["convert", s(&trace), s(&log)]));
        let ours = std::fs::read_to_string(&log).unwrap().lines().count();
        assert!(ours > 100, "{ext}: {ours} records; {said}");
        assert_eq!(
            python_can_count(&trace),
            ours,
            "{ext}: python-can and harvemu disagree"
        );
    }
}

/// Decodes the plain (not multiplexed) messages of `argv[2]`'s DBC two ways: cantools on the
/// frames python-can reads from the candump log `argv[1]`, and asammdf's `extract_bus_logging`
/// of the MF4 `argv[3]`; prints the counts and the signals that differ.
const DECODE_BOTH: &str = r#"
import json, sys, asammdf, can, cantools
def value(v):
    if isinstance(v, bytes):
        return v.decode()
    if isinstance(v, (int, float)):
        return float(v)
    return str(v)
db = cantools.database.load_file(sys.argv[2])
plain = {m.frame_id: m for m in db.messages if not m.is_multiplexed()}
want = {}
for msg in can.LogReader(sys.argv[1]):
    m = plain.get(msg.arbitration_id)
    if m is None or msg.is_error_frame or msg.is_remote_frame or not msg.is_extended_id:
        continue
    for name, v in m.decode(bytes(msg.data)).items():
        want.setdefault(f"{m.name}.{name}", []).append((round(msg.timestamp * 1e6), value(v)))
mdf = asammdf.MDF(sys.argv[3])
start = mdf.header.start_time.timestamp()
out = mdf.extract_bus_logging({"CAN": [(sys.argv[2], 0)]})
got = {}
for gi, g in enumerate(out.groups):
    # "CAN1 message ID=0x500F5B0 EXT=True"
    fid = int(g.channel_group.acq_name.split()[2].split("=")[1], 16)
    if fid not in plain:
        continue
    for ci, c in enumerate(g.channels):
        if c.name != "time":
            s = out.get(group=gi, index=ci)
            got.setdefault(f"{plain[fid].name}.{c.name}", []).extend(
                (round((start + t) * 1e6), value(v)) for t, v in zip(s.timestamps, s.samples.tolist()))
differ = sorted(k for k in set(want) | set(got) if sorted(got.get(k, [])) != want.get(k))
print(json.dumps({"messages": len({k.split(".")[0] for k in want}), "signals": len(want),
                  "samples": sum(map(len, want.values())), "differ": differ}))
"#;

#[test]
fn asammdf_decodes_the_mf4_with_harvemus_dbc_as_cantools_decodes_the_log() {
    let (dir, log) = recorded();
    let mf4 = dir.join("decoded.mf4");
    ok(harvemu(&["convert", s(log), s(&mf4)]));
    let dbc = dir.join("harvester.dbc");
    ok(harvemu(&["dbc", "-o", s(&dbc)]));
    let out = Command::new(python())
        .env("TZ", "UTC")
        .args(["-c", DECODE_BOTH])
        .args([log, &dbc, &mf4])
        .output()
        .unwrap_or_else(|e| {
            panic!("{e}: set HARVEMU_PYTHON to a python with python-can, cantools and asammdf")
        });
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "the python check failed (HARVEMU_PYTHON needs python-can, cantools and asammdf): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_str(text.trim()).unwrap();
    assert_eq!(report["differ"], serde_json::json!([]), "{report}");
    // The harvester's cyclic plain messages: speed, row, alarm and parameter status at least.
    assert!(report["messages"].as_u64().unwrap() >= 10, "{report}");
    assert!(report["samples"].as_u64().unwrap() > 1000, "{report}");
}
