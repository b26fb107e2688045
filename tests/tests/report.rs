//! The HTML run report (`harvemu scenario ... --report FILE`), read back with an XML parser that
//! knows nothing of how it was written.

use clap::Parser;
use harvemu_e2e::root;
use std::path::{Path, PathBuf};
use supervisor::scenarios_cli::{self, ScenarioArgs};
use supervisor::{Error, report, scenario};

/// The command line as far as these tests need it.
#[derive(Parser)]
#[command(name = "harvemu")]
enum Cli {
    Scenario(ScenarioArgs),
}

/// Runs `harvemu` with `words` (after the program name) in-process: Ok(all passed) or the error.
fn harvemu(words: &[String]) -> anyhow::Result<bool> {
    let Cli::Scenario(args) =
        Cli::try_parse_from(std::iter::once("harvemu".to_string()).chain(words.iter().cloned()))?;
    Ok(scenarios_cli::run(&args).map(|e| !e.expectations_failed)?)
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("harvemu-report-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A 6 s scenario with one bit error, whose name needs escaping; its second expectation fails.
const NAME: &str = "escape <&> \"quotes\" </section>";

fn write_scenario(dir: &Path) -> PathBuf {
    let config = root().join("configs/harvester.ron");
    let text = format!(
        r#"Scenario(
    name: "{}",
    description: "one bit error on B1 & a wrong expectation",
    config: "{}",
    duration_s: 6.0,
    timeline: [(at_s: 3.0, action: BitErrors(target: Node("B1"), hits: Once))],
    expect: [
        ErrorFrames(min: 1, max: 1),
        ErrorFrames(min: 5, max: 9),
        Display(field: "engine_rpm", min: 2000.0, max: 2400.0),
    ],
)"#,
        NAME.replace('"', "\\\""),
        config.display()
    );
    let path = dir.join("small.ron");
    std::fs::write(&path, text).unwrap();
    path
}

/// (expectation, result, at, observed) of every verdict row, section by section.
type Rows = Vec<Vec<[String; 4]>>;

/// The page as XML (it starts with the HTML doctype, which the parser must be told to accept).
fn parse(html: &str) -> Result<roxmltree::Document<'_>, roxmltree::Error> {
    let options = roxmltree::ParsingOptions {
        allow_dtd: true,
        ..Default::default()
    };
    roxmltree::Document::parse_with_options(html, options)
}

fn text(n: roxmltree::Node) -> String {
    n.descendants()
        .filter(|d| d.is_text())
        .map(|d| d.text().unwrap_or(""))
        .collect()
}

fn has_class(n: &roxmltree::Node, class: &str) -> bool {
    n.attribute("class")
        .is_some_and(|c| c.split_whitespace().any(|x| x == class))
}

fn sections<'a>(doc: &'a roxmltree::Document) -> Vec<roxmltree::Node<'a, 'a>> {
    doc.descendants().filter(|n| n.has_tag_name("section")).collect()
}

fn verdict_rows(doc: &roxmltree::Document) -> Rows {
    sections(doc)
        .iter()
        .map(|s| {
            let table = s
                .descendants()
                .find(|n| n.has_tag_name("table") && has_class(n, "verdicts"))
                .expect("a verdict table");
            table
                .descendants()
                .filter(|n| n.has_tag_name("tr") && n.parent().is_some_and(|p| p.has_tag_name("tbody")))
                .map(|tr| {
                    let cells: Vec<String> =
                        tr.children().filter(|c| c.has_tag_name("td")).map(text).collect();
                    [
                        cells[0].clone(),
                        cells[1].clone(),
                        cells[2].clone(),
                        cells[3].clone(),
                    ]
                })
                .collect()
        })
        .collect()
}

fn reproduce_command(section: &roxmltree::Node) -> String {
    text(
        section
            .descendants()
            .find(|n| n.has_tag_name("code") && has_class(n, "reproduce"))
            .expect("a reproducing command"),
    )
}

/// Points of each `<polyline>` of an SVG element.
fn polylines(svg: roxmltree::Node) -> Vec<Vec<(f64, f64)>> {
    svg.descendants()
        .filter(|n| n.has_tag_name("polyline"))
        .map(|p| {
            p.attribute("points")
                .unwrap_or("")
                .split_whitespace()
                .map(|xy| {
                    let (x, y) = xy.split_once(',').unwrap();
                    (x.parse().unwrap(), y.parse().unwrap())
                })
                .collect()
        })
        .collect()
}

