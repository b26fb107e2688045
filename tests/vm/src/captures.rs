//! Captures of vcan0 by real capture tools, read back by harvemu.
//!
//! While the emulated harvester runs on vcan0, Wireshark's `dumpcap` (pcapng, with an interface
//! description naming vcan0) and `tcpdump` (classic pcap) capture the interface; both are brought
//! into the VM with their shared libraries (`HARVEMU_VM_PROGRAMS` of scripts/vm/run). They are
//! started, and seen to be capturing, before harvemu starts. Once harvemu has exited the checker
//! sends [`PROBES`] (base, empty and remote frames, which the harvester never sends) and reads
//! them back, and the tools are stopped with SIGTERM. Then `harvemu convert` turns each capture
//! into a candump log, and the log must hold the frames the checker itself read from vcan0
//! during its recording, in the same order, and end with the probes, with kernel times within
//! [`TIME_TOLERANCE`] of the checker's receive times; the dumpcap log must name vcan0; and
//! `harvemu replay` must play the pcapng capture. Expectations come from the checker's own
//! socket; the logs are read with the checker's own parser ([`crate::parse_frame`]).

use crate::harvester::{EXIT_TIMEOUT, IFACE, Recording, seconds_since, spawn_keeping_stderr, wait};
use crate::{Outcome, Report, format_frame, parse_frame};
use socketcan::{CanSocket, Socket};
use std::collections::HashMap;
use std::path::Path;
use std::process::{Child, Command};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// A capture tool and how it is run.
struct Tool {
    /// Its name in the check lines.
    name: &'static str,
    /// The program in the VM (scripts/vm/test-harvester puts it there).
    program: &'static str,
    /// Its arguments.
    args: &'static [&'static str],
    /// The capture it writes.
    capture: &'static str,
    /// The candump log harvemu converts the capture into.
    log: &'static str,
    /// The start of the stderr line that says it is capturing (the interface is open).
    ready: &'static str,
    /// The interface name the log must give every frame, if the format keeps one.
    iface: Option<&'static str>,
}

/// The tools. tcpdump: `-U` writes each packet out at once, `--immediate-mode` hands each packet
/// over at once (otherwise the last second's packets, not yet handed over, are lost on SIGTERM),
/// `-s 72` (a CAN FD frame) because in immediate mode libpcap gives every packet a ring slot of
/// the snapshot length (bounded by the MTU only on Ethernet): with the default 262144 bytes its
/// 2 MiB ring has 8 slots, and it dropped frames; `-Z root` keeps it root (it drops to a
/// `tcpdump` user by default, which the VM lacks). dumpcap: `-q` leaves out the running packet
/// count.
const TOOLS: [Tool; 2] = [
    Tool {
        name: "tcpdump",
        program: "/usr/bin/tcpdump",
        args: &[
            "-i",
            IFACE,
            "-U",
            "--immediate-mode",
            "-s",
            "72",
            "-Z",
            "root",
            "-w",
            "/tmp/tcpdump.pcap",
        ],
        capture: "/tmp/tcpdump.pcap",
        log: "/tmp/tcpdump.log",
        ready: "tcpdump: listening on",
        iface: None,
    },
    Tool {
        name: "dumpcap",
        program: "/usr/bin/dumpcap",
        args: &["-q", "-i", IFACE, "-w", "/tmp/dumpcap.pcapng"],
        capture: "/tmp/dumpcap.pcapng",
        log: "/tmp/dumpcap.log",
        ready: "File: ",
        iface: Some(IFACE),
    },
];

/// How long a tool may take to start capturing (TCG is slow; it takes about 0.2 s).
const READY_TIMEOUT: Duration = Duration::from_secs(15);

/// Largest accepted difference between a captured frame's time and the checker's receive time.
const TIME_TOLERANCE: f64 = 0.050;

/// The share of the checker's frames the capture must hold in one stretch, in order.
const COMMON_SHARE: f64 = 0.9;

/// How long the tools go on capturing once harvemu has exited, before they are stopped: libpcap
/// hands packets over in blocks, which dumpcap (no immediate mode) reads every 250 ms, and a
/// block not yet handed over is lost on SIGTERM.
const DRAIN: Duration = Duration::from_millis(300);

/// Frames the checker sends once harvemu has exited, for the flags the harvester's frames never
/// have: base data, base empty, base remote with a DLC, extended remote, the largest identifiers.
const PROBES: [&str; 5] = [
    "123#DEADBEEF",
    "7FF#",
    "123#R2",
    "0300A0F5#R",
    "1FFFFFFF#0102030405060708",
];

