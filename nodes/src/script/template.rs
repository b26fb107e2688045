//! Script templates: one node script with named placeholders, and short instance files that give
//! the placeholders their values (the six flow sensors are one template and six instances).
//!
//! A template file is `Template(params: {"name": "what it is", …}, script: NodeScript(…))`. In
//! its text, `${name}` inside a string literal is a placeholder:
//! - a literal that is one placeholder and nothing else (`address: "${address}"`) is replaced,
//!   quotes and all, by the parameter's value exactly as the instance writes it: a number, a
//!   string, a map of field bindings, any RON value;
//! - a placeholder inside a longer literal (`Signal("${row}.unit1")`) is replaced by the text of
//!   the value: a string's characters without its quotes, or a number as written.
//!
//! An instance file is `Instance(template: "templates/x.ron", params: {"name": value, …})`; the
//! template's path is relative to the instance's directory.
//!
//! Contract:
//! - The template is read by the caller's [`Reader`] ([`disk`]: [`crate::file::read_text`], at
//!   most [`crate::file::MAX_FILE`] bytes), the only file read here; the expanded text is refused
//!   past the same limit.
//! - One level only: the file an instance names must be a `Template`; an instance (the instance
//!   itself included) or a plain script is refused. Values are inserted as they are and never
//!   scanned again, so expansion is one pass and always ends.
//! - Every parameter problem is reported at once, naming the file and the parameter: a value
//!   for a parameter the template does not declare (unknown), a declared parameter with no value
//!   (missing), a declared parameter the template never uses (unused), a placeholder that names
//!   no declared parameter, a `${` that does not form a placeholder.
//! - Comments, raw strings (`r"…"`) and byte strings (`b"…"`) are never scanned: `${` in a
//!   comment stays text. In any other string literal of a template, `${` always starts a
//!   placeholder (no script needs the two characters otherwise).
//! - A syntax error in the expansion is reported where its text came from: at its line and
//!   column in the template, or at the parameter of the instance whose value is wrong.

use super::model::NodeScript;
use crate::file::{MAX_FILE, read_text};
use crate::{Error, Problem, parse_ron};
use bus::text::{LIST_CHARS, cut, quote};
use ron::value::RawValue;
use serde::Deserialize;
use serde::de::IgnoredAny;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// An instance file: which template, and the values of its parameters.
#[derive(Deserialize)]
#[serde(rename = "Instance", deny_unknown_fields)]
struct Instance {
    template: String,
    params: BTreeMap<String, Box<RawValue>>,
}

/// A template read for its declarations only; the script is skipped.
#[derive(Deserialize)]
#[serde(rename = "Template", deny_unknown_fields)]
struct Declared {
    params: BTreeMap<String, String>,
    #[allow(dead_code)]
    script: IgnoredAny,
}

/// A template after expansion.
#[derive(Deserialize)]
#[serde(rename = "Template", deny_unknown_fields)]
struct Expanded {
    #[allow(dead_code)]
    params: IgnoredAny,
    script: NodeScript,
}

/// The name of the struct at the top of a RON text (`NodeScript`, `Instance`, `Template`,
/// `Harvester`…), after any whitespace and comments; `None` when the text starts otherwise.
pub fn top_name(text: &str) -> Option<&str> {
    let b = text.as_bytes();
    let mut i = 0;
    loop {
        while i < b.len() && b[i].is_ascii_whitespace() {
            i += 1;
        }
        match (b.get(i), b.get(i + 1)) {
            (Some(b'/'), Some(b'/')) => i = line_end(b, i),
            (Some(b'/'), Some(b'*')) => i = comment_end(b, i),
            _ => break,
        }
    }
    let end = i + b[i..].iter().take_while(|c| is_ident(**c)).count();
    (end > i).then(|| &text[i..end])
}

/// Reads the file at a path: the name problems give it, and its text. [`disk`] reads the disk; a
/// caller with files of its own (configs built into a binary) passes another.
pub type Reader<'a> = &'a dyn Fn(&Path) -> Result<(String, String), Error>;

/// The [`Reader`] of files on disk: [`read_text`], so at most [`MAX_FILE`] bytes, named by their
/// path.
pub fn disk(path: &Path) -> Result<(String, String), Error> {
    Ok((path.display().to_string(), read_text(path)?))
}

