//! Vector ASC, classic CAN lines only.
//!
//! Written:
//!
//! ```text
//! date Thu Feb 22 05:15:03.978 pm 2024
//! base hex  timestamps absolute
//! internal events logged
//! // version 9.0.0
//! Begin Triggerblock Thu Feb 22 05:15:03.978 pm 2024
//!    0.000000 Start of measurement
//!    1.234567 1  0300A0F5x       Rx   d 2 01 01
//!    1.300000 1  123             Rx   r 4
//!    1.400000 1  ErrorFrame
//! End TriggerBlock
//! ```
//!
//! Times are seconds since the start of the measurement ("absolute" in ASC means "not relative
//! to the previous line"); the `date` is the wall-clock time of that start, in UTC. Extended
//! identifiers are written with 8 digits and an `x`, base identifiers with 3, as in candump logs.
//!
//! `timestamps relative` in the `base` line makes each time relative to the previous timestamped
//! line's (frames and events alike); the reader accumulates them. `absolute` is the default.
//!
//! Read: the header lines (`date`, `base hex|dec`, `internal events logged`, `Begin
//! Triggerblock`, `End TriggerBlock`), `//` comments, and every timestamped line that is not a
//! frame (start of measurement, statistics, chip status, system variables, J1939 transport
//! lines...) are skipped. A timestamped line with a channel number, an identifier and `Rx`/`Tx` is
//! a frame and must be well formed. CAN FD lines are refused: the harvester's bus is classic CAN.

use super::{Entry, parse_time};
use crate::frame::{extended_id, standard_id};
use crate::text::quote;
use crate::time::{BusTime, Stamp};
use crate::{Frame, Id};
use core::fmt::Write;
use std::time::SystemTime;

/// What the reader keeps from the header: the number base of identifiers and data bytes, and
/// whether times are relative (then also the time of the previous timestamped line).
#[derive(Debug)]
pub(super) struct ReadState {
    radix: u32,
    relative: bool,
    clock: Stamp,
    /// The channel of the last frame or error frame.
    pub(super) channel: u32,
    /// The measurement's start, from the first `date` line that reads as one.
    pub(super) start: Option<Stamp>,
}

impl Default for ReadState {
    fn default() -> Self {
        ReadState {
            radix: 16,
            relative: false,
            clock: Stamp(0),
            channel: 1,
            start: None,
        }
    }
}

/// Header lines, matched case-insensitively at the start of a line.
const HEADER: &[&str] = &[
    "date ",
    "internal events logged",
    "no internal events logged",
    "begin triggerblock",
    "end triggerblock",
];

impl ReadState {
    /// Parses one line (trimmed, not blank): `None` for lines that hold no frame.
    pub(super) fn parse_line(&mut self, line: &str) -> Result<Option<(Stamp, Entry)>, String> {
        let lower = line.to_ascii_lowercase();
        if lower.starts_with("date ") && self.start.is_none() {
            self.start = parse_date(&line[5..]);
        }
        if lower.starts_with("//") || HEADER.iter().any(|h| lower.starts_with(h)) {
            return Ok(None);
        }
        let mut tokens = line.split_whitespace();
        let first = tokens.next().unwrap_or_default();
        if first.eq_ignore_ascii_case("base") {
            self.radix = match tokens.next().map(str::to_ascii_lowercase).as_deref() {
                Some("hex") => 16,
                Some("dec") => 10,
                _ => return Err(format!("{}: the base is hex or dec", quote(line))),
            };
            self.relative = match tokens.next().map(str::to_ascii_lowercase).as_deref() {
                None => false,
                Some("timestamps") => match tokens.next().map(str::to_ascii_lowercase).as_deref() {
                    Some("absolute") => false,
                    Some("relative") => true,
                    _ => return Err(format!("{}: timestamps are absolute or relative", quote(line))),
                },
                Some(_) => {
                    return Err(format!(
                        "{}: base hex|dec timestamps absolute|relative",
                        quote(line)
                    ));
                }
            };
            return Ok(None);
        }
        let mut at = parse_time(first).map_err(|_| {
            format!(
                "{} is not an ASC line (a header line, a // comment or a timestamped line)",
                quote(line)
            )
        })?;
        if self.relative {
            at = Stamp(
                self.clock
                    .as_nanos()
                    .checked_add(at.as_nanos())
                    .ok_or_else(|| format!("{}: the accumulated time is too large", quote(line)))?,
            );
            self.clock = at;
        }
        let rest: Vec<&str> = tokens.collect();
        match rest.as_slice() {
            ["CANFD", ..] => Err("CAN FD frame: only classic CAN is supported".to_string()),
            [channel, word, ..] if is_channel(channel) && word.eq_ignore_ascii_case("errorframe") => {
                self.channel = channel.parse().unwrap_or(u32::MAX);
                Ok(Some((at, Entry::Error(None))))
            }
            [channel, id, dir, fields @ ..] if is_channel(channel) && is_direction(dir) => {
                let frame = self
                    .frame(id, fields)
                    .map_err(|e| format!("{}: {e}", quote(line)))?;
                self.channel = channel.parse().unwrap_or(u32::MAX);
                Ok(Some((at, Entry::Frame(frame))))
            }
            // Events: start of measurement, statistics, chip status, SV:, J1939TP, ...
            _ => Ok(None),
        }
    }

