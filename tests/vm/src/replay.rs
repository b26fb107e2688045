//! The check of `harvemu replay TRACE --iface vcan0`: a small candump log is written and replayed
//! onto the interface, and the interface must carry exactly the log's frames, in order: by
//! default replay puts only what the trace holds on an interface, not the emulated harvester.

use crate::harvester::{EXIT_TIMEOUT, IFACE, STARTUP_TIMEOUT, spawn_keeping_stderr};
use crate::{Report, format_frame};
use socketcan::{CanSocket, Socket};
use std::io;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

/// Where the log is written in the VM.
const TRACE: &str = "/tmp/vmcheck-replay.log";

/// The log's frames, 50 ms apart: extended and base data frames, an empty one, a remote one.
const FRAMES: [&str; 5] = [
    "0601F5D0#200D0002FFBFFF00",
    "123#DEADBEEF",
    "0300A0F5#0101",
    "7FF#",
    "0500F5B1#R",
];

/// How long the interface is still read after replay has exited.
const AFTER_EXIT: Duration = Duration::from_millis(300);

/// Writes the log, replays it with `harvemu` and checks what `rx` reads.
pub fn run(rx: &CanSocket, harvemu: &Path, config: &Path, report: &mut Report) {
    let log: String = FRAMES
        .iter()
        .enumerate()
        .map(|(i, f)| format!("({}.{:06}) {IFACE} {f}\n", 1_700_000_000, i * 50_000))
        .collect();
    if let Err(e) = std::fs::write(TRACE, log) {
        report.check(&format!("write {TRACE}"), Err(e.to_string()));
        return;
    }
    // Whatever the run before left unread is not the replay's.
    while rx.read_frame().is_ok() {}
    let mut command = Command::new(harvemu);
    command
        .args(["replay", TRACE, "--config"])
        .arg(config)
        .args(["--iface", IFACE]);
    let shown = format!(
        "{} replay {TRACE} --config {} --iface {IFACE}",
        harvemu.display(),
        config.display()
    );
    println!("vmcheck: starting {shown}");
    let (mut child, _stderr) = match spawn_keeping_stderr(&mut command) {
        Ok(started) => started,
        Err(e) => {
            report.check(&format!("start {shown}"), Err(e.to_string()));
            return;
        }
    };
    let deadline = Instant::now() + STARTUP_TIMEOUT + EXIT_TIMEOUT;
    let mut seen = Vec::new();
    let mut exited: Option<(Instant, Result<String, String>)> = None;
    loop {
        if exited.is_none() {
            match child.try_wait() {
                Ok(Some(status)) => {
                    let outcome = match status.code() {
                        Some(0) => Ok(String::new()),
                        _ => Err(format!("ended with {status}")),
                    };
                    exited = Some((Instant::now(), outcome));
                }
                Ok(None) if Instant::now() > deadline => {
                    let killed = child.kill().and_then(|()| child.wait());
                    exited = Some((
                        Instant::now(),
                        Err(format!(
                            "still running after {:?}; killed ({killed:?})",
                            STARTUP_TIMEOUT + EXIT_TIMEOUT
                        )),
                    ));
                }
                Ok(None) => {}
                Err(e) => exited = Some((Instant::now(), Err(format!("wait: {e}")))),
            }
        }
        if let Some((at, _)) = &exited
            && at.elapsed() >= AFTER_EXIT
        {
            break;
        }
        match rx.read_frame() {
            Ok(frame) => seen.push(format_frame(&frame)),
            Err(e) if matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock) => {}
            Err(e) => {
                seen.push(format!("read error: {e}"));
                break;
            }
        }
    }
    let outcome = exited.map_or(Err("not waited for".to_owned()), |(_, o)| o);
    report.check("harvemu replay --iface exits with code 0", outcome);
    report.check(
        "replay --iface puts exactly the trace's frames on the interface",
        exactly(&seen),
    );
}

/// `seen` is `FRAMES`, in order.
fn exactly(seen: &[String]) -> Result<String, String> {
    if seen == FRAMES {
        return Ok(seen.join(" "));
    }
    let shown: Vec<&str> = seen.iter().take(8).map(String::as_str).collect();
    Err(format!(
        "expected {}; read {} frames: {}{}",
        FRAMES.join(" "),
        seen.len(),
        shown.join(" "),
        if seen.len() > shown.len() { " ..." } else { "" }
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_trace_in_order_passes() {
        let exact: Vec<String> = FRAMES.iter().map(|f| f.to_string()).collect();
        assert!(exactly(&exact).is_ok());
        let mut more = exact.clone();
        more.insert(1, "0200F5E0#10000000000000".to_owned());
        assert!(exactly(&more).is_err());
        let mut swapped = exact.clone();
        swapped.swap(0, 1);
        assert!(exactly(&swapped).is_err());
    }
}
