//! The `ID#DATA` frame notation of can-utils (`cansend`, `candump -L`).
//!
//! - `123#DEADBEEF`: base data frame (exactly 3 hex digits of identifier).
//! - `0601F5D0#200D0002FFBFFF00`: extended data frame (exactly 8 hex digits).
//! - `123#R` or `123#R4`: remote frame, optionally with its DLC.
//! - Data bytes may be separated by dots: `123#DE.AD.BE.EF`.

use crate::frame::{extended_id, standard_id};
use crate::text::quote;
use crate::{Error, Frame, Id};

/// Parses one frame in `ID#DATA` notation.
pub fn parse_frame(text: &str) -> Result<Frame, Error> {
    let text = text.trim();
    let (id_text, data_text) = text
        .split_once('#')
        .ok_or_else(|| syntax(format!("{} has no '#' between identifier and data", quote(text))))?;
    let id = parse_id(id_text)?;
    if let Some(dlc) = data_text.strip_prefix(['R', 'r']) {
        let dlc = match dlc {
            "" => 0,
            d => d
                .parse::<usize>()
                .map_err(|_| syntax(format!("remote frame DLC {} is not a digit 0-8", quote(d))))?,
        };
        return Frame::new_remote(id, dlc);
    }
    let data = parse_hex_bytes(data_text)?;
    Frame::new_data(id, &data)
}

/// Parses an identifier: 3 hex digits for a base frame, 8 for an extended frame.
pub fn parse_id(text: &str) -> Result<Id, Error> {
    if text.is_empty() || !text.chars().all(|c| c.is_ascii_hexdigit()) {
        return Err(syntax(format!("identifier {} is not hexadecimal", quote(text))));
    }
    match text.len() {
        3 => {
            let raw = u16::from_str_radix(text, 16).map_err(|e| syntax(e.to_string()))?;
            Ok(Id::Standard(standard_id(raw)?))
        }
        8 => {
            let raw = u32::from_str_radix(text, 16).map_err(|e| syntax(e.to_string()))?;
            Ok(Id::Extended(extended_id(raw)?))
        }
        n => Err(syntax(format!(
            "identifier {} has {n} hex digits; use 3 for a base frame or 8 for an extended frame",
            quote(text)
        ))),
    }
}

/// Parses contiguous (or dot-separated) hex byte pairs.
pub fn parse_hex_bytes(text: &str) -> Result<Vec<u8>, Error> {
    let digits: Vec<u8> = text.bytes().filter(|&b| b != b'.').collect();
    if let Some(bad) = digits.iter().find(|b| !b.is_ascii_hexdigit()) {
        return Err(syntax(format!(
            "data {} has a non-hex character {}",
            quote(text),
            quote(&char::from(*bad).to_string())
        )));
    }
    if !digits.len().is_multiple_of(2) {
        return Err(syntax(format!(
            "data {} has an odd number of hex digits",
            quote(text)
        )));
    }
    if digits.len() > 16 {
        return Err(Error::TooMuchData(digits.len() / 2));
    }
    Ok(digits
        .chunks(2)
        .map(|pair| (hex_value(pair[0]) << 4) | hex_value(pair[1]))
        .collect())
}

fn hex_value(digit: u8) -> u8 {
    match digit {
        b'0'..=b'9' => digit - b'0',
        b'a'..=b'f' => digit - b'a' + 10,
        _ => digit - b'A' + 10,
    }
}

fn syntax(message: String) -> Error {
    Error::Syntax(message)
}

/// Writes a frame in `ID#DATA` notation (upper-case hex, as candump does).
pub fn format_frame(frame: &Frame) -> String {
    let mut out = String::with_capacity(26);
    write_frame(&mut out, frame);
    out
}

/// Appends a frame in `ID#DATA` notation to `out` ([`Frame::write_text`]).
pub fn write_frame(out: &mut String, frame: &Frame) {
    frame.write_text(out);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_formats() {
        for text in [
            "0601F5D0#200D0002FFBFFF00",
            "123#DEADBEEF",
            "7FF#R",
            "123#R4",
            "000#",
            "1FFFFFFF#00",
        ] {
            let f = parse_frame(text).unwrap();
            assert_eq!(format_frame(&f), text);
        }
        let f = parse_frame("123#de.ad.BE.ef").unwrap();
        assert_eq!(f.data(), &[0xDE, 0xAD, 0xBE, 0xEF]);
        assert!(parse_frame("0601F5D0#20").unwrap().is_extended());
    }

    #[test]
    fn rejects_bad_text() {
        for bad in [
            "xyz",
            "xyz#00",
            "1234#00",
            "20000000#00",
            "800#00",
            "123#0",
            "123#0G",
            "123#000102030405060708",
            "123#R9",
            "123#Rx",
        ] {
            assert!(parse_frame(bad).is_err(), "{bad} should be rejected");
        }
        assert_eq!(parse_frame("123#000102030405060708"), Err(Error::TooMuchData(9)));
    }
}
