//! python-can as the external parser: it reads the candump logs and ASC files harvemu writes,
//! and harvemu reads the ASC files python-can writes.
//!
//! The python is `HARVEMU_PYTHON` (scripts/test points it at a virtual environment it makes with
//! python-can), else `python3`. Without python-can the tests fail: a cross-check that cannot run
//! has checked nothing.

mod common;

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Prints every message of a trace as one JSON object a line.
const DUMP: &str = r#"
import json, sys, can
path = sys.argv[1]
# ASC times count from the header's date: read absolute, they must be the candump log's times.
reader = can.ASCReader(path, relative_timestamp=False) if path.endswith(".asc") else can.CanutilsLogReader(path)
for m in reader:
    print(json.dumps({
        "t_us": round(m.timestamp * 1e6), "error": m.is_error_frame,
        "id": m.arbitration_id, "ext": m.is_extended_id, "remote": m.is_remote_frame,
        "dlc": m.dlc, "data": m.data.hex() if not m.is_remote_frame else "",
    }))
"#;

/// Writes an ASC file with python-can and prints what it wrote, as DUMP does.
const WRITE: &str = r#"
import json, sys, can
msgs = [
    can.Message(timestamp=100.0, arbitration_id=0x0300A0F5, is_extended_id=True, data=[1, 1]),
    can.Message(timestamp=100.000250, arbitration_id=0x123, is_extended_id=False, data=[]),
    can.Message(timestamp=100.5, arbitration_id=0x7FF, is_extended_id=False, is_remote_frame=True, dlc=8),
    can.Message(timestamp=101.25, arbitration_id=0x5, is_extended_id=True, is_remote_frame=True, dlc=0),
    can.Message(timestamp=101.5, is_error_frame=True),
    can.Message(timestamp=102.000001, arbitration_id=0x1FFFFFFF, is_extended_id=True, data=range(0xF8, 0x100)),
]
w = can.ASCWriter(sys.argv[1])
for m in msgs:
    w.on_message_received(m)
w.stop()
for m in msgs:
    print(json.dumps({
        "t_us": round((m.timestamp - 100.0) * 1e6), "error": m.is_error_frame,
        "id": m.arbitration_id, "ext": m.is_extended_id, "remote": m.is_remote_frame,
        "dlc": m.dlc, "data": bytes(m.data).hex() if not m.is_remote_frame else "",
    }))
"#;

/// The python to run: `HARVEMU_PYTHON`, else `python3`.
fn interpreter() -> PathBuf {
    std::env::var_os("HARVEMU_PYTHON").map_or_else(|| "python3".into(), PathBuf::from)
}

/// Fails the test, saying how to get python-can, unless the interpreter imports it.
fn require_python_can() {
    let python = interpreter();
    let out = Command::new(&python).args(["-c", "import can"]).output();
    let why = match out {
        Ok(o) if o.status.success() => return,
        // The traceback's last line says what is missing.
        Ok(o) => String::from_utf8_lossy(&o.stderr)
            .lines()
            .last()
            .unwrap_or_default()
            .to_owned(),
        Err(e) => e.to_string(),
    };
    panic!(
        "python-can cannot be imported with {} ({why}): run scripts/test, which makes a virtual \
         environment with it, or set HARVEMU_PYTHON to a python that has it",
        python.display()
    );
}

