//! The check of a network imported from a DBC file on vcan0: `harvemu import DBC --out DIR`,
//! then `harvemu run DIR/network.ron --iface vcan0 --for RUN_FOR`. For `RECORD` from the first
//! frame the interface must carry every cyclic message of the DBC with its identifier's format
//! (11 or 29 bits) and its length, about as often as its cycle time says (the VM's clock is an
//! emulated one: within half and one and a half times), and no frame the DBC does not send on
//! its own.

use crate::Report;
use crate::harvester::{EXIT_TIMEOUT, IFACE, STARTUP_TIMEOUT, spawn_keeping_stderr};
use protocol::database::Database;
use socketcan::{CanFrame, CanSocket, EmbeddedFrame, Id, Socket};
use std::collections::BTreeMap;
use std::io;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

/// The DBC, as `scripts/vm/test-harvester` brings it into the VM.
pub const DBC: &str = "/dbc/sprayer.dbc";

/// Where the network is written in the VM.
const OUT: &str = "/tmp/vmcheck-imported";

/// How much emulated time the run is given.
const RUN_FOR: &str = "4s";

/// How long frames are counted, from the first one.
const RECORD: Duration = Duration::from_millis(3000);

/// A frame's identifier, format and length, as the count's key.
fn key(frame: &CanFrame) -> (u32, bool, usize) {
    match frame.id() {
        Id::Standard(id) => (u32::from(id.as_raw()), false, frame.dlc()),
        Id::Extended(id) => (id.as_raw(), true, frame.dlc()),
    }
}

/// Imports the DBC, runs the network on the interface and checks what `rx` reads.
pub fn run(rx: &CanSocket, harvemu: &Path, report: &mut Report) {
    let db = match std::fs::read_to_string(DBC)
        .map_err(|e| e.to_string())
        .and_then(|t| Database::parse(DBC, &t).map_err(|e| e.to_string()))
    {
        Ok(db) => db,
        Err(why) => {
            report.check(&format!("read {DBC}"), Err(why));
            return;
        }
    };
    let imported = Command::new(harvemu)
        .args(["import", DBC, "--out", OUT, "--force", "--signals", "walk"])
        .output();
    let outcome = match imported {
        Ok(out) if out.status.success() => Ok(String::new()),
        Ok(out) => Err(String::from_utf8_lossy(&out.stderr).into_owned()),
        Err(e) => Err(e.to_string()),
    };
    if !report.check(&format!("harvemu import {DBC}"), outcome) {
        return;
    }
    while rx.read_frame().is_ok() {}
    let network = format!("{OUT}/network.ron");
    let mut command = Command::new(harvemu);
    command.args(["run", &network, "--iface", IFACE, "--for", RUN_FOR]);
    println!(
        "vmcheck: starting {} run {network} --iface {IFACE} --for {RUN_FOR}",
        harvemu.display()
    );
    let (mut child, _stderr) = match spawn_keeping_stderr(&mut command) {
        Ok(started) => started,
        Err(e) => {
            report.check("start harvemu run on the imported network", Err(e.to_string()));
            return;
        }
    };
    let mut counts: BTreeMap<(u32, bool, usize), u32> = BTreeMap::new();
    let deadline = Instant::now() + STARTUP_TIMEOUT;
    let mut first: Option<Instant> = None;
    loop {
        if first.is_some_and(|f| f.elapsed() >= RECORD) || (first.is_none() && Instant::now() > deadline) {
            break;
        }
        match rx.read_frame() {
            Ok(frame) => {
                first.get_or_insert_with(Instant::now);
                *counts.entry(key(&frame)).or_default() += 1;
            }
            Err(e) if matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock) => {}
            Err(e) => {
                report.check("read the imported network's frames", Err(e.to_string()));
                break;
            }
        }
    }
    let waited = wait(&mut child);
    report.check("harvemu run on the imported network exits with code 0", waited);
    report.check(
        "an imported network on vcan0 sends every cyclic message of its DBC at its period",
        judge(&db, &counts),
    );
}

/// Waits for the run to end by itself, else kills it.
fn wait(child: &mut std::process::Child) -> Result<String, String> {
    let deadline = Instant::now() + EXIT_TIMEOUT;
    loop {
        match child.try_wait() {
            Ok(Some(status)) if status.success() => return Ok(String::new()),
            Ok(Some(status)) => return Err(format!("ended with {status}")),
            Ok(None) if Instant::now() > deadline => {
                let killed = child.kill().and_then(|()| child.wait());
                return Err(format!(
                    "still running after {EXIT_TIMEOUT:?}; killed ({killed:?})"
                ));
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(50)),
            Err(e) => return Err(format!("wait: {e}")),
        }
    }
}

/// Every cyclic message counted about `RECORD / cycle` times with its format and length, and
/// nothing else on the interface.
fn judge(db: &Database, counts: &BTreeMap<(u32, bool, usize), u32>) -> Result<String, String> {
    let mut problems = Vec::new();
    let mut expected = BTreeMap::new();
    for m in &db.messages {
        let Some(cycle) = m.cycle_ms.filter(|&c| c > 0 && m.transmitter.is_some()) else {
            continue;
        };
        let k = (m.id, m.extended, usize::from(m.dlc));
        expected.insert(k, ());
        let want = RECORD.as_millis() as f64 / f64::from(cycle);
        let got = f64::from(counts.get(&k).copied().unwrap_or(0));
        if got < want * 0.5 - 1.0 || got > want * 1.5 + 1.0 {
            problems.push(format!("{}: {got} frames, about {want:.0} expected", m.name));
        }
    }
    for (k, n) in counts {
        if !expected.contains_key(k) {
            problems.push(format!(
                "{n} frames of {:X} ({} bytes) that no cyclic message is",
                k.0, k.2
            ));
        }
    }
    if problems.is_empty() {
        Ok(format!(
            "{} messages, {} frames",
            expected.len(),
            counts.values().sum::<u32>()
        ))
    } else {
        problems.truncate(8);
        Err(problems.join("; "))
    }
}
