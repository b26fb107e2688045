//! The supervisor: crashed nodes are rebuilt from their spec under the restart policy, and the
//! others go on.

use harvemu_e2e::root;
use supervisor::harvester::Happened;
use supervisor::scenario;

#[test]
fn restarts_within_the_policy_then_gives_up() {
    let dir = std::env::temp_dir().join(format!("harvemu-supervision-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("crashes.ron");
    // The default policy: 3 restarts in 60 s, 100 ms backoff. Four crashes of D3.
    std::fs::write(
        &file,
        format!(
            r#"Scenario(name: "crash loop", config: "{}", duration_s: 20.0,
                timeline: [
                    (at_s: 5.0, action: Crash("D3")), (at_s: 8.0, action: Crash("D3")),
                    (at_s: 11.0, action: Crash("D3")), (at_s: 14.0, action: Crash("D3")),
                    (at_s: 6.0, action: Crash("B2")),
                ],
                expect: [Restarts(node: "D3", count: 3), Restarts(node: "B2", count: 1), ErrorFrames(min: 0, max: 0),
                         Display(field: "engine_rpm", min: 2000.0, max: 2400.0)])"#,
            root().join("configs/harvester.ron").display()
        ),
    )
    .unwrap();
    let loaded = scenario::load(&file, None).unwrap();
    let outcome = scenario::run(&loaded, None, |_| {}).unwrap();
    for v in &outcome.verdicts {
        assert!(v.passed, "{} -> {}", v.expectation, v.observed);
    }
    let d3: Vec<(f64, String)> = outcome
        .events
        .iter()
        .filter(|e| e.node == "D3")
        .map(|e| match e.what {
            Happened::Crashed(_) => (e.at.as_secs_f64(), "crash".to_string()),
            _ => (e.at.as_secs_f64(), e.what.to_string()),
        })
        .collect();
    // Each crash is seen within 10 ms and restarted 100 ms later; the fourth is one too many.
    let kinds: Vec<&str> = d3.iter().map(|(_, w)| w.as_str()).collect();
    assert_eq!(
        kinds,
        [
            "crash",
            "restarted",
            "crash",
            "restarted",
            "crash",
            "restarted",
            "crash",
            "gave up after 3 restarts in 60 s"
        ]
    );
    let (crash, restart) = (d3[0].0, d3[1].0);
    assert!((restart - crash - 0.1).abs() < 1e-9, "{crash} -> {restart}");
}
