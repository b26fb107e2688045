//! `harvemu campaign`: shards as separate processes merge into the unsharded campaign, a
//! shrunk failing run reruns to the same failure, the shard comes from Kubernetes' environment,
//! and bad input, unwritable outputs and a stop signal end it as docs/CAMPAIGNS.md says.

mod common;

use common::{finish_within, harvemu, root, scratch, signal, spawn};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

/// A campaign over the flow sensors whose property (D0 never bus off) some runs break: a fault
/// that hits every second frame of D0 for long enough takes it bus off.
fn campaign_file(dir: &Path, seconds: f64) -> PathBuf {
    let config = root().join("configs/harvester.ron").canonicalize().unwrap();
    let text = format!(
        r#"Scenario(
    name: "sensor faults",
    config: {config:?},
    duration_s: {seconds:.1},
    random_faults: Some((
        mean_interval_s: 1.0,
        kinds: [ErrorPassive, Hang, Disconnect],
        nodes: ["D0", "D1", "D2", "D3", "D4", "D5"],
        from_s: 5.0,
        quiet_end_s: 5.0,
        min_fault_s: 0.2,
        max_fault_s: 1.0,
        node_rest_s: 0.5,
    )),
    expect: [BusOffCount(node: "D0", min: 0, max: 0)],
)
"#
    );
    let path = dir.join("sensor_faults.ron");
    std::fs::write(&path, text).unwrap();
    path
}