/// The script an instance file describes, `text` being the instance's content read from `path`
/// and named `file` in problems; `read` reads its template. The script is parsed, not validated
/// (see [`super::validate`]).
pub fn expand(file: &str, path: &Path, text: &str, read: Reader) -> Result<NodeScript, Error> {
    let instance: Instance = parse_ron(file, text)?;
    let tpl_path = path.parent().unwrap_or(Path::new("")).join(&instance.template);
    let at_instance = |field: &str, message: String| Error::Invalid(vec![Problem::at(file, field, message)]);
    let (tpl_file, tpl_text) = read(&tpl_path).map_err(|e| at_instance("template", e.to_string()))?;
    match top_name(&tpl_text) {
        Some("Template") => {}
        Some("Instance") => {
            return Err(at_instance(
                "template",
                format!("{tpl_file} is an instance, not a Template: templates do not nest"),
            ));
        }
        other => {
            return Err(at_instance(
                "template",
                format!(
                    "{tpl_file} is {}, not a Template",
                    other.map_or("not RON".to_string(), |n| format!("a {}", quote(n)))
                ),
            ));
        }
    }
    let (declared, found) = declarations(&tpl_file, &tpl_text)?;
    let mut problems = Vec::new();
    let names: Vec<&str> = declared.keys().map(String::as_str).collect();
    let known = cut(&names.join(", "), LIST_CHARS);
    for name in instance.params.keys() {
        if !declared.contains_key(name) {
            problems.push(Problem::at(
                file,
                format!("params.{}", cut(name, 40)),
                format!("unknown parameter: {tpl_file} takes {known}"),
            ));
        }
    }
    for (name, what) in &declared {
        if !instance.params.contains_key(name) {
            problems.push(Problem::at(
                file,
                "params",
                format!("missing parameter {} ({})", quote(name), cut(what, LIST_CHARS)),
            ));
        }
    }
    for p in found.iter().filter(|p| !p.whole) {
        if let Some(v) = instance.params.get(&p.name)
            && inline(v.get_ron().trim()).is_none()
        {
            problems.push(Problem::at(
                file,
                format!("params.{}", p.name),
                format!(
                    "{} is used inside a string of {tpl_file}, so its value must be a string or a number",
                    quote(&p.name)
                ),
            ));
        }
    }
    dedup(&mut problems);
    if !problems.is_empty() {
        return Err(Error::Invalid(problems));
    }
    let (expanded, pieces) = substitute(&tpl_text, &found, &instance.params).ok_or_else(|| {
        at_instance(
            "template",
            format!("{tpl_file} expands to more than {MAX_FILE} bytes"),
        )
    })?;
    match parse_ron::<Expanded>(&tpl_file, &expanded) {
        Ok(e) => Ok(e.script),
        Err(Error::Invalid(problems)) => Err(Error::Invalid(
            problems
                .into_iter()
                .map(|p| locate(p, &expanded, &pieces, &tpl_text, file))
                .collect(),
        )),
        Err(e) => Err(e),
    }
}

/// Checks a template file on its own, `text` being its content and `file` its name in problems:
/// its declarations against its placeholders.
pub fn check(file: &str, text: &str) -> Result<(), Error> {
    declarations(file, text).map(|_| ())
}

/// A template's declared parameters and its placeholders, or every problem between them.
fn declarations(file: &str, text: &str) -> Result<(BTreeMap<String, String>, Vec<Placeholder>), Error> {
    let declared: Declared = parse_ron(file, text)?;
    let mut problems = Vec::new();
    let found = placeholders(file, text, &mut problems);
    let names: Vec<&str> = declared.params.keys().map(String::as_str).collect();
    let mut reported = BTreeSet::new();
    for p in &found {
        if !declared.params.contains_key(&p.name) && reported.insert(&p.name) {
            problems.push(Problem {
                file: file.to_string(),
                // At the `${`, inside the quote of a whole-value placeholder.
                position: Some(position_of(text, p.start + usize::from(p.whole))),
                node: None,
                field: None,
                message: format!(
                    "placeholder {} is not a declared parameter (params: {})",
                    quote(&p.name),
                    cut(&names.join(", "), LIST_CHARS)
                ),
            });
        }
    }
    let used: BTreeSet<&str> = found.iter().map(|p| p.name.as_str()).collect();
    for name in declared.params.keys() {
        if !used.contains(name.as_str()) {
            problems.push(Problem::at(
                file,
                format!("params.{}", cut(name, 40)),
                "unused parameter: the script never uses it",
            ));
        }
    }
    if problems.is_empty() {
        Ok((declared.params, found))
    } else {
        Err(Error::Invalid(problems))
    }
}

