//! `harvemu-vmcheck harvester HARVEMU CONFIG`: the end-to-end check of `harvemu run --iface`
//! with a monitor that is not harvemu's.
//!
//! Creates vcan0, opens two raw sockets on it (one records, one sends), runs `HARVEMU run CONFIG
//! --iface vcan0 --without F5 --for RUN_FOR` as a child process (its stderr echoed and kept) and,
//! for `RECORD` from the first frame, records every frame with its kernel receive time while
//! [`crate::monitor`] plays the monitor F5: it calibrates and acknowledges the six flow sensors.
//! 2.5 s into the recording it sends `0300A0F5#0101` (`row.command`: start auto alignment); from
//! 4.5 s on it freezes harvemu three times for 400 ms (SIGSTOP, SIGCONT, 1.5 s apart). Then it
//! waits for the child and checks the identifiers, the periods before the first freeze, A0's
//! state before and after the command, the frames' format, the monitor's sessions, the stalls
//! ([`crate::outside`]) and what harvemu said on stderr. tcpdump and dumpcap capture vcan0 from
//! before harvemu starts until it has exited, and harvemu must read their captures back as the
//! frames recorded here ([`crate::captures`]). Then [`crate::replay`] checks `harvemu replay
//! --iface`, and [`crate::imported`] a network imported from a DBC file on the interface.

use crate::captures::Captures;
use crate::monitor::Monitor;
use crate::{Outcome, Report, create_vcan, delete_vcan, format_frame, parse_frame, read_error};
use socketcan::{CanFrame, CanSocket, EmbeddedFrame, Id, Socket, SocketOptions};
use std::collections::BTreeMap;
use std::io::{self, BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant, SystemTime};

/// The interface the harvester is put on.
pub const IFACE: &str = "vcan0";

/// How much emulated time `harvemu run` is given: the recording plus harvemu's start-up, less
/// the bus time the freezes slip, with a margin.
const RUN_FOR: &str = "11s";

/// How long frames are recorded, from the first one.
const RECORD: Duration = Duration::from_millis(9500);

/// When, from the first frame, the row command is injected.
const INJECT_AFTER: Duration = Duration::from_millis(2500);

/// The injected frame: `row.command` to A0, start auto alignment.
const INJECTED: &str = "0300A0F5#0101";

/// When, in seconds from the first frame, harvemu is frozen (after the calibration and the period
/// window, 1.5 s apart so that each freeze is over and streaming again before the next).
pub const STALLS: [f64; 3] = [4.5, 6.0, 7.5];

/// How long each freeze lasts.
pub const STALL: Duration = Duration::from_millis(400);

/// The periods are measured from here to the first freeze (seconds from the first frame).
const PERIODS_FROM: f64 = 2.0;

/// How long harvemu may take to put its first frame on the interface (TCG is slow).
pub const STARTUP_TIMEOUT: Duration = Duration::from_secs(30);

/// How long harvemu may take to exit once the recording is over.
pub const EXIT_TIMEOUT: Duration = Duration::from_secs(20);

/// How long one read waits, so that the loop can look at the clock.
pub const POLL: Duration = Duration::from_millis(5);

/// Allowed deviation of a mean period from the nominal one.
const PERIOD_TOLERANCE: f64 = 0.10;

/// After the command, a row.status frame this soon may still have been produced before A0 saw it.
const REACTION_GRACE: f64 = 0.1;

/// A0 locks onto the row 2 s after it starts seeking (configs/nodes/a0.ron); from this long after
/// the command `row.status` may report 2 = locked instead of 1 = seeking.
const SEEKING_FOR: f64 = 1.8;

/// One received frame: seconds since the first frame, and the frame.
pub struct Rx {
    /// Kernel receive time, in seconds since the first frame's.
    pub at: f64,
    /// The frame.
    pub frame: CanFrame,
}

/// One freeze of harvemu, in seconds since the first frame.
#[derive(Clone, Debug, Default)]
pub struct Stall {
    /// When SIGSTOP was sent.
    pub stopped: f64,
    /// When SIGCONT was sent.
    pub resumed: Option<f64>,
    /// What went wrong sending a signal.
    pub error: Option<String>,
}

