use thiserror::Error;

/// Every way input to the harvester protocol can be wrong.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum Error {
    /// The identifier's priority field is 5 bits wide.
    #[error("priority {0} is out of range 0..=31")]
    BadPriority(u8),
    /// The harvester protocol uses only extended identifiers.
    #[error("the harvester protocol uses 29-bit identifiers; 0x{0:03X} is a base identifier")]
    NotExtended(u16),
    /// A payload does not match the catalogue's layout for its message.
    #[error("message {message}: {reason}")]
    Payload {
        /// Catalogue name of the message.
        message: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// A DBC file that cannot be read: where (line and column from 1; 0 when the parser could
    /// not say) and why.
    #[error("{}", dbc_at(file, *line, *column, reason))]
    Dbc {
        /// The file, as the caller names it.
        file: String,
        /// Line, from 1.
        line: usize,
        /// Column, from 1.
        column: usize,
        /// What is wrong.
        reason: String,
    },
    /// A CAN-level refusal (an identifier out of range, a payload over 8 bytes).
    #[error(transparent)]
    Can(#[from] bus::Error),
}

fn dbc_at(file: &str, line: usize, column: usize, reason: &str) -> String {
    if line == 0 {
        format!("{file}: {reason}")
    } else {
        format!("{file}:{line}:{column}: {reason}")
    }
}
