//! `harvemu SUBCOMMAND --help` as a newcomer reads it: the same placeholder for the same kind of
//! value everywhere, and an example under each subcommand; `protocol` starts with its first
//! message.

mod common;

use common::harvemu;

const SUBCOMMANDS: [&str; 12] = [
    "run", "replay", "scenario", "soak", "validate", "convert", "inspect", "bench", "dbc", "import",
    "config", "protocol",
];

/// Every placeholder a help may use: files are `<FILE>` (`convert`'s two, `<IN>` and `<OUT>`),
/// durations `<DURATION>`, counts `<N>`, trace formats `<FORMAT>`, other choices `<KIND>`.
const PLACEHOLDERS: [&str; 20] = [
    "<KIND>",
    "<IN>",
    "<OUT>",
    "<FORMAT>",
    "<FILE>",
    "<FROM..TO>",
    "<DIR>",
    "<COMMAND>",
    "<TIME>",
    "<DURATION>",
    "<N>",
    "<N,...>",
    "<NODE>",
    "<IFACE>",
    "<ADDR>",
    "<SECONDS>",
    "<HOURS>",
    "<BPS>",
    "<TRACE>",
    "<ID#DATA>",
];

fn help(subcommand: &str) -> String {
    let out = harvemu(&[subcommand, "--help"]);
    assert!(out.status.success(), "{subcommand} --help");
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn every_subcommand_has_an_example_that_uses_it() {
    for sub in SUBCOMMANDS {
        let text = help(sub);
        let (_, examples) = text
            .split_once("\nExamples:\n")
            .unwrap_or_else(|| panic!("no examples under {sub} --help:\n{text}"));
        assert!(
            examples.contains(&format!("harvemu {sub} ")) || examples.contains(&format!("harvemu {sub}\n")),
            "{sub}: {examples}"
        );
    }
}

#[test]
fn placeholders_are_the_same_for_the_same_kind_of_value() {
    for sub in SUBCOMMANDS {
        let text = help(sub);
        let mut rest = text.as_str();
        while let Some(start) = rest.find('<') {
            let end = rest[start..].find('>').map_or(rest.len(), |e| start + e + 1);
            let placeholder = &rest[start..end];
            let known = PLACEHOLDERS.contains(&placeholder) || placeholder.starts_with("<SCENARIO");
            assert!(known, "{sub} --help: {placeholder}\n{text}");
            rest = &rest[end..];
        }
        for option in ["--record", "--junit", "--report", "--config", "--output"] {
            if let Some(at) = text.find(&format!("{option} <")) {
                assert!(
                    text[at..].starts_with(&format!("{option} <FILE>")),
                    "{sub}: {option}\n{text}"
                );
            }
        }
        // An option of this subcommand, not another's in an example.
        let options = text.split("\nExamples:").next().unwrap_or("");
        if options.contains("--for ") {
            assert!(options.contains("--for <DURATION>"), "{sub}\n{text}");
        }
    }
}

#[test]
fn protocol_starts_with_its_first_message() {
    let out = harvemu(&["protocol"]);
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.starts_with("01 speed.mode "), "{text}");
    assert!(text.lines().all(|l| !l.trim().is_empty()), "no blank line");
}
