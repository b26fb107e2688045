//! What users see stays the same, and harvemu's traces are in time order.
//!
//! Every shipped scenario runs with seeds 1 to 5 (`harvemu scenario S --seed N --record
//! --junit --report`), and a few `harvemu run`s with the same seeds (the default harvester; the
//! harvester with C0 as firmware, with its state dump and an instruction trace). Each output
//! (standard output and error with the exit code, the trace, the JUnit XML, the HTML report, the
//! state dump) must have the digest stored in `scenario_outputs.digests`, after wall-clock times
//! are taken out (the "s wall" of a verdict's heading, JUnit's `time` attributes, the report's
//! wall-time row). A digest is a CRC-64 (XZ) of the bytes: it tells whether they changed, and the
//! file stays small. A change on purpose stores the new digests in the same commit:
//! `HARVEMU_UPDATE_DIGESTS=1 cargo test --profile vm -p supervisor --test scenario_outputs`
//! rewrites the file (check `git diff` of it says what you meant).
//!
//! Every trace must be in time order (docs/TRACES.md, "Time order"), and `harvemu replay` must
//! take it: each is replayed with `--fast` for 100 ms, and that replay's own recording and output
//! are digested and checked for order too.
//!
//! HARVEMU_OUTPUT_SEEDS=N runs seeds 1 to N (1 to 5). A plain `cargo test` leaves this test out
//! (`test = false` in Cargo.toml); `scripts/test` runs it by name, all five seeds, in the
//! optimised build, where the runs take seconds (every shipped scenario also runs in the debug
//! build, in `tests/tests/scenarios.rs`).

mod common;

use common::harvemu;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Output;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Seeds 1 to this, unless HARVEMU_OUTPUT_SEEDS says fewer.
const SEEDS: u64 = 5;
const DIGESTS: &str = "tests/scenario_outputs.digests";

fn seeds() -> u64 {
    match std::env::var("HARVEMU_OUTPUT_SEEDS") {
        Err(_) => SEEDS,
        Ok(n) => match n.parse::<u64>() {
            Ok(n) if (1..=SEEDS).contains(&n) => n,
            _ => panic!("HARVEMU_OUTPUT_SEEDS={n}: not a number of seeds from 1 to {SEEDS}"),
        },
    }
}