/// How long the checker waits to read back a probe it sent.
const PROBE_TIMEOUT: Duration = Duration::from_secs(1);

/// How long `harvemu replay CAPTURE --fast` plays.
const REPLAY_FOR: &str = "1s";

/// One tool's run.
struct Capture {
    /// The tool.
    tool: &'static Tool,
    /// The process while it runs.
    child: Option<Child>,
    /// Its stderr lines.
    stderr: Arc<Mutex<Vec<String>>>,
    /// Why it did not start capturing; None if it did.
    not_started: Option<String>,
    /// Whether it started and stopped cleanly, and what it said about its packets; None before
    /// it is stopped.
    outcome: Option<Outcome>,
}

/// The capture tools while and after they run.
pub struct Captures {
    /// One per tool.
    captures: Vec<Capture>,
    /// The probes as the checker read them back, with their kernel receive times; or why not.
    probes: Result<Vec<(SystemTime, String)>, String>,
}

impl Captures {
    /// Starts the tools on vcan0 and waits until each says it is capturing; a tool that does not
    /// start fails its check now, and its capture checks later.
    pub fn start(report: &mut Report) -> Captures {
        let started = Instant::now();
        let mut captures = Vec::new();
        for tool in &TOOLS {
            let mut command = Command::new(tool.program);
            command.args(tool.args);
            println!("vmcheck: starting {} {}", tool.program, tool.args.join(" "));
            match spawn_keeping_stderr(&mut command) {
                Ok((child, stderr)) => captures.push(Capture {
                    tool,
                    child: Some(child),
                    stderr,
                    not_started: None,
                    outcome: None,
                }),
                Err(e) => captures.push(Capture {
                    tool,
                    child: None,
                    stderr: Arc::default(),
                    not_started: None,
                    outcome: Some(Err(format!("start {}: {e}", tool.program))),
                }),
            }
        }
        for capture in &mut captures {
            if capture.outcome.is_none() {
                capture.wait_ready(started);
            }
            let name = format!("start {} on {IFACE}", capture.tool.name);
            match &capture.outcome {
                Some(Err(why)) => {
                    capture.not_started = Some(why.clone());
                    report.check(&name, Err(why.clone()));
                }
                _ => {
                    report.check(
                        &name,
                        Ok(format!(
                            "capturing {:.2} s after the start",
                            started.elapsed().as_secs_f64()
                        )),
                    );
                }
            }
        }
        Captures {
            captures,
            probes: Err("not sent".to_owned()),
        }
    }

    /// Sends the probes on `tx` and reads them back on `rx`, then stops the tools with SIGTERM,
    /// `DRAIN` later, and checks that each exits with code 0.
    pub fn stop(&mut self, rx: &CanSocket, tx: &CanSocket, report: &mut Report) {
        self.probes = probe(rx, tx);
        report.check(
            &format!(
                "send {} base, empty and remote frames and read them back",
                PROBES.len()
            ),
            self.probes
                .as_ref()
                .map(|_| PROBES.join(" "))
                .map_err(String::clone),
        );
        std::thread::sleep(DRAIN);
        for capture in &mut self.captures {
            if let Some(child) = &capture.child {
                let pid = child.id();
                match Command::new("kill").arg("-TERM").arg(pid.to_string()).status() {
                    Ok(status) if status.success() => {}
                    Ok(status) => capture.outcome = Some(Err(format!("kill -TERM {pid}: {status}"))),
                    Err(e) => capture.outcome = Some(Err(format!("kill -TERM {pid}: {e}"))),
                }
            }
        }
        for capture in &mut self.captures {
            let Some(mut child) = capture.child.take() else {
                continue;
            };
            let exited = wait(&mut child).and_then(|status| match status.code() {
                Some(0) => Ok(()),
                Some(code) => Err(format!("exit code {code}")),
                None => Err(format!("ended by {status}")),
            });
            // The stderr thread ends with the tool; give it a moment to keep the last lines.
            std::thread::sleep(Duration::from_millis(20));
            let said = capture.said();
            capture.outcome = Some(match (capture.outcome.take(), exited) {
                (Some(Err(why)), _) => Err(why),
                (_, Err(why)) => Err(format!("{why}; it said: {said}")),
                (_, Ok(())) => Ok(said),
            });
            let name = format!("{} stops with exit code 0 on SIGTERM", capture.tool.name);
            let outcome = capture
                .outcome
                .clone()
                .unwrap_or_else(|| Err("not run".to_owned()));
            report.check(&name, outcome);
        }
    }

