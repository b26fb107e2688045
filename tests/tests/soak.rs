//! A shortened soak: a quarter of an hour with a random fault every few seconds. Nothing panics,
//! every kind of fault happens and is undone, the monitor's books balance exactly, and the trace,
//! read back independently, holds every frame.

use bus::fault::ErrorState;
use bus::node::CrashCause;
use clap::Parser;
use harvemu_e2e::{Shared, candump, default_harvester, parse_trace, root};
use std::collections::{BTreeMap, BTreeSet};
use supervisor::harvester::Happened;
use supervisor::scenario::{self, Action, RandomFault, Target, random};
use supervisor::{exit, soak};

/// The command line as far as these tests need it.
#[derive(Parser)]
#[command(name = "harvemu")]
enum Cli {
    Soak(soak::Args),
}

/// Runs `harvemu soak` with `words` in-process: Ok(passed and flat) or the error.
fn harvemu_soak(words: &[&str]) -> anyhow::Result<bool> {
    let Cli::Soak(args) = Cli::try_parse_from(["harvemu", "soak"].iter().chain(words))?;
    Ok(soak::run(&args).map(|e| !e.expectations_failed)?)
}

/// True when `e` is bad input (exit code 2).
fn is_bad_input(e: &anyhow::Error) -> bool {
    e.downcast_ref::<supervisor::Error>()
        .is_some_and(|e| e.exit_code() == exit::BAD_INPUT)
}

const SCENARIO: &str = r#"Scenario(
    name: "short soak",
    config: "CONFIG",
    duration_s: 900.0,
    random_faults: Some((
        mean_interval_s: 5.0,
        kinds: [BitErrors, ErrorPassive, Crash, Hang, Babble, Disconnect],
        max_fault_s: 3.0,
        node_rest_s: 20.0,
        quiet_end_s: 30.0,
    )),
    expect: [FramesAccounted, TraceComplete],
)"#;

