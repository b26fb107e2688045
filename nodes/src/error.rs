use bus::text::{LIST_CHARS, QUOTE_CHARS, cut};
use std::fmt;
use thiserror::Error;

/// One problem in a script or config: where it is and what is wrong.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Problem {
    /// The file.
    pub file: String,
    /// Line and column, where the parser knows them.
    pub position: Option<(usize, usize)>,
    /// The node the problem belongs to, if any.
    pub node: Option<String>,
    /// The field, as a path (`messages[2].frames[0].fields.unit3`).
    pub field: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl Problem {
    /// A problem in `field` of `file`, with no position or node.
    pub fn at(file: &str, field: impl Into<String>, message: impl Into<String>) -> Problem {
        Problem {
            file: file.to_string(),
            position: None,
            node: None,
            field: Some(field.into()),
            message: message.into(),
        }
    }
}

impl fmt::Display for Problem {
    /// `file:line:col: node N: field: message`; the node's name and the field's path come from
    /// the file, so they are cut to a few dozen characters.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some((line, col)) = self.position {
            write!(f, ":{line}:{col}")?;
        }
        if let Some(node) = &self.node {
            write!(f, ": node {}", cut(node, QUOTE_CHARS))?;
        }
        if let Some(field) = &self.field {
            write!(f, ": {}", cut(field, LIST_CHARS))?;
        }
        write!(f, ": {}", self.message)
    }
}

/// Every way the nodes crate can fail.
#[derive(Debug, Error)]
pub enum Error {
    /// Scripts or configs with problems; all of them are listed.
    #[error("{}", list(.0))]
    Invalid(Vec<Problem>),
    /// A file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
}

fn list(problems: &[Problem]) -> String {
    let mut s = format!(
        "{}:",
        bus::text::count(problems.len() as u64, "problem", "problems")
    );
    for p in problems {
        s.push_str("\n  ");
        s.push_str(&p.to_string());
    }
    s
}

/// Parses RON text as `T`; a syntax error or an unknown field comes back as one [`Problem`]
/// with its line and column. What the message quotes from the text (between backticks) is cut
/// to a few dozen characters.
pub fn parse_ron<T: serde::de::DeserializeOwned>(file: &str, text: &str) -> Result<T, Error> {
    ron::from_str::<T>(text).map_err(|e| {
        Error::Invalid(vec![Problem {
            file: file.to_string(),
            position: Some((e.span.start.line, e.span.start.col)),
            node: None,
            field: None,
            message: short_quotes(&e.code.to_string()),
        }])
    })
}

/// `message` with every part between backticks (what RON's messages quote) cut to
/// [`QUOTE_CHARS`], and the whole cut to a few lines' worth.
fn short_quotes(message: &str) -> String {
    let parts: Vec<String> = message
        .split('`')
        .enumerate()
        .map(|(i, part)| {
            if i % 2 == 1 {
                cut(part, QUOTE_CHARS)
            } else {
                part.to_string()
            }
        })
        .collect();
    cut(&parts.join("`"), MESSAGE_CHARS)
}

/// The longest RON message shown, characters: room for the list of a struct's fields.
const MESSAGE_CHARS: usize = 400;