    fn number(&self, text: &str, what: &str) -> Result<u32, String> {
        u32::from_str_radix(text, self.radix).map_err(|_| {
            let base = if self.radix == 16 { "hex" } else { "decimal" };
            format!("{what} {} is not a {base} number", quote(text))
        })
    }

    fn frame(&self, id: &str, fields: &[&str]) -> Result<Frame, String> {
        let id = match id.strip_suffix(['x', 'X']) {
            Some(raw) => {
                Id::Extended(extended_id(self.number(raw, "identifier")?).map_err(|e| e.to_string())?)
            }
            None => {
                let raw = self.number(id, "identifier")?;
                let raw = u16::try_from(raw).map_err(|_| {
                    format!(
                        "identifier {} does not fit in 11 bits (an extended identifier ends in x)",
                        quote(id)
                    )
                })?;
                Id::Standard(standard_id(raw).map_err(|e| e.to_string())?)
            }
        };
        let (kind, rest) = fields
            .split_first()
            .ok_or("no frame type after the direction (d for data, r for remote)")?;
        let dlc = match rest.first() {
            Some(d) => {
                let dlc = self.number(d, "DLC")?;
                if dlc > 8 {
                    return Err(format!(
                        "DLC {} is above 8: only classic CAN is supported",
                        quote(d)
                    ));
                }
                Some(dlc as usize)
            }
            None => None,
        };
        match kind.to_ascii_lowercase().as_str() {
            "r" => Frame::new_remote(id, dlc.unwrap_or(0)).map_err(|e| e.to_string()),
            "d" => {
                let dlc = dlc.ok_or("a data frame without a DLC")?;
                let bytes = rest
                    .get(1..=dlc)
                    .ok_or_else(|| format!("DLC {dlc} but {} data bytes", rest.len().saturating_sub(1)))?;
                if rest.get(dlc + 1).is_some_and(|t| self.is_byte(t)) {
                    return Err(format!("more data bytes than the DLC {dlc}"));
                }
                let data = bytes
                    .iter()
                    .map(|b| match self.number(b, "data byte")? {
                        v @ 0..=255 => Ok(v as u8),
                        _ => Err(format!("data byte {} is above 255", quote(b))),
                    })
                    .collect::<Result<Vec<u8>, String>>()?;
                Frame::new_data(id, &data).map_err(|e| e.to_string())
            }
            other => Err(format!("frame type {}: d (data) or r (remote)", quote(other))),
        }
    }

    /// True for a token that reads as a data byte (what follows the data is not one: `Length =`).
    fn is_byte(&self, token: &str) -> bool {
        token.len() <= 3 && self.number(token, "").is_ok_and(|v| v <= 255)
    }
}

fn is_channel(token: &str) -> bool {
    !token.is_empty() && token.bytes().all(|b| b.is_ascii_digit())
}

fn is_direction(token: &str) -> bool {
    token.eq_ignore_ascii_case("rx") || token.eq_ignore_ascii_case("tx")
}