/// The longest line of a plot: the series sampled most often.
fn longest(svg: roxmltree::Node) -> Vec<(f64, f64)> {
    polylines(svg)
        .into_iter()
        .max_by_key(|p| p.len())
        .unwrap_or_default()
}

/// Nothing that a browser would fetch: no elements that load things, no attribute or text with
/// a URL (namespace declarations are not attributes to the parser).
fn assert_self_contained(doc: &roxmltree::Document) {
    for n in doc.descendants() {
        if n.is_element() {
            let tag = n.tag_name().name();
            assert!(
                ![
                    "script", "link", "img", "iframe", "object", "embed", "use", "image"
                ]
                .contains(&tag),
                "<{tag}> in the report"
            );
            for a in n.attributes() {
                assert!(
                    !["href", "src"].contains(&a.name()),
                    "{}=\"{}\" on <{tag}>",
                    a.name(),
                    a.value()
                );
                assert!(
                    !a.value().contains("://") && !a.value().contains("url("),
                    "{}=\"{}\" on <{tag}>",
                    a.name(),
                    a.value()
                );
            }
        }
        if let Some(t) = n.text().filter(|_| n.is_text()) {
            for bad in ["://", "url(", "@import", "@font-face"] {
                assert!(!t.contains(bad), "text with {bad}: {t}");
            }
        }
    }
}

