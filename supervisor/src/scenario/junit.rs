//! JUnit XML for CI systems: one test suite for the batch, one test case per scenario run.
//!
//! Contract: `<testsuite name="harvemu scenario">` holds a `<testcase classname="harvemu.scenario"
//! name="NAME (FILE)">` per run, in the order they ran, with the run's file and seed as
//! `<properties>`. A run with a failed expectation has one `<failure>`, whose message counts the
//! failed expectations and whose text gives each with what was observed, then the seed and the
//! command that reproduces the run; every test case's `<system-out>` gives every verdict and the
//! run's events (crashes, restarts, power cycles). Text XML 1.0 cannot carry becomes U+FFFD.

use super::{Outcome, Scenario, Verdict};

/// True for a character XML 1.0 can carry (its `Char` production): tab, line feed, carriage
/// return, and everything from U+0020 except U+FFFE and U+FFFF (surrogates are not `char`s).
pub(crate) fn xml_char(c: char) -> bool {
    matches!(c, '\t' | '\n' | '\r') || (c >= ' ' && c != '\u{FFFE}' && c != '\u{FFFF}')
}

/// Replaces every character XML 1.0 cannot carry, not even escaped, with U+FFFD.
pub(crate) fn xml_text(s: &str) -> String {
    s.chars()
        .map(|c| {
            if xml_char(c) {
                c
            } else {
                char::REPLACEMENT_CHARACTER
            }
        })
        .collect()
}

/// Escapes text for XML and HTML (element content and double-quoted attributes); characters
/// that XML 1.0 cannot carry become U+FFFD.
pub(crate) fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            c if xml_char(c) => out.push(c),
            _ => out.push(char::REPLACEMENT_CHARACTER),
        }
    }
    out
}

/// The XML for a set of scenario runs: `(file, scenario, outcome)`, the file as the user named
/// it.
pub fn xml(runs: &[(String, &Scenario, &Outcome)]) -> String {
    let failures = runs.iter().filter(|(_, _, o)| !o.passed()).count();
    // Folded from 0.0: an empty `sum` of floats is -0.0, which would print as "-0.000".
    let time = runs.iter().fold(0.0, |t, (_, _, o)| t + o.wall_seconds);
    let mut out = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites>\n  <testsuite name=\"harvemu scenario\" tests=\"{}\" failures=\"{failures}\" time=\"{time:.3}\">\n",
        runs.len()
    );
    for (file, s, o) in runs {
        out += &format!(
            "    <testcase classname=\"harvemu.scenario\" name=\"{} ({})\" time=\"{:.3}\">\n      <properties><property name=\"file\" value=\"{}\"/><property name=\"seed\" value=\"{}\"/></properties>\n",
            escape(&s.name),
            escape(file),
            o.wall_seconds,
            escape(file),
            o.seed
        );
        let failed: Vec<&Verdict> = o.verdicts.iter().filter(|v| !v.passed).collect();
        if !failed.is_empty() {
            let mut text: Vec<String> = failed.iter().map(|v| verdict(v)).collect();
            text.push(format!(
                "seed {}; reproduce: harvemu scenario {file} --seed {}",
                o.seed, o.seed
            ));
            out += &format!(
                "      <failure message=\"{} of {} expectations failed\">{}</failure>\n",
                failed.len(),
                o.verdicts.len(),
                escape(&text.join("\n"))
            );
        }
        // Every verdict, then crashes, restarts and power cycles.
        let lines: Vec<String> = o
            .verdicts
            .iter()
            .map(verdict)
            .chain(
                o.events
                    .iter()
                    .map(|e| format!("event {} {} {}", e.at, e.node, e.what)),
            )
            .collect();
        out += &format!(
            "      <system-out>{}</system-out>\n    </testcase>\n",
            escape(&lines.join("\n"))
        );
    }
    out += "  </testsuite>\n</testsuites>\n";
    out
}

