//! An ASC file fed with candump log lines.
//!
//! The hub writes its trace as candump log lines into any `Write`; recording ASC instead is this
//! `Write` in between, which turns each complete line into its ASC line as it arrives. So the
//! hub, the harvester assembly and every caller stay unaware of the format, and both formats come
//! from the same events.
//!
//! Contract: the header, dated at the measurement's epoch, is written on creation, each candump line becomes one ASC line (frames,
//! and `ErrorFrame` for SocketCAN error frames, whose class bits ASC cannot carry), `flush`
//! flushes the file, and the end of the measurement is written by [`AscWriter::finish`] or, at
//! the latest, when the writer is dropped (an interrupted run still gives a complete file). A line
//! that is not a candump log line is an `InvalidData` error, and nothing of it is written.

use super::Entry;
use super::asc;
use super::candump_log::parse_line;
use crate::time::Epoch;
use std::io::{self, Write};

/// Writes ASC to `W` from candump log lines.
pub struct AscWriter<W: Write> {
    inner: W,
    pending: Vec<u8>,
    out: String,
    finished: bool,
    epoch: Epoch,
}

impl<W: Write> AscWriter<W> {
    /// Starts a measurement that began at `epoch` and writes its header, dated `epoch`. The
    /// candump lines fed to it carry times stamped with the same epoch (as the hub writes them);
    /// ASC times are relative to the start, so each is written less the epoch.
    pub fn new(mut inner: W, epoch: Epoch) -> io::Result<AscWriter<W>> {
        let mut out = String::with_capacity(256);
        asc::header(&mut out, epoch.system_time());
        inner.write_all(out.as_bytes())?;
        Ok(AscWriter {
            inner,
            pending: Vec::with_capacity(256),
            out,
            finished: false,
            epoch,
        })
    }

    /// Writes the end of the measurement and flushes; later writes are refused.
    pub fn finish(&mut self) -> io::Result<()> {
        if !self.finished {
            self.finished = true;
            self.out.clear();
            asc::footer(&mut self.out);
            self.inner.write_all(self.out.as_bytes())?;
        }
        self.inner.flush()
    }

    fn convert(&mut self, line: &[u8]) -> io::Result<()> {
        let invalid = |m: String| io::Error::new(io::ErrorKind::InvalidData, m);
        let text = std::str::from_utf8(line).map_err(|e| invalid(e.to_string()))?;
        let text = text.trim();
        if text.is_empty() {
            return Ok(());
        }
        let (at, entry) = parse_line(text).map_err(invalid)?;
        let at = self.epoch.unstamp(at);
        self.out.clear();
        match entry {
            Entry::Frame(frame) => asc::frame_line(&mut self.out, at, 1, &frame),
            Entry::Error(_) => asc::error_line(&mut self.out, at, 1),
        }
        self.inner.write_all(self.out.as_bytes())
    }
}

impl<W: Write> Write for AscWriter<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if self.finished {
            return Err(io::Error::other("the ASC measurement has ended"));
        }
        self.pending.extend_from_slice(buf);
        while let Some(end) = self.pending.iter().position(|&b| b == b'\n') {
            let line: Vec<u8> = self.pending.drain(..=end).collect();
            self.convert(&line)?;
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

impl<W: Write> Drop for AscWriter<W> {
    fn drop(&mut self) {
        // Nowhere to report a failure to from here; `finish` is there for callers who care.
        let _ = self.finish();
    }
}
