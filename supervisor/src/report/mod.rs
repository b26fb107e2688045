//! The run report: one self-contained HTML page for a batch of scenario runs.
//!
//! Contract: [`html`] turns finished runs (file as given, scenario, outcome) into one page with a
//! section per scenario: name, description, file, seed, the command that reproduces the run,
//! a pass/fail summary, the verdicts, the supervisor events, the monitor's alarms, and inline
//! SVG plots of bus load, latency per priority class, error counters per node, yield and travel
//! speed. Every text is
//! escaped; the page loads nothing from elsewhere (no links, scripts, fonts or images). The page
//! is also well-formed XML, so that any XML parser can check it. No I/O: the caller writes it.

mod plots;

pub use plots::{COUNTERS, LATENCY, LOAD, SPEED, YIELD};

use crate::scenario::junit::escape;
use crate::scenario::{Outcome, Scenario, Series};
use std::fmt::Write;

const STYLE: &str = "
body { font-family: sans-serif; margin: 2em auto; max-width: 800px; color: #222; }
h2 { border-bottom: 2px solid #ccc; margin-top: 2em; }
table { border-collapse: collapse; margin: 0.5em 0; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.5em; text-align: left; vertical-align: top; }
td.num { text-align: right; }
.pass { color: #176317; }
.fail { color: #b01515; font-weight: bold; }
code { background: #f2f2f2; padding: 0.2em 0.4em; }
figure { margin: 1em 0; }
";

/// The command that runs the scenario again with the same seed (verdicts depend on nothing else).
pub fn reproduce(file: &str, seed: u64) -> String {
    let file = shlex::try_quote(file).map_or_else(|_| file.into(), |q| q.into_owned());
    format!("harvemu scenario {file} --seed {seed}")
}

fn counts(o: &Outcome) -> (usize, usize) {
    let failed = o.verdicts.iter().filter(|v| !v.passed).count();
    (o.verdicts.len() - failed, failed)
}

fn summary(passed: usize, failed: usize) -> String {
    if failed == 0 {
        format!("<p class=\"summary pass\">PASS: all {passed} expectations passed</p>\n")
    } else {
        format!(
            "<p class=\"summary fail\">FAIL: {failed} of {} expectations failed</p>\n",
            passed + failed
        )
    }
}

/// The page for a set of runs, in the order given.
pub fn html(runs: &[(String, &Scenario, &Outcome)]) -> String {
    let names: Vec<&str> = runs.iter().map(|(_, s, _)| s.name.as_str()).collect();
    let mut out = format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\"/>\n<title>harvemu run report: {}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n<h1>harvemu run report</h1>\n",
        escape(&names.join(", "))
    );
    let (passed, failed) = runs
        .iter()
        .map(|(_, _, o)| counts(o))
        .fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    out += &summary(passed, failed);
    for (i, (file, s, o)) in runs.iter().enumerate() {
        section(&mut out, i + 1, file, s, o);
    }
    out += "</body>\n</html>\n";
    out
}

fn section(out: &mut String, n: usize, file: &str, s: &Scenario, o: &Outcome) {
    let _ = write!(
        out,
        "<section class=\"scenario\" id=\"scenario-{n}\">\n<h2>{}</h2>\n<p class=\"description\">{}</p>\n",
        escape(&s.name),
        escape(&s.description)
    );
    let reached = if o.interrupted {
        format!("{:.1} s of {} s (interrupted)", o.series.end_s, s.duration_s)
    } else {
        format!("{:.1} s", o.series.end_s)
    };
    out.push_str("<table class=\"facts\">\n");
    for (key, value) in [
        ("file", file.to_string()),
        ("seed", o.seed.to_string()),
        ("bus time", reached),
        ("wall time", format!("{:.1} s", o.wall_seconds)),
    ] {
        let _ = writeln!(out, "<tr><th>{key}</th><td>{}</td></tr>", escape(&value));
    }
    for line in o.disturbances() {
        let _ = writeln!(out, "<tr><th>disturbance</th><td>{}</td></tr>", escape(&line));
    }
    out.push_str("</table>\n");
    let _ = writeln!(
        out,
        "<p>Reproduce: <code class=\"reproduce\">{}</code></p>",
        escape(&reproduce(file, o.seed))
    );
    let (passed, failed) = counts(o);
    out.push_str(&summary(passed, failed));
    verdicts(out, o);
    events(out, o);
    alarms(out, o);
    plots(out, n, o);
    out.push_str("</section>\n");
}

fn verdicts(out: &mut String, o: &Outcome) {
    out.push_str("<h3>Verdicts</h3>\n<table class=\"verdicts\">\n<thead><tr><th>expectation</th><th>result</th><th>at [s]</th><th>observed</th></tr></thead>\n<tbody>\n");
    for v in &o.verdicts {
        let (class, result) = if v.passed {
            ("pass", "pass")
        } else {
            ("fail", "FAIL")
        };
        let at = v.at.map_or("-".to_string(), |t| t.to_string());
        let _ = writeln!(
            out,
            "<tr class=\"{class}\"><td>{}</td><td class=\"result\">{result}</td><td class=\"num\">{at}</td><td>{}</td></tr>",
            escape(&v.expectation),
            escape(&v.observed)
        );
    }
    out.push_str("</tbody>\n</table>\n");
}

fn events(out: &mut String, o: &Outcome) {
    out.push_str("<h3>Supervisor events</h3>\n");
    if o.events.is_empty() {
        out.push_str("<p class=\"events\">none: no crash, restart or power cycle</p>\n");
        return;
    }
    out.push_str("<table class=\"events\">\n<thead><tr><th>at [s]</th><th>node</th><th>what</th></tr></thead>\n<tbody>\n");
    for e in &o.events {
        let _ = writeln!(
            out,
            "<tr><td class=\"num\">{}</td><td>{}</td><td>{}</td></tr>",
            e.at,
            escape(&e.node),
            escape(&e.what.to_string())
        );
    }
    out.push_str("</tbody>\n</table>\n");
}

/// The reference monitor's alarms: each raised, and cleared if it was ("missing": an expected
/// node never heard; "silent": one heard, then not).
fn alarms(out: &mut String, o: &Outcome) {
    out.push_str("<h3>Monitor alarms</h3>\n");
    if o.alarms.is_empty() {
        out.push_str("<p class=\"alarms\">none</p>\n");
        return;
    }
    out.push_str("<table class=\"alarms\">\n<thead><tr><th>raised [s]</th><th>node</th><th>alarm</th><th>cleared [s]</th></tr></thead>\n<tbody>\n");
    for a in &o.alarms {
        let cleared = a.cleared.map_or("still active".to_string(), |t| t.to_string());
        let _ = writeln!(
            out,
            "<tr><td class=\"num\">{}</td><td>{}</td><td>{}</td><td class=\"num\">{}</td></tr>",
            a.raised,
            escape(&a.node),
            escape(&a.name),
            escape(&cleared)
        );
    }
    out.push_str("</tbody>\n</table>\n");
}

/// Draws one plot of a run's series as an SVG document.
type Plot = fn(&Series) -> Result<String, String>;

fn plots(out: &mut String, n: usize, o: &Outcome) {
    let s = &o.series;
    out.push_str("<h3>Over time</h3>\n");
    let figures: [(&str, &str, Plot); 5] = [
        ("load", plots::LOAD, plots::load),
        ("latency", plots::LATENCY, plots::latency),
        ("counters", plots::COUNTERS, plots::counters),
        ("yield", plots::YIELD, plots::yield_kg),
        ("speed", plots::SPEED, plots::speed),
    ];
    for (id, title, draw) in figures {
        let _ = writeln!(out, "<figure id=\"plot-{id}-{n}\" class=\"plot-{id}\">");
        match draw(s) {
            Ok(svg) => out.push_str(&svg),
            Err(e) => {
                let _ = write!(
                    out,
                    "<p class=\"fail\">{}: cannot draw: {}</p>",
                    escape(title),
                    escape(&e)
                );
            }
        }
        out.push_str("\n</figure>\n");
        if id == "latency" {
            latency_table(out, s);
        }
    }
}

fn latency_table(out: &mut String, s: &Series) {
    out.push_str("<table class=\"latency\">\n<thead><tr><th>class</th><th>frames</th><th>mean [µs]</th><th>p99 [µs]</th><th>max [µs]</th></tr></thead>\n<tbody>\n");
    for c in &s.latency {
        let _ = writeln!(
            out,
            "<tr><td>{}</td><td class=\"num\">{}</td><td class=\"num\">{:.0}</td><td class=\"num\">{:.0}</td><td class=\"num\">{:.0}</td></tr>",
            escape(&c.class),
            c.frames,
            c.mean_us,
            c.p99_us,
            c.max_us
        );
    }
    out.push_str("</tbody>\n</table>\n");
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harvester::{Happened, SupervisorEvent};
    use crate::scenario::Verdict;
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

    #[test]
    fn the_command_survives_a_shell() {
        let c = reproduce("my runs/it's <1>.ron", 7);
        assert_eq!(
            shlex::split(&c).unwrap(),
            ["harvemu", "scenario", "my runs/it's <1>.ron", "--seed", "7"]
        );
    }

    #[test]
    fn a_run_stopped_at_once_still_gets_a_page_with_every_plot() {
        // Interrupted before the first sample: empty series, one failed verdict, one event.
        let outcome = Outcome {
            verdicts: vec![Verdict {
                expectation: "the run completes".into(),
                passed: false,
                at: Some(BusTime::from_nanos(500_000_000)),
                observed: "interrupted (Ctrl-C)".into(),
            }],
            seed: 3,
            events: vec![SupervisorEvent {
                at: BusTime::from_nanos(400_000_000),
                node: "D3".into(),
                what: Happened::Crashed(bus::node::CrashCause::Panic("<boom> & gone".into())),
            }],
            wall_seconds: 0.1,
            interrupted: true,
            down: Vec::new(),
            series: Series::default(),
            books: Default::default(),
            applied: Default::default(),
            snapshot: None,
            hardware: Vec::new(),
            coverage: None,
            disturbed: Vec::new(),
            alarms: Vec::new(),
        };
        let s = scenario("short");
        let page = html(&[("a.ron".into(), &s, &outcome)]);
        assert_eq!(page.matches("<svg").count(), 5);
        assert!(!page.contains("cannot draw"));
        assert!(page.contains("(interrupted)"));
        assert!(page.contains("FAIL: 1 of 1 expectations failed"));
        assert!(page.contains("<td>crashed: &lt;boom&gt; &amp; gone</td>"));
        assert!(page.contains("no error counter rose above zero"));
    }
}