#[test]
fn a_short_soak_with_dense_random_faults_balances_its_books() {
    let dir = std::env::temp_dir().join(format!("harvemu-soak-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("short_soak.ron");
    let config = root().join("configs/harvester.ron");
    std::fs::write(&file, SCENARIO.replace("CONFIG", &config.display().to_string())).unwrap();
    let loaded = scenario::load(&file, Some(77)).unwrap();
    let trace = Shared::default();
    let outcome = scenario::run(&loaded, Some(candump(trace.clone(), &loaded.harvester)), |_| {}).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    for v in &outcome.verdicts {
        println!("{} {} -> {}", v.passed, v.expectation, v.observed);
    }
    assert!(outcome.passed());
    let snap = outcome.snapshot.as_ref().unwrap();
    let books = &outcome.books;
    let monitor = books.monitor.as_ref().unwrap();
    println!("{}", monitor.table());

    // No logic panicked: every crash is an injected one, and each was followed by a restart.
    let timeline = &loaded.scenario.timeline;
    let steps = |kind: RandomFault| {
        timeline
            .iter()
            .filter(|s| random::kind_of(&s.action) == Some(kind))
            .count()
    };
    let crashes: Vec<_> = outcome
        .events
        .iter()
        .filter(|e| matches!(e.what, Happened::Crashed(_)))
        .collect();
    assert!(
        crashes
            .iter()
            .all(|e| e.what == Happened::Crashed(CrashCause::Injected)),
        "{crashes:?}"
    );
    assert_eq!(crashes.len(), steps(RandomFault::Crash));
    let restarts = outcome
        .events
        .iter()
        .filter(|e| e.what == Happened::Restarted)
        .count();
    assert_eq!(restarts, crashes.len());

    // Every kind was drawn, and every action was carried out.
    for k in RandomFault::ALL {
        assert!(steps(k) >= 3, "{k:?}: {} time(s)", steps(k));
    }
    let mut written: BTreeMap<&str, u64> = BTreeMap::new();
    for s in timeline {
        *written.entry(s.action.name()).or_insert(0) += 1;
    }
    assert_eq!(outcome.applied, written);
    assert_eq!(written["Hang"], written["Resume"]);
    assert_eq!(written["Disconnect"], written["Reconnect"]);

    // The trace, read back by the tests' own reader.
    let text = String::from_utf8(trace.0.borrow().clone()).unwrap();
    let lines = parse_trace(&text);
    assert_eq!(lines.len() as u64, snap.stats.frames);
    assert_eq!(books.frames, snap.stats.frames);
    let to_f5 = lines
        .iter()
        .filter(|l| l.frame.is_extended() && (l.frame.raw_id() >> 8) & 0xFF == 0xF5)
        .count() as u64;
    assert_eq!(monitor.on_bus, to_f5);
    let reasons: u64 = monitor.reasons().iter().map(|(_, n)| n).sum();
    assert_eq!(reasons, to_f5);
    // The faults reached the books: the monitor lost frames for several reasons.
    let losses = monitor.reasons().iter().skip(1).filter(|(_, n)| *n > 0).count();
    assert!(losses >= 4, "{}", monitor.table());
    assert!(monitor.tally.processed > to_f5 / 2);

    // Effects of each kind. Babbling: the idiot's frames are on the bus.
    let babbled = lines
        .iter()
        .filter(|l| l.frame.raw_id() == random::BABBLE_ID)
        .count();
    assert!(babbled > 1000, "{babbled} babbled frames");
    // Error passive: some node went error passive.
    let passive = snap.stats.nodes.iter().any(|n| {
        n.counters
            .points
            .iter()
            .any(|(_, (_, _, s))| *s == ErrorState::Passive)
    });
    assert!(passive);
    // Bit errors on the whole bus: transmit errors at nodes no targeted rule aimed at.
    let targeted: BTreeSet<&str> = timeline
        .iter()
        .filter_map(|s| match &s.action {
            Action::BitErrors {
                target: Target::Node(n),
                ..
            } => Some(n.as_str()),
            _ => None,
        })
        .collect();
    let hit_untargeted = snap
        .nodes
        .iter()
        .filter(|n| n.name != "babbler" && !targeted.contains(n.name.as_str()))
        .any(|n| n.counters.tx_errors > 0);
    assert!(hit_untargeted, "targeted {targeted:?}");
    assert!(snap.stats.error_frames > 0);

    // Everything was undone: nobody hangs, and every node is still talking at the end.
    assert!(snap.nodes.iter().all(|n| !n.hung || n.name == "babbler"));
    let end = snap.now;
    let recent: BTreeSet<u8> = lines
        .iter()
        .filter(|l| end - l.at < bus::time::BusDuration::from_secs(5))
        .map(|l| l.frame.raw_id() as u8)
        .collect();
    for s in &default_harvester().scripts {
        assert!(recent.contains(&s.address), "{} silent at the end", s.name);
    }
    assert!(recent.contains(&0xF5), "the monitor is silent at the end");
}

#[test]
fn bad_soak_input_is_named_and_nothing_runs() {
    let shipped = root().join("configs/soak/soak_24h.ron");
    let shipped = shipped.to_str().unwrap();
    for (words, says) in [
        (vec![shipped, "--hours=-1"], "--hours -1"),
        (vec![shipped, "--hours", "0"], "--hours 0"),
        (vec![shipped, "--hours", "NaN"], "--hours NaN"),
        (vec!["no/such/soak.ron"], "no/such/soak.ron"),
    ] {
        let e = harvemu_soak(&words).unwrap_err();
        assert!(is_bad_input(&e), "{words:?}: {e}");
        assert!(e.to_string().contains(says), "{words:?}: {e}");
    }
    let dir = std::env::temp_dir().join(format!("harvemu-soak-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("bad.ron");
    let config = root().join("configs/harvester.ron");
    let text = SCENARIO
        .replace("CONFIG", &config.display().to_string())
        .replace("mean_interval_s: 5.0", "mean_interval_s: 0.0")
        .replace("Hang, Babble", "Hang, Z9");
    std::fs::write(&file, text.replace("Z9", "Babble")).unwrap();
    let e = harvemu_soak(&[file.to_str().unwrap()]).unwrap_err();
    std::fs::write(&file, text).unwrap();
    let unknown = harvemu_soak(&[file.to_str().unwrap()]).unwrap_err();
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(is_bad_input(&e));
    let e = e.to_string();
    assert!(
        e.contains("bad.ron") && e.contains("random_faults.mean_interval_s"),
        "{e}"
    );
    let unknown = unknown.to_string();
    assert!(unknown.contains("bad.ron") && unknown.contains("Z9"), "{unknown}");
}