/// What the recording saw.
pub struct Recording {
    /// Every frame, in order of arrival (the monitor's own included).
    pub frames: Vec<Rx>,
    /// The first frame's kernel receive time, which `Rx::at` counts from.
    pub origin: Option<SystemTime>,
    /// When the row command was sent, in seconds since the first frame.
    injected_at: Option<f64>,
    /// Read errors other than timeouts, and the injection's and the monitor's send failures.
    errors: Vec<String>,
    /// The monitor, with what it saw.
    pub monitor: Monitor,
    /// The freezes.
    pub stalls: Vec<Stall>,
    /// Seconds from the first frame to the end of the recording.
    pub end: f64,
}

/// Runs the harvester checks with `harvemu` and `config`.
pub fn run(harvemu: &Path, config: &Path, report: &mut Report) {
    let iface = match create_vcan(IFACE) {
        Ok(iface) => iface,
        Err(why) => {
            report.check(&format!("create and bring up {IFACE}"), Err(why));
            return;
        }
    };
    report.check(&format!("create and bring up {IFACE}"), Ok("netlink".to_owned()));
    match open(IFACE).and_then(|rx| Ok((rx, open(IFACE)?))) {
        Ok((rx, tx)) => {
            report.check("open raw CAN sockets with receive timestamps", Ok(String::new()));
            with_socket(&rx, &tx, harvemu, config, report);
            crate::replay::run(&rx, harvemu, config, report);
            crate::imported::run(&rx, harvemu, report);
        }
        Err(why) => {
            report.check("open raw CAN sockets with receive timestamps", Err(why));
        }
    }
    report.check(&format!("delete {IFACE}"), delete_vcan(iface, IFACE));
}

/// Opens a raw socket, with `SO_TIMESTAMPNS` and a short read timeout.
fn open(name: &str) -> Result<CanSocket, String> {
    let socket = CanSocket::open(name).map_err(|e| format!("open a raw CAN socket on {name}: {e}"))?;
    socket
        .set_read_timeout(POLL)
        .map_err(|e| format!("SO_RCVTIMEO: {e}"))?;
    socket
        .set_recv_timestamp(true)
        .map_err(|e| format!("set SO_TIMESTAMPNS: {e}"))?;
    Ok(socket)
}

/// Starts `command` with stderr piped; a thread echoes each line to this process's stderr and
/// keeps it.
pub fn spawn_keeping_stderr(command: &mut Command) -> io::Result<(Child, Arc<Mutex<Vec<String>>>)> {
    let mut child = command
        .stdin(Stdio::null())
        .stdout(Stdio::inherit())
        .stderr(Stdio::piped())
        .spawn()?;
    let lines = Arc::new(Mutex::new(Vec::new()));
    if let Some(stderr) = child.stderr.take() {
        let kept = lines.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                eprintln!("{line}");
                if let Ok(mut kept) = kept.lock() {
                    kept.push(line);
                }
            }
        });
    }
    Ok((child, lines))
}

/// Starts the capture tools and harvemu, records while monitoring, waits for harvemu, stops the
/// tools and checks what was recorded and captured.
fn with_socket(rx: &CanSocket, tx: &CanSocket, harvemu: &Path, config: &Path, report: &mut Report) {
    let mut captures = Captures::start(report);
    let ran = run_and_record(rx, tx, harvemu, config, report);
    captures.stop(rx, tx, report);
    let Some((recording, stderr)) = ran else {
        captures.fail("harvemu did not run", report);
        return;
    };
    let recording = match recording {
        Ok(recording) => recording,
        Err(why) => {
            report.check("record the bus", Err(why));
            captures.fail("the bus was not recorded", report);
            return;
        }
    };
    report.check(
        "record the bus",
        if recording.errors.is_empty() {
            Ok(format!(
                "{} frames, {} identifiers, in {:.2} s",
                recording.frames.len(),
                identifiers(&recording.frames).len(),
                recording.frames.last().map_or(0.0, |rx| rx.at)
            ))
        } else {
            Err(recording.errors.join("; "))
        },
    );
    check_identifiers(&recording, report);
    check_periods(&recording, report);
    report.check("A0 reacts to row.command", row_state(&recording));
    report.check(
        "every frame is a well-formed harvester frame",
        well_formed(&recording.frames),
    );
    // The stderr thread ends with harvemu; what it kept is complete once harvemu has exited.
    let lines = stderr.lock().map(|l| l.clone()).unwrap_or_default();
    crate::outside::check(&recording, &lines, report);
    captures.check(&recording, harvemu, config, report);
}

