//! Trace timestamps are wall-clock dates: the wall clock at the start of a real-time run, a fixed
//! epoch (2024-01-01T00:00:00Z) or `--start-time` in virtual time, so that tools reading the
//! traces (python-can, can-utils) see real dates and a seed still gives the same bytes.
//!
//! python-can is the independent reference for the dates (`HARVEMU_PYTHON`, as in python_can.rs).

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{SystemTime, UNIX_EPOCH};

/// 2024-01-01T00:00:00Z in seconds: 54 years of 365 days and the 13 leap days 1972..=2020.
const NEW_YEAR_2024: u64 = (54 * 365 + 13) * 86_400;

fn harvemu(args: &[&str], record: &Path) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .args(args)
        .arg("--record")
        .arg(record)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    out
}

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("harvemu-timestamps-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The first line's time, in microseconds since 1970, read by hand.
fn first_stamp_us(log: &str) -> u64 {
    let first = log.lines().next().expect("a frame");
    let (time, _) = first.strip_prefix('(').unwrap().split_once(')').unwrap();
    let (secs, us) = time.split_once('.').unwrap();
    secs.parse::<u64>().unwrap() * 1_000_000 + us.parse::<u64>().unwrap()
}

#[test]
fn a_fast_run_starts_at_the_fixed_epoch_and_repeats_byte_for_byte() {
    let d = dir();
    let (a, b) = (d.join("a.log"), d.join("b.log"));
    let args = ["run", "--fast", "--for", "2s", "--seed", "7"];
    harvemu(&args, &a);
    harvemu(&args, &b);
    let (a, b) = (std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    assert_eq!(a, b, "one seed, one trace");
    let first = first_stamp_us(&String::from_utf8(a).unwrap());
    // The first frame comes within the first second of bus time.
    let epoch = NEW_YEAR_2024 * 1_000_000;
    assert!(
        (epoch..epoch + 1_000_000).contains(&first),
        "first stamp {first} µs"
    );
}

#[test]
fn start_time_moves_the_stamps_and_a_bad_one_is_refused() {
    let d = dir();
    let (fixed, moved, secs) = (d.join("fixed.log"), d.join("moved.log"), d.join("secs.log"));
    let args = ["run", "--fast", "--for", "1s", "--seed", "3"];
    harvemu(&args, &fixed);
    // 2030-06-15T12:00:00Z: 2024-01-01 plus the 366 days of 2024, 365 each of 2025..=2029 and
    // the leap day of 2028, then January to May 2030 (151 days) and 14 days, and 12 hours.
    let june_2030 = NEW_YEAR_2024 + (366 + 5 * 365 + 1 + 151 + 14) * 86_400 + 12 * 3_600;
    harvemu(
        &[&args[..], &["--start-time", "2030-06-15T12:00:00Z"]].concat(),
        &moved,
    );
    harvemu(
        &[&args[..], &["--start-time", &june_2030.to_string()]].concat(),
        &secs,
    );
    let read = |p: &Path| std::fs::read_to_string(p).unwrap();
    let (fixed, moved) = (read(&fixed), read(&moved));
    assert_eq!(
        moved,
        read(&secs),
        "RFC 3339 and seconds since 1970 are the same start"
    );
    let shift = (june_2030 - NEW_YEAR_2024) * 1_000_000;
    assert_eq!(first_stamp_us(&moved), first_stamp_us(&fixed) + shift);
    assert_eq!(moved.lines().count(), fixed.lines().count());
    for bad in ["yesterday", "2024-13-01T00:00:00Z", "-1"] {
        let out = Command::new(env!("CARGO_BIN_EXE_harvemu"))
            .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
            .args(["run", "--fast", "--for", "1s", &format!("--start-time={bad}")])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{bad}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("--start-time"), "{bad}: {err}");
    }
}

#[test]
fn a_real_time_run_stamps_with_the_wall_clock() {
    let d = dir();
    let log = d.join("real.log");
    let before = SystemTime::now().duration_since(UNIX_EPOCH).unwrap().as_micros() as u64;
    harvemu(&["run", "--for", "1s"], &log);
    let after = SystemTime::now().duration_since(UNIX_EPOCH).unwrap().as_micros() as u64;
    let first = first_stamp_us(&std::fs::read_to_string(&log).unwrap());
    assert!(
        (before..=after).contains(&first),
        "first stamp {first} µs outside the run's {before}..={after}"
    );
}

#[test]
fn a_fast_asc_is_dated_at_the_epoch_and_repeats_byte_for_byte() {
    let d = dir();
    let (a, b) = (d.join("a.asc"), d.join("b.asc"));
    let args = ["run", "--fast", "--for", "1s", "--seed", "7"];
    harvemu(&args, &a);
    harvemu(&args, &b);
    let (a, b) = (
        std::fs::read_to_string(&a).unwrap(),
        std::fs::read_to_string(&b).unwrap(),
    );
    assert_eq!(a, b, "one seed, one ASC trace");
    // 2024-01-01 was a Monday.
    assert!(
        a.starts_with("date Mon Jan 01 12:00:00.000 am 2024\n"),
        "{}",
        &a[..80]
    );
}

/// Reads a candump log with python-can, writes it as ASC and BLF with python-can, and prints the
/// date each of those files starts at (UTC).
const CONVERT: &str = r#"
import sys, datetime, can
log, asc, blf = sys.argv[1:4]
msgs = list(can.CanutilsLogReader(log))
for path in (asc, blf):
    with can.Logger(path) as w:
        for m in msgs:
            w.on_message_received(m)
for line in open(asc):
    if line.startswith("Begin Triggerblock"):
        print("asc", line.split(None, 2)[2].strip())
start = can.BLFReader(blf).start_timestamp
print("blf", datetime.datetime.fromtimestamp(start, datetime.timezone.utc).strftime("%Y-%m-%d"))
"#;

fn python_dates(log: &Path) -> String {
    let python = std::env::var_os("HARVEMU_PYTHON").map_or_else(|| "python3".into(), PathBuf::from);
    let out = Command::new(python)
        .env("TZ", "UTC")
        .args(["-c", CONVERT])
        .arg(log)
        .arg(log.with_extension("asc"))
        .arg(log.with_extension("blf"))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "python-can is needed (HARVEMU_PYTHON): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn python_can_dates_the_converted_files_at_the_epoch() {
    let d = dir();
    let (fixed, moved) = (d.join("py-fixed.log"), d.join("py-moved.log"));
    harvemu(&["run", "--fast", "--for", "1s"], &fixed);
    harvemu(
        &[
            "run",
            "--fast",
            "--for",
            "1s",
            "--start-time",
            "2030-06-15T12:00:00Z",
        ],
        &moved,
    );
    let got = python_dates(&fixed);
    // python-can dates the ASC trigger block at the first frame, within the first second.
    assert!(got.contains("asc Mon Jan 01 00:00:00."), "{got}");
    assert!(got.contains(" 2024\n"), "{got}");
    assert!(got.contains("blf 2024-01-01\n"), "{got}");
    let got = python_dates(&moved);
    assert!(got.contains("asc Sat Jun 15 12:00:00."), "{got}");
    assert!(got.contains(" 2030\n"), "{got}");
    assert!(got.contains("blf 2030-06-15\n"), "{got}");
}

/// `harvemu` without the `--record` that [`harvemu`] adds, for commands that are expected to
/// succeed and record elsewhere.
fn harvemu_plain(args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .args(args)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    out
}

#[test]
fn scenario_and_soak_take_a_start_time() {
    let d = dir();
    // 2030-06-15T12:00:00Z, counted as in the test above.
    let june_2030 = NEW_YEAR_2024 + (366 + 5 * 365 + 1 + 151 + 14) * 86_400 + 12 * 3_600;
    let shift = (june_2030 - NEW_YEAR_2024) * 1_000_000;
    let runs: [(&str, &[&str]); 2] = [
        (
            "scenario",
            &["scenario", "configs/scenarios/crash.ron", "--seed", "5"],
        ),
        ("soak", &["soak", "--hours", "0.002", "--seed", "5"]),
    ];
    for (name, args) in runs {
        let (fixed, moved) = (
            d.join(format!("{name}-fixed.log")),
            d.join(format!("{name}-moved.log")),
        );
        let (f, m) = (fixed.to_str().unwrap(), moved.to_str().unwrap());
        harvemu_plain(&[args, &["--record", f]].concat());
        harvemu_plain(&[args, &["--record", m, "--start-time", "2030-06-15T12:00:00Z"]].concat());
        let (fixed, moved) = (
            std::fs::read_to_string(&fixed).unwrap(),
            std::fs::read_to_string(&moved).unwrap(),
        );
        let first = first_stamp_us(&fixed);
        assert!(
            (NEW_YEAR_2024 * 1_000_000..(NEW_YEAR_2024 + 2) * 1_000_000).contains(&first),
            "{name}: first stamp {first} µs"
        );
        assert_eq!(first_stamp_us(&moved), first + shift, "{name}");
        assert_eq!(moved.lines().count(), fixed.lines().count(), "{name}");
    }
}

/// can-utils' `log2asc` reads a candump log and writes an ASC file. With times that started at
/// zero it wrote its date header again and again; with dates it writes one, at the first frame,
/// and times relative to it.
#[test]
fn can_utils_log2asc_writes_one_date_and_the_log_s_times() {
    let d = dir();
    let log = d.join("log2asc.log");
    harvemu(&["run", "--fast", "--for", "2s", "--seed", "7"], &log);
    let out = Command::new("log2asc")
        .env("TZ", "UTC")
        .arg("-I")
        .arg(&log)
        .arg("harv0")
        .output()
        .expect("log2asc from can-utils is needed (scripts/test installs it)");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let asc = String::from_utf8(out.stdout).unwrap();
    let dates: Vec<&str> = asc.lines().filter(|l| l.starts_with("date ")).collect();
    assert_eq!(dates, ["date Mon Jan  1 00:00:00 2024"], "{}", &asc[..200]);
    // Frame lines: "   0.008888 1  400F5C0x        Rx   d 4 30 00 AC 0D".
    let asc_times: Vec<u64> = asc
        .lines()
        .filter(|l| l.contains(" Rx "))
        .map(|l| {
            let (s, us) = l.split_whitespace().next().unwrap().split_once('.').unwrap();
            s.parse::<u64>().unwrap() * 1_000_000 + us.parse::<u64>().unwrap()
        })
        .collect();
    let text = std::fs::read_to_string(&log).unwrap();
    let first = first_stamp_us(&text);
    let log_times: Vec<u64> = text.lines().map(|l| first_stamp_us(l) - first).collect();
    assert_eq!(
        asc_times, log_times,
        "log2asc's times are the log's, from its first frame"
    );
}

/// Prints the first frame's timestamp as python-can's socketcand interface gives it, and the
/// wall clock then.
const SOCKETCAND_STAMP: &str = r#"
import sys, time, can
host, port = sys.argv[1].rsplit(":", 1)
bus = can.Bus(interface="socketcand", channel="harv0", host=host, port=int(port))
m = bus.recv(30)
print(m.timestamp if m else "none", time.time())
bus.shutdown()
"#;

/// The first socketcand frame's stamp and the wall clock then, in seconds, read by python-can
/// from `harvemu run --socketcand` with `extra` arguments.
fn socketcand_stamp(extra: &[&str]) -> (f64, f64) {
    // Long enough for a loaded machine; the test stops it when python-can is done.
    let args: Vec<&str> = ["--for", "120s"].iter().chain(extra).copied().collect();
    let (mut child, addr) = common::socketcand_gateway(&args);
    let python = std::env::var_os("HARVEMU_PYTHON").map_or_else(|| "python3".into(), PathBuf::from);
    let out = Command::new(python)
        .args(["-c", SOCKETCAND_STAMP, &addr])
        .output()
        .unwrap();
    let _ = child.kill();
    let _ = child.wait();
    assert!(
        out.status.success(),
        "python-can is needed (HARVEMU_PYTHON): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let mut words = text.split_whitespace().map(|w| w.parse::<f64>().expect(&text));
    (words.next().unwrap(), words.next().unwrap())
}

#[test]
fn socketcand_frames_carry_the_wall_clock_or_the_start_time() {
    let (stamp, now) = socketcand_stamp(&[]);
    assert!(
        stamp <= now && now - stamp < 30.0,
        "stamp {stamp} s, wall clock {now} s"
    );
    let (stamp, _) = socketcand_stamp(&["--start-time", "2030-06-15T12:00:00Z"]);
    let june_2030 = (NEW_YEAR_2024 + (366 + 5 * 365 + 1 + 151 + 14) * 86_400 + 12 * 3_600) as f64;
    assert!(
        (june_2030..june_2030 + 5.0).contains(&stamp),
        "stamp {stamp} s, start {june_2030} s"
    );
}
