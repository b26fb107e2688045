//! One line of a candump log: `(secs.usecs) iface ID#DATA`, as `candump -L` and the hub's trace
//! write it. A trailing direction flag (` R`, ` T`, which python-can and newer can-utils add) is
//! accepted. An 8-digit identifier with `CAN_ERR_FLAG` set is a SocketCAN error frame.

use super::{Entry, parse_time};
use crate::candump::{parse_frame, parse_hex_bytes};
use crate::filter::CAN_ERR_FLAG;
use crate::text::quote;
use crate::time::Stamp;
use crate::trace::ErrorFrame;

/// Parses one line (already trimmed, not blank): its time, interface and entry.
pub(super) fn parse_line(line: &str) -> Result<(Stamp, &str, Entry), String> {
    let (time, rest) = line
        .strip_prefix('(')
        .and_then(|l| l.split_once(')'))
        .ok_or_else(|| {
            format!(
                "{} is not a candump log line: (secs.usecs) iface ID#DATA",
                quote(line)
            )
        })?;
    let at = parse_time(time)?;
    let mut fields = rest.split_whitespace();
    let (Some(iface), Some(frame)) = (fields.next(), fields.next()) else {
        return Err(format!("{} lacks the interface or the frame", quote(line)));
    };
    match fields.next() {
        None | Some("R" | "T" | "r" | "t") if fields.next().is_none() => {}
        _ => return Err(format!("{} has text after the frame", quote(line))),
    }
    if frame.contains("##") {
        return Err(format!(
            "{} is a CAN FD frame: only classic CAN is supported",
            quote(frame)
        ));
    }
    if let Some(error) = error_frame(frame)? {
        return Ok((at, iface, Entry::Error(Some(error))));
    }
    let frame = parse_frame(frame).map_err(|e| format!("frame {}: {e}", quote(frame)))?;
    Ok((at, iface, Entry::Frame(frame)))
}

/// An error frame, when the identifier has `CAN_ERR_FLAG` set.
fn error_frame(text: &str) -> Result<Option<ErrorFrame>, String> {
    let Some((id, data)) = text.split_once('#') else {
        return Ok(None);
    };
    let can_id = match u32::from_str_radix(id, 16) {
        Ok(v) if id.len() == 8 && v & CAN_ERR_FLAG != 0 => v,
        _ => return Ok(None),
    };
    if can_id > CAN_ERR_FLAG | 0x1FFF_FFFF {
        return Err(format!(
            "error frame identifier {} has flags other than CAN_ERR_FLAG",
            quote(id)
        ));
    }
    let bytes = parse_hex_bytes(data).map_err(|e| format!("error frame {}: {e}", quote(text)))?;
    let mut data = [0u8; 8];
    data[..bytes.len()].copy_from_slice(&bytes);
    Ok(Some(ErrorFrame { can_id, data }))
}