/// What harvemu's run gave: the recording (or why there is none) and harvemu's stderr lines.
type Ran = (Result<Recording, String>, Arc<Mutex<Vec<String>>>);

/// Starts harvemu, records while monitoring and waits for it; None when it did not start.
fn run_and_record(
    rx: &CanSocket,
    tx: &CanSocket,
    harvemu: &Path,
    config: &Path,
    report: &mut Report,
) -> Option<Ran> {
    let mut command = Command::new(harvemu);
    command
        .arg("run")
        .arg(config)
        .args(["--iface", IFACE, "--without", "F5", "--for", RUN_FOR]);
    let shown = format!(
        "{} run {} --iface {IFACE} --without F5 --for {RUN_FOR}",
        harvemu.display(),
        config.display()
    );
    println!("vmcheck: starting {shown}");
    let (mut child, stderr) = match spawn_keeping_stderr(&mut command) {
        Ok(started) => started,
        Err(e) => {
            report.check(&format!("start {shown}"), Err(e.to_string()));
            return None;
        }
    };
    report.check(&format!("start {shown}"), Ok(format!("pid {}", child.id())));
    let spawned = Instant::now();

    let recording = record(rx, tx, &mut child, spawned);
    // harvemu's live line (in a terminal) ends without a newline; start the checker's lines on a fresh one.
    println!();
    report.check(
        "harvemu exits with code 0",
        wait(&mut child).and_then(|status| match status.code() {
            Some(0) => Ok(format!(
                "{:.1} s after it started",
                spawned.elapsed().as_secs_f64()
            )),
            Some(code) => Err(format!("exit code {code}")),
            None => Err(format!("ended by {status}")),
        }),
    );
    Some((recording, stderr))
}

/// Records frames until `RECORD` after the first one, answering as the monitor, injecting the
/// row command and freezing harvemu on the way. Fails when harvemu ends, or sends nothing, before
/// the recording starts.
fn record(rx: &CanSocket, tx: &CanSocket, child: &mut Child, spawned: Instant) -> Result<Recording, String> {
    let mut recording = Recording {
        frames: Vec::new(),
        origin: None,
        injected_at: None,
        errors: Vec::new(),
        monitor: Monitor::default(),
        stalls: Vec::new(),
        end: RECORD.as_secs_f64(),
    };
    let mut first: Option<(SystemTime, Instant)> = None;
    let pid = child.id();
    loop {
        match first {
            None => {
                if let Ok(Some(status)) = child.try_wait() {
                    return Err(format!("harvemu ended ({status}) before it sent a frame"));
                }
                if spawned.elapsed() > STARTUP_TIMEOUT {
                    return Err(format!(
                        "no frame on {IFACE} within {STARTUP_TIMEOUT:?} of the start"
                    ));
                }
            }
            Some((origin, started)) => {
                let elapsed = started.elapsed();
                if elapsed >= RECORD {
                    if let Some(stall) = recording.stalls.last_mut().filter(|s| s.resumed.is_none()) {
                        stall.resumed = Some(signal(pid, "CONT", origin, &mut stall.error));
                    }
                    return Ok(recording);
                }
                if recording.injected_at.is_none() && elapsed >= INJECT_AFTER {
                    recording.injected_at = Some(inject(tx, origin, &mut recording.errors));
                }
                freeze(&mut recording.stalls, pid, origin, elapsed);
            }
        }
        match rx.read_frame_with_timestamp() {
            Ok((frame, stamp)) => {
                let (origin, _) = *first.get_or_insert_with(|| {
                    println!(
                        "vmcheck: first frame {:.2} s after the start: recording for {RECORD:?}",
                        spawned.elapsed().as_secs_f64()
                    );
                    (stamp, Instant::now())
                });
                recording.origin = Some(origin);
                let at = seconds_since(origin, stamp);
                for answer in recording.monitor.handle(at, &frame) {
                    if let Err(e) = tx.write_frame(&answer)
                        && recording.errors.len() < 5
                    {
                        recording
                            .errors
                            .push(format!("monitor: send {}: {e}", format_frame(&answer)));
                    }
                }
                recording.frames.push(Rx { at, frame });
            }
            Err(e) if matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock) => {}
            Err(e) => {
                let why = read_error(&e, POLL, "recorder");
                if recording.errors.len() < 5 {
                    recording.errors.push(why);
                }
                if recording.errors.len() >= 5 {
                    return Ok(recording);
                }
            }
        }
    }
}

