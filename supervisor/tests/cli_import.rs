//! `harvemu import` on the command line: what it writes runs and validates; a DBC that does not
//! parse is exit 2 at its line and column; an `--out` that holds files is refused unless
//! `--force`; each case the scripts cannot do as the DBC says is a warning line and a comment
//! in the script concerned; scenarios (and removing their fault fails them), a campaign, every
//! trace format and the socketcand gateway work on an imported network.

mod common;

use common::{harvemu, scratch};
use std::path::{Path, PathBuf};
use std::process::Output;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A small network with one of each thing an import warns about: DASH sends nothing, Event has
/// no cycle time, Over shares bit 0 with Lamp, Wide reaches past its 2-byte message.
const DBC: &str = r#"VERSION ""

NS_ :

BS_:

BU_: ENGINE BRAKE DASH

BO_ 2566844926 EEC1: 8 ENGINE
 SG_ EngineSpeed : 24|16@1+ (0.125,0) [0|8031.875] "rpm" DASH,BRAKE
 SG_ Torque : 16|8@1- (1,-125) [-125|125] "%" DASH

BO_ 256 Brake: 4 BRAKE
 SG_ Mode M : 7|8@0+ (1,0) [0|2] "" DASH
 SG_ Pressure m1 : 15|16@0+ (0.1,0) [0|250] "bar" DASH
 SG_ Temp m2 : 15|8@0- (1,0) [-40|125] "C" DASH

BO_ 512 Lamps: 2 BRAKE
 SG_ Lamp : 0|1@1+ (1,0) [0|1] "" DASH
 SG_ Over : 0|4@1+ (1,0) [0|15] "" DASH
 SG_ Wide : 8|16@1+ (1,0) [0|100] "" DASH

BO_ 513 Event: 1 ENGINE
 SG_ Code : 0|8@1+ (1,0) [0|255] "" DASH

BA_DEF_ BO_ "GenMsgCycleTime" INT 0 65535;
BA_DEF_DEF_ "GenMsgCycleTime" 0;
BA_ "GenMsgCycleTime" BO_ 2566844926 20;
BA_ "GenMsgCycleTime" BO_ 256 100;
BA_ "GenMsgCycleTime" BO_ 512 500;
"#;

