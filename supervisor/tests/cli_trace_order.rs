//! harvemu's own traces are in time order (docs/TRACES.md, "Reading" and "Recording"): every
//! shipped scenario, recorded with three seeds, gives a candump log whose timestamps never
//! decrease, and which `harvemu replay` takes without refusing it.
//!
//! HARVEMU_TRACE_ORDER_SEEDS=N records with seeds 1 to N instead (at least 1). `scripts/test`
//! runs seed 1 in the debug build of the workspace tests and all three again in the optimised
//! build, where the 60 runs take seconds instead of a minute and a half.

mod common;

use common::harvemu;
use std::path::{Path, PathBuf};
use std::process::Output;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Seeds 1 to this, unless HARVEMU_TRACE_ORDER_SEEDS says otherwise.
const SEEDS: u64 = 3;

fn seeds() -> u64 {
    match std::env::var("HARVEMU_TRACE_ORDER_SEEDS") {
        Err(_) => SEEDS,
        Ok(n) => match n.parse::<u64>() {
            Ok(n) if n >= 1 => n,
            _ => panic!("HARVEMU_TRACE_ORDER_SEEDS={n}: not a number of seeds (1 or more)"),
        },
    }
}

/// The shipped scenarios, `configs/scenarios/*.ron`, by name.
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

/// Records `scenario` with `seed` into `dir`, checks the order of the trace, replays it (and
/// checks the order of the replay's own recording): everything that went wrong, if anything.
fn check(scenario: &Path, seed: u64, dir: &Path) -> Result<(), String> {
    let name = scenario.file_stem().unwrap().to_string_lossy().into_owned();
    let what = format!("{name} --seed {seed}");
    let log = dir.join(format!("{name}.{seed}.log"));
    let (scenario, log_s) = (scenario.to_str().unwrap(), log.to_str().unwrap());
    let seed_s = seed.to_string();
    let out = harvemu(&["scenario", scenario, "--seed", &seed_s, "--record", log_s]);
    // 1 is an expectation that failed: not this test's concern. Anything else is.
    if !matches!(out.status.code(), Some(0 | 1)) {
        return Err(format!("{what}: scenario failed\n{}", text(&out)));
    }
    let trace = std::fs::read_to_string(&log).map_err(|e| format!("{what}: {log_s}: {e}"))?;
    if trace.lines().count() < 10 {
        return Err(format!("{what}: a trace of {} lines", trace.lines().count()));
    }
    let mut problems = Vec::new();
    if let Some(at) = goes_back(&trace) {
        problems.push(format!("{what}: the recorded trace goes back in time at {at}"));
    }
    // Replay reads and checks the whole trace before it plays any of it (docs/TRACES.md,
    // "Replay"), so a trace out of order is refused whatever is played; playing the first
    // 100 ms onto the emulated harvester (the default config) keeps it short.
    let again = dir.join(format!("{name}.{seed}.replayed.log"));
    let again_s = again.to_str().unwrap();
    let out = harvemu(&["replay", log_s, "--fast", "--for", "100ms", "--record", again_s]);
    if out.status.success() {
        let replayed = std::fs::read_to_string(&again).map_err(|e| format!("{what}: {again_s}: {e}"))?;
        if let Some(at) = goes_back(&replayed) {
            problems.push(format!(
                "{what}: the replay's recording goes back in time at {at}"
            ));
        }
    } else {
        problems.push(format!("{what}: replay refused the trace\n{}", text(&out)));
    }
    if !problems.is_empty() {
        return Err(problems.join("\n"));
    }
    let _ = std::fs::remove_file(&log);
    let _ = std::fs::remove_file(&again);
    Ok(())
}

#[test]
fn every_shipped_scenario_records_a_trace_in_time_order_that_replay_takes() {
    let started = std::time::Instant::now();
    let dir = common::scratch("cli-trace-order", "all");
    let seeds = seeds();
    let jobs: Vec<(PathBuf, u64)> = scenarios()
        .into_iter()
        .flat_map(|s| (1..=seeds).map(move |seed| (s.clone(), seed)))
        .collect();
    assert!(
        jobs.len() as u64 >= seeds * 20,
        "{} runs: the scenarios are missing",
        jobs.len()
    );
    // The runs are independent processes: as many at once as there are cores.
    let workers = std::thread::available_parallelism()
        .map_or(2, |n| n.get())
        .min(jobs.len());
    let next = AtomicUsize::new(0);
    let failures = Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..workers {
            s.spawn(|| {
                while let Some((scenario, seed)) = jobs.get(next.fetch_add(1, Ordering::Relaxed)) {
                    if let Err(e) = check(scenario, *seed, &dir) {
                        failures.lock().unwrap().push(e);
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
    let _ = std::fs::remove_dir_all(&dir);
    eprintln!(
        "{} scenario runs recorded and replayed in {:.1} s",
        jobs.len(),
        started.elapsed().as_secs_f64()
    );
}

#[test]
fn a_trace_that_goes_back_is_found() {
    let ok = "(1704067210.029100) harv0 123#\n(1704067210.029100) harv0.C0 20000304#0040000000000000\n";
    assert_eq!(goes_back(ok), None);
    let back = "(1704067210.029117) harv0.D5 20000288#0000040A00000012\n(1704067210.029112) harv0.C0 20000304#0040000000000000\n";
    let at = goes_back(back).expect("found");
    assert!(at.starts_with("line 2: (1704067210.029112)"), "{at}");
}
