//! Where a field is in RON text: the line and column of the field a problem names by its path
//! (`timeline[3].action.bit`), so that a check made after parsing can point into the file as a
//! syntax error does.
//!
//! Contract: [`position`] follows the path through struct and enum-variant fields (by name) and
//! list elements (by index), skipping strings, characters, comments and nested values as RON
//! writes them; it gives the 1-based line and character column of the last field's name (or of
//! the element, for an index), and `None` when the text does not hold the path (or is not RON it
//! can follow). It never panics, on any text.

/// One step of a path.
enum Step<'a> {
    Key(&'a str),
    Index(usize),
}

/// The steps of `path`: names separated by dots, each optionally followed by `[n]` indices.
fn steps(path: &str) -> Option<Vec<Step<'_>>> {
    let mut out = Vec::new();
    for part in path.split('.') {
        let (name, mut rest) = part.split_at(part.find('[').unwrap_or(part.len()));
        if !name.is_empty() {
            out.push(Step::Key(name));
        }
        while let Some(r) = rest.strip_prefix('[') {
            let close = r.find(']')?;
            out.push(Step::Index(r[..close].parse().ok()?));
            rest = &r[close + 1..];
        }
        if !rest.is_empty() {
            return None;
        }
    }
    Some(out)
}

/// The 1-based line and character column of the field at `path` in `text`.
pub fn position(text: &str, path: &str) -> Option<(usize, usize)> {
    let b = text.as_bytes();
    let steps = steps(path)?;
    // The top-level value: `Name(` or `(`.
    let mut at = open(b, ws(b, 0))?;
    let mut found = None;
    for (i, step) in steps.iter().enumerate() {
        let last = i + 1 == steps.len();
        let (name_at, value_at) = match step {
            Step::Key(k) => key(b, at, k)?,
            Step::Index(n) => {
                let v = index(b, at, *n)?;
                (v, v)
            }
        };
        found = Some(name_at);
        if !last {
            at = open(b, value_at)?;
        }
    }
    found.map(|o| line_col(text, o))
}

/// After whitespace and comments from `i`.
fn ws(b: &[u8], mut i: usize) -> usize {
    loop {
        while i < b.len() && b[i].is_ascii_whitespace() {
            i += 1;
        }
        if b[i..].starts_with(b"//") {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if b[i..].starts_with(b"/*") {
            i += 2;
            while i < b.len() && !b[i..].starts_with(b"*/") {
                i += 1;
            }
            i = (i + 2).min(b.len());
        } else {
            return i;
        }
    }
}

/// An identifier's end (RON identifiers: letters, digits, `_`; raw `r#` ones too).
fn ident(b: &[u8], mut i: usize) -> usize {
    if b[i..].starts_with(b"r#") {
        i += 2;
    }
    while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
        i += 1;
    }
    i
}

/// Inside the value at `i` (after its opening bracket): `Name(`, `(`, `[` or `{`, an optional
/// `Some(` around it stepped through as any variant.
fn open(b: &[u8], i: usize) -> Option<usize> {
    let i = ws(b, i);
    let j = ws(b, ident(b, i));
    match b.get(j) {
        Some(b'(' | b'[' | b'{') => Some(j + 1),
        _ => None,
    }
}

/// The end of a quoted string or character starting at `i`.
fn quoted(b: &[u8], i: usize) -> usize {
    let q = b[i];
    let mut j = i + 1;
    while j < b.len() && b[j] != q {
        j += if b[j] == b'\\' { 2 } else { 1 };
    }
    (j + 1).min(b.len())
}

/// The end of the value starting at `i` (after whitespace): nested brackets, strings and
/// comments skipped, up to the `,` or closing bracket that ends it.
fn value_end(b: &[u8], i: usize) -> usize {
    let mut depth = 0usize;
    let mut j = ws(b, i);
    while j < b.len() {
        match b[j] {
            b'"' | b'\'' => {
                j = quoted(b, j);
                continue;
            }
            b'/' if matches!(b.get(j + 1), Some(b'/' | b'*')) => {
                j = ws(b, j);
                continue;
            }
            b'(' | b'[' | b'{' => depth += 1,
            b')' | b']' | b'}' => {
                if depth == 0 {
                    return j;
                }
                depth -= 1;
            }
            b',' if depth == 0 => return j,
            _ => {}
        }
        j += 1;
    }
    j
}

/// Past the value at `i` and the comma after it, if any; `None` at the closing bracket.
fn next(b: &[u8], i: usize) -> Option<usize> {
    let end = ws(b, value_end(b, i));
    match b.get(end) {
        Some(b',') => Some(end + 1),
        _ => None,
    }
}

/// The field `k` of the struct whose fields start at `i`: where its name and its value start.
fn key(b: &[u8], mut i: usize, k: &str) -> Option<(usize, usize)> {
    loop {
        i = ws(b, i);
        if matches!(b.get(i), Some(b')' | b'}') | None) {
            return None;
        }
        let end = ident(b, i);
        let colon = ws(b, end);
        if end > i && b.get(colon) == Some(&b':') {
            let name = std::str::from_utf8(&b[i..end]).ok()?;
            let value = ws(b, colon + 1);
            if name.trim_start_matches("r#") == k {
                return Some((i, value));
            }
            i = next(b, value)?;
        } else {
            i = next(b, i)?;
        }
    }
}

/// Where element `n` of the list whose elements start at `i` starts.
fn index(b: &[u8], mut i: usize, n: usize) -> Option<usize> {
    for _ in 0..n {
        i = next(b, i)?;
    }
    let i = ws(b, i);
    (!matches!(b.get(i), Some(b']' | b')') | None)).then_some(i)
}

/// The 1-based line and character column of byte `offset`.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let start = before.rfind('\n').map_or(0, |p| p + 1);
    (line, before[start..].chars().count() + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = r#"// A comment with "quotes" and ( brackets
Scenario(
    name: "a, b (c)",
    timeline: [
        (at_s: 1.0, action: SendFrame(node: "TX", frame: "012#80")),
        /* two */ (at_s: 2.0, action: Disturb(target: Node("TX"), hits: Once,
            field: Data, bit: 99, level: Dominant, seen_by: Nodes(["R1", "X"]))),
    ],
    expect: [Counters(node: "R1", at_s: 0.5, tec: 0, rec: 1)],
)"#;

    #[test]
    fn finds_fields_by_path() {
        assert_eq!(position(TEXT, "name"), Some((3, 5)));
        assert_eq!(position(TEXT, "timeline[1].action.bit"), Some((7, 26)));
        assert_eq!(position(TEXT, "timeline[1].at_s"), Some((6, 20)));
        assert_eq!(position(TEXT, "timeline[1].action.seen_by"), Some((7, 52)));
        assert_eq!(position(TEXT, "timeline[0].action.frame"), Some((5, 51)));
        assert_eq!(position(TEXT, "expect[0].rec"), Some((9, 54)));
        assert_eq!(position(TEXT, "expect[0]"), Some((9, 14)));
    }

    #[test]
    fn paths_that_are_not_there_give_none() {
        for path in [
            "timeline[2].at_s",
            "nothing",
            "expect[0].node.x",
            "timeline[x]",
            "a]b",
            "",
        ] {
            assert_eq!(position(TEXT, path), None, "{path}");
        }
        for text in [
            "",
            "(",
            "Scenario(name: \"",
            "[[[",
            "/*",
            "x: ,,,",
            "(a: (b: [1, 2",
        ] {
            let _ = position(text, "a.b[1]");
            let _ = position(text, "name");
        }
    }
}