fn dbc(dir: &Path, text: &str) -> PathBuf {
    let path = dir.join("truck.dbc");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn an_import_runs_validates_and_says_what_it_could_not_do() {
    let dir = scratch("import", "warnings");
    let file = dbc(&dir, DBC);
    let out_dir = dir.join("truck");
    let out = harvemu(&["import", s(&file), "--out", s(&out_dir), "--signals", "sine"]);
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    for warning in [
        "harvemu: warning: node DASH sends nothing: its script only listens (its controller acknowledges frames)",
        "harvemu: warning: Event (0x201): no cycle time: an event message, written with `when: OnRequest`",
        "harvemu: warning: Lamps (0x200) signal Over: shares bit 0 with signal Lamp",
        "harvemu: warning: Lamps (0x200) signal Wide: 16 bits from bit 8 do not fit in the message's 2 bytes",
    ] {
        assert!(err.contains(warning), "{warning}\n{err}");
    }
    assert!(
        err.contains(
            "3 nodes, 3 messages sent on their own, 1 event message for actions to send; 4 warnings."
        ),
        "{err}"
    );
    let brake = std::fs::read_to_string(out_dir.join("nodes/brake.ron")).unwrap();
    assert!(
        brake.contains("// Warning: Lamps (0x200) signal Over: shares bit 0"),
        "{brake}"
    );
    assert!(
        brake.contains("// Warning: Lamps (0x200) signal Wide: 16 bits"),
        "{brake}"
    );
    let engine = std::fs::read_to_string(out_dir.join("nodes/engine.ron")).unwrap();
    assert!(
        engine.contains("// Not generated (event messages, no cycle time): Event."),
        "{engine}"
    );
    let dash = std::fs::read_to_string(out_dir.join("nodes/dash.ron")).unwrap();
    assert!(dash.contains("messages: [\n    ],"), "{dash}");
    assert_eq!(std::fs::read_to_string(out_dir.join("truck.dbc")).unwrap(), DBC);

    let network = out_dir.join("network.ron");
    let out = harvemu(&["validate", s(&network)]);
    assert!(out.status.success(), "{}", stderr(&out));
    let log = dir.join("truck.log");
    let out = harvemu(&["run", s(&network), "--fast", "--for", "2s", "--record", s(&log)]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = std::fs::read_to_string(&log).unwrap();
    // 2 s: EEC1 every 20 ms, Brake every 100 ms, Lamps every 500 ms, Event never.
    let count = |id: &str| text.lines().filter(|l| l.contains(&format!(" {id}#"))).count();
    assert_eq!(
        (count("18FEF1FE"), count("100"), count("200"), count("201")),
        (100, 20, 4, 0),
        "{text}"
    );
}

#[test]
fn a_dbc_that_does_not_parse_is_refused_at_its_line_and_column() {
    let dir = scratch("import", "bad");
    let file = dbc(&dir, &DBC.replace("(0.125,0)", "(0.125,zero)"));
    let out = harvemu(&["import", s(&file), "--out", s(&dir.join("x"))]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert_eq!(
        stderr(&out).trim(),
        format!("harvemu: error: {}:10:36: expected offset", file.display())
    );
    assert!(!dir.join("x").exists());
    // A base identifier too wide for 11 bits, at its line.
    let file = dbc(&dir, &DBC.replace("BO_ 512 Lamps", "BO_ 4095 Lamps"));
    let out = harvemu(&["import", s(&file), "--out", s(&dir.join("x"))]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains("truck.dbc:18:1: message Lamps: identifier 4095 is over 0x7FF"),
        "{}",
        stderr(&out)
    );
    // A file with no node and no transmitter has nothing to run.
    let file = dbc(&dir, "VERSION \"\"\nNS_ :\nBS_:\nBU_:\n");
    let out = harvemu(&["import", s(&file), "--out", s(&dir.join("x"))]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("no nodes (BU_) and no message with a transmitter: nothing to run"),
        "{}",
        stderr(&out)
    );
    // A transmitter BU_ does not list is a node all the same, with a warning.
    let file = dbc(
        &dir,
        &DBC.replace("BO_ 513 Event: 1 ENGINE", "BO_ 513 Event: 1 GHOST"),
    );
    let out = harvemu(&["import", s(&file), "--out", s(&dir.join("g"))]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("warning: Event (0x201): its transmitter GHOST is not in BU_: taken as a node"),
        "{}",
        stderr(&out)
    );
    assert!(dir.join("g/nodes/ghost.ron").exists());
    // /dev/zero is no DBC and never ends: refused at the size limit.
    let out = harvemu(&["import", "/dev/zero", "--out", s(&dir.join("x"))]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("larger than 1 MiB"), "{}", stderr(&out));
}

#[test]
fn an_out_folder_that_holds_files_is_refused_unless_force() {
    let dir = scratch("import", "force");
    let file = dbc(&dir, DBC);
    let out_dir = dir.join("net");
    std::fs::create_dir_all(&out_dir).unwrap();
    std::fs::write(out_dir.join("notes.txt"), "mine").unwrap();
    let out = harvemu(&["import", s(&file), "--out", s(&out_dir)]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("the folder holds files: nothing written (--force writes into it)"));
    assert!(!out_dir.join("network.ron").exists());
    let out = harvemu(&["import", s(&file), "--out", s(&out_dir), "--force"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(out_dir.join("network.ron").exists());
    assert_eq!(
        std::fs::read_to_string(out_dir.join("notes.txt")).unwrap(),
        "mine"
    );
}

/// A scenario on the imported network: BRAKE's frames corrupted for 150 ms from 5 s.
const BRAKE_OFF: &str = r#"Scenario(
    name: "BRAKE bus off",
    description: "Every frame of BRAKE is corrupted for 150 ms from 5 s: it goes bus off and comes back; ENGINE stays error active.",
    duration_s: 10.0,
    timeline: [(at_s: 5.0, action: BitErrors(target: Node("BRAKE"), hits: Always, until_s: Some(5.15)))],
    expect: [
        NodeState(node: "BRAKE", state: BusOff, after_s: 5.0, within_ms: 120),
        BusOffCount(node: "BRAKE", min: 1, max: 6),
        NodeStateNever(node: "ENGINE", state: Passive, from_s: 0.0, to_s: 10.0),
        NodeStateHolds(node: "BRAKE", state: Active, from_s: 8.0, to_s: 10.0),
    ],
)"#;

/// Half a minute with random faults: every frame in the trace, no node crashing by itself.
const FAULTS: &str = r#"Scenario(
    name: "truck faults",
    description: "Half a minute of the imported truck with a fault every second on average: every frame on the bus is in the trace and no node crashes by itself.",
    duration_s: 30.0,
    random_faults: Some((mean_interval_s: 1.0, kinds: [BitErrors, ErrorPassive, Crash, Hang, Babble, Disconnect], from_s: 5.0, quiet_end_s: 10.0)),
    expect: [TraceComplete, NoCrashes],
)"#;

/// python-can's socketcand interface at argv[1] (host:port): the identifiers of 40 messages.
const SOCKETCAND: &str = r#"
import sys, can
host, port = sys.argv[1].rsplit(":", 1)
with can.Bus(interface="socketcand", channel="harv0", host=host, port=int(port)) as bus:
    seen = set()
    for _ in range(40):
        m = bus.recv(timeout=5.0)
        if m is not None:
            seen.add((m.arbitration_id, m.is_extended_id))
    print(sorted(seen))
"#;

#[test]
fn scenarios_campaigns_every_trace_format_and_socketcand_work_on_an_imported_network() {
    let dir = scratch("import", "everything");
    let file = dbc(&dir, DBC);
    let net = dir.join("truck");
    let out = harvemu(&["import", s(&file), "--out", s(&net), "--signals", "walk"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let network = net.join("network.ron");

    let scenario = dir.join("brake_off.ron");
    std::fs::write(&scenario, BRAKE_OFF).unwrap();
    let out = harvemu(&["scenario", s(&scenario), "--config", s(&network)]);
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{said}{}", stderr(&out));
    assert!(said.contains("4 passed, 0 failed"), "{said}");
    // Without the fault BRAKE never goes bus off: an expectation fails (exit code 1).
    let faultless = BRAKE_OFF.replace(
        r#"timeline: [(at_s: 5.0, action: BitErrors(target: Node("BRAKE"), hits: Always, until_s: Some(5.15)))],"#,
        "timeline: [],",
    );
    assert_ne!(faultless, BRAKE_OFF);
    std::fs::write(&scenario, faultless).unwrap();
    let out = harvemu(&["scenario", s(&scenario), "--config", s(&network)]);
    let said = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{said}{}", stderr(&out));
    assert!(said.contains("FAIL NodeState {"), "{said}");

    let campaign = dir.join("faults.ron");
    std::fs::write(&campaign, FAULTS).unwrap();
    let runs = dir.join("campaign");
    let out = harvemu(&[
        "campaign",
        s(&campaign),
        "--config",
        s(&network),
        "--runs",
        "4",
        "--out",
        s(&runs),
    ]);
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{said}{}", stderr(&out));
    assert!(said.contains("4 of 4 runs, 4 passed, 0 failed"), "{said}");

    // The same run in every format converts back to its candump log.
    let log = dir.join("run.log");
    let args = |record: &Path| {
        vec![
            "run".to_string(),
            s(&network).into(),
            "--fast".into(),
            "--for".into(),
            "3s".into(),
            "--record".into(),
            s(record).into(),
        ]
    };
    let run = |record: &Path| {
        let a = args(record);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        let out = harvemu(&a);
        assert!(out.status.success(), "{}", stderr(&out));
    };
    run(&log);
    let want = std::fs::read_to_string(&log).unwrap();
    assert!(want.lines().count() > 150, "{want}");
    for ext in ["asc", "blf", "pcapng", "mf4"] {
        let trace = dir.join(format!("run.{ext}"));
        run(&trace);
        let back = dir.join(format!("run-{ext}.log"));
        let out = harvemu(&["convert", s(&trace), s(&back)]);
        assert!(out.status.success(), "{ext}: {}", stderr(&out));
        let got = std::fs::read_to_string(&back).unwrap();
        if ext == "asc" {
            // ASC keeps no interface names: the same frames at the same times.
            let strip = |t: &str| {
                t.lines()
                    .map(|l| {
                        let f: Vec<&str> = l.split(' ').collect();
                        format!("{} {}", f[0], f[2])
                    })
                    .collect::<Vec<_>>()
            };
            assert_eq!(strip(&got), strip(&want), "{ext}");
        } else {
            assert_eq!(got, want, "{ext}");
        }
    }

    let (mut child, addr) = common::socketcand_gateway(&[s(&network), "--for", "20s"]);
    let py = std::env::var("HARVEMU_PYTHON").unwrap_or_else(|_| "python3".into());
    let out = std::process::Command::new(&py)
        .args(["-c", SOCKETCAND, &addr])
        .output();
    let _ = child.kill();
    let _ = child.wait();
    let out = out
        .unwrap_or_else(|e| panic!("cannot run `{py}`: {e}; set HARVEMU_PYTHON to a python with python-can"));
    assert!(
        out.status.success(),
        "python-can's socketcand client failed (HARVEMU_PYTHON must have python-can): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let seen = String::from_utf8_lossy(&out.stdout);
    // EEC1 (29-bit) and Brake (11-bit 0x100) from the imported nodes.
    assert!(
        seen.contains("(419361278, True)") && seen.contains("(256, False)"),
        "{seen}"
    );
}

/// Numbers at the edges: a factor of 0, a range as wide as f64 goes, literals past it.
const EXTREME: &str = r#"VERSION ""
NS_ :
BS_:
BU_: A B
BO_ 256 M1: 8 A
 SG_ Zero : 0|8@1+ (0,5) [0|0] "" B
 SG_ Huge : 16|16@1- (1e300,1e308) [-1e308|1e308] "" B
 SG_ Tiny : 32|16@1+ (1e-300,0) [0|0] "" B
 SG_ Over : 48|8@1+ (1,1e400) [0|1e999] "" B
BA_DEF_ BO_ "GenMsgCycleTime" INT 0 65535;
BA_DEF_DEF_ "GenMsgCycleTime" 0;
BA_ "GenMsgCycleTime" BO_ 256 100;
"#;

#[test]
fn extreme_numbers_are_warned_about_and_the_network_still_sends() {
    let dir = scratch("import", "extreme");
    let file = dbc(&dir, EXTREME);
    for signals in ["initial", "sine", "ramp", "walk"] {
        let net = dir.join(signals);
        let out = harvemu(&["import", s(&file), "--out", s(&net), "--signals", signals]);
        let err = stderr(&out);
        assert!(out.status.success(), "{signals}: {err}");
        for warning in [
            "M1 (0x100) signal Zero: factor 0: no raw value stands for a chosen physical one; raw 0 is sent",
            "M1 (0x100) signal Over: range [0|inf] is not finite: taken as no range",
            "M1 (0x100) signal Over: offset inf is not finite: taken as 0",
        ] {
            assert!(err.contains(warning), "{signals}: {warning}\n{err}");
        }
        let log = dir.join(format!("{signals}.log"));
        let out = harvemu(&[
            "run",
            s(&net.join("network.ron")),
            "--fast",
            "--for",
            "1s",
            "--record",
            s(&log),
        ]);
        assert!(out.status.success(), "{signals}: {}", stderr(&out));
        let text = std::fs::read_to_string(&log).unwrap();
        // M1 every 100 ms, B acknowledging: no error frame.
        assert_eq!(
            text.lines().filter(|l| l.contains(" 100#")).count(),
            10,
            "{signals}: {text}"
        );
        assert_eq!(text.lines().count(), 10, "{signals}: {text}");
    }
}