/// A verdict on one line: `FAIL BusLoadBelow(1.0) at 2.000000 s: load 31.2 %`.
fn verdict(v: &Verdict) -> String {
    let at = v.at.map_or(String::new(), |t| format!(" at {t} s"));
    format!(
        "{} {}{at}: {}",
        if v.passed { "PASS" } else { "FAIL" },
        v.expectation,
        v.observed
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harvester::{Happened, SupervisorEvent};
    use crate::scenario::Series;
    use bus::time::BusTime;

    fn scenario(name: &str) -> Scenario {
        Scenario {
            name: name.into(),
            description: String::new(),
            config: "../harvester.ron".into(),
            seed: None,
            duration_s: 30.0,
            cruise_start_s: None,
            timeline: Vec::new(),
            random_faults: None,
            expect: Vec::new(),
        }
    }

    fn verdict(expectation: &str, passed: bool, at_s: Option<u64>, observed: &str) -> Verdict {
        Verdict {
            expectation: expectation.into(),
            passed,
            at: at_s.map(|s| BusTime::from_nanos(s * 1_000_000_000)),
            observed: observed.into(),
        }
    }

    fn outcome(
        seed: u64,
        wall_seconds: f64,
        verdicts: Vec<Verdict>,
        events: Vec<SupervisorEvent>,
    ) -> Outcome {
        Outcome {
            verdicts,
            seed,
            events,
            wall_seconds,
            interrupted: false,
            down: Vec::new(),
            series: Series::default(),
            books: Default::default(),
            applied: Default::default(),
            snapshot: None,
            hardware: Vec::new(),
            coverage: None,
            disturbed: Vec::new(),
            alarms: Vec::new(),
        }
    }

    /// The text of every element `tag` (`<tag ...>TEXT</tag>`), in order.
    fn texts<'a>(xml: &'a str, tag: &str) -> Vec<&'a str> {
        let open = format!("<{tag}");
        let close = format!("</{tag}>");
        let mut found = Vec::new();
        let mut rest = xml;
        while let Some(at) = rest.find(&open) {
            let after = &rest[at..];
            let Some(body) = after.find('>').map(|e| &after[e + 1..]) else {
                break;
            };
            let Some(end) = body.find(&close) else {
                break;
            };
            found.push(&body[..end]);
            rest = &body[end..];
        }
        found
    }

    #[test]
    fn one_test_case_per_scenario_and_one_failure_listing_what_failed() {
        let ok = scenario("all good");
        let bad = scenario("D2 bus off");
        let passed = outcome(
            3,
            0.25,
            vec![verdict(
                "ErrorFrames { min: 0, max: 0 }",
                true,
                None,
                "0 error frames",
            )],
            Vec::new(),
        );
        let failed = outcome(
            7,
            1.5,
            vec![
                verdict("BusLoadBelow(1.0)", false, Some(2), "load 31.2 %"),
                verdict("NoCrashes", true, None, "no crash"),
                verdict(
                    "BusOffCount { node: \"D2\", min: 1, max: 1 }",
                    false,
                    None,
                    "D2 bus off 3 times",
                ),
            ],
            vec![SupervisorEvent {
                at: BusTime::from_nanos(500_000_000),
                node: "D3".into(),
                what: Happened::Restarted,
            }],
        );
        let runs = [
            ("ok.ron".to_string(), &ok, &passed),
            ("dir/bad.ron".to_string(), &bad, &failed),
        ];
        let xml = xml(&runs);
        assert_eq!(xml.matches("<testsuite ").count(), 1, "{xml}");
        assert!(
            xml.contains("<testsuite name=\"harvemu scenario\" tests=\"2\" failures=\"1\" time=\"1.750\">"),
            "{xml}"
        );
        let cases = texts(&xml, "testcase");
        assert_eq!(cases.len(), 2, "{xml}");
        assert!(
            xml.contains(
                "<testcase classname=\"harvemu.scenario\" name=\"all good (ok.ron)\" time=\"0.250\">"
            ),
            "{xml}"
        );
        assert!(
            xml.contains(
                "<testcase classname=\"harvemu.scenario\" name=\"D2 bus off (dir/bad.ron)\" time=\"1.500\">"
            ),
            "{xml}"
        );
        // Each case carries its own file and seed.
        assert!(cases[0].contains(
            "<properties><property name=\"file\" value=\"ok.ron\"/><property name=\"seed\" value=\"3\"/></properties>"
        ));
        assert!(cases[1].contains(
            "<properties><property name=\"file\" value=\"dir/bad.ron\"/><property name=\"seed\" value=\"7\"/></properties>"
        ));
        // The passing case has no failure; the failing one exactly one, naming both failures.
        assert!(!cases[0].contains("<failure"), "{xml}");
        assert_eq!(cases[1].matches("<failure ").count(), 1, "{xml}");
        assert!(
            cases[1].contains("<failure message=\"2 of 3 expectations failed\">"),
            "{xml}"
        );
        let failure = texts(cases[1], "failure");
        assert_eq!(
            failure,
            ["FAIL BusLoadBelow(1.0) at 2.000000 s: load 31.2 %\n\
                 FAIL BusOffCount { node: &quot;D2&quot;, min: 1, max: 1 }: D2 bus off 3 times\n\
                 seed 7; reproduce: harvemu scenario dir/bad.ron --seed 7"]
        );
        // Every verdict, passed or not, and the events are in the case's output.
        let outputs = texts(&xml, "system-out");
        assert_eq!(
            outputs,
            [
                "PASS ErrorFrames { min: 0, max: 0 }: 0 error frames",
                "FAIL BusLoadBelow(1.0) at 2.000000 s: load 31.2 %\n\
                 PASS NoCrashes: no crash\n\
                 FAIL BusOffCount { node: &quot;D2&quot;, min: 1, max: 1 }: D2 bus off 3 times\n\
                 event 0.500000 D3 restarted",
            ]
        );
        assert!(
            xml.ends_with("    </testcase>\n  </testsuite>\n</testsuites>\n"),
            "{xml}"
        );
    }

    #[test]
    fn no_runs_is_an_empty_suite() {
        let xml = xml(&[]);
        assert!(
            xml.contains("<testsuite name=\"harvemu scenario\" tests=\"0\" failures=\"0\" time=\"0.000\">\n  </testsuite>"),
            "{xml}"
        );
        assert!(!xml.contains("<testcase"));
    }

    #[test]
    fn names_and_files_are_escaped() {
        let s = scenario("a <b> & \"c\"");
        let o = outcome(1, 0.0, vec![verdict("X", false, None, "<&>")], Vec::new());
        let xml = xml(&[("d&e.ron".to_string(), &s, &o)]);
        assert!(
            xml.contains("name=\"a &lt;b&gt; &amp; &quot;c&quot; (d&amp;e.ron)\""),
            "{xml}"
        );
        assert!(
            xml.contains("<property name=\"file\" value=\"d&amp;e.ron\"/>"),
            "{xml}"
        );
        assert!(xml.contains("FAIL X: &lt;&amp;&gt;"), "{xml}");
        assert!(!xml.contains("<&>"), "{xml}");
    }
}