/// Starts the next freeze of harvemu when its time has come, and ends the present one after
/// `STALL`.
fn freeze(stalls: &mut Vec<Stall>, pid: u32, origin: SystemTime, elapsed: Duration) {
    match stalls.last_mut() {
        Some(stall) if stall.resumed.is_none() => {
            if seconds_since(origin, SystemTime::now()) >= stall.stopped + STALL.as_secs_f64() {
                stall.resumed = Some(signal(pid, "CONT", origin, &mut stall.error));
            }
        }
        _ => {
            if let Some(&at) = STALLS.get(stalls.len())
                && elapsed.as_secs_f64() >= at
            {
                let mut stall = Stall::default();
                stall.stopped = signal(pid, "STOP", origin, &mut stall.error);
                println!("vmcheck: froze harvemu (SIGSTOP) at {:.3} s", stall.stopped);
                stalls.push(stall);
            }
        }
    }
}

/// Sends SIG`name` to `pid` with busybox's `kill` (this checker links nothing but socketcan) and
/// returns when it was delivered, in seconds since `origin`; a failure goes to `error`.
fn signal(pid: u32, name: &str, origin: SystemTime, error: &mut Option<String>) -> f64 {
    match Command::new("kill")
        .arg(format!("-{name}"))
        .arg(pid.to_string())
        .status()
    {
        Ok(status) if status.success() => {}
        Ok(status) => *error = Some(format!("kill -{name} {pid}: {status}")),
        Err(e) => *error = Some(format!("kill -{name} {pid}: {e}")),
    }
    seconds_since(origin, SystemTime::now())
}

/// Sends the row command and returns when, in seconds since the first frame.
fn inject(socket: &CanSocket, origin: SystemTime, errors: &mut Vec<String>) -> f64 {
    let sent = parse_frame(INJECTED).and_then(|frame| {
        let at = SystemTime::now();
        socket
            .write_frame(&frame)
            .map(|()| at)
            .map_err(|e| format!("send {INJECTED}: {e}"))
    });
    match sent {
        Ok(at) => {
            let at = seconds_since(origin, at);
            println!("vmcheck: sent {INJECTED} at {at:.3} s");
            at
        }
        Err(why) => {
            errors.push(why);
            f64::NAN
        }
    }
}

/// Seconds from `origin` to `at` (negative if `at` is earlier).
pub fn seconds_since(origin: SystemTime, at: SystemTime) -> f64 {
    match at.duration_since(origin) {
        Ok(d) => d.as_secs_f64(),
        Err(e) => -e.duration().as_secs_f64(),
    }
}

/// Waits for a child to exit, killing it after `EXIT_TIMEOUT`.
pub fn wait(child: &mut Child) -> Result<ExitStatus, String> {
    let deadline = Instant::now() + EXIT_TIMEOUT;
    loop {
        match child.try_wait() {
            Ok(Some(status)) => return Ok(status),
            Ok(None) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(50)),
            Ok(None) => {
                let killed = child.kill().and_then(|()| child.wait());
                return Err(format!(
                    "still running {EXIT_TIMEOUT:?} after the recording; killed ({killed:?})"
                ));
            }
            Err(e) => return Err(format!("wait: {e}")),
        }
    }
}