/// The shipped scenarios, `configs/scenarios/*.ron`.
fn scenarios() -> Vec<PathBuf> {
    let dir = common::root().join("configs/scenarios");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("read configs/scenarios")
        .map(|e| e.expect("a directory entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "ron"))
        .collect();
    files.sort();
    files
}

fn text(out: &Output) -> String {
    format!(
        "exit {:?}\nstdout:\n{}\nstderr:\n{}",
        out.status.code(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

fn crc64(bytes: &[u8]) -> String {
    format!("{:016x}", crc::Crc::<u64>::new(&crc::CRC_64_XZ).checksum(bytes))
}

/// Replaces what follows each `key` up to the next `end` with `-`.
fn blank(s: &str, key: &str, end: char) -> String {
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(i) = rest.find(key) {
        out.push_str(&rest[..i + key.len()]);
        rest = &rest[i + key.len()..];
        let j = rest.find(end).unwrap_or(rest.len());
        out.push('-');
        rest = &rest[j..];
    }
    out.push_str(rest);
    out
}

/// A verdict's heading ends "seed N, 1.4 s wall)": the wall time goes.
fn without_wall(s: &str) -> String {
    s.lines()
        .map(|l| match l.rfind(", ") {
            Some(i) if l.ends_with(" s wall)") => format!("{}, - s wall)", &l[..i]),
            _ => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The first place where a candump log's time goes back, if any: its time in microseconds is
/// read from the digits themselves, never as a float.
fn goes_back(log: &str) -> Option<String> {
    let mut last: Option<(u64, usize, &str)> = None;
    for (n, line) in log.lines().enumerate() {
        let (time, _) = line
            .strip_prefix('(')
            .and_then(|l| l.split_once(')'))
            .unwrap_or_else(|| panic!("line {}: not a candump line: {line}", n + 1));
        let (secs, us) = time.split_once('.').expect("seconds.microseconds");
        assert_eq!(us.len(), 6, "line {}: {line}", n + 1);
        let at = secs.parse::<u64>().expect("seconds") * 1_000_000 + us.parse::<u64>().expect("µs");
        if let Some((before, m, previous)) = last
            && at < before
        {
            return Some(format!(
                "line {}: {line}\n  comes after line {}: {previous}",
                n + 1,
                m
            ));
        }
        last = Some((at, n + 1, line));
    }
    None
}

/// Takes wall-clock times out of an output.
type Clean = fn(&str) -> String;

/// One run of harvemu: its arguments (`{dir}` is the scratch directory), and the files it
/// writes there, each with how to take wall-clock times out of it.
struct Job {
    key: String,
    args: Vec<String>,
    files: Vec<(&'static str, Clean)>,
    /// Exit codes that are its outcome (1: an expectation failed, not this test's concern).
    exits: &'static [i32],
}

fn same(s: &str) -> String {
    s.to_string()
}
fn junit(s: &str) -> String {
    blank(s, "time=\"", '"')
}
fn report(s: &str) -> String {
    blank(s, "<th>wall time</th><td>", '<')
}

fn jobs(seeds: u64) -> Vec<Job> {
    let mut jobs = Vec::new();
    for seed in 1..=seeds {
        for s in scenarios() {
            let name = s.file_stem().unwrap().to_string_lossy().into_owned();
            let key = format!("scenario {name} {seed}");
            // Relative to the repository root, where harvemu runs: outputs name the file as given,
            // and must not depend on where the repository is.
            let args = format!(
                "scenario configs/scenarios/{name}.ron --seed {seed} --record {{dir}}/trace.log --junit {{dir}}/junit.xml --report {{dir}}/report.html"
            );
            jobs.push(Job {
                key,
                args: args.split(' ').map(str::to_string).collect(),
                files: vec![("trace.log", same), ("junit.xml", junit), ("report.html", report)],
                exits: &[0, 1],
            });
        }
        jobs.push(Job {
            key: format!("run harvester {seed}"),
            args: format!("run --fast --for 10s --seed {seed} --record {{dir}}/trace.log")
                .split(' ')
                .map(str::to_string)
                .collect(),
            files: vec![("trace.log", same)],
            exits: &[0],
        });
        jobs.push(Job {
            key: format!("run harvester-firmware-c0 {seed}"),
            args: format!(
                "run configs/harvester-firmware-c0.ron --fast --for 3s --seed {seed} --record {{dir}}/trace.log --dump-state {{dir}}/state.json --trace-cpu C0 --trace-cpu-window 2s..2.002s"
            )
            .split(' ')
            .map(str::to_string)
            .collect(),
            files: vec![("trace.log", same), ("state.json", same)],
            exits: &[0],
        });
    }
    jobs
}

/// Runs `job` in a directory of its own under `dir`: its digests, or what went wrong.
fn run(job: &Job, dir: &Path) -> Result<Vec<(String, String)>, String> {
    let own = dir.join(job.key.replace(' ', "-"));
    std::fs::create_dir_all(&own).map_err(|e| format!("{}: {e}", own.display()))?;
    let own_s = own.to_str().unwrap();
    let args: Vec<String> = job.args.iter().map(|a| a.replace("{dir}", own_s)).collect();
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let what = &job.key;
    let out = harvemu(&args);
    if !out.status.code().is_some_and(|c| job.exits.contains(&c)) {
        return Err(format!("{what}: harvemu {}\n{}", args.join(" "), text(&out)));
    }
    let mut digests = Vec::new();
    // The scratch directory's name differs between runs; outputs that name a file say `{dir}`.
    let shown = format!(
        "exit {:?}\n{}\n--\n{}",
        out.status.code(),
        without_wall(&String::from_utf8_lossy(&out.stdout)),
        String::from_utf8_lossy(&out.stderr)
    )
    .replace(own_s, "{dir}");
    let mut problems = Vec::new();
    located(what, "output", &shown, &mut problems);
    digests.push((format!("{what} output"), crc64(shown.as_bytes())));
    for (file, clean) in &job.files {
        let path = own.join(file);
        let body = std::fs::read_to_string(&path).map_err(|e| format!("{what}: {}: {e}", path.display()))?;
        let cleaned = clean(&body).replace(own_s, "{dir}");
        located(what, file, &cleaned, &mut problems);
        digests.push((format!("{what} {file}"), crc64(cleaned.as_bytes())));
        if *file == "trace.log" {
            if body.lines().count() < 10 {
                problems.push(format!("{what}: a trace of {} lines", body.lines().count()));
            }
            if let Some(at) = goes_back(&body) {
                problems.push(format!("{what}: the recorded trace goes back in time at {at}"));
            }
            replayed(what, &path, &own, &mut digests, &mut problems);
        }
    }
    if problems.is_empty() {
        let _ = std::fs::remove_dir_all(&own);
        Ok(digests)
    } else {
        Err(problems.join("\n"))
    }
}

/// A digest must not depend on where the repository is: an output that names the repository's
/// own path is a problem of the test (a path given absolute) or of harvemu.
fn located(what: &str, output: &str, text: &str, problems: &mut Vec<String>) {
    let root = common::root();
    let canonical = root.canonicalize().unwrap_or_else(|_| root.clone());
    let named = [root, canonical]
        .into_iter()
        .map(|p| p.to_string_lossy().into_owned())
        .find(|p| text.contains(p.as_str()));
    if let Some(path) = named {
        problems.push(format!("{what} {output}: names the repository's path {path}"));
    }
}

/// Replay reads and checks the whole trace before it plays any of it (docs/TRACES.md,
/// "Replay"), so a trace out of order is refused whatever is played; playing the first 100 ms
/// onto the emulated harvester (the default config) keeps it short.
fn replayed(
    what: &str,
    log: &Path,
    own: &Path,
    digests: &mut Vec<(String, String)>,
    problems: &mut Vec<String>,
) {
    let again = own.join("replayed.log");
    let (log_s, again_s) = (log.to_str().unwrap(), again.to_str().unwrap());
    let out = harvemu(&["replay", log_s, "--fast", "--for", "100ms", "--record", again_s]);
    if !out.status.success() {
        problems.push(format!("{what}: replay refused the trace\n{}", text(&out)));
        return;
    }
    let Ok(replayed) = std::fs::read_to_string(&again) else {
        problems.push(format!("{what}: replay wrote no {again_s}"));
        return;
    };
    if let Some(at) = goes_back(&replayed) {
        problems.push(format!(
            "{what}: the replay's recording goes back in time at {at}"
        ));
    }
    let own_s = own.to_str().unwrap();
    let shown = format!(
        "{}\n--\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
    .replace(own_s, "{dir}");
    digests.push((format!("{what} replay output"), crc64(shown.as_bytes())));
    digests.push((format!("{what} replay trace"), crc64(replayed.as_bytes())));
}

fn stored() -> BTreeMap<String, String> {
    let path = common::root().join("supervisor").join(DIGESTS);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let (digest, key) = l
                .split_once(' ')
                .unwrap_or_else(|| panic!("{DIGESTS}: not `digest key`: {l}"));
            (key.to_string(), digest.to_string())
        })
        .collect()
}

fn store(digests: &BTreeMap<String, String>) {
    let path = common::root().join("supervisor").join(DIGESTS);
    let mut text = String::from(
        "# CRC-64 (XZ) of each output of tests/scenario_outputs.rs, wall-clock times taken out.\n\
         # Rewritten by HARVEMU_UPDATE_DIGESTS=1 cargo test --profile vm -p supervisor --test scenario_outputs\n",
    );
    for (key, digest) in digests {
        text.push_str(&format!("{digest} {key}\n"));
    }
    std::fs::write(&path, text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

#[test]
fn every_output_is_as_stored_and_every_trace_in_time_order() {
    let started = std::time::Instant::now();
    let dir = common::scratch("scenario-outputs", "all");
    let jobs = jobs(seeds());
    assert!(
        jobs.len() as u64 >= seeds() * 22,
        "{} runs: the scenarios are missing",
        jobs.len()
    );
    // The runs are independent processes: as many at once as there are cores.
    let workers = std::thread::available_parallelism()
        .map_or(2, |n| n.get())
        .min(jobs.len());
    let next = AtomicUsize::new(0);
    let failures = Mutex::new(Vec::new());
    let digests = Mutex::new(BTreeMap::new());
    std::thread::scope(|s| {
        for _ in 0..workers {
            s.spawn(|| {
                while let Some(job) = jobs.get(next.fetch_add(1, Ordering::Relaxed)) {
                    match run(job, &dir) {
                        Ok(d) => digests.lock().unwrap().extend(d),
                        Err(e) => failures.lock().unwrap().push(e),
                    }
                }
            });
        }
    });
    let failures = failures.into_inner().unwrap();
    assert!(
        failures.is_empty(),
        "{} of {} runs:\n{}",
        failures.len(),
        jobs.len(),
        failures.join("\n\n")
    );
    let digests = digests.into_inner().unwrap();
    if std::env::var_os("HARVEMU_UPDATE_DIGESTS").is_some() {
        let mut all = stored_or_empty();
        all.extend(digests);
        store(&all);
    } else {
        let stored = stored();
        let changed: Vec<String> = digests
            .iter()
            .filter(|(key, digest)| stored.get(*key) != Some(*digest))
            .map(|(key, digest)| match stored.get(key) {
                Some(was) => format!("{key}: {digest}, stored {was}"),
                None => format!("{key}: {digest}, none stored"),
            })
            .collect();
        assert!(
            changed.is_empty(),
            "{} of {} outputs differ from {DIGESTS} (a change on purpose: see this file's docs):\n{}",
            changed.len(),
            digests.len(),
            changed.join("\n")
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
    eprintln!(
        "{} runs checked in {:.1} s",
        jobs.len(),
        started.elapsed().as_secs_f64()
    );
}

fn stored_or_empty() -> BTreeMap<String, String> {
    let path = common::root().join("supervisor").join(DIGESTS);
    if path.exists() { stored() } else { BTreeMap::new() }
}

#[test]
fn a_trace_that_goes_back_is_found() {
    let ok = "(1704067210.029100) harv0 123#\n(1704067210.029100) harv0.C0 20000304#0040000000000000\n";
    assert_eq!(goes_back(ok), None);
    let back = "(1704067210.029117) harv0.D5 20000288#0000040A00000012\n(1704067210.029112) harv0.C0 20000304#0040000000000000\n";
    let at = goes_back(back).expect("found");
    assert!(at.starts_with("line 2: (1704067210.029112)"), "{at}");
}

#[test]
fn wall_clock_times_are_taken_out() {
    assert_eq!(
        without_wall("D3 crashes (configs/scenarios/crash.ron, seed 1, 0.1 s wall)\n  pass"),
        "D3 crashes (configs/scenarios/crash.ron, seed 1, - s wall)\n  pass"
    );
    assert_eq!(
        junit(r#"<testsuite time="1.495" tests="3">"#),
        r#"<testsuite time="-" tests="3">"#
    );
    assert_eq!(
        report("<tr><th>wall time</th><td>1.5 s</td></tr>"),
        "<tr><th>wall time</th><td>-</td></tr>"
    );
}

#[test]
fn an_output_that_names_the_repository_is_found() {
    let mut problems = Vec::new();
    let root = common::root().to_string_lossy().into_owned();
    located(
        "scenario x 1",
        "output",
        &format!("x ({root}/configs/scenarios/x.ron, seed 1)"),
        &mut problems,
    );
    assert_eq!(problems.len(), 1, "{problems:?}");
    located(
        "scenario x 1",
        "output",
        "x (configs/scenarios/x.ron, seed 1)",
        &mut problems,
    );
    assert_eq!(problems.len(), 1, "{problems:?}");
}
