//! Every trace format through one door: [`items`] reads a file of any [`FileFormat`] as
//! numbered [`Item`]s.
//!
//! Contract: the records come in the file's order, each with its number (the line of a text
//! trace, the record or block of a binary one), read as they are taken (memory does not grow with
//! the file). Times never go backwards: a record stamped earlier than the one before it is an
//! error naming both, as for the text traces, since a replay plays them in order. Error frames
//! are kept or left out as asked. The first error ends the iteration.

use super::{Entry, ErrorFrames, FileFormat, Item, PcapngReader, text_items};
use crate::Error;
use crate::time::Stamp;
use std::io::{BufReader, Read, Seek};

/// Numbered items, or the error that ended them.
pub type Items<'a> = Box<dyn Iterator<Item = Result<(u64, Item), Error>> + 'a>;

/// Reads `input` as `format`. A binary format's header is read here: a bad one is the error.
pub fn items<'a, R: Read + Seek + 'a>(
    input: R,
    format: FileFormat,
    errors: ErrorFrames,
) -> Result<Items<'a>, Error> {
    let input = BufReader::with_capacity(1 << 16, input);
    let inner: Items<'a> = match format {
        FileFormat::Log | FileFormat::Asc => Box::new(text_items(input, errors)),
        FileFormat::Pcapng => Box::new(PcapngReader::new(input)?),
        FileFormat::Blf => Box::new(super::blf::BlfReader::new(input)?),
        FileFormat::Mf4 => Box::new(super::mf4::Mf4Reader::new(input)?),
    };
    let text = matches!(format, FileFormat::Log | FileFormat::Asc);
    let mut last: Option<(Stamp, u64)> = None;
    let mut failed = false;
    Ok(Box::new(inner.filter_map(move |r| {
        if failed {
            return None;
        }
        let (number, item) = match r {
            Ok(x) => x,
            Err(e) => {
                failed = true;
                return Some(Err(e));
            }
        };
        // The text reader checks the order itself, skipped error frames included.
        if !text {
            if let Some((before, before_number)) = last
                && item.at < before
            {
                failed = true;
                return Some(Err(Error::TraceTime {
                    format: format.describe(),
                    record: number,
                    at: item.at,
                    before_record: before_number,
                    before,
                }));
            }
            last = Some((item.at, number));
            if errors == ErrorFrames::Skip && matches!(item.entry, Entry::Error(_)) {
                return None;
            }
        }
        Some(Ok((number, item)))
    })))
}
