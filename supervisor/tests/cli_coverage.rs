//! `--coverage DIR` from the command line: lcov that genhtml reads, reports that say what the
//! scenario exercised, merges that add up and refuse another image, an assembler image mapped
//! through its listing, debug files that do not belong refused, and the bad outputs and signals
//! every output is held to.

mod common;

use common::{finish_within, harvemu, harvemu_limited, root, scratch, signal, spawn};
use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Command, Output};
use std::time::Duration;

fn err(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// `DA` records of an lcov tracefile: line → count.
fn lines(info: &str) -> BTreeMap<u32, u64> {
    info.lines()
        .filter_map(|l| {
            let (line, count) = l.strip_prefix("DA:")?.split_once(',')?;
            Some((line.parse().ok()?, count.parse().ok()?))
        })
        .collect()
}

/// The line of `source` (1-based) that holds `text`, found in the source itself.
fn line_of(source: &str, text: &str) -> u32 {
    let n = source
        .lines()
        .position(|l| l.contains(text))
        .unwrap_or_else(|| panic!("no line with {text:?}"));
    u32::try_from(n + 1).unwrap()
}

/// The counts of a `NAME.coverage.json`: address → [runs, jumped, fell through].
fn counts(path: &Path) -> BTreeMap<u64, [u64; 3]> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let v: serde_json::Value = serde_json::from_str(&text).expect("JSON");
    v["counts"]
        .as_array()
        .expect("counts")
        .iter()
        .map(|c| {
            let n = |i: usize| c[i].as_u64().expect("a count");
            (n(0), [n(1), n(2), n(3)])
        })
        .collect()
}