#[test]
fn the_report_shows_verdicts_plots_and_a_command_that_gives_the_same_verdicts() {
    let dir = scratch("full");
    let small = write_scenario(&dir);
    let shipped = root().join("configs/scenarios/bit_error_once.ron");
    let out = dir.join("report.html");
    let words: Vec<String> = vec![
        "scenario".into(),
        small.display().to_string(),
        shipped.display().to_string(),
        "--seed".into(),
        "77".into(),
        "--report".into(),
        out.display().to_string(),
    ];
    let passed = harvemu(&words).unwrap();
    assert!(!passed, "one expectation fails");
    let html = std::fs::read_to_string(&out).expect("the report is written although a run failed");
    let doc = parse(&html).expect("the report is well-formed");
    assert_self_contained(&doc);

    // Escaping: the name comes back as written, and its markup never reaches the page raw.
    assert!(!html.contains("<&>") && !html.contains("\"quotes\""));
    let sections = sections(&doc);
    assert_eq!(sections.len(), 2, "a section per scenario");
    let h2: Vec<String> = doc
        .descendants()
        .filter(|n| n.has_tag_name("h2"))
        .map(text)
        .collect();
    assert_eq!(h2, [NAME, "one bit error"]);
    let title = doc
        .descendants()
        .find(|n| n.has_tag_name("title"))
        .map(text)
        .unwrap();
    assert!(title.contains(NAME), "{title}");

    // Verdicts: one row per expectation, with the result the scenario's physics dictate (one
    // bit error gives exactly one error frame).
    let rows = verdict_rows(&doc);
    let summary: Vec<(bool, String)> = rows[0]
        .iter()
        .map(|r| (r[0].starts_with("ErrorFrames"), r[1].clone()))
        .collect();
    assert_eq!(
        summary,
        [
            (true, "pass".to_string()),
            (true, "FAIL".to_string()),
            (false, "pass".to_string())
        ]
    );
    assert!(rows[0][1][0].contains("min: 5") && rows[0][1][3].contains("1 error frame"));
    let expectations = scenario::load(&shipped, None).unwrap().scenario.expect.len();
    assert_eq!(
        rows[1].len(),
        expectations,
        "a row per expectation of bit_error_once.ron"
    );
    assert!(rows[1].iter().all(|r| r[1] == "pass"), "{:?}", rows[1]);
    assert!(html.contains(&format!("FAIL: 1 of {} expectations failed", 3 + expectations)));

    // One plot per subject, each an SVG whose first text is its title.
    let expected_titles = [
        report::LOAD,
        report::LATENCY,
        report::COUNTERS,
        report::YIELD,
        report::SPEED,
    ];
    for s in &sections {
        let svgs: Vec<_> = s.descendants().filter(|n| n.has_tag_name("svg")).collect();
        let titles: Vec<String> = svgs
            .iter()
            .map(|svg| {
                svg.descendants()
                    .find(|n| n.has_tag_name("text"))
                    .map(|t| text(t).trim().to_string())
                    .unwrap_or_default()
            })
            .collect();
        assert_eq!(titles, expected_titles);
    }
    // Load and speed: one point per second of a 6 s run (load windows end at 1..=6 s; start-up
    // ends at 0.5 s, so samples are taken at 1..=6 s), drawn left to right.
    let svgs: Vec<_> = sections[0]
        .descendants()
        .filter(|n| n.has_tag_name("svg"))
        .collect();
    for i in [0, 4] {
        let line = longest(svgs[i]);
        assert_eq!(line.len(), 6, "{}: {line:?}", expected_titles[i]);
        assert!(line.windows(2).all(|w| w[0].0 < w[1].0), "{line:?}");
    }
    assert_eq!(longest(svgs[0]).len(), 6);
    let shipped_load = longest(sections[1].descendants().find(|n| n.has_tag_name("svg")).unwrap());
    assert_eq!(shipped_load.len(), 10, "bit_error_once.ron runs 10 s");

    // The command in each section reproduces that section's verdicts.
    for (i, s) in sections.iter().enumerate() {
        let command = reproduce_command(s);
        let words = shlex::split(&command).expect("a shell command");
        assert_eq!(&words[..2], ["harvemu", "scenario"], "{command}");
        assert!(command.ends_with("--seed 77"), "{command}");
        let again = dir.join(format!("again-{i}.html"));
        let mut args = words[1..].to_vec();
        args.extend(["--report".to_string(), again.display().to_string()]);
        harvemu(&args).unwrap();
        let html = std::fs::read_to_string(&again).unwrap();
        let doc = parse(&html).unwrap();
        assert_eq!(verdict_rows(&doc), vec![rows[i].clone()], "{command}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_report_path_that_cannot_be_written_is_an_output_failure_and_nothing_runs() {
    let dir = scratch("bad");
    let small = write_scenario(&dir);
    let out = dir.join("no such dir").join("r.html");
    let e = harvemu(&[
        "scenario".into(),
        small.display().to_string(),
        "--report".into(),
        out.display().to_string(),
    ])
    .unwrap_err();
    let Some(Error::Output { what, .. }) = e.downcast_ref::<Error>() else {
        panic!("not an output that failed (exit code 3): {e:?}");
    };
    assert_eq!(*what, out.display().to_string());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_series_has_one_sample_per_second_and_sees_counters_rise_and_decay() {
    let dir = scratch("series");
    let l = scenario::load(&write_scenario(&dir), None).unwrap();
    let o = scenario::run(&l, None, |_| {}).unwrap();
    let s = &o.series;
    let times: Vec<f64> = s.samples.iter().map(|x| x.t_s).collect();
    assert_eq!(times, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
    let load_ends: Vec<f64> = s.load.iter().map(|x| x.0).collect();
    assert_eq!(load_ends, times, "1 s load windows");
    assert!(s.load.iter().all(|x| x.1 > 0.0 && x.1 < 1.0), "{:?}", s.load);
    assert_eq!(s.end_s, 6.0);
    // The plant harvests as it drives; the monitor's figure follows it.
    assert!(
        s.samples
            .windows(2)
            .all(|w| w[0].harvested_kg <= w[1].harvested_kg)
    );
    let last = s.samples.last().unwrap();
    assert!(last.speed_kmh > 1.0 && last.harvested_kg > 1.0, "{last:?}");
    assert!(last.monitor_kg.is_some_and(|kg| kg > 0.0));
    // The bit error raises B1's TEC by 8 (transmitter) at 3 s; successful frames bring it back
    // to 0 before the end, which only the per-second samples show.
    let b1 = s
        .counters
        .iter()
        .find(|c| c.node == "B1")
        .expect("B1's counters rose");
    let peak = b1.points.iter().map(|p| p.1).max();
    assert_eq!(peak, Some(8));
    let at_peak = b1.points.iter().find(|p| p.1 == 8).unwrap().0;
    assert!((3.0..3.1).contains(&at_peak), "{at_peak}");
    assert_eq!(b1.points.last().map(|p| p.1), Some(0));
    assert!(b1.points.windows(2).all(|w| w[0].0 <= w[1].0));
    // Latency classes: every frame was counted in one.
    assert!(!s.latency.is_empty());
    assert!(
        s.latency
            .iter()
            .all(|c| c.mean_us <= c.p99_us && c.p99_us <= c.max_us)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn characters_xml_cannot_carry_become_replacement_characters_in_junit_and_the_report() {
    use bus::time::BusTime;
    use supervisor::harvester::{Happened, SupervisorEvent};
    use supervisor::scenario::series::{ClassLatency, NodeCounters};
    use supervisor::scenario::{Outcome, Scenario, Series, Verdict, junit};
    // Validation refuses them in the scenario's own text; everything else (node names from
    // configs, verdict text, file paths) is replaced on the way out.
    let bad = "a\u{1}b\u{1b}[31m\u{8}\u{FFFF}\u{FFFE}\u{7f}";
    let scenario = Scenario {
        name: bad.into(),
        description: bad.into(),
        config: "harvester.ron".into(),
        seed: None,
        duration_s: 3.0,
        cruise_start_s: None,
        timeline: Vec::new(),
        random_faults: None,
        expect: Vec::new(),
    };
    let mut series = Series::default();
    series.load = vec![(1.0, 0.3), (2.0, 0.31)];
    series.latency = vec![ClassLatency {
        class: bad.into(),
        frames: 10,
        mean_us: 100.0,
        p99_us: 200.0,
        max_us: 300.0,
    }];
    series.counters = vec![NodeCounters {
        node: bad.into(),
        points: vec![(1.0, 8, 0), (2.0, 7, 0)],
    }];
    series.end_s = 3.0;
    let outcome = Outcome {
        verdicts: vec![
            Verdict {
                expectation: bad.into(),
                passed: false,
                at: Some(BusTime::from_nanos(1_000_000_000)),
                observed: bad.into(),
            },
            Verdict {
                expectation: bad.into(),
                passed: true,
                at: None,
                observed: bad.into(),
            },
        ],
        seed: 1,
        events: vec![SupervisorEvent {
            at: BusTime::from_nanos(500_000_000),
            node: bad.into(),
            what: Happened::Crashed(bus::node::CrashCause::Panic(bad.into())),
        }],
        wall_seconds: 0.1,
        interrupted: false,
        down: Vec::new(),
        series,
        books: Default::default(),
        applied: Default::default(),
        snapshot: None,
        hardware: Vec::new(),
        coverage: None,
        disturbed: Vec::new(),
        alarms: Vec::new(),
    };
    let runs = [(format!("dir/{bad}.ron"), &scenario, &outcome)];
    let xml = junit::xml(&runs);
    let doc = roxmltree::Document::parse(&xml).unwrap_or_else(|e| panic!("{e}:\n{xml}"));
    let case = doc.descendants().find(|n| n.has_tag_name("testcase")).unwrap();
    let clean = "a\u{FFFD}b\u{FFFD}[31m\u{FFFD}\u{FFFD}\u{FFFD}\u{7f}";
    assert_eq!(
        case.attribute("name"),
        Some(format!("{clean} (dir/{clean}.ron)").as_str())
    );
    let file = case
        .descendants()
        .find(|n| n.has_tag_name("property") && n.attribute("name") == Some("file"))
        .unwrap();
    assert_eq!(file.attribute("value"), Some(format!("dir/{clean}.ron").as_str()));
    let failure = case.children().find(|n| n.has_tag_name("failure")).unwrap();
    assert_eq!(failure.attribute("message"), Some("1 of 2 expectations failed"));
    assert!(failure.text().unwrap().contains(clean), "{xml}");
    let output = case.children().find(|n| n.has_tag_name("system-out")).unwrap();
    // Both verdicts (expectation and observation each) and the event (node and cause).
    assert_eq!(output.text().unwrap().matches(clean).count(), 6, "{xml}");
    let html = report::html(&runs);
    let doc = parse(&html).unwrap_or_else(|e| panic!("{e}:\n{html}"));
    let page = text(doc.root_element());
    assert!(page.contains(clean), "{page}");
    assert!(!page.contains('\u{1}') && !page.contains('\u{FFFF}'));
    assert_eq!(doc.descendants().filter(|n| n.has_tag_name("svg")).count(), 5);
}
