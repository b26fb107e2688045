//! `harvemu run --trace-cpu NODE [--trace-cpu-window FROM..TO]`: a firmware node's executed
//! instructions on standard output, one line each (docs/FIRMWARE.md).

use crate::Error;
use crate::harvester::{CpuTraceRequest, Harvester};
use bus::time::BusTime;
use std::cell::RefCell;
use std::io::{self, Write};
use std::path::Path;
use std::rc::Rc;

/// The window of bus time a trace covers: `FROM..TO` with durations as `--for` takes them
/// (`0.5s..600ms`); either side may be left out (`..10ms`, `1s..`).
pub fn parse_window(text: &str) -> Result<(BusTime, BusTime), String> {
    let (from, to) = text
        .split_once("..")
        .ok_or_else(|| format!("{text:?}: a window is FROM..TO, e.g. 0s..10ms"))?;
    let side = |s: &str, default: BusTime| -> Result<BusTime, String> {
        if s.trim().is_empty() {
            Ok(default)
        } else {
            super::parse_duration(s).map(BusTime::from_duration)
        }
    };
    let (from, to) = (side(from, BusTime::ZERO)?, side(to, BusTime::NEVER)?);
    if from > to {
        return Err(format!("{text:?}: the window ends before it starts"));
    }
    Ok((from, to))
}

/// Where the lines go, and the first write error (after which nothing more is written).
pub struct TraceOut {
    out: io::BufWriter<io::Stdout>,
    error: Option<io::Error>,
}

impl TraceOut {
    fn line(&mut self, line: &str) {
        if self.error.is_none()
            && let Err(e) = writeln!(self.out, "{line}")
        {
            self.error = Some(e);
        }
    }

    /// Flushes; the first error, if any, as an output failure (a reader that went away ends the
    /// trace quietly, as it ends any Unix filter).
    pub fn finish(&mut self) -> crate::Result<()> {
        let flushed = self.out.flush();
        match self.error.take().map_or(flushed, Err) {
            Err(e) if e.kind() != io::ErrorKind::BrokenPipe => {
                Err(crate::output::failed("write", Path::new("standard output"), e))
            }
            _ => Ok(()),
        }
    }
}

/// The request for `node` over `window`, checked against the harvester: the node must be a
/// firmware node.
pub fn request(
    h: &Harvester,
    node: &str,
    window: (BusTime, BusTime),
) -> crate::Result<(CpuTraceRequest, Rc<RefCell<TraceOut>>)> {
    if !h.firmware.iter().any(|f| f.name == node) {
        let names: Vec<&str> = h.firmware.iter().map(|f| f.name.as_str()).collect();
        return Err(Error::BadInput(format!(
            "--trace-cpu {node}: no firmware node of that name (firmware nodes: {})",
            if names.is_empty() {
                "none".to_string()
            } else {
                names.join(", ")
            }
        )));
    }
    let out = Rc::new(RefCell::new(TraceOut {
        out: io::BufWriter::new(io::stdout()),
        error: None,
    }));
    let sink = out.clone();
    let request = CpuTraceRequest {
        node: node.to_string(),
        from: window.0,
        to: window.1,
        out: Rc::new(RefCell::new(move |line: &str| sink.borrow_mut().line(line))),
    };
    Ok((request, out))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_take_durations_and_open_ends() {
        let ms = |n| BusTime::from_millis(n);
        assert_eq!(parse_window("0s..10ms"), Ok((ms(0), ms(10))));
        assert_eq!(parse_window("..10ms"), Ok((ms(0), ms(10))));
        assert_eq!(parse_window("1s.."), Ok((ms(1000), BusTime::NEVER)));
        assert!(parse_window("10ms").unwrap_err().contains("FROM..TO"));
        assert!(
            parse_window("2s..1s")
                .unwrap_err()
                .contains("ends before it starts")
        );
        assert!(parse_window("x..1s").is_err());
    }
}
