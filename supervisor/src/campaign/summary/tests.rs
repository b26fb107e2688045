use super::*;

fn failed(run: u64) -> Failed {
    Failed {
        run,
        seed: run * 1000,
        expectation: "NoFrameLost".into(),
        observed: "2 lost <at> F5".into(),
        shrunk: shrunk_file(run),
        faults_before: 40,
        faults_after: 2,
        shrink_trials: 60,
        shrink_complete: true,
    }
}

/// The summary of shard `k/m` of a 20-run campaign whose runs 3, 6 and 17 fail.
fn shard(k: u64, m: u64) -> Summary {
    let s = Shard::new(k, m).unwrap();
    let runs: Vec<u64> = s.runs(20).collect();
    let failed: Vec<Failed> = runs
        .iter()
        .filter(|i| [3, 6, 17].contains(*i))
        .map(|&i| failed(i))
        .collect();
    Summary {
        campaign: "harvest".into(),
        scenario_id: "00ff".into(),
        runs: 20,
        seed: 7,
        shard: s.to_string(),
        done: runs.len() as u64,
        passed: (runs.len() - failed.len()) as u64,
        failed,
        interrupted: false,
    }
}

fn named(parts: Vec<Summary>) -> Vec<(String, Summary)> {
    parts
        .into_iter()
        .enumerate()
        .map(|(i, s)| (format!("dir{i}"), s))
        .collect()
}

#[test]
fn four_shards_merge_into_the_whole() {
    let whole = shard(1, 1);
    assert_eq!(whole.passed, 17);
    // In any order.
    let parts = named(vec![shard(3, 4), shard(1, 4), shard(4, 4), shard(2, 4)]);
    assert_eq!(merge(&parts).unwrap(), whole);
    assert_eq!(merge(&named(vec![shard(1, 1)])).unwrap(), whole);
}

#[test]
fn shards_of_other_campaigns_do_not_merge() {
    let mut other_seed = shard(2, 2);
    other_seed.seed = 8;
    let e = merge(&named(vec![shard(1, 2), other_seed])).unwrap_err();
    assert!(e.contains("seed 8, not 7"), "{e}");
    let mut other_text = shard(2, 2);
    other_text.scenario_id = "0100".into();
    assert!(
        merge(&named(vec![shard(1, 2), other_text]))
            .unwrap_err()
            .contains("scenario text")
    );
    let mut other_runs = shard(2, 2);
    other_runs.runs = 21;
    assert!(
        merge(&named(vec![shard(1, 2), other_runs]))
            .unwrap_err()
            .contains("runs 21")
    );
    let e = merge(&named(vec![shard(1, 2), shard(2, 3)])).unwrap_err();
    assert!(e.contains("one of 2 shards"), "{e}");
    let e = merge(&named(vec![shard(1, 3), shard(3, 3)])).unwrap_err();
    assert!(e.contains("2/3 missing"), "{e}");
    let e = merge(&named(vec![shard(1, 2), shard(1, 2), shard(2, 2)])).unwrap_err();
    assert!(e.contains("both shard 1/2"), "{e}");
    let mut cut = shard(2, 2);
    cut.interrupted = true;
    assert!(
        merge(&named(vec![shard(1, 2), cut]))
            .unwrap_err()
            .contains("interrupted")
    );
    let mut short = shard(2, 2);
    short.done -= 1;
    short.passed -= 1;
    assert!(
        merge(&named(vec![shard(1, 2), short]))
            .unwrap_err()
            .contains("covers 9 runs")
    );
    assert!(merge(&[]).is_err());
}

#[test]
fn junit_lists_each_run_of_the_shard() {
    let xml = shard(2, 4).junit().unwrap();
    // Shard 2/4 of 20 runs: 1, 5, 9, 13, 17; run 17 fails.
    let cases: Vec<&str> = xml
        .match_indices("name=\"run ")
        .map(|(i, _)| &xml[i + 10..i + 13])
        .collect();
    assert_eq!(cases, ["1\"/", "5\"/", "9\"/", "13\"", "17\""]);
    assert!(xml.contains("tests=\"5\" failures=\"1\""), "{xml}");
    assert!(xml.contains("2 lost &lt;at&gt; F5"), "{xml}");
    assert!(
        xml.contains("reproduce: harvemu scenario failing/run-17.ron"),
        "{xml}"
    );
}

#[test]
fn a_summary_names_no_file_but_its_own_runs() {
    let mut outside = shard(2, 4);
    outside.failed[0].shrunk = "../../elsewhere.ron".into();
    let e = merge(&named(vec![shard(1, 4), outside, shard(3, 4), shard(4, 4)])).unwrap_err();
    assert!(e.contains("shrunk file is \"../../elsewhere.ron\""), "{e}");
    let mut foreign = shard(2, 4);
    foreign.failed[0].run = 6;
    foreign.failed[0].shrunk = shrunk_file(6);
    let e = merge(&named(vec![shard(1, 4), foreign, shard(3, 4), shard(4, 4)])).unwrap_err();
    assert!(e.contains("run 6 is not a run of shard 2/4"), "{e}");
    let mut twice = shard(3, 4);
    let again = twice.failed[0].clone();
    twice.failed.push(again);
    twice.passed -= 1;
    let e = merge(&named(vec![shard(1, 4), shard(2, 4), twice, shard(4, 4)])).unwrap_err();
    assert!(e.contains("in order"), "{e}");
}

#[test]
fn a_campaign_of_10000_runs_that_all_failed_merges_within_the_summary_limit() {
    // Each run failed with texts far longer than the shipped scenarios give (an expectation
    // and an observation of 1,000 characters each); four shards of 2,500 runs.
    let long = |what: &str, run: u64| format!("{what} of run {run}: {}", "x".repeat(1000));
    let dir = tempfile::tempdir().unwrap();
    let mut parts = Vec::new();
    for k in 1..=4 {
        let s = Shard::new(k, 4).unwrap();
        let failed: Vec<Failed> = s
            .runs(10_000)
            .map(|run| Failed {
                expectation: long("expectation", run),
                observed: long("observed", run),
                ..failed(run)
            })
            .collect();
        let summary = Summary {
            campaign: "harvest".into(),
            scenario_id: "00ff".into(),
            runs: 10_000,
            seed: 7,
            shard: s.to_string(),
            done: failed.len() as u64,
            passed: 0,
            failed,
            interrupted: false,
        };
        let path = dir.path().join(format!("summary-{k}.json"));
        std::fs::write(&path, serde_json::to_string_pretty(&summary).unwrap()).unwrap();
        let text = crate::campaign::merge::read_summary(&path).unwrap();
        assert!(
            (text.len() as u64) < crate::campaign::merge::MAX_SUMMARY / 8,
            "{}",
            text.len()
        );
        parts.push((
            format!("shard-{k}"),
            serde_json::from_str::<Summary>(&text).unwrap(),
        ));
    }
    let whole = merge(&parts).unwrap();
    assert_eq!(
        (whole.done, whole.passed, whole.failed.len()),
        (10_000, 0, 10_000)
    );
    // The whole campaign's summary, as one shard would have written it, is within the limit.
    let path = dir.path().join("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(&whole).unwrap()).unwrap();
    assert!(crate::campaign::merge::read_summary(&path).is_ok());
}