/// The wall-clock time of a measurement's start as ASC writes it: `Thu Feb 22 05:15:03.978 pm
/// 2024` (UTC; months and days in English whatever the locale).
pub fn date(start: SystemTime) -> String {
    let t = time::OffsetDateTime::from(start);
    let weekday = &t.weekday().to_string()[..3];
    let month = &t.month().to_string()[..3];
    let (hour, pm) = match t.hour() {
        0 => (12, false),
        h @ 1..=11 => (h, false),
        12 => (12, true),
        h => (h - 12, true),
    };
    format!(
        "{weekday} {month} {:02} {hour:02}:{:02}:{:02}.{:03} {} {}",
        t.day(),
        t.minute(),
        t.second(),
        t.millisecond(),
        if pm { "pm" } else { "am" },
        t.year()
    )
}

/// Reads a `date` line's date as [`date`] writes it, or in 24-hour time without `am`/`pm`
/// (`Thu Feb 22 17:15:03.978 2024`), as UTC. `None` for anything else (a date in another
/// language): the measurement's start is then unknown.
pub fn parse_date(text: &str) -> Option<Stamp> {
    let t: Vec<&str> = text.split_whitespace().collect();
    let (month, day, clock, half, year) = match t.as_slice() {
        [_, month, day, clock, half, year] => (month, day, clock, Some(half.to_ascii_lowercase()), year),
        [_, month, day, clock, year] => (month, day, clock, None, year),
        _ => return None,
    };
    let month = MONTHS
        .iter()
        .position(|m| m.eq_ignore_ascii_case(month))
        .and_then(|i| time::Month::try_from(i as u8 + 1).ok())?;
    let (hms, millis) = clock.split_once('.').unwrap_or((clock, "0"));
    let mut parts = hms.split(':').map(|p| p.parse::<u8>().ok());
    let (Some(Some(mut hour)), Some(Some(minute)), Some(Some(second)), None) =
        (parts.next(), parts.next(), parts.next(), parts.next())
    else {
        return None;
    };
    match half.as_deref() {
        Some("am") if hour == 12 => hour = 0,
        Some("pm") if hour < 12 => hour += 12,
        Some("am" | "pm") | None => {}
        Some(_) => return None,
    }
    let nanos: u32 = format!("{millis:0<9}").get(..9)?.parse().ok()?;
    let date = time::Date::from_calendar_date(year.parse().ok()?, month, day.parse().ok()?).ok()?;
    let clock = time::Time::from_hms_nano(hour, minute, second, nanos).ok()?;
    let at = date.with_time(clock).assume_utc().unix_timestamp_nanos();
    u64::try_from(at).ok().map(Stamp)
}

const MONTHS: [&str; 12] = [
    "Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec",
];

/// Appends the header of a measurement that started at `start`.
pub fn header(out: &mut String, start: SystemTime) {
    let date = date(start);
    let _ = write!(
        out,
        "date {date}\nbase hex  timestamps absolute\ninternal events logged\n// version 9.0.0\n\
         Begin Triggerblock {date}\n"
    );
    event_line(out, BusTime::ZERO, "Start of measurement");
}

/// Appends an event line: `   0.000000 Start of measurement`.
pub fn event_line(out: &mut String, at: BusTime, text: &str) {
    time(out, at);
    let _ = writeln!(out, " {text}");
}

fn time(out: &mut String, at: BusTime) {
    let _ = write!(out, "{:>11}", at.to_string());
}

/// Appends a frame line on `channel` (1-based, as CANalyzer counts).
pub fn frame_line(out: &mut String, at: BusTime, channel: u8, frame: &Frame) {
    time(out, at);
    let id = match frame.id() {
        Id::Standard(id) => format!("{:03X}", id.as_raw()),
        Id::Extended(id) => format!("{:08X}x", id.as_raw()),
    };
    let _ = write!(out, " {channel}  {id:<15} Rx   ");
    if frame.is_remote() {
        let _ = write!(out, "r {:X}", frame.dlc());
    } else {
        let _ = write!(out, "d {:X}", frame.dlc());
        for b in frame.data() {
            let _ = write!(out, " {b:02X}");
        }
    }
    out.push('\n');
}

/// Appends an error frame line on `channel`.
pub fn error_line(out: &mut String, at: BusTime, channel: u8) {
    time(out, at);
    let _ = writeln!(out, " {channel}  ErrorFrame");
}

/// Appends the end of the measurement.
pub fn footer(out: &mut String) {
    out.push_str("End TriggerBlock\n");
}
