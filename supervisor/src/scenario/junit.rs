//! JUnit XML for CI systems: one test suite per scenario, one test case per expectation.

use super::{Outcome, Scenario};

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

/// The XML for a set of scenario runs.
pub fn xml(runs: &[(String, &Scenario, &Outcome)]) -> String {
    let mut out = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites>\n");
    for (file, s, o) in runs {
        let failures = o.verdicts.iter().filter(|v| !v.passed).count();
        out += &format!(
            "  <testsuite name=\"{}\" tests=\"{}\" failures=\"{failures}\" time=\"{:.3}\">\n    <properties><property name=\"file\" value=\"{}\"/><property name=\"seed\" value=\"{}\"/></properties>\n",
            escape(&s.name),
            o.verdicts.len(),
            o.wall_seconds,
            escape(file),
            o.seed
        );
        for v in &o.verdicts {
            out += &format!(
                "    <testcase classname=\"{}\" name=\"{}\"",
                escape(&s.name),
                escape(&v.expectation)
            );
            if v.passed {
                out += "/>\n";
            } else {
                let at = v.at.map_or("-".to_string(), |t| format!("{t} s"));
                out += &format!(
                    ">\n      <failure message=\"{}\">at {at}; seed {}; reproduce: harvemu scenario {} --seed {}</failure>\n    </testcase>\n",
                    escape(&v.observed),
                    o.seed,
                    escape(file),
                    o.seed
                );
            }
        }
        // Crashes, restarts and power cycles are part of the report.
        let events: Vec<String> = o
            .events
            .iter()
            .map(|e| format!("{} {} {}", e.at, e.node, e.what))
            .collect();
        out += &format!("    <system-out>{}</system-out>\n", escape(&events.join("\n")));
        out += "  </testsuite>\n";
    }
    out += "</testsuites>\n";
    out
}