fn text(o: &Output) -> String {
    format!(
        "exit {:?}\nstdout:\n{}\nstderr:\n{}",
        o.status.code(),
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A shrunk scenario without its comment lines (the rerun line names the file's own place).
fn scenario_part(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.lines()
        .skip_while(|l| l.starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn four_shard_processes_merge_into_the_unsharded_campaign() {
    let dir = scratch("campaign", "shards");
    let file = campaign_file(&dir, 20.0);
    let common = ["--runs", "8", "--seed", "5", "--shrink-trials", "8"];
    let all = dir.join("all");
    let whole = harvemu(
        &[
            &["campaign", s(&file)],
            &common[..],
            &["--jobs", "2", "--out", s(&all)],
        ]
        .concat(),
    );
    // Some run fails (exit code 1): the campaign found what it looks for.
    assert_eq!(whole.status.code(), Some(1), "{}", text(&whole));

    // Four processes at once, one job each.
    let shards: Vec<PathBuf> = (1..=4).map(|k| dir.join(format!("shard-{k}"))).collect();
    let children: Vec<_> = shards
        .iter()
        .enumerate()
        .map(|(i, out)| {
            let shard = format!("{}/4", i + 1);
            let args = [
                &["campaign", s(&file)],
                &common[..],
                &["--jobs", "1", "--shard", &shard, "--out", s(out)],
            ]
            .concat();
            spawn(&args)
        })
        .collect();
    for (k, child) in children.into_iter().enumerate() {
        let o = finish_within(child, Duration::from_secs(600));
        let code = o.status.code();
        assert!(
            code == Some(0) || code == Some(1),
            "shard {}: {}",
            k + 1,
            text(&o)
        );
        let summary = json(&shards[k].join("summary.json"));
        assert_eq!(summary["shard"], format!("{}/4", k + 1));
        assert_eq!(summary["done"], 2, "8 runs over 4 shards");
    }
    let merged = dir.join("merged");
    let mut args = vec!["campaign", "merge"];
    // In another order than their numbers: the merge sorts them out.
    for k in [3, 1, 4, 2] {
        args.push(s(&shards[k - 1]));
    }
    args.extend(["--out", s(&merged)]);
    let o = harvemu(&args);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));

    // Byte for byte: the merged summary is the unsharded one.
    let read = |p: PathBuf| std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    assert_eq!(read(merged.join("summary.json")), read(all.join("summary.json")));
    let summary = json(&all.join("summary.json"));
    assert_eq!(
        (summary["runs"].as_u64(), summary["seed"].as_u64()),
        (Some(8), Some(5))
    );
    assert_eq!(summary["shard"], "1/1");
    let failed = summary["failed"].as_array().unwrap();
    assert!(!failed.is_empty() && failed.len() < 8, "{summary}");
    assert_eq!(summary["passed"].as_u64().unwrap() as usize + failed.len(), 8);
    for f in failed {
        let shrunk = f["shrunk"].as_str().unwrap();
        assert_eq!(shrunk, format!("failing/run-{}.ron", f["run"]));
        assert_eq!(f["expectation"], r#"BusOffCount { node: "D0", min: 0, max: 0 }"#);
        let (before, after) = (
            f["faults_before"].as_u64().unwrap(),
            f["faults_after"].as_u64().unwrap(),
        );
        assert!(after >= 1 && after < before, "{f}");
        assert_eq!(
            scenario_part(&merged.join(shrunk)),
            scenario_part(&all.join(shrunk))
        );
    }
    // JUnit: a test case per run, the failing ones failed; well-formed for an XML parser.
    let junit = read(merged.join("junit.xml"));
    assert_eq!(junit.matches("<testcase ").count(), 8, "{junit}");
    assert_eq!(junit.matches("<failure ").count(), failed.len(), "{junit}");
    let python = std::env::var("HARVEMU_PYTHON").unwrap_or_else(|_| "python3".into());
    let parsed = Command::new(&python)
        .args(["-c", "import sys, xml.etree.ElementTree as E; r = E.parse(sys.argv[1]).getroot(); print(sum(1 for _ in r.iter('testcase')))"])
        .arg(merged.join("junit.xml"))
        .output()
        .unwrap_or_else(|e| panic!("cannot run {python}: {e}"));
    assert_eq!(
        String::from_utf8_lossy(&parsed.stdout).trim(),
        "8",
        "{}",
        text(&parsed)
    );

    // The first shrunk run, rerun as an ordinary scenario, fails the same expectation.
    let first = merged.join(failed[0]["shrunk"].as_str().unwrap());
    let o = harvemu(&["scenario", s(&first)]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains(r#"FAIL BusOffCount { node: "D0", min: 0, max: 0 }"#),
        "{out}"
    );
    assert!(
        !read(first.clone()).contains("random_faults: Some"),
        "a plain timeline"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_most_runs_there_can_be_take_nothing_up_front() {
    // Nothing is set aside per run before it is played: u64::MAX runs start at once, and a
    // stop signal ends them with a summary of what was done.
    let dir = scratch("campaign", "most");
    let out = dir.join("out");
    let most = u64::MAX.to_string();
    let child = spawn(&[
        "campaign",
        "harvest",
        "--runs",
        &most,
        "--jobs",
        "2",
        "--out",
        s(&out),
    ]);
    // The output folder is made once the campaign is read, after the signals are handled.
    let started = std::time::Instant::now();
    while !out.join("failing").exists() {
        assert!(started.elapsed() < Duration::from_secs(600), "no output folder");
        std::thread::sleep(Duration::from_millis(50));
    }
    signal(&child, libc::SIGTERM);
    let o = finish_within(child, Duration::from_secs(120));
    assert_eq!(o.status.code(), Some(143), "{}", text(&o));
    let summary = json(&out.join("summary.json"));
    assert_eq!(summary["runs"].as_u64(), Some(u64::MAX), "{summary}");
    assert_eq!(summary["interrupted"], true);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn kubernetes_index_and_shard_count_pick_the_shard() {
    let dir = scratch("campaign", "env");
    let file = campaign_file(&dir, 12.0);
    let run = |out: &Path, env: &[(&str, &str)], extra: &[&str]| {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_harvemu"));
        cmd.current_dir(root())
            .args([
                "campaign",
                s(&file),
                "--runs",
                "4",
                "--shrink-trials",
                "0",
                "--out",
                s(out),
            ])
            .args(extra)
            .env_remove("JOB_COMPLETION_INDEX")
            .env_remove("HARVEMU_SHARDS");
        for (k, v) in env {
            cmd.env(k, v);
        }
        cmd.output().unwrap()
    };
    let by_env = dir.join("env");
    let o = run(
        &by_env,
        &[("JOB_COMPLETION_INDEX", "1"), ("HARVEMU_SHARDS", "4")],
        &[],
    );
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", text(&o));
    let by_flag = dir.join("flag");
    let o = run(&by_flag, &[], &["--shard", "2/4"]);
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", text(&o));
    let (a, b) = (
        json(&by_env.join("summary.json")),
        json(&by_flag.join("summary.json")),
    );
    assert_eq!(a["shard"], "2/4");
    assert_eq!(a, b);
    // --shard wins over the environment.
    let o = run(
        &dir.join("both"),
        &[("JOB_COMPLETION_INDEX", "0"), ("HARVEMU_SHARDS", "4")],
        &["--shard", "2/4"],
    );
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", text(&o));
    assert_eq!(json(&dir.join("both/summary.json"))["shard"], "2/4");
    // An index without the shard count is refused.
    let o = run(&dir.join("bad"), &[("JOB_COMPLETION_INDEX", "1")], &[]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("HARVEMU_SHARDS"),
        "{}",
        text(&o)
    );
    // And the shard count without an index: which shard is unknown, nothing runs.
    let o = run(&dir.join("count"), &[("HARVEMU_SHARDS", "4")], &[]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("JOB_COMPLETION_INDEX"),
        "{}",
        text(&o)
    );
    assert!(!dir.join("count/summary.json").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_input_is_refused_with_exit_code_2() {
    let dir = scratch("campaign", "bad");
    let file = campaign_file(&dir, 8.0);
    let out = dir.join("out");
    let expect2 = |args: &[&str], says: &str| {
        let o = harvemu(args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(says), "{args:?}: {says:?} not in {err}");
    };
    expect2(
        &[
            "campaign",
            "configs/scenarios/crash.ron",
            "--runs",
            "4",
            "--out",
            s(&out),
        ],
        "random_faults",
    );
    expect2(
        &[
            "campaign",
            s(&file),
            "--runs",
            "4",
            "--shard",
            "5/4",
            "--out",
            s(&out),
        ],
        "5/4",
    );
    expect2(
        &[
            "campaign",
            s(&file),
            "--runs",
            "4",
            "--shard",
            "0/4",
            "--out",
            s(&out),
        ],
        "0/4",
    );
    expect2(&["campaign", s(&file), "--runs", "0", "--out", s(&out)], "--runs");
    expect2(
        &[
            "campaign",
            s(&file),
            "--runs",
            "4",
            "--jobs",
            "1025",
            "--out",
            s(&out),
        ],
        "--jobs",
    );
    expect2(&["campaign", s(&file), "--runs", "4"], "--out");
    expect2(
        &["campaign", "no-such-campaign", "--runs", "4", "--out", s(&out)],
        "no-such-campaign",
    );
    assert!(!out.exists(), "nothing written for bad input");

    // Shards of two campaigns (another seed) do not merge; nor does a missing shard.
    let shard = |seed: &str, k: u32| {
        let d = dir.join(format!("seed{seed}-{k}"));
        let o = harvemu(&[
            "campaign",
            s(&file),
            "--runs",
            "2",
            "--seed",
            seed,
            "--shrink-trials",
            "0",
            "--shard",
            &format!("{k}/2"),
            "--out",
            s(&d),
        ]);
        assert!(matches!(o.status.code(), Some(0 | 1)), "{}", text(&o));
        d
    };
    let (a1, b2) = (shard("1", 1), shard("2", 2));
    let merged = dir.join("merged");
    expect2(
        &["campaign", "merge", s(&a1), s(&b2), "--out", s(&merged)],
        "another campaign",
    );
    expect2(&["campaign", "merge", s(&a1), "--out", s(&merged)], "2/2 missing");
    expect2(
        &["campaign", "merge", s(&a1), s(&a1), "--out", s(&merged)],
        "both shard 1/2",
    );
    // A folder without a summary, and a summary that is not one.
    expect2(
        &["campaign", "merge", s(&dir), "--out", s(&merged)],
        "summary.json",
    );
    let junk = dir.join("junk");
    std::fs::create_dir_all(&junk).unwrap();
    std::fs::write(junk.join("summary.json"), "{\"runs\": \"many\"}").unwrap();
    expect2(
        &["campaign", "merge", s(&junk), "--out", s(&merged)],
        "not a campaign summary",
    );
    assert!(!merged.exists(), "nothing merged");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn outputs_that_cannot_be_written_exit_3() {
    let dir = scratch("campaign", "full");
    let file = campaign_file(&dir, 8.0);
    let o = harvemu(&["campaign", s(&file), "--runs", "1", "--out", "/dev/full/campaign"]);
    assert_eq!(o.status.code(), Some(3), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("/dev/full/campaign"),
        "{}",
        text(&o)
    );
    // A full disk while the summary is written (a file-size limit of 100 bytes).
    let out = dir.join("limited");
    let o = common::harvemu_limited(
        &[
            "campaign",
            s(&file),
            "--runs",
            "1",
            "--shrink-trials",
            "0",
            "--out",
            s(&out),
        ],
        100,
    );
    assert_eq!(o.status.code(), Some(3), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("summary.json"),
        "{}",
        text(&o)
    );
    assert!(!out.join("summary.json").exists(), "no half summary");
    // Standard output that takes no write: the files are whole, the exit code says it.
    let out = dir.join("stdout");
    let o = Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(root())
        .args([
            "campaign",
            s(&file),
            "--runs",
            "1",
            "--shrink-trials",
            "0",
            "--out",
            s(&out),
        ])
        .stdout(std::fs::File::create("/dev/full").unwrap())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(3), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("standard output"),
        "{}",
        text(&o)
    );
    assert_eq!(json(&out.join("summary.json"))["done"], 1);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn sigterm_ends_the_campaign_with_a_summary_that_says_so() {
    let dir = scratch("campaign", "term");
    let out = dir.join("out");
    let mut child = spawn(&[
        "campaign",
        "harvest",
        "--runs",
        "20",
        "--jobs",
        "1",
        "--out",
        s(&out),
    ]);
    // Stopped once it says that two runs are done (a line per tenth of the runs in a log):
    // whenever that is, the summary must cover those.
    let stderr = child.stderr.take().unwrap();
    let (said, heard) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        use std::io::BufRead;
        for line in std::io::BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = said.send(line);
        }
    });
    let progress = loop {
        let line = heard
            .recv_timeout(Duration::from_secs(600))
            .expect("a progress line on standard error");
        if line.starts_with("harvemu: campaign harvest: 2/20 runs") {
            break line;
        }
    };
    assert!(
        progress.contains("0 failed") && progress.contains("runs/h"),
        "{progress}"
    );
    signal(&child, libc::SIGTERM);
    let o = finish_within(child, Duration::from_secs(60));
    assert_eq!(o.status.code(), Some(143), "{}", text(&o));
    let summary = json(&out.join("summary.json"));
    assert_eq!(summary["interrupted"], true);
    let done = summary["done"].as_u64().unwrap();
    assert!((2..20).contains(&done), "{summary}");
    assert_eq!(
        summary["passed"].as_u64().unwrap() + summary["failed"].as_array().unwrap().len() as u64,
        done
    );
    let junit = std::fs::read_to_string(out.join("junit.xml")).unwrap();
    assert_eq!(junit.matches("<testcase ").count() as u64, done);
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("INTERRUPTED"),
        "{}",
        text(&o)
    );
    // An interrupted shard is no part of a merge.
    let o = harvemu(&["campaign", "merge", s(&out), "--out", s(&dir.join("merged"))]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("interrupted"),
        "{}",
        text(&o)
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_planted_overlap_shrinks_to_the_two_faults_that_make_it() {
    // Three nodes: D0 sends, B0 and B1 acknowledge. By the CAN rules a transmitter that no
    // receiver acknowledges counts 8 up per attempt and is error passive at 128 (ISO 11898-1,
    // fault confinement), so D0 turns error passive only while B0 and B1 are both
    // disconnected. The other faults (hangs, crashes, bit errors on the bus) are noise: a hung
    // or restarting node's controller still acknowledges.
    let dir = scratch("campaign", "planted");
    let node = |n: &str| root().join("configs/nodes").join(n).canonicalize().unwrap();
    std::fs::write(
        dir.join("net.ron"),
        format!(
            "Network(name: \"three\", bitrate: 250000, nodes: [{:?}, {:?}, {:?}])",
            node("d0.ron"),
            node("b0.ron"),
            node("b1.ron")
        ),
    )
    .unwrap();
    let file = dir.join("planted.ron");
    std::fs::write(
        &file,
        r#"Scenario(
    name: "planted overlap",
    config: "net.ron",
    duration_s: 60.0,
    random_faults: Some((
        mean_interval_s: 0.7,
        kinds: [Disconnect, Hang, BitErrors, Crash],
        nodes: ["B0", "B1"],
        from_s: 5.0,
        quiet_end_s: 5.0,
        min_fault_s: 0.2,
        max_fault_s: 2.0,
        node_rest_s: 0.0,
    )),
    expect: [NodeStateNever(node: "D0", state: Passive, from_s: 0.0, to_s: 60.0)],
)
"#,
    )
    .unwrap();
    let out = dir.join("out");
    let o = harvemu(&[
        "campaign",
        s(&file),
        "--runs",
        "6",
        "--seed",
        "0",
        "--out",
        s(&out),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let summary = json(&out.join("summary.json"));
    let failed = summary["failed"].as_array().unwrap();
    assert!(!failed.is_empty(), "{summary}");
    for f in failed {
        assert!(f["faults_before"].as_u64().unwrap() >= 40, "{f}");
        assert_eq!(f["faults_after"], 2, "{f}");
        assert_eq!(f["shrink_complete"], true, "{f}");
        let shrunk = out.join(f["shrunk"].as_str().unwrap());
        let l = supervisor::scenario::load(&shrunk, None).unwrap_or_else(|e| panic!("{e}"));
        let steps: Vec<(f64, String)> = l
            .scenario
            .timeline
            .iter()
            .map(|st| (st.at_s, format!("{:?}", st.action)))
            .collect();
        let at = |what: &str| {
            steps
                .iter()
                .find(|(_, a)| a == what)
                .unwrap_or_else(|| panic!("{what} not in {steps:?}"))
                .0
        };
        assert_eq!(steps.len(), 4, "{steps:?}");
        let (b0, b1) = (at("Disconnect(\"B0\")"), at("Disconnect(\"B1\")"));
        let (b0_back, b1_back) = (at("Reconnect(\"B0\")"), at("Reconnect(\"B1\")"));
        assert!(b0 < b1_back && b1 < b0_back, "they overlap: {steps:?}");
        // Moved to the campaign's earliest start, 5 s, as early as the overlap allows.
        assert_eq!(b0.min(b1), 5.0, "{steps:?}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The files in `out/failing`, and the ones its summary.json lists: the same when nothing stale
/// survived.
fn failing_files(out: &Path) -> (Vec<String>, Vec<String>) {
    let mut on_disk: Vec<String> = std::fs::read_dir(out.join("failing"))
        .map(|d| {
            d.map(|e| format!("failing/{}", e.unwrap().file_name().to_string_lossy()))
                .collect()
        })
        .unwrap_or_default();
    on_disk.sort();
    let summary = json(&out.join("summary.json"));
    let mut listed: Vec<String> = summary["failed"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["shrunk"].as_str().unwrap().to_string())
        .collect();
    listed.sort();
    (on_disk, listed)
}

#[test]
fn a_reused_out_holds_one_campaign_and_nothing_stale() {
    let dir = scratch("campaign", "reuse");
    // 20 s runs: seeds 5 and 6 each fail two of four.
    let file = campaign_file(&dir, 20.0);
    let out = dir.join("out");
    let campaign = |seed: &str, extra: &[&str]| {
        let args = [
            &[
                "campaign",
                s(&file),
                "--runs",
                "4",
                "--seed",
                seed,
                "--shrink-trials",
                "0",
                "--jobs",
                "2",
            ],
            &["--out", s(&out)][..],
            extra,
        ]
        .concat();
        harvemu(&args)
    };
    let first = campaign("5", &[]);
    assert_eq!(first.status.code(), Some(1), "{}", text(&first));
    // What an earlier, longer run of the same campaign left: a CI retry clears it.
    std::fs::write(out.join("failing/run-999.ron"), "stale").unwrap();
    let again = campaign("5", &[]);
    assert_eq!(again.status.code(), first.status.code(), "{}", text(&again));
    let (on_disk, listed) = failing_files(&out);
    assert_eq!(on_disk, listed, "only the failing runs its summary lists");
    assert!(!listed.is_empty());
    assert!(!out.join("failing/run-999.ron").exists());

    // Another seed is another campaign: refused, the results there untouched.
    let before = std::fs::read(out.join("summary.json")).unwrap();
    let other = campaign("6", &[]);
    assert_eq!(other.status.code(), Some(2), "{}", text(&other));
    let err = String::from_utf8_lossy(&other.stderr);
    assert!(err.contains("seed 5, not 6") && err.contains("--force"), "{err}");
    assert_eq!(std::fs::read(out.join("summary.json")).unwrap(), before);
    // ...unless forced: then only its own results are there.
    std::fs::write(out.join("failing/run-999.ron"), "stale").unwrap();
    let forced = campaign("6", &["--force"]);
    assert_eq!(forced.status.code(), Some(1), "{}", text(&forced));
    assert_eq!(json(&out.join("summary.json"))["seed"], 6);
    let (on_disk, listed) = failing_files(&out);
    assert_eq!(on_disk, listed);
    assert!(!listed.is_empty());

    // Failing runs without a summary (a campaign killed outright): whose they are is unknown.
    let orphan = dir.join("orphan");
    std::fs::create_dir_all(orphan.join("failing")).unwrap();
    std::fs::write(orphan.join("failing/run-1.ron"), "stale").unwrap();
    let o = harvemu(&["campaign", s(&file), "--runs", "4", "--out", s(&orphan)]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("without a summary.json"),
        "{}",
        text(&o)
    );

    // A merge into a folder holding another campaign is refused the same way.
    let merged = harvemu(&["campaign", "merge", s(&out), "--out", s(&orphan)]);
    assert_eq!(merged.status.code(), Some(2), "{}", text(&merged));
    let merged = harvemu(&["campaign", "merge", s(&out), "--out", s(&orphan), "--force"]);
    assert_eq!(merged.status.code(), Some(1), "{}", text(&merged));
    let (on_disk, listed) = failing_files(&orphan);
    assert_eq!(on_disk, listed);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_jobs_reported_are_the_ones_used_and_counts_read_as_english() {
    let dir = scratch("cli_campaign", "jobs");
    let file = campaign_file(&dir, 6.0);
    let out = dir.join("out");
    // No --jobs: as many as the machine has cores, but one run needs one job.
    let o = harvemu(&[
        "campaign",
        file.to_str().unwrap(),
        "--runs",
        "1",
        "--out",
        dir.join("out2").to_str().unwrap(),
    ]);
    let t = text(&o);
    assert!(t.contains("runs per hour on 1 job\n"), "{t}");
    let o = harvemu(&[
        "campaign",
        file.to_str().unwrap(),
        "--runs",
        "2",
        "--jobs",
        "64",
        "--out",
        out.to_str().unwrap(),
    ]);
    let t = text(&o);
    assert!(t.contains("runs per hour on 2 jobs\n"), "{t}");
    std::fs::remove_dir_all(&dir).unwrap();
}
