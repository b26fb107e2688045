//! Planted failures: properties decided here from the history alone, so that what shrinking must
//! find is known exactly.

use super::*;
use crate::scenario::random::{RandomFault, RandomFaults, draw};

const NODES: [&str; 8] = ["D0", "D1", "D2", "D3", "D4", "D5", "A0", "B0"];

/// About 60 faults in 70 s: every kind, any node at any time.
fn history(seed: u64) -> History {
    let section = RandomFaults {
        seed: None,
        mean_interval_s: 0.8,
        kinds: RandomFault::ALL.to_vec(),
        nodes: Vec::new(),
        from_s: 10.0,
        quiet_end_s: 10.0,
        min_fault_s: 0.5,
        max_fault_s: 5.0,
        node_rest_s: 0.0,
    };
    let nodes: Vec<String> = NODES.iter().map(|n| n.to_string()).collect();
    History {
        faults: draw(&section, seed, 70.0, &nodes),
        duration_s: 70.0,
    }
}

fn overlap(a: &Fault, b: &Fault) -> bool {
    a.at_s < b.until_s && b.at_s < a.until_s
}

/// The first two lasting faults on different nodes' hits that overlap: the planted pair.
fn planted(h: &History) -> Option<(Hit, Hit)> {
    let lasting: Vec<&Fault> = h.faults.iter().filter(|f| f.lasts()).collect();
    for (i, a) in lasting.iter().enumerate() {
        for b in &lasting[i + 1..] {
            if a.hit != b.hit && overlap(a, b) {
                return Some((a.hit.clone(), b.hit.clone()));
            }
        }
    }
    None
}

/// Fails when a fault with hit `a` overlaps one with hit `b`.
fn pair_fails(h: &History, a: &Hit, b: &Hit) -> bool {
    h.faults
        .iter()
        .filter(|f| &f.hit == a)
        .any(|fa| h.faults.iter().filter(|f| &f.hit == b).any(|fb| overlap(fa, fb)))
}

#[test]
fn a_pair_that_must_overlap_is_all_that_is_left() {
    let mut trials = Vec::new();
    for seed in 0..100 {
        let start = history(seed);
        assert!(
            start.faults.len() >= 40,
            "seed {seed}: {} faults",
            start.faults.len()
        );
        let (a, b) = planted(&start).expect("some faults overlap");
        let fails = |h: &History| pair_fails(h, &a, &b);
        let out = shrink(start.clone(), Bounds::default(), 1000, fails);
        assert!(out.complete, "seed {seed}: budget spent");
        let h = &out.history;
        assert_eq!(h.faults.len(), 2, "seed {seed}: {:?}", h.faults);
        assert!(pair_fails(h, &a, &b), "seed {seed}: the result must still fail");
        // Earliest and shortest: the first one starts within a resolution step of time zero,
        // both are short, and the run ends soon after the last one.
        let first = h.faults.iter().map(|f| ms(f.at_s)).min().unwrap();
        assert!(first <= 10, "seed {seed}: first fault at {first} ms");
        for f in &h.faults {
            let length = ms(f.until_s) - ms(f.at_s);
            assert!(length <= 320, "seed {seed}: {length} ms long: {f:?}");
        }
        let end = ms(h.last_end_s());
        assert!(
            ms(h.duration_s) - end <= 10,
            "seed {seed}: run {} s",
            h.duration_s
        );
        trials.push(out.trials);
    }
    let max = trials.iter().max().unwrap();
    let mean = trials.iter().sum::<u32>() as f64 / trials.len() as f64;
    println!("planted pairs: 100 histories, trials mean {mean:.1}, max {max}");
}

#[test]
fn rates_are_lowered_until_the_failure_goes() {
    // Fails while some bus-wide bit errors have a rate of at least 2e-5 per bit.
    let fails = |h: &History| {
        h.faults
            .iter()
            .any(|f| matches!(f.hit, Hit::BitErrors(r) if r >= 2e-5))
    };
    for seed in 0..20 {
        let start = history(seed);
        if !fails(&start) {
            continue;
        }
        let out = shrink(start, Bounds::default(), 1000, fails);
        let [f] = &out.history.faults[..] else {
            panic!("seed {seed}: {:?}", out.history.faults)
        };
        // Halving from a rate in 1e-5..=1e-4 stops below twice the threshold.
        let Hit::BitErrors(rate) = f.hit else {
            panic!("{f:?}")
        };
        assert!((2e-5..4e-5).contains(&rate), "seed {seed}: rate {rate}");
    }
}

#[test]
fn a_failure_without_faults_needs_one_trial() {
    let out = shrink(history(1), Bounds::default(), 1000, |h: &History| {
        h.duration_s > 30.0
    });
    assert!(out.history.faults.is_empty());
    // Then the run shortens to just above 30 s.
    let d = ms(out.history.duration_s);
    assert!((30_001..=30_000 + resolution_ms(d)).contains(&d), "{d} ms");
}

#[test]
fn the_budget_is_kept_and_said() {
    let start = history(3);
    let (a, b) = planted(&start).unwrap();
    let mut calls = 0;
    let out = shrink(start.clone(), Bounds::default(), 7, |h: &History| {
        calls += 1;
        pair_fails(h, &a, &b)
    });
    assert_eq!(calls, 7);
    assert_eq!(out.trials, 7);
    assert!(!out.complete);
    assert!(pair_fails(&out.history, &a, &b));
    // No budget: the start as it was.
    let out = shrink(start.clone(), Bounds::default(), 0, |_: &History| true);
    assert_eq!(out.history, start);
}

#[test]
fn the_campaigns_rules_are_kept() {
    let bounds = Bounds {
        earliest_s: 10.0,
        settle_s: 15.0,
    };
    // Any one fault fails: it is moved to the earliest start and the run ends when the machine
    // has settled after it.
    let out = shrink(history(5), bounds, 1000, |h: &History| !h.faults.is_empty());
    let [f] = &out.history.faults[..] else {
        panic!("{:?}", out.history.faults)
    };
    assert_eq!(ms(f.at_s), 10_000, "{f:?}");
    let end = ms(out.history.duration_s);
    assert!((25_000..=25_000 + resolution_ms(end)).contains(&end), "{end} ms");
    // Without faults the run is never shorter than the earliest start and the settling time.
    let out = shrink(history(5), bounds, 1000, |_: &History| true);
    assert!(out.history.faults.is_empty());
    assert_eq!(ms(out.history.duration_s), 25_000);
    // A fault that lasts past the settling time keeps the run going until it ends.
    let mut long = history(5);
    long.faults.truncate(1);
    long.faults[0].hit = Hit::Hang("D0".into());
    long.faults[0].until_s = long.faults[0].at_s + 30.0;
    let length = long.faults[0].until_s - long.faults[0].at_s;
    let out = shrink(long, bounds, 1000, |h: &History| {
        h.faults.iter().any(|f| f.until_s - f.at_s >= length - 1e-9)
    });
    assert!(out.history.duration_s >= out.history.last_end_s());
    assert_eq!(ms(out.history.last_end_s()), 40_000);
}
