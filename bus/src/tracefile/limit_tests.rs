//! The trace reader on input too large to hold: over-long lines, endless input, and errors that
//! quote long text.

use super::*;
use proptest::prelude::*;
use std::io::{BufReader, Read};

/// The longest an error about one line may be when displayed.
const SHORT: usize = 200;

fn first_error(input: impl BufRead) -> Error {
    match read(input, ErrorFrames::Keep).find_map(Result::err) {
        Some(e) => e,
        None => panic!("no error"),
    }
}

#[test]
fn a_line_of_the_limit_is_read_one_byte_more_is_refused() {
    // An ASC comment is a line the reader skips, so only its length can make it bad.
    let comment = |len: usize| format!("// {}", "c".repeat(len - 3));
    let frame = "1.000000 1  123  Rx   d 1 00\n";
    let fits = format!("base hex  timestamps absolute\n{}\r\n{frame}", comment(MAX_LINE));
    let records = read_str(&fits, ErrorFrames::Keep).unwrap();
    assert_eq!(records.len(), 1);
    assert_eq!(records[0].line, 3);
    let over = format!(
        "base hex  timestamps absolute\n{}\n{frame}",
        comment(MAX_LINE + 1)
    );
    let e = read_str(&over, ErrorFrames::Keep).unwrap_err();
    let text = e.to_string();
    assert!(matches!(e, Error::TraceLine { line: 2, .. }), "{text}");
    assert!(text.contains("longer than 65536 bytes"), "{text}");
    assert!(text.contains("'// cccc"), "{text}");
    assert!(text.len() < SHORT, "{} characters: {text}", text.len());
}

#[test]
fn a_100_mb_line_is_refused_without_holding_it() {
    let first = &b"(1.000000) can0 123#00\n"[..];
    let huge = std::io::repeat(b'7').take(100_000_000);
    let e = first_error(BufReader::new(first.chain(huge)));
    let text = e.to_string();
    assert!(text.starts_with("line 2: longer than 65536 bytes"), "{text}");
    assert!(text.len() < SHORT, "{} characters", text.len());
}

#[test]
fn endless_input_without_line_breaks_ends_at_once() {
    // What `/dev/zero` gives: the reader must stop after the limit, not read for ever.
    let e = first_error(BufReader::new(std::io::repeat(0)));
    let text = e.to_string();
    assert!(text.starts_with("line 1: longer than 65536 bytes"), "{text}");
    assert!(text.contains(r"'\0\0\0"), "{text}");
    assert!(text.len() < SHORT, "{} characters: {text}", text.len());
}

#[test]
fn text_that_is_not_utf8_is_named_by_line() {
    let e = first_error(&b"(1.000000) can0 123#00\n(2.0) can0 \xff#00\n"[..]);
    let text = e.to_string();
    assert!(text.starts_with("line 2: not UTF-8"), "{text}");
}

/// Bad lines of every kind the reader names, with `{}` where a token of any length goes.
const BAD: &[&str] = &[
    "({}) can0 123#00",
    "(1.0) can0 {}",
    "(1.0) can0 123#{}",
    "(1.0) can0 123#R{}",
    "(1.0) can0 {}##00",
    "(1.0) can0 {}#00",
    "(1.0) can0 2000{}#00",
    "(1.0) can0 20000288#{}",
    "(1.0) can0 123#00 {}",
    "(1.0{}",
    "1.0 1 123 Rx d 1 00\n{}",
    "base {}",
    "base hex timestamps {}",
    "base hex {}",
    "{} 1 123 Rx d 1 00",
    "1.0 1 {} Rx d 1 00",
    "1.0 1 {}x Rx d 1 00",
    "1.0 1 123 Rx {} 1 00",
    "1.0 1 123 Rx d {} 00",
    "1.0 1 123 Rx d 1 {}",
    "1.0 1 123 Rx d 2 00 {}",
    "base hex timestamps relative\n18446744073.0 1 1 x\n18446744073.0 1 {}",
];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Whatever token, however long, goes into a bad line, the error stays one short line.
    #[test]
    fn every_error_quotes_at_most_a_few_dozen_characters(
        which in 0..BAD.len(),
        piece in "[0-9A-Fa-fxXrR#.() \\t\u{1b}\u{0}é-]{1,8}",
        times in prop_oneof![1usize..4, 1000usize..9000],
    ) {
        let line = BAD[which].replace("{}", &piece.repeat(times));
        if let Err(e) = read_str(&line, ErrorFrames::Keep) {
            let text = e.to_string();
            prop_assert!(text.chars().count() < SHORT, "{} characters: {}", text.chars().count(), text);
            prop_assert!(!text.contains('\n'), "{}", text);
        }
    }
}