    /// Converts each capture with `harvemu convert` and compares it with `recording`; replays the
    /// pcapng capture.
    pub fn check(&self, recording: &Recording, harvemu: &Path, config: &Path, report: &mut Report) {
        let Some(origin) = recording.origin else {
            self.fail("no frame was recorded to compare with", report);
            return;
        };
        let expected: Vec<(f64, String)> = recording
            .frames
            .iter()
            .map(|rx| (rx.at, format_frame(&rx.frame)))
            .collect();
        for capture in &self.captures {
            let tool = capture.tool;
            if let Some(why) = &capture.not_started {
                self.fail_one(tool, &format!("{} did not capture: {why}", tool.name), report);
                continue;
            }
            let converted = run_harvemu(
                harvemu,
                &["convert", tool.capture, tool.log],
                &format!("harvemu convert {} {}", tool.capture, tool.log),
                report,
            );
            let log = converted.and_then(|()| {
                std::fs::read_to_string(tool.log)
                    .map_err(|e| format!("read {}: {e}", tool.log))
                    .and_then(|text| read_log(&text, origin))
            });
            let log = match log {
                Ok(log) => log,
                Err(why) => {
                    self.fail_one(tool, &why, report);
                    continue;
                }
            };
            let got: Vec<String> = log.iter().map(|f| f.frame.clone()).collect();
            let want: Vec<String> = expected.iter().map(|(_, f)| f.clone()).collect();
            let compared = Instant::now();
            let (from_want, from_got, len) = longest_common_stretch(&want, &got);
            println!(
                "vmcheck: compared {} with {} frames in {:.2} s",
                want.len(),
                got.len(),
                compared.elapsed().as_secs_f64()
            );
            report.check(
                &format!(
                    "{}'s capture holds the checker's frames in order (at least {:.0} % in one stretch)",
                    tool.name,
                    COMMON_SHARE * 100.0
                ),
                stretch(&expected, &log, (from_want, from_got, len)),
            );
            report.check(
                &format!(
                    "{}'s times within {:.0} ms of the checker's receive times",
                    tool.name,
                    TIME_TOLERANCE * 1e3
                ),
                times(&expected, &log, (from_want, from_got, len)),
            );
            report.check(
                &format!(
                    "{}'s capture ends with the checker's base, empty and remote frames",
                    tool.name
                ),
                ends_with_probes(&self.probes, &log, origin),
            );
            if let Some(iface) = tool.iface {
                report.check(
                    &format!("the {} log names the interface {iface}", tool.name),
                    names(&log, iface),
                );
            }
        }
        let Some(pcapng) = self.captures.iter().find(|c| c.tool.name == "dumpcap") else {
            return;
        };
        let args = [
            "replay",
            pcapng.tool.capture,
            "--fast",
            "--for",
            REPLAY_FOR,
            "--config",
        ];
        let shown = format!(
            "harvemu replay {} --fast --for {REPLAY_FOR} --config {}",
            pcapng.tool.capture,
            config.display()
        );
        let mut command = Command::new(harvemu);
        command.args(args).arg(config);
        let outcome = match &pcapng.not_started {
            Some(why) => Err(format!("dumpcap did not capture: {why}")),
            None => run(&mut command, &shown),
        };
        report.check(
            &format!("{shown} exits with code 0"),
            outcome.map(|()| String::new()),
        );
    }

    /// Every capture check fails with `why`.
    pub fn fail(&self, why: &str, report: &mut Report) {
        for capture in &self.captures {
            self.fail_one(capture.tool, why, report);
        }
        report.check("harvemu replay of the dumpcap capture", Err(why.to_owned()));
    }

    /// `tool`'s capture checks fail with `why`.
    fn fail_one(&self, tool: &Tool, why: &str, report: &mut Report) {
        report.check(
            &format!(
                "{}'s capture converted and compared with the checker's frames",
                tool.name
            ),
            Err(why.to_owned()),
        );
    }
}