fn dedup(problems: &mut Vec<Problem>) {
    let mut seen = Vec::new();
    problems.retain(|p| {
        let new = !seen.contains(p);
        if new {
            seen.push(p.clone());
        }
        new
    });
}

/// One `${name}` in a template: the bytes it replaces (the whole literal with its quotes when
/// `whole`).
struct Placeholder {
    name: String,
    start: usize,
    end: usize,
    whole: bool,
}

fn is_ident(c: u8) -> bool {
    c.is_ascii_alphanumeric() || c == b'_'
}

/// Every placeholder of a template, in order; a `${` that does not form one is a problem.
fn placeholders(file: &str, text: &str, problems: &mut Vec<Problem>) -> Vec<Placeholder> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'/' if b.get(i + 1) == Some(&b'/') => i = line_end(b, i),
            b'/' if b.get(i + 1) == Some(&b'*') => i = comment_end(b, i),
            b'"' => {
                let end = quoted_end(b, i);
                in_string(file, text, i, end, &mut out, problems);
                i = end;
            }
            b'\'' => i = quoted_end(b, i),
            c if is_ident(c) => {
                let start = i;
                while i < b.len() && is_ident(b[i]) {
                    i += 1;
                }
                let word = &b[start..i];
                if (word == b"r" || word == b"br") && matches!(b.get(i), Some(b'"' | b'#')) {
                    i = raw_end(b, i);
                } else if word == b"b" && b.get(i) == Some(&b'"') {
                    i = quoted_end(b, i);
                }
            }
            _ => i += 1,
        }
    }
    out
}

/// The placeholders in the string literal `text[start..end]` (quotes included).
fn in_string(
    file: &str,
    text: &str,
    start: usize,
    end: usize,
    out: &mut Vec<Placeholder>,
    problems: &mut Vec<Problem>,
) {
    let close = if end > start + 1 && text.as_bytes()[end - 1] == b'"' {
        end - 1
    } else {
        end
    };
    let content = &text[start + 1..close];
    let mut k = 0;
    while let Some(p) = content[k..].find("${") {
        let at = k + p;
        let rest = &content[at + 2..];
        let len = rest.bytes().take_while(|c| is_ident(*c)).count();
        let from = start + 1 + at;
        if len == 0 || rest.as_bytes().get(len) != Some(&b'}') {
            problems.push(Problem {
                file: file.to_string(),
                position: Some(position_of(text, from)),
                node: None,
                field: None,
                message: "`${` starts no placeholder: write ${name}, the name in letters, digits and _"
                    .to_string(),
            });
            k = at + 2;
            continue;
        }
        let to = from + len + 3;
        let whole = at == 0 && to == close && close < end;
        out.push(Placeholder {
            name: rest[..len].to_string(),
            start: if whole { start } else { from },
            end: if whole { end } else { to },
            whole,
        });
        k = at + len + 3;
    }
}

/// Past the newline that ends a `//` comment.
fn line_end(b: &[u8], i: usize) -> usize {
    b[i..]
        .iter()
        .position(|&c| c == b'\n')
        .map_or(b.len(), |p| i + p + 1)
}

/// Past the `*/` that ends the (nested) block comment opening at `i`.
fn comment_end(b: &[u8], mut i: usize) -> usize {
    let mut depth = 0;
    while i < b.len() {
        if b[i..].starts_with(b"/*") {
            depth += 1;
            i += 2;
        } else if b[i..].starts_with(b"*/") {
            depth -= 1;
            i += 2;
            if depth == 0 {
                return i;
            }
        } else {
            i += 1;
        }
    }
    b.len()
}

