//! Fitting text into cells so that the screen never shows a wrong number.
//!
//! ratatui cuts whatever is wider than its cell: a right-aligned "13.7" in three columns becomes
//! "3.7", and a line cut at the panel's edge can end in "frames 12" for 12345. Everything with a
//! number in it goes through here instead: labels may be cut, numbers are shown whole or, when
//! even the number does not fit, as `#`s, which nobody reads as a value.

/// `text` (a number) right-aligned in exactly `width` columns, or `width` `#`s when it is wider.
pub fn number(text: &str, width: usize) -> String {
    let len = text.chars().count();
    if len <= width {
        format!("{text:>width$}")
    } else {
        "#".repeat(width)
    }
}

/// `text` (a label) left-aligned in exactly `width` columns, cut at the end when wider.
pub fn label(text: &str, width: usize) -> String {
    let cut: String = text.chars().take(width).collect();
    format!("{cut:<width$}")
}

/// As many of `parts` as fit in `width` columns, whole and in order, joined by `separator`; the
/// rest is left out (a part is a label with its number, which is never split).
pub fn parts(parts: &[String], separator: &str, width: usize) -> String {
    let mut out = String::new();
    let mut used = 0;
    for p in parts {
        let cost = p.chars().count()
            + if out.is_empty() {
                0
            } else {
                separator.chars().count()
            };
        if used + cost > width {
            break;
        }
        if !out.is_empty() {
            out.push_str(separator);
        }
        out.push_str(p);
        used += cost;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_whole_or_hashes() {
        assert_eq!(number("13.7", 6), "  13.7");
        assert_eq!(number("13.7", 4), "13.7");
        assert_eq!(number("13.7", 3), "###");
        assert_eq!(number("2.62", 0), "");
    }

    #[test]
    fn parts_are_whole_or_left_out() {
        let p = ["load 12.3 %".to_string(), "frames 12345".to_string()];
        assert_eq!(parts(&p, "  ", 40), "load 12.3 %  frames 12345");
        assert_eq!(parts(&p, "  ", 24), "load 12.3 %");
        assert_eq!(parts(&p, "  ", 10), "");
        assert_eq!(label("°C", 1), "°");
    }
}
