use super::*;
use std::collections::BTreeSet;

fn nodes() -> Vec<String> {
    ["F5", "A0", "B0", "C0", "D0", "D1", "E0"]
        .map(String::from)
        .to_vec()
}

fn section(mean: f64, kinds: &[RandomFault]) -> RandomFaults {
    RandomFaults {
        seed: None,
        mean_interval_s: mean,
        kinds: kinds.to_vec(),
        nodes: Vec::new(),
        from_s: default_from(),
        quiet_end_s: default_quiet_end(),
        min_fault_s: default_min_fault(),
        max_fault_s: default_max_fault(),
        node_rest_s: default_node_rest(),
    }
}

fn kind(a: &Action) -> Option<RandomFault> {
    kind_of(a)
}

fn text(steps: &[Step]) -> String {
    format!("{steps:?}")
}

#[test]
fn the_same_seed_gives_the_same_schedule_and_another_seed_another() {
    let r = section(20.0, &RandomFault::ALL);
    let a = expand(&r, 7, 3600.0, &nodes());
    let b = expand(&r, 7, 3600.0, &nodes());
    let c = expand(&r, 8, 3600.0, &nodes());
    assert!(a.len() > 50, "{} steps", a.len());
    assert_eq!(text(&a), text(&b));
    assert_ne!(text(&a), text(&c));
}

#[test]
fn every_kind_appears_and_each_round_deals_every_kind() {
    let r = section(120.0, &RandomFault::ALL);
    // Few nodes busy for long: nothing is skipped in the first round.
    let steps = expand(&r, 1, 24.0 * 3600.0, &nodes());
    let kinds: Vec<RandomFault> = steps.iter().filter_map(|s| kind(&s.action)).collect();
    let first: BTreeSet<RandomFault> = kinds.iter().take(6).copied().collect();
    assert_eq!(first, BTreeSet::from(RandomFault::ALL), "{kinds:?}");
    for k in RandomFault::ALL {
        let n = kinds.iter().filter(|&&x| x == k).count();
        // About 720 faults over 6 kinds; skips (no free node, a babble running) take a few.
        assert!(n > 80, "{k:?} {n} times");
    }
}

#[test]
fn every_fault_is_undone_in_time_and_nodes_rest_between_faults() {
    let r = section(5.0, &RandomFault::ALL);
    let duration = 1200.0;
    let steps = expand(&r, 42, duration, &nodes());
    let mut babbles: Vec<(f64, f64)> = Vec::new();
    // Per node: (start, end) of each of its faults.
    let mut spans: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
    let undo_of = |node: &str, at: f64, want: fn(&Action, &str) -> bool| {
        steps
            .iter()
            .find(|s| s.at_s >= at && want(&s.action, node))
            .map(|s| s.at_s)
    };
    for s in &steps {
        if kind(&s.action).is_some() {
            assert!(s.at_s >= r.from_s && s.at_s < duration - r.quiet_end_s, "{s:?}");
        }
        let span = match &s.action {
            Action::BitErrors { target, until_s, .. } => {
                let until = until_s.expect("bit errors end");
                assert!(until > s.at_s && until <= duration);
                match target {
                    Target::Node(n) => Some((n.clone(), until)),
                    _ => None,
                }
            }
            Action::Babble { until_s, .. } => {
                babbles.push((s.at_s, *until_s));
                None
            }
            Action::Hang(n) => {
                let back = undo_of(n, s.at_s, |a, n| matches!(a, Action::Resume(x) if x == n));
                Some((n.clone(), back.expect("a resume")))
            }
            Action::Disconnect(n) => {
                let back = undo_of(n, s.at_s, |a, n| matches!(a, Action::Reconnect(x) if x == n));
                Some((n.clone(), back.expect("a reconnect")))
            }
            Action::Crash(n) => Some((n.clone(), s.at_s)),
            _ => None,
        };
        if let Some((n, end)) = span {
            assert!(end - s.at_s <= r.max_fault_s + 1e-9, "{s:?} lasts until {end}");
            spans.entry(n).or_default().push((s.at_s, end));
        }
    }
    assert!(babbles.len() > 5);
    for w in babbles.windows(2) {
        assert!(w[1].0 >= w[0].1, "babbles overlap: {w:?}");
    }
    assert_eq!(spans.len(), nodes().len(), "every node gets faults");
    for (n, s) in &spans {
        for w in s.windows(2) {
            assert!(w[1].0 >= w[0].1 + r.node_rest_s, "{n}: {w:?}");
        }
    }
}

#[test]
fn fault_starts_are_a_poisson_process_of_the_given_mean() {
    // Bit errors need no node and never overlap anything: no start is skipped.
    let r = section(10.0, &[RandomFault::BitErrors]);
    let duration = 200_000.0;
    let steps = expand(&r, 3, duration, &nodes());
    let n = steps.len() as f64;
    let span = duration - r.quiet_end_s - r.from_s;
    // 20 000 gaps: the mean is within 3 % of 10 s (about 4 standard errors).
    let mean = span / n;
    assert!((mean - 10.0).abs() < 0.3, "mean gap {mean} s over {n} faults");
    // Exponential gaps: about e^-1 of them are longer than the mean.
    let long = steps.windows(2).filter(|w| w[1].at_s - w[0].at_s > 10.0).count() as f64;
    assert!((long / n - (-1f64).exp()).abs() < 0.02, "{long} of {n}");
}

#[test]
fn a_narrowed_node_list_is_kept_to() {
    let mut r = section(5.0, &[RandomFault::Crash, RandomFault::Hang]);
    r.nodes = vec!["F5".into(), "D1".into()];
    let steps = expand(&r, 9, 3600.0, &nodes());
    let hit: BTreeSet<&str> = steps
        .iter()
        .filter_map(|s| match &s.action {
            Action::Crash(n) | Action::Hang(n) | Action::Resume(n) => Some(n.as_str()),
            _ => None,
        })
        .collect();
    assert_eq!(hit, BTreeSet::from(["F5", "D1"]));
}

#[test]
fn bad_sections_are_named_field_by_field_and_expand_to_nothing() {
    let mut r = section(0.0, &[]);
    r.nodes = vec!["Z9".into()];
    r.min_fault_s = 3.0;
    r.max_fault_s = 1.0;
    r.from_s = -1.0;
    let p = problems(&r, 100.0, &nodes());
    let fields: Vec<&str> = p.iter().map(|(f, _)| f.as_str()).collect();
    assert_eq!(
        fields,
        [
            "random_faults.mean_interval_s",
            "random_faults.kinds",
            "random_faults.nodes",
            "random_faults.from_s",
            "random_faults.max_fault_s",
        ]
    );
    assert!(p[2].1.contains("'Z9'"), "{p:?}");
    assert!(expand(&r, 1, 100.0, &nodes()).is_empty());
    let too_many = section(0.001, &[RandomFault::Crash]);
    assert_eq!(problems(&too_many, 86_400.0, &nodes()).len(), 1);
}