/// The raw identifier of an extended frame, None for a base one.
pub fn extended_id(frame: &CanFrame) -> Option<u32> {
    match frame.id() {
        Id::Extended(id) => Some(id.as_raw()),
        Id::Standard(_) => None,
    }
}

/// How many frames of each extended identifier were received.
fn identifiers(frames: &[Rx]) -> BTreeMap<u32, usize> {
    let mut seen = BTreeMap::new();
    for rx in frames {
        if let Some(id) = extended_id(&rx.frame) {
            *seen.entry(id).or_insert(0) += 1;
        }
    }
    seen
}

/// Receive times of the data frames with identifier `id` whose payload starts with `prefix`.
pub fn times(frames: &[Rx], id: u32, prefix: &[u8]) -> Vec<f64> {
    frames
        .iter()
        .filter(|rx| extended_id(&rx.frame) == Some(id) && rx.frame.data().starts_with(prefix))
        .map(|rx| rx.at)
        .collect()
}

/// Checks that every expected message appears, each on its own PASS/FAIL line.
fn check_identifiers(recording: &Recording, report: &mut Report) {
    let frames = &recording.frames;
    let mut expect = |what: &str, id: u32, prefix: &[u8]| {
        let n = times(frames, id, prefix).len();
        let name = format!("identifier {id:08X} {what} present");
        report.check(
            &name,
            if n > 0 {
                Ok(format!("{n} frames"))
            } else {
                Err("not received".to_owned())
            },
        );
    };
    expect("E0 speed.status", 0x0200_F5E0, &[0x10]);
    expect("B1 param.engine", 0x0500_F5B1, &[0x21]);
    expect("A0 row.status", 0x0300_F5A0, &[0x10]);
    for sensor in 0..6u32 {
        let d = 0xD0 + sensor;
        expect(
            &format!("D{sensor} flow.marker_flow"),
            0x0601_F500 | d,
            &[0x20, 0x0D, 0x00, 0x02, 0xFF, 0xBF, 0xFF, 0x00],
        );
        expect(
            &format!("monitor flow.ack to D{sensor}"),
            0x0601_00F5 | d << 8,
            &[0x21],
        );
    }
}

/// Checks the mean periods between `PERIODS_FROM` and the first freeze: the other nodes' and every
/// flow sensor's flow group, which keeps coming only while the outside monitor acknowledges.
fn check_periods(recording: &Recording, report: &mut Report) {
    let (from, to) = (PERIODS_FROM, STALLS[0]);
    let mut periodic = vec![
        ("E0 speed.status".to_owned(), 0x0200_F5E0, &[0x10u8][..], 50.0),
        ("B1 param.engine".to_owned(), 0x0500_F5B1, &[0x21][..], 100.0),
        ("A0 row.status".to_owned(), 0x0300_F5A0, &[0x10][..], 200.0),
    ];
    for sensor in 0..6u32 {
        periodic.push((
            format!("D{sensor} flow.marker_flow"),
            0x0601_F5D0 | sensor,
            &[0x20, 0x0D][..],
            100.0,
        ));
    }
    for (what, id, prefix, nominal_ms) in periodic {
        let name = format!("{what} period {nominal_ms} ms ±10 % ({from:.1}–{to:.1} s)");
        let window: Vec<f64> = times(&recording.frames, id, prefix)
            .into_iter()
            .filter(|&at| at >= from && at < to)
            .collect();
        report.check(&name, period(&window, nominal_ms));
    }
}