#[test]
fn a_scenario_s_lcov_shows_the_bus_off_handler_ran_and_genhtml_reads_it() {
    let dir = scratch("cli-coverage", "genhtml");
    let cov = dir.join("cov");
    let out = harvemu(&["scenario", "c0_bus_off", "--coverage", cov.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", err(&out));
    assert!(err(&out).contains("c0_alarm.hex (C0): "), "{}", err(&out));
    let info = std::fs::read_to_string(cov.join("c0_alarm.info")).expect("the lcov tracefile");
    let source = std::fs::read_to_string(root().join("configs/firmware/c0/c0_alarm.c")).unwrap();
    // The restart of a controller gone bus off: the scenario's point. In a plain run it never
    // runs (below).
    let restart = line_of(&source, "can_restarts++;");
    let da = lines(&info);
    assert!(
        da.get(&restart).is_some_and(|&n| n >= 1),
        "line {restart}: {:?}",
        da.get(&restart)
    );
    // The sources lie beside the reports, where SF names them.
    let sf = info.lines().find_map(|l| l.strip_prefix("SF:")).expect("SF");
    assert_eq!(std::fs::read_to_string(sf).expect("the source SF names"), source);

    let html = dir.join("html");
    let genhtml = Command::new("genhtml")
        .args([
            cov.join("c0_alarm.info").to_str().unwrap(),
            "--branch-coverage",
            "-o",
            html.to_str().unwrap(),
        ])
        .output()
        .unwrap_or_else(|e| panic!("cannot run genhtml ({e}): install the Debian package lcov"));
    assert!(
        genhtml.status.success(),
        "genhtml: {}{}",
        String::from_utf8_lossy(&genhtml.stdout),
        String::from_utf8_lossy(&genhtml.stderr)
    );
    let page = std::fs::read_to_string(html.join("index.html")).expect("genhtml's index");
    assert!(page.contains("c0_alarm"), "the index names the source's folder");

    // Without the bus off, the restart never runs.
    let plain = dir.join("plain");
    let out = harvemu(&[
        "run",
        "configs/harvester-firmware-c0.ron",
        "--fast",
        "--for",
        "3s",
        "--coverage",
        plain.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", err(&out));
    let da = lines(&std::fs::read_to_string(plain.join("c0_alarm.info")).unwrap());
    assert_eq!(da.get(&restart), Some(&0), "line {restart} in a plain run");
}

#[test]
fn merged_counts_are_the_sum_and_another_image_is_refused() {
    let dir = scratch("cli-coverage", "merge");
    let run = |name: &str, secs: &str| {
        let d = dir.join(name);
        let out = harvemu(&[
            "run",
            "configs/harvester-firmware-c0.ron",
            "--fast",
            "--for",
            secs,
            "--coverage",
            d.to_str().unwrap(),
        ]);
        assert_eq!(out.status.code(), Some(0), "{}", err(&out));
        d
    };
    let (a, b) = (run("a", "2s"), run("b", "3s"));
    let merged = dir.join("merged");
    // A folder used before: its stale record would be merged next time; it goes.
    std::fs::create_dir_all(&merged).unwrap();
    std::fs::copy(b.join("c0_alarm.coverage.json"), merged.join("old.coverage.json")).unwrap();
    std::fs::write(merged.join("old.info"), "TN:\n").unwrap();
    std::fs::write(merged.join("notes.txt"), "mine").unwrap();
    let out = harvemu(&[
        "coverage",
        "merge",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--out",
        merged.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", err(&out));
    let (ca, cb, cm) = (
        counts(&a.join("c0_alarm.coverage.json")),
        counts(&b.join("c0_alarm.coverage.json")),
        counts(&merged.join("c0_alarm.coverage.json")),
    );
    let mut sum = ca.clone();
    for (addr, c) in &cb {
        let s = sum.entry(*addr).or_insert([0; 3]);
        for i in 0..3 {
            s[i] += c[i];
        }
    }
    assert_eq!(cm, sum);
    assert!(!merged.join("old.coverage.json").exists() && !merged.join("old.info").exists());
    assert!(merged.join("notes.txt").exists(), "a file of the user's stays");
    assert!(ca != cb, "two runs of different lengths count differently");
    let listing = std::fs::read_to_string(merged.join("c0_alarm.coverage.lst")).unwrap();
    assert!(
        listing.contains("2 runs"),
        "{}",
        listing.lines().next().unwrap_or("")
    );

    // The same file name, another image: refused, named.
    let other = dir.join("other");
    std::fs::create_dir_all(&other).unwrap();
    let text = std::fs::read_to_string(b.join("c0_alarm.coverage.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let sha = v["sha256"].as_str().unwrap().to_string();
    let forged = text.replace(&sha, &"0".repeat(64));
    std::fs::write(other.join("c0_alarm.coverage.json"), forged).unwrap();
    let out = harvemu(&[
        "coverage",
        "merge",
        a.to_str().unwrap(),
        other.to_str().unwrap(),
        "--out",
        dir.join("refused").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", err(&out));
    assert!(
        err(&out).contains("c0_alarm.hex is not the same image in both"),
        "{}",
        err(&out)
    );
    assert!(!dir.join("refused").exists(), "nothing written");
}

#[test]
fn an_assembler_image_maps_to_its_source_through_the_as31_listing() {
    let dir = scratch("cli-coverage", "as31");
    let out = harvemu(&[
        "run",
        "configs/firmware/irq_lab.ron",
        "--fast",
        "--for",
        "1s",
        "--coverage",
        dir.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", err(&out));
    let info = std::fs::read_to_string(dir.join("irq_receiver.info")).expect("lcov from the listing");
    let source = std::fs::read_to_string(root().join("configs/firmware/irq_receiver.asm")).unwrap();
    let da = lines(&info);
    // Ten frames by 1 s (docs/FIRMWARE.md): the handler runs ten times, its copy loop eight
    // times a frame; the set-up once.
    let at = |text: &str| da.get(&line_of(&source, text)).copied();
    assert_eq!(at("MOV     SP, #60H"), Some(1));
    assert_eq!(at("ISR0:   PUSH    ACC"), Some(10));
    assert_eq!(at("COPY:   MOVX    A, @DPTR"), Some(80));
    assert_eq!(at("INC     R5"), Some(10));
    let djnz = line_of(&source, "DJNZ    R2, COPY");
    assert!(
        info.contains(&format!("BRDA:{djnz},0,0,70\nBRDA:{djnz},0,1,10\n")),
        "{info}"
    );
    // Comments and directives are no lines of code.
    assert_eq!(at("; irq_receiver.asm"), None);
    assert_eq!(at(".org    0003H"), None);
}

/// The shipped firmware folder with `extra` files written into it: (name, text).
fn firmware_with(tag: &str, extra: &[(&str, &str)]) -> std::path::PathBuf {
    let dir = scratch("cli-coverage", tag);
    common::copy_dir(&root().join("configs/firmware"), &dir);
    for (name, text) in extra {
        std::fs::write(dir.join(name), text).unwrap();
    }
    dir
}

#[test]
fn debug_files_that_are_not_the_image_s_are_refused_naming_them() {
    // A line record past the end of the image (it ends before 0100h).
    let outside = firmware_with(
        "outside",
        &[("irq_receiver.cdb", "M:irq\nL:C$irq_receiver.c$3$0_0$1:1234\n")],
    );
    // A line record inside an instruction: 0031h is the middle of `MOV SP, #60H` at 0030h. A
    // function must span it for the boundaries to be known.
    let inside = firmware_with(
        "inside",
        &[(
            "irq_receiver.cdb",
            "M:irq\nF:G$main$0_0$0({2}DF,SV:S),C,0,0,0,0,0\nL:G$main$0$0:30\nL:XG$main$0$0:80\nL:C$irq_receiver.c$3$0_0$1:31\n",
        )],
    );
    // An .ihx of another build: one byte changed.
    let hex = std::fs::read_to_string(root().join("configs/firmware/irq_receiver.hex")).unwrap();
    let other = hex.replacen(":03000000020030CB", ":03000000020031CA", 1);
    assert_ne!(other, hex, "the first record is the reset jump");
    let ihx = firmware_with("ihx", &[("irq_receiver.ihx", &other)]);
    for (dir, file, why) in [
        (&outside, "irq_receiver.cdb", "lies outside the image"),
        (&inside, "irq_receiver.cdb", "is not on an instruction of main"),
        (&ihx, "irq_receiver.ihx", "differs from the image beside it"),
    ] {
        let (net, cov) = (dir.join("irq_lab.ron"), dir.join("cov"));
        let (net, cov) = (net.to_str().unwrap(), cov.to_str().unwrap());
        let out = harvemu(&["run", net, "--fast", "--for", "1s", "--coverage", cov]);
        assert_eq!(out.status.code(), Some(2), "{file}: {}", err(&out));
        assert!(
            err(&out).contains(file) && err(&out).contains(why),
            "{}",
            err(&out)
        );
        assert!(!dir.join("cov").exists(), "refused before anything is written");
        // A run that counts no coverage needs no debug files: it goes on without them.
        let out = harvemu(&["run", net, "--fast", "--for", "1s"]);
        assert_eq!(out.status.code(), Some(0), "{file}: {}", err(&out));
    }
}

#[test]
fn an_unwritable_folder_is_exit_3_and_a_full_disk_loses_no_trace() {
    let dir = scratch("cli-coverage", "bad");
    let file = dir.join("file");
    std::fs::write(&file, "").unwrap();
    let under_a_file = file.join("cov");
    let out = harvemu(&[
        "run",
        "configs/harvester-firmware-c0.ron",
        "--fast",
        "--for",
        "1s",
        "--coverage",
        under_a_file.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(3), "{}", err(&out));
    assert!(
        err(&out).contains(&under_a_file.display().to_string()),
        "{}",
        err(&out)
    );

    // Files of at most 12 KiB: a second of trace fits (about 7 KB), C0's coverage record (about
    // 15 KB) does not.
    let trace = dir.join("t.log");
    let cov = dir.join("cov");
    let out = harvemu_limited(
        &[
            "run",
            "configs/harvester-firmware-c0.ron",
            "--fast",
            "--for",
            "1s",
            "--record",
            trace.to_str().unwrap(),
            "--coverage",
            cov.to_str().unwrap(),
        ],
        12 << 10,
    );
    assert_eq!(out.status.code(), Some(3), "{}", err(&out));
    assert!(err(&out).contains("c0_alarm.coverage.json"), "{}", err(&out));
    let trace = std::fs::read_to_string(&trace).expect("the trace");
    assert!(trace.lines().count() > 100, "the frames of the second");
    assert!(trace.ends_with('\n'), "whole lines");
}

#[test]
fn sigterm_mid_run_writes_the_coverage_so_far() {
    let dir = scratch("cli-coverage", "term");
    let cov = dir.join("cov");
    let child = spawn(&[
        "run",
        "configs/harvester-firmware-c0.ron",
        "--fast",
        "--for",
        "10h",
        "--coverage",
        cov.to_str().unwrap(),
    ]);
    std::thread::sleep(Duration::from_secs(3));
    signal(&child, libc::SIGTERM);
    let out = finish_within(child, Duration::from_secs(60));
    assert_eq!(out.status.code(), Some(143), "{}", err(&out));
    let listing = std::fs::read_to_string(cov.join("c0_alarm.coverage.lst")).expect("the listing");
    // The timer interrupt's jump at 002Bh ran once per 10 ms tick until the signal.
    let row = listing.lines().find(|l| l.starts_with("002B ")).expect("002Bh");
    let runs: u64 = row.split_whitespace().last().unwrap().parse().unwrap();
    assert!(runs > 100, "{row}");
    assert!(cov.join("c0_alarm.info").exists());
}

#[test]
fn a_campaign_merges_its_runs_and_its_shards_merge_to_the_whole() {
    let dir = scratch("cli-coverage", "campaign");
    let config = root().join("configs/harvester-firmware-c0.ron");
    let file = dir.join("c0_faults.ron");
    std::fs::write(
        &file,
        format!(
            r#"Scenario(
    name: "c0 faults",
    config: {:?},
    duration_s: 4.0,
    random_faults: Some((
        mean_interval_s: 0.5,
        kinds: [ErrorPassive, Hang, Disconnect],
        nodes: ["C0"],
        from_s: 1.0,
        quiet_end_s: 1.0,
        min_fault_s: 0.2,
        max_fault_s: 0.5,
        node_rest_s: 0.2,
    )),
    expect: [NoCrashes],
)
"#,
            config.display().to_string()
        ),
    )
    .unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let campaign = |out: &Path, shard: Option<&str>| {
        let mut args = vec![
            "campaign".to_string(),
            s(&file),
            "--runs".into(),
            "3".into(),
            "--out".into(),
            s(out),
            "--coverage".into(),
            s(&out.join("coverage")),
        ];
        if let Some(k) = shard {
            args.extend(["--shard".into(), k.into()]);
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = harvemu(&args);
        assert!(matches!(out.status.code(), Some(0 | 1)), "{}", err(&out));
    };
    let whole = dir.join("whole");
    campaign(&whole, None);
    let (one, two) = (dir.join("one"), dir.join("two"));
    campaign(&one, Some("1/2"));
    campaign(&two, Some("2/2"));
    let merged = dir.join("merged");
    let out = harvemu(&["campaign", "merge", &s(&one), &s(&two), "--out", &s(&merged)]);
    assert!(matches!(out.status.code(), Some(0 | 1)), "{}", err(&out));
    let record = |d: &Path| d.join("coverage/c0_alarm.coverage.json");
    assert_eq!(counts(&record(&merged)), counts(&record(&whole)));
    assert!(
        counts(&record(&one)) != counts(&record(&whole)),
        "a shard is not the whole"
    );
    let text = std::fs::read_to_string(record(&merged)).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["runs"], 3);
}

/// An sdas program: its lines come from the listing the linker completes (`sdld -u`).
const SDAS_PROGRAM: &str = "\t.area\tCSEG\t(ABS,CODE)
\t.org\t0x0000
start:\tmov\tr7, #200
delay:\tdjnz\tr7, delay
\tmov\tr6, #5
again:\tinc\ta
\tdjnz\tr6, again
loop:\tsjmp\tloop
\t.db\t0x01, 0x02
";

#[test]
fn an_sdas_image_maps_to_its_source_through_the_linked_listing() {
    let dir = scratch("cli-coverage", "sdas");
    std::fs::write(dir.join("prog.asm"), SDAS_PROGRAM).unwrap();
    let tool = |program: &str, args: &[&str]| {
        let out = Command::new(program)
            .current_dir(&dir)
            .args(args)
            .output()
            .unwrap_or_else(|e| panic!("cannot run {program} ({e}): install the Debian package sdcc"));
        assert!(
            out.status.success(),
            "{program}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        out.stdout
    };
    tool("sdas8051", &["-plosgffw", "prog.asm"]);
    tool("sdld", &["-n", "-u", "-i", "prog.ihx", "prog.rel"]);
    let hex = tool("packihx", &["prog.ihx"]);
    std::fs::write(dir.join("prog.hex"), hex).unwrap();
    std::fs::write(
        dir.join("prog.ron"),
        "Firmware(name: \"PROG\", image: \"prog.hex\", cpu: I80C51(clock_hz: 12000000), controllers: [])",
    )
    .unwrap();
    std::fs::write(
        dir.join("net.ron"),
        "Network(name: \"sdas\", bitrate: 250000, nodes: [\"prog.ron\"])",
    )
    .unwrap();
    let cov = dir.join("cov");
    let out = harvemu(&[
        "run",
        dir.join("net.ron").to_str().unwrap(),
        "--fast",
        "--for",
        "100ms",
        "--coverage",
        cov.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", err(&out));
    let info = std::fs::read_to_string(cov.join("prog.info")).expect("lcov from the linked listing");
    let da = lines(&info);
    let at = |text: &str| da.get(&line_of(SDAS_PROGRAM, text)).copied();
    assert_eq!(at("mov\tr7, #200"), Some(1));
    // The delay loop, passed in closed form: 200 turns.
    assert_eq!(at("djnz\tr7, delay"), Some(200));
    assert_eq!(at("mov\tr6, #5"), Some(1));
    assert_eq!(at("inc\ta"), Some(5));
    assert_eq!(at("djnz\tr6, again"), Some(5));
    assert!(
        at("sjmp\tloop").is_some_and(|n| n > 1000),
        "{:?}",
        at("sjmp\tloop")
    );
    assert_eq!(at(".db"), None, "data is no line of code");
    let again = line_of(SDAS_PROGRAM, "djnz\tr6, again");
    assert!(
        info.contains(&format!("BRDA:{again},1,0,4\nBRDA:{again},1,1,1\n")),
        "{info}"
    );
}