impl Capture {
    /// Waits until the tool says it is capturing; notes in `outcome` when it does not.
    fn wait_ready(&mut self, started: Instant) {
        loop {
            let ready = self
                .stderr
                .lock()
                .map(|lines| lines.iter().any(|l| l.starts_with(self.tool.ready)))
                .unwrap_or(false);
            if ready {
                return;
            }
            let Some(child) = &mut self.child else {
                return;
            };
            match child.try_wait() {
                Ok(Some(status)) => {
                    self.child = None;
                    std::thread::sleep(Duration::from_millis(20));
                    self.outcome = Some(Err(format!(
                        "ended ({status}) before it said it is capturing: {}",
                        self.said()
                    )));
                    return;
                }
                Ok(None) if started.elapsed() > READY_TIMEOUT => {
                    self.outcome = Some(Err(format!(
                        "not capturing within {READY_TIMEOUT:?} (no line starting {:?}): {}",
                        self.tool.ready,
                        self.said()
                    )));
                    return;
                }
                Ok(None) => std::thread::sleep(Duration::from_millis(10)),
                Err(e) => {
                    self.outcome = Some(Err(format!("wait: {e}")));
                    return;
                }
            }
        }
    }

    /// What the tool said on stderr, on one line.
    fn said(&self) -> String {
        let lines = self.stderr.lock().map(|l| l.clone()).unwrap_or_default();
        lines
            .iter()
            .map(|l| l.trim_matches(|c: char| c.is_whitespace() || c == '\r'))
            .filter(|l| !l.is_empty())
            .collect::<Vec<_>>()
            .join("; ")
    }
}

/// Reads whatever `rx` holds (harvemu's last frames, after the recording), then sends each probe
/// on `tx` and reads it back on `rx` with its kernel receive time.
fn probe(rx: &CanSocket, tx: &CanSocket) -> Result<Vec<(SystemTime, String)>, String> {
    while rx.read_frame().is_ok() {}
    let mut read = Vec::new();
    for text in PROBES {
        let frame = parse_frame(text)?;
        tx.write_frame(&frame).map_err(|e| format!("send {text}: {e}"))?;
        let deadline = Instant::now() + PROBE_TIMEOUT;
        loop {
            match rx.read_frame_with_timestamp() {
                Ok((got, at)) => {
                    let got = format_frame(&got);
                    if got != text {
                        return Err(format!("sent {text}, read {got}"));
                    }
                    read.push((at, got));
                    break;
                }
                Err(_) if Instant::now() < deadline => {}
                Err(e) => return Err(format!("{text} not read back within {PROBE_TIMEOUT:?}: {e}")),
            }
        }
    }
    Ok(read)
}

/// The log's last frames are the probes, at the times the checker read them.
fn ends_with_probes(
    probes: &Result<Vec<(SystemTime, String)>, String>,
    log: &[Logged],
    origin: SystemTime,
) -> Outcome {
    let probes = probes.as_ref().map_err(|why| format!("no probes: {why}"))?;
    let tail = log
        .get(log.len().saturating_sub(probes.len())..)
        .unwrap_or_default();
    let got: Vec<&str> = tail.iter().map(|l| l.frame.as_str()).collect();
    let want: Vec<&str> = probes.iter().map(|(_, f)| f.as_str()).collect();
    if got != want {
        return Err(format!(
            "expected the last {} frames {}, the log ends with {}",
            want.len(),
            want.join(" "),
            got.join(" ")
        ));
    }
    let worst = probes
        .iter()
        .zip(tail)
        .map(|((at, _), l)| l.at - seconds_since(origin, *at))
        .fold(0.0f64, |w, d| if d.abs() > w.abs() { d } else { w });
    let detail = format!(
        "{}; largest time difference {:+.3} ms",
        got.join(" "),
        worst * 1e3
    );
    if worst.abs() <= TIME_TOLERANCE {
        Ok(detail)
    } else {
        Err(detail)
    }
}

/// Runs `harvemu ARGS` and checks its exit code, on a line named after `shown`.
fn run_harvemu(harvemu: &Path, args: &[&str], shown: &str, report: &mut Report) -> Result<(), String> {
    let mut command = Command::new(harvemu);
    command.args(args);
    let outcome = run(&mut command, shown);
    report.check(
        &format!("{shown} exits with code 0"),
        outcome.clone().map(|()| String::new()),
    );
    outcome
}

/// Runs `command` to its end (killed after `EXIT_TIMEOUT`), stderr echoed; Ok on exit code 0.
fn run(command: &mut Command, shown: &str) -> Result<(), String> {
    println!("vmcheck: running {shown}");
    let started = Instant::now();
    let (mut child, _stderr) = spawn_keeping_stderr(command).map_err(|e| format!("start: {e}"))?;
    let status = wait(&mut child)?;
    println!("vmcheck: ran for {:.2} s", started.elapsed().as_secs_f64());
    match status.code() {
        Some(0) => Ok(()),
        Some(code) => Err(format!("exit code {code} (within {EXIT_TIMEOUT:?})")),
        None => Err("ended by a signal".to_owned()),
    }
}