/// Past the closing quote of the string or character opening at `i`, escapes skipped.
fn quoted_end(b: &[u8], i: usize) -> usize {
    let quote = b[i];
    let mut j = i + 1;
    while j < b.len() {
        match b[j] {
            b'\\' => j += 2,
            c if c == quote => return j + 1,
            _ => j += 1,
        }
    }
    b.len()
}

/// Past the end of the raw string whose `#`s or quote start at `i`.
fn raw_end(b: &[u8], i: usize) -> usize {
    let hashes = b[i..].iter().take_while(|&&c| c == b'#').count();
    let open = i + hashes;
    if b.get(open) != Some(&b'"') {
        return open;
    }
    let mut closing = vec![b'"'];
    closing.extend(std::iter::repeat_n(b'#', hashes));
    b[open + 1..]
        .windows(closing.len())
        .position(|w| w == closing.as_slice())
        .map_or(b.len(), |p| open + 1 + p + closing.len())
}

/// What a value reads as inside a string: a string's text without quotes (already escaped as RON
/// wants it), or a number as written.
fn inline(raw: &str) -> Option<&str> {
    if raw.len() >= 2 && raw.starts_with('"') && raw.ends_with('"') {
        return Some(&raw[1..raw.len() - 1]);
    }
    let number = raw.starts_with(|c: char| c.is_ascii_digit() || c == '-' || c == '+')
        && raw
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '+' | '-'));
    number.then_some(raw)
}

/// Where a stretch of the expanded text came from.
enum Origin {
    /// The template, from this byte on.
    Template(usize),
    /// The value of this parameter.
    Param(String),
}

/// The template with every placeholder replaced, and where each stretch of it came from (by
/// its first byte in the expansion); `None` past [`MAX_FILE`] bytes.
fn substitute(
    text: &str,
    found: &[Placeholder],
    params: &BTreeMap<String, Box<RawValue>>,
) -> Option<(String, Vec<(usize, Origin)>)> {
    let mut out = String::new();
    let mut pieces = Vec::new();
    let mut from = 0;
    for p in found {
        pieces.push((out.len(), Origin::Template(from)));
        out.push_str(&text[from..p.start]);
        let raw = params.get(&p.name)?.get_ron().trim();
        pieces.push((out.len(), Origin::Param(p.name.clone())));
        out.push_str(if p.whole { raw } else { inline(raw)? });
        from = p.end;
        if out.len() as u64 > MAX_FILE {
            return None;
        }
    }
    pieces.push((out.len(), Origin::Template(from)));
    out.push_str(&text[from..]);
    (out.len() as u64 <= MAX_FILE).then_some((out, pieces))
}

/// A syntax problem in the expansion, moved to where its text came from.
fn locate(
    mut p: Problem,
    expanded: &str,
    pieces: &[(usize, Origin)],
    template: &str,
    instance: &str,
) -> Problem {
    let Some((line, col)) = p.position else {
        return p;
    };
    // RON may place an error on the blank before the offending value: the value tells where
    // the text came from.
    let at = offset_of(expanded, line, col);
    let offset = at + expanded[at..].len() - expanded[at..].trim_start().len();
    let Some((start, origin)) = pieces.iter().rev().find(|(s, _)| *s <= offset) else {
        return p;
    };
    match origin {
        Origin::Template(from) => {
            p.position = Some(position_of(template, from + (offset - start)));
            p.message = format!("{} (expanding {instance})", p.message);
        }
        Origin::Param(name) => {
            p.file = instance.to_string();
            p.position = None;
            p.field = Some(format!("params.{name}"));
        }
    }
    p
}

/// The byte offset of a 1-based line and character column.
fn offset_of(text: &str, line: usize, col: usize) -> usize {
    let mut start = 0;
    for _ in 1..line {
        match text[start..].find('\n') {
            Some(p) => start += p + 1,
            None => return text.len(),
        }
    }
    text[start..]
        .char_indices()
        .nth(col.saturating_sub(1))
        .map_or(text.len(), |(i, _)| start + i)
}

/// The 1-based line and character column of a byte offset.
pub(crate) fn position_of(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |p| p + 1);
    (line, before[line_start..].chars().count() + 1)
}
