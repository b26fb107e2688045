//! The conformance suite (`configs/scenarios/conformance/`): every case passes for seeds 1 to
//! 20; every case without its `Disturb` lines fails at least one expectation (so each
//! expectation rests on the stimulus, not on the bench); docs/CONFORMANCE.md lists exactly the
//! cases, with their names and descriptions; and `Counters` and `ErrorKinds` can fail.

use std::path::{Path, PathBuf};
use supervisor::configs::Source;
use supervisor::harvester::Harvester;
use supervisor::scenario::{self, Outcome};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn folder() -> PathBuf {
    root().join("configs/scenarios/conformance")
}

/// The cases, by file name, with their text.
fn cases() -> Vec<(String, String)> {
    let mut files: Vec<(String, String)> = std::fs::read_dir(folder())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "ron"))
        .map(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read_to_string(&p).unwrap())
        })
        .collect();
    files.sort();
    assert!(files.len() >= 20, "the suite has {} cases", files.len());
    files
}

/// Runs a case's text (as if it were the file `name` of the suite) with `seed`.
fn run(name: &str, text: &str, seed: u64) -> Outcome {
    let path = folder().join(name);
    let loaded = scenario::from_text(&path, text, Some(seed), |p| Harvester::open(&Source::file(p)))
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    scenario::run(&loaded, None, |_| {}).unwrap()
}

fn failures(o: &Outcome) -> Vec<String> {
    o.verdicts
        .iter()
        .filter(|v| !v.passed)
        .map(|v| format!("{} -> {}", v.expectation, v.observed))
        .collect()
}

#[test]
fn every_case_passes_for_seeds_1_to_20() {
    for (name, text) in cases() {
        for seed in 1..=20 {
            let o = run(&name, &text, seed);
            assert!(o.passed(), "{name}, seed {seed}: {:#?}", failures(&o));
        }
    }
}

#[test]
fn every_case_fails_without_its_disturbances() {
    for (name, text) in cases() {
        let lines = text.lines().filter(|l| l.contains("action: Disturb(")).count();
        assert!(lines > 0, "{name} has no Disturb line");
        let without: String = text
            .lines()
            .filter(|l| !l.contains("action: Disturb("))
            .map(|l| format!("{l}\n"))
            .collect();
        let o = run(&name, &without, 1);
        assert!(!o.passed(), "{name} passes without its {lines} Disturb line(s)");
    }
}

/// A wrong count and a wrong kind fail, with what was seen.
#[test]
fn false_counters_and_error_kinds_fail() {
    let (name, text) = cases()
        .into_iter()
        .find(|(n, _)| n == "rule_03_transmitter_error.ron")
        .unwrap();
    let wrong = text
        .replace(
            "Counters(node: \"TX\", at_s: 0.010070, tec: 8, rec: 0)",
            "Counters(node: \"TX\", at_s: 0.010070, tec: 9, rec: 0)",
        )
        .replace(
            "ErrorKinds(node: \"TX\", kind: Bit, min: 1, max: 1)",
            "ErrorKinds(node: \"TX\", kind: Stuff, min: 1, max: 1)",
        );
    assert_ne!(wrong, text, "the expectations to falsify are in the case");
    let o = run(&name, &wrong, 1);
    let failed = failures(&o);
    assert_eq!(failed.len(), 2, "{failed:#?}");
    assert!(
        failed[0].contains("tec: 9") && failed[0].contains("TEC 8, REC 0"),
        "{failed:#?}"
    );
    assert!(
        failed[1].contains("Stuff") && failed[1].contains("detected 0"),
        "{failed:#?}"
    );
}

/// docs/CONFORMANCE.md's table has one row per case, in file order, with the case's name and
/// description as the file gives them.
#[test]
fn the_doc_lists_every_case() {
    let doc = std::fs::read_to_string(root().join("docs/CONFORMANCE.md")).unwrap();
    let rows: Vec<&str> = doc.lines().filter(|l| l.starts_with("| [`")).collect();
    let want: Vec<String> = cases()
        .iter()
        .map(|(file, text)| {
            let s: scenario::Scenario = ron::from_str(text).unwrap();
            format!(
                "| [`{file}`](../configs/scenarios/conformance/{file}) | {} | {} |",
                s.name, s.description
            )
        })
        .collect();
    assert_eq!(
        rows, want,
        "regenerate the table of docs/CONFORMANCE.md from the cases"
    );
}