/// One frame of a candump log.
#[derive(Debug)]
struct Logged {
    /// Its time, in seconds since the checker's first frame.
    at: f64,
    /// The interface name.
    iface: String,
    /// The frame in can-utils notation, as the checker writes it.
    frame: String,
}

/// Reads a candump log `(SECS.USECS) IFACE ID#DATA` per line, times relative to `origin`.
fn read_log(text: &str, origin: SystemTime) -> Result<Vec<Logged>, String> {
    let mut frames = Vec::new();
    for (n, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let bad = |why: &str| format!("log line {}: {why}: {line:?}", n + 1);
        let mut words = line.split_whitespace();
        let (Some(stamp), Some(iface), Some(frame), None) =
            (words.next(), words.next(), words.next(), words.next())
        else {
            return Err(bad("not `(SECS.USECS) IFACE FRAME`"));
        };
        let stamp = stamp
            .strip_prefix('(')
            .and_then(|s| s.strip_suffix(')'))
            .ok_or_else(|| bad("time not in parentheses"))?;
        let (secs, fraction) = stamp
            .split_once('.')
            .ok_or_else(|| bad("time without a fraction"))?;
        if fraction.len() != 6 || !fraction.bytes().all(|b| b.is_ascii_digit()) {
            return Err(bad("time's fraction is not 6 digits"));
        }
        let secs: u64 = secs.parse().map_err(|_| bad("seconds are not a number"))?;
        let micros: u32 = fraction
            .parse()
            .map_err(|_| bad("microseconds are not a number"))?;
        let at = UNIX_EPOCH + Duration::new(secs, micros * 1000);
        let frame = parse_frame(frame).map_err(|why| bad(&why))?;
        frames.push(Logged {
            at: seconds_since(origin, at),
            iface: iface.to_owned(),
            frame: format_frame(&frame),
        });
    }
    Ok(frames)
}

/// The longest stretch of consecutive frames `a` and `b` share: where it starts in each, and
/// its length.
fn longest_common_stretch(a: &[String], b: &[String]) -> (usize, usize, usize) {
    let mut ids: HashMap<&str, u32> = HashMap::new();
    let a = intern(&mut ids, a);
    let b = intern(&mut ids, b);
    // The usual case, a whole in b, in linear time.
    if !a.is_empty()
        && let Some(at) = b.windows(a.len()).position(|w| w == a.as_slice())
    {
        return (0, at, a.len());
    }
    // current[j + 1]: length of the common stretch ending at a[i] and b[j].
    let mut previous = vec![0usize; b.len() + 1];
    let mut current = vec![0usize; b.len() + 1];
    let mut best = (0, 0, 0);
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            current[j + 1] = if x == y { previous[j] + 1 } else { 0 };
            if current[j + 1] > best.2 {
                let len = current[j + 1];
                best = (i + 1 - len, j + 1 - len, len);
            }
        }
        std::mem::swap(&mut previous, &mut current);
    }
    best
}

/// Each string's number in `ids`, new ones numbered on.
fn intern<'a>(ids: &mut HashMap<&'a str, u32>, list: &'a [String]) -> Vec<u32> {
    list.iter()
        .map(|s| {
            let next = u32::try_from(ids.len()).unwrap_or(u32::MAX);
            *ids.entry(s.as_str()).or_insert(next)
        })
        .collect()
}

/// The common stretch covers at least `COMMON_SHARE` of the checker's frames.
fn stretch(
    expected: &[(f64, String)],
    log: &[Logged],
    (from_want, from_got, len): (usize, usize, usize),
) -> Outcome {
    let n = expected.len();
    if n == 0 {
        return Err("the checker recorded no frames".to_owned());
    }
    let share = len as f64 / n as f64;
    let span = |from: usize| match (expected.get(from), expected.get(from + len.max(1) - 1)) {
        (Some((a, _)), Some((b, _))) => format!("{a:.3}–{b:.3} s"),
        _ => "none".to_owned(),
    };
    let detail = format!(
        "{len} of the checker's {n} frames ({:.1} %, {}) in one stretch, from its frame {} and the \
         capture's frame {} of {}",
        share * 100.0,
        span(from_want),
        from_want + 1,
        from_got + 1,
        log.len()
    );
    if share >= COMMON_SHARE {
        Ok(detail)
    } else {
        let mismatch = expected
            .get(from_want + len)
            .map(|(at, f)| {
                let got = log.get(from_got + len).map_or("nothing", |l| l.frame.as_str());
                format!("; after it the checker read {f} at {at:.3} s, the capture has {got}")
            })
            .unwrap_or_default();
        Err(format!("{detail}{mismatch}"))
    }
}

