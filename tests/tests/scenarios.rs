//! Every shipped scenario runs and passes.

use harvemu_e2e::root;
use supervisor::scenario;

#[test]
fn every_shipped_scenario_passes() {
    let dir = root().join("configs/scenarios");
    // What `harvemu scenario configs/scenarios/*.ron` runs.
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "ron"))
        .collect();
    files.sort();
    assert!(files.len() >= 12, "{} scenarios", files.len());
    let mut failed = Vec::new();
    for f in &files {
        let loaded = scenario::load(f, None).unwrap_or_else(|e| panic!("{}: {e}", f.display()));
        // Long runs (the soak) live elsewhere: the glob must not run a day of virtual time.
        assert!(
            loaded.scenario.duration_s <= 3600.0,
            "{}: {} s of virtual time in the scenario glob",
            f.display(),
            loaded.scenario.duration_s
        );
        let outcome = scenario::run(&loaded, None, |_| {}).unwrap();
        println!(
            "{} ({} expectations)",
            loaded.scenario.name,
            outcome.verdicts.len()
        );
        for v in &outcome.verdicts {
            println!(
                "  {} {} -> {}",
                if v.passed { "pass" } else { "FAIL" },
                v.expectation,
                v.observed
            );
            if !v.passed {
                failed.push(format!("{}: {} -> {}", f.display(), v.expectation, v.observed));
            }
        }
    }
    assert!(failed.is_empty(), "{failed:#?}");
}

#[test]
fn the_same_seed_gives_the_same_verdicts_and_another_seed_runs_too() {
    let f = root().join("configs/scenarios/bit_error_rate.ron");
    let observed = |seed| {
        let l = scenario::load(&f, Some(seed)).unwrap();
        let o = scenario::run(&l, None, |_| {}).unwrap();
        (
            o.seed,
            o.verdicts.iter().map(|v| v.observed.clone()).collect::<Vec<_>>(),
        )
    };
    let (a, b, c) = (observed(5), observed(5), observed(6));
    assert_eq!(a, b);
    assert_eq!(a.0, 5);
    assert_ne!(a.1, c.1, "the error frames come from the seed");
}
