//! Quoting input in error messages, and counts with their nouns.
//!
//! Contract: [`quote`] gives text from a file or a command line back in single quotes, short
//! enough for a one-line error whatever the input: at most [`QUOTE_CHARS`] characters of it,
//! then `…` when there was more. Control characters are escaped (`\0`, `\u{1b}`) so that a
//! quoted line cannot move the cursor or clear the terminal, and count as the characters of
//! their escape. The whole quote is never longer than `QUOTE_CHARS` + 3 characters. [`cut`] does
//! the same without the quotes and with a length of the caller's choice (lists of names from a
//! file, messages of other libraries that quote input).

/// How many characters of the quoted text an error message shows.
pub const QUOTE_CHARS: usize = 40;

/// How many characters of a list of names from a file an error message shows.
pub const LIST_CHARS: usize = 120;

/// `text` in single quotes, cut to [`QUOTE_CHARS`] characters (with `…` when cut).
pub fn quote(text: &str) -> String {
    format!("'{}'", cut(text, QUOTE_CHARS))
}

/// `text` cut to `chars` characters (then `…`), control characters escaped.
pub fn cut(text: &str, chars: usize) -> String {
    let mut out = String::new();
    let mut shown = 0;
    for c in text.chars() {
        let piece: String = if c.is_control() {
            c.escape_debug().collect()
        } else {
            c.to_string()
        };
        let width = piece.chars().count();
        if shown + width > chars {
            out.push('…');
            break;
        }
        out.push_str(&piece);
        shown += width;
    }
    out
}

/// `n` and the noun that goes with it: `1 problem`, `2 problems`, `0 problems`.
pub fn count(n: u64, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_text_is_quoted_whole() {
        assert_eq!(quote("123#0G"), "'123#0G'");
        assert_eq!(quote(""), "''");
        assert_eq!(quote("é ü"), "'é ü'");
    }

    #[test]
    fn long_text_is_cut_with_an_ellipsis() {
        let long = "x".repeat(1000);
        let q = quote(&long);
        assert_eq!(q, format!("'{}…'", "x".repeat(40)));
        // Exactly the limit is not cut.
        assert_eq!(quote(&"y".repeat(40)), format!("'{}'", "y".repeat(40)));
    }

    #[test]
    fn control_characters_are_escaped_and_counted() {
        assert_eq!(quote("a\0b"), "'a\\0b'");
        assert_eq!(quote("\u{1b}[2J"), "'\\u{1b}[2J'");
        let zeros = quote(&"\0".repeat(1000));
        assert_eq!(zeros, format!("'{}…'", "\\0".repeat(20)));
        for text in ["\u{1}".repeat(500), "\t".repeat(500), "€".repeat(500)] {
            assert!(
                quote(&text).chars().count() <= QUOTE_CHARS + 3,
                "{}",
                quote(&text)
            );
        }
    }
}