/// The mean period of `times` against `nominal_ms`.
fn period(times: &[f64], nominal_ms: f64) -> Outcome {
    let (Some(first), Some(last)) = (times.first(), times.last()) else {
        return Err("no frames".to_owned());
    };
    if times.len() < 3 {
        return Err(format!("only {} frames", times.len()));
    }
    let gaps: Vec<f64> = times.windows(2).map(|w| (w[1] - w[0]) * 1e3).collect();
    let mean = (last - first) * 1e3 / gaps.len() as f64;
    let min = gaps.iter().copied().fold(f64::INFINITY, f64::min);
    let max = gaps.iter().copied().fold(0.0, f64::max);
    let detail = format!(
        "mean {mean:.1} ms over {} periods, min {min:.1} ms, max {max:.1} ms",
        gaps.len()
    );
    if (mean - nominal_ms).abs() <= nominal_ms * PERIOD_TOLERANCE {
        Ok(detail)
    } else {
        Err(detail)
    }
}

/// A0's `row.status` state (Data1) reads 0 before the injected command, 1 = seeking after it
/// (2 = locked is allowed from `SEEKING_FOR` after it).
fn row_state(recording: &Recording) -> Outcome {
    let Some(injected) = recording.injected_at.filter(|at| at.is_finite()) else {
        return Err(format!("{INJECTED} was not sent"));
    };
    let statuses: Vec<(f64, u8)> = recording
        .frames
        .iter()
        .filter(|rx| extended_id(&rx.frame) == Some(0x0300_F5A0) && rx.frame.data().first() == Some(&0x10))
        .map(|rx| (rx.at - injected, rx.frame.data().get(1).copied().unwrap_or(0xFF)))
        .collect();
    let before: Vec<u8> = statuses
        .iter()
        .filter(|(t, _)| *t < 0.0)
        .map(|&(_, s)| s)
        .collect();
    let after: Vec<(f64, u8)> = statuses
        .iter()
        .copied()
        .filter(|(t, _)| *t >= REACTION_GRACE)
        .collect();
    let states = |list: &[(f64, u8)]| {
        list.iter()
            .map(|(t, s)| format!("{s}@{:+.0}ms", t * 1e3))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let detail = format!(
        "before: {} frames, states {:?}; after: {}",
        before.len(),
        before.iter().collect::<std::collections::BTreeSet<_>>(),
        states(
            &statuses
                .iter()
                .copied()
                .filter(|(t, _)| *t >= 0.0)
                .collect::<Vec<_>>()
        )
    );
    if before.is_empty() || before.iter().any(|&s| s != 0) {
        return Err(format!("expected only state 0 before the command; {detail}"));
    }
    let seeking = after.iter().filter(|&&(t, s)| t < SEEKING_FOR && s == 1).count();
    let wrong: Vec<(f64, u8)> = after
        .iter()
        .copied()
        .filter(|&(t, s)| !(s == 1 || (t >= SEEKING_FOR && s == 2)))
        .collect();
    if seeking == 0 {
        return Err(format!(
            "no state 1 within {SEEKING_FOR} s of the command; {detail}"
        ));
    }
    if !wrong.is_empty() {
        return Err(format!("unexpected states {}; {detail}", states(&wrong)));
    }
    Ok(detail)
}

/// Every frame is an extended data frame with identifier fields and a DLC harvemu can send:
/// priority 2–6, frame type 00 or 01, DLC 1–8, and the catalogue's DLC for the checked messages.
fn well_formed(frames: &[Rx]) -> Outcome {
    if frames.is_empty() {
        return Err("no frames".to_owned());
    }
    let mut bad = Vec::new();
    let mut dlcs: BTreeMap<usize, usize> = BTreeMap::new();
    for rx in frames {
        let why = malformed(&rx.frame);
        *dlcs.entry(rx.frame.dlc()).or_insert(0) += 1;
        if let Some(why) = why {
            if bad.len() < 5 {
                bad.push(format!("{} at {:.3} s: {why}", format_frame(&rx.frame), rx.at));
            } else {
                bad.push(String::new());
            }
        }
    }
    if bad.is_empty() {
        Ok(format!("{} frames, DLCs {dlcs:?}", frames.len()))
    } else {
        let n = bad.len();
        bad.retain(|s| !s.is_empty());
        Err(format!("{n} bad frames: {}", bad.join("; ")))
    }
}

/// Why a frame is not one harvemu sends, or None.
fn malformed(frame: &CanFrame) -> Option<String> {
    if !matches!(frame, CanFrame::Data(_)) {
        return Some("not a data frame".to_owned());
    }
    let Some(id) = extended_id(frame) else {
        return Some("base identifier".to_owned());
    };
    let (priority, kind) = (id >> 24, (id >> 16) & 0xFF);
    if !(2..=6).contains(&priority) {
        return Some(format!("priority {priority}"));
    }
    if kind > 1 {
        return Some(format!("frame type {kind:02X}"));
    }
    let dlc = frame.dlc();
    if !(1..=8).contains(&dlc) || dlc != frame.data().len() {
        return Some(format!("DLC {dlc} with {} data bytes", frame.data().len()));
    }
    let data = frame.data();
    let expected = match (id, data[0]) {
        (0x0200_F5E0, 0x10) => Some(7),
        (0x0500_F5B1, 0x21) => Some(3),
        (0x0300_F5A0, 0x10) => Some(5),
        (id, 0x20 | 0x01 | 0x02) if id & 0xFFFF_FFF0 == 0x0601_F5D0 => Some(8),
        (id, 0x30) if id & 0xFFFF_FFF0 == 0x0601_F5D0 => Some(4),
        (id, 0x21) if id & 0xFFFF_F0FF == 0x0601_D0F5 => Some(3),
        (id, 0x10) if id & 0xFFFF_F0FF == 0x0601_D0F5 => Some(5),
        _ => None,
    };
    match expected {
        Some(n) if n != dlc => Some(format!("DLC {dlc}, the catalogue says {n}")),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rx(at: f64, text: &str) -> Rx {
        Rx {
            at,
            frame: parse_frame(text).expect("valid frame"),
        }
    }

    #[test]
    fn periods_are_measured_as_means() {
        let times: Vec<f64> = (0..20)
            .map(|i| f64::from(i) * 0.05 + if i % 2 == 0 { 0.004 } else { 0.0 })
            .collect();
        assert!(period(&times, 50.0).is_ok());
        assert!(period(&times, 100.0).is_err());
        assert!(period(&[0.0, 0.05], 50.0).is_err());
    }

    #[test]
    fn malformed_frames_are_found() {
        assert!(malformed(&parse_frame("0200F5E0#10000000000000").expect("frame")).is_none());
        assert!(malformed(&parse_frame("0601F5D3#200D0002FFBFFF00").expect("frame")).is_none());
        assert!(malformed(&parse_frame("0601D2F5#210D05").expect("frame")).is_none());
        assert!(malformed(&parse_frame("0200F5E0#1000").expect("frame")).is_some());
        assert!(malformed(&parse_frame("123#10").expect("frame")).is_some());
        assert!(malformed(&parse_frame("0300F5A0#R").expect("frame")).is_some());
        assert!(malformed(&parse_frame("0702F5A0#10").expect("frame")).is_some());
        assert!(malformed(&parse_frame("0500F5B2#").expect("frame")).is_some());
    }

    #[test]
    fn row_state_wants_idle_then_seeking() {
        let frames = vec![
            rx(0.1, "0300F5A0#1000000000"),
            rx(0.3, "0300F5A0#1000000000"),
            rx(0.55, "0300F5A0#1000000000"),
            rx(0.75, "0300F5A0#1001000000"),
            rx(2.7, "0300F5A0#1002000000"),
        ];
        let ok = Recording {
            frames,
            origin: None,
            injected_at: Some(0.5),
            errors: Vec::new(),
            monitor: Monitor::default(),
            stalls: Vec::new(),
            end: 3.0,
        };
        assert!(row_state(&ok).is_ok(), "{:?}", row_state(&ok));
        let late = Recording {
            frames: vec![rx(0.1, "0300F5A0#1000000000"), rx(0.75, "0300F5A0#1000000000")],
            origin: None,
            injected_at: Some(0.5),
            errors: Vec::new(),
            monitor: Monitor::default(),
            stalls: Vec::new(),
            end: 3.0,
        };
        assert!(row_state(&late).is_err());
    }
}