/// Over the common stretch, every capture time is within `TIME_TOLERANCE` of the checker's.
fn times(
    expected: &[(f64, String)],
    log: &[Logged],
    (from_want, from_got, len): (usize, usize, usize),
) -> Outcome {
    if len == 0 {
        return Err("no frames in common".to_owned());
    }
    let mut worst = (0.0f64, 0usize);
    let mut sum = 0.0;
    for k in 0..len {
        let (Some((want, _)), Some(got)) = (expected.get(from_want + k), log.get(from_got + k)) else {
            return Err("the stretch runs past the frames".to_owned());
        };
        let d = got.at - want;
        sum += d.abs();
        if d.abs() > worst.0.abs() {
            worst = (d, from_want + k);
        }
    }
    let detail = format!(
        "largest difference {:+.3} ms (checker's frame {}), mean {:.3} ms over {len} frames",
        worst.0 * 1e3,
        worst.1 + 1,
        sum / len as f64 * 1e3
    );
    if worst.0.abs() <= TIME_TOLERANCE {
        Ok(detail)
    } else {
        Err(detail)
    }
}

/// Every frame of the log is on `iface`.
fn names(log: &[Logged], iface: &str) -> Outcome {
    if log.is_empty() {
        return Err("the log holds no frames".to_owned());
    }
    let other: Vec<&str> = log
        .iter()
        .filter(|l| l.iface != iface)
        .map(|l| l.iface.as_str())
        .take(3)
        .collect();
    if other.is_empty() {
        Ok(format!("{} frames", log.len()))
    } else {
        Err(format!("frames on {}", other.join(", ")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn strings(list: &[&str]) -> Vec<String> {
        list.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn the_longest_common_stretch_is_found() {
        let a = strings(&["1", "2", "3", "4", "5", "6"]);
        let b = strings(&["0", "2", "3", "4", "5", "7", "1"]);
        assert_eq!(longest_common_stretch(&a, &b), (1, 1, 4));
        assert_eq!(longest_common_stretch(&a, &a), (0, 0, 6));
        assert_eq!(longest_common_stretch(&a, &[]), (0, 0, 0));
        let c = strings(&["9", "1", "2", "3", "4", "5", "6", "7"]);
        assert_eq!(longest_common_stretch(&a, &c), (0, 1, 6));
    }

    #[test]
    fn logs_are_read_relative_to_the_origin() {
        let origin = UNIX_EPOCH + Duration::new(1_700_000_000, 500_000_000);
        let log = read_log(
            "(1700000000.750000) vcan0 0601F5D0#200D0002FFBFFF00\n(1700000001.000001) can0 123#R2\n",
            origin,
        )
        .expect("a good log");
        assert_eq!(log.len(), 2);
        assert!((log[0].at - 0.25).abs() < 1e-9);
        assert_eq!(log[1].iface, "can0");
        assert_eq!(log[1].frame, "123#R2");
        assert!(read_log("(1700000000.75) vcan0 123#01\n", origin).is_err());
        assert!(read_log("(1700000000.750000) vcan0 12345678#01\n", origin).is_ok());
        assert!(read_log("(1700000000.750000) vcan0 20000080#01\n", origin).is_err());
    }

    #[test]
    fn stretch_and_times_are_judged() {
        let expected: Vec<(f64, String)> = (0..10)
            .map(|i| (f64::from(i) * 0.1, format!("123#0{i}")))
            .collect();
        let log: Vec<Logged> = (1..10)
            .map(|i| Logged {
                at: f64::from(i) * 0.1 + 0.001,
                iface: "vcan0".to_owned(),
                frame: format!("123#0{i}"),
            })
            .collect();
        assert!(stretch(&expected, &log, (1, 0, 9)).is_ok());
        assert!(stretch(&expected, &log, (1, 0, 8)).is_err());
        assert!(times(&expected, &log, (1, 0, 9)).is_ok());
        assert!(times(&expected, &log, (0, 0, 9)).is_err());
        assert!(names(&log, "vcan0").is_ok());
        assert!(names(&log, "can0").is_err());
    }
}