fn python(script: &str, arg: &Path) -> Vec<Value> {
    let out = Command::new(interpreter())
        // ASC dates are UTC; python-can reads and writes them in local time.
        .env("TZ", "UTC")
        .args(["-c", script])
        .arg(arg)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("harvemu-python-can-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The frames of a candump log as the JSON DUMP prints, read here by hand.
fn expected(log: &str) -> Vec<Value> {
    log.lines()
        .map(|l| {
            let (time, rest) = l.strip_prefix('(').unwrap().split_once(") harv0 ").unwrap();
            let (secs, us) = time.split_once('.').unwrap();
            let (id, data) = rest.split_once('#').unwrap();
            let (remote, dlc, data) = match data.strip_prefix('R') {
                Some(d) => (true, d.parse().unwrap_or(0), String::new()),
                None => (false, data.len() / 2, data.to_lowercase()),
            };
            serde_json::json!({
                "t_us": secs.parse::<u64>().unwrap() * 1_000_000 + us.parse::<u64>().unwrap(),
                "error": false, "id": u32::from_str_radix(id, 16).unwrap(), "ext": id.len() == 8,
                "remote": remote, "dlc": dlc, "data": data,
            })
        })
        .collect()
}

#[test]
fn python_can_reads_what_harvemu_writes() {
    require_python_can();
    let d = dir();
    let run = |file: &Path| {
        let out = Command::new(env!("CARGO_BIN_EXE_harvemu"))
            .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
            .args(["run", "--fast", "--for", "3s", "--record"])
            .arg(file)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    };
    let (log, asc) = (d.join("run.log"), d.join("run.asc"));
    run(&log);
    run(&asc);
    let want = expected(&std::fs::read_to_string(&log).unwrap());
    assert!(want.len() > 1000, "{} frames", want.len());
    assert_eq!(python(DUMP, &log), want, "candump log");
    assert_eq!(python(DUMP, &asc), want, "ASC (the same run)");
}

#[test]
fn a_candump_log_and_an_asc_file_of_the_same_records_agree_frame_by_frame() {
    use bus::trace::{CandumpWriter, ErrorFrame, Kind, Record, Sink, Source};
    require_python_can();
    let d = dir();
    // Frames, remote frames and a controller's bus error, as the hub hands them to its sinks,
    // written by the two writers `--record` uses.
    let data = |id: u32, bytes: &[u8]| {
        Kind::Frame(bus::Frame::new_data(bus::extended_id(id).unwrap(), bytes).unwrap())
    };
    let base_remote = Kind::Frame(bus::Frame::new_remote(bus::standard_id(0x7FF).unwrap(), 8).unwrap());
    let ext_remote = Kind::Frame(bus::Frame::new_remote(bus::extended_id(5).unwrap(), 0).unwrap());
    let ack = Kind::Error(ErrorFrame {
        can_id: 0x2000_02A8,
        data: [0, 0, 0x80, 0x19, 0, 0, 0x08, 0],
    });
    let e0 = Source::Controller {
        node: bus::engine::NodeId(0),
        name: "E0",
    };
    let records = [
        (500_000, Source::Bus, data(0x0300_A0F5, &[1, 1])),
        (600_000, e0, ack),
        (700_000, Source::Bus, base_remote),
        (800_000, Source::Bus, ext_remote),
        (
            900_001,
            Source::Bus,
            data(0x1FFF_FFFF, &[0xF8, 0xF9, 0xFA, 0xFB, 0xFC, 0xFD, 0xFE, 0xFF]),
        ),
    ];
    let (log_path, asc_path) = (d.join("records.log"), d.join("records.asc"));
    {
        let epoch = bus::time::Epoch::from_secs(1_704_067_200);
        let mut log = CandumpWriter::new(std::fs::File::create(&log_path).unwrap(), epoch);
        let mut asc =
            bus::tracefile::AscWriter::new(std::fs::File::create(&asc_path).unwrap(), epoch).unwrap();
        for (us, source, kind) in records {
            let r = Record {
                at: bus::time::BusTime::from_micros(us),
                bus: "harv0",
                source,
                kind,
            };
            log.record(&r).unwrap();
            asc.record(&r).unwrap();
        }
        log.flush().unwrap();
        asc.finish().unwrap();
    }
    // What the candump format and python-can make of these records, written out by hand.
    let at = |us: u64| 1_704_067_200_000_000 + us;
    let frame = |us, id: u32, ext, remote, dlc: u64, data: &str| {
        serde_json::json!({"t_us": at(us), "error": false, "id": id, "ext": ext,
                           "remote": remote, "dlc": dlc, "data": data})
    };
    let want = [
        frame(500_000, 0x0300_A0F5, true, false, 2, "0101"),
        frame(700_000, 0x7FF, false, true, 8, ""),
        frame(800_000, 5, true, true, 0, ""),
        frame(900_001, 0x1FFF_FFFF, true, false, 8, "f8f9fafbfcfdfeff"),
    ];
    let log = python(DUMP, &log_path);
    let asc = python(DUMP, &asc_path);
    assert_eq!(log.len(), 5, "{log:?}");
    assert_eq!(asc.len(), 5, "{asc:?}");
    for (i, (l, a)) in log.iter().zip(&asc).enumerate() {
        if i == 1 {
            // The bus error: python-can keeps its time and that it is an error frame.
            for m in [l, a] {
                assert_eq!(
                    (m["t_us"].as_u64(), m["error"].as_bool()),
                    (Some(at(600_000)), Some(true))
                );
            }
        } else {
            let w = &want[if i == 0 { 0 } else { i - 1 }];
            assert_eq!(l, w, "candump log, message {i}");
            assert_eq!(a, w, "ASC, message {i}");
        }
    }
}

#[test]
fn harvemu_reads_what_python_can_writes() {
    require_python_can();
    let path = dir().join("python.asc");
    let written = python(WRITE, &path);
    let text = std::fs::read_to_string(&path).unwrap();
    let records = bus::tracefile::read_str(&text, bus::tracefile::ErrorFrames::Keep).unwrap();
    let got: Vec<Value> = records
        .iter()
        .map(|r| {
            let t_us = r.at.as_nanos() / 1000;
            match r.entry {
                bus::tracefile::Entry::Error(_) => serde_json::json!({
                    "t_us": t_us, "error": true, "id": 0, "ext": true, "remote": false, "dlc": 0, "data": "",
                }),
                bus::tracefile::Entry::Frame(f) => serde_json::json!({
                    "t_us": t_us, "error": false, "id": f.raw_id(), "ext": f.is_extended(),
                    "remote": f.is_remote(), "dlc": f.dlc(),
                    "data": f.data().iter().map(|b| format!("{b:02x}")).collect::<String>(),
                }),
            }
        })
        .collect();
    assert_eq!(got, written, "{text}");
    // And the command line plays it.
    let out = Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .arg("replay")
        .arg(&path)
        .arg("--fast")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("1 error frames (not replayable)") && err.contains(" 5 replayed"),
        "{err}"
    );
}

/// The README's socketcand example, from the command line: the README's python-can one-liner
/// (argv[2], its port replaced) receives a frame and sends the README's example frame through
/// `harvemu run --socketcand`, and a second python-can client sees it.
const SOCKETCAND: &str = r#"
import sys, time, can
host, port = sys.argv[1].rsplit(":", 1)
watcher = can.Bus(interface="socketcand", channel="harv0", host=host, port=int(port))
exec(sys.argv[2].replace("port=29536", "port=" + port))
seen, end = [], time.time() + 5
while time.time() < end and (0x0300A0F5, "0101") not in seen:
    m = watcher.recv(1)
    if m is not None:
        seen.append((m.arbitration_id, bytes(m.data).hex()))
print("seen", (0x0300A0F5, "0101") in seen, len(seen))
watcher.shutdown()
"#;

/// The python-can one-liner of the README's socketcand example.
fn readme_socketcand_script() -> String {
    let readme = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../README.md")).unwrap();
    let line = readme
        .lines()
        .find(|l| l.starts_with("python3 -c 'import can;") && l.contains("socketcand"))
        .expect("the README's python-can example");
    let script = line
        .strip_prefix("python3 -c '")
        .and_then(|l| l.strip_suffix('\''))
        .unwrap();
    assert!(
        script.contains("0x0300A0F5") && script.contains("port=29536"),
        "{script}"
    );
    script.to_string()
}

#[test]
fn python_can_sends_the_readme_frame_through_harvemu_run_socketcand() {
    require_python_can();
    let (mut child, addr) = common::socketcand_gateway(&["--for", "15s"]);
    let out = Command::new(interpreter())
        .args(["-c", SOCKETCAND, &addr, &readme_socketcand_script()])
        .output()
        .unwrap();
    let _ = child.kill();
    let _ = child.wait();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("seen True"), "{stdout}");
    // The one-liner printed the frame it received.
    assert!(stdout.starts_with("Timestamp:"), "{stdout}");
}
