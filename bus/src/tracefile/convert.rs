//! An ASC file written from the hub's typed trace records.
//!
//! Contract: the header, dated at the measurement's epoch, is written on creation; each record
//! becomes one ASC line at its bus time (frames on channel 1, and `ErrorFrame` for a
//! controller's error frame, whose class bits and interface ASC cannot carry); `flush` flushes
//! the file; the end of the measurement is written by [`AscWriter::finish`] or, at the latest,
//! when the writer is dropped (an interrupted run still gives a complete file). After `finish`
//! records are refused.

use super::asc;
use crate::time::Epoch;
use crate::trace::{Kind, Record, Sink};
use std::io::{self, Write};

/// Writes ASC to `W` from trace records.
pub struct AscWriter<W: Write> {
    inner: W,
    out: String,
    finished: bool,
}

impl<W: Write> AscWriter<W> {
    /// Starts a measurement that began at `epoch` and writes its header, dated `epoch`. ASC
    /// times are relative to the start: a record's bus time is written as it is.
    pub fn new(mut inner: W, epoch: Epoch) -> io::Result<AscWriter<W>> {
        let mut out = String::with_capacity(256);
        asc::header(&mut out, epoch.system_time());
        inner.write_all(out.as_bytes())?;
        Ok(AscWriter {
            inner,
            out,
            finished: false,
        })
    }

    /// Writes the end of the measurement and flushes; later records are refused.
    pub fn finish(&mut self) -> io::Result<()> {
        if !self.finished {
            self.finished = true;
            self.out.clear();
            asc::footer(&mut self.out);
            self.inner.write_all(self.out.as_bytes())?;
        }
        self.inner.flush()
    }
}

impl<W: Write> Sink for AscWriter<W> {
    fn record(&mut self, r: &Record<'_>) -> io::Result<()> {
        if self.finished {
            return Err(io::Error::other("the ASC measurement has ended"));
        }
        self.out.clear();
        match &r.kind {
            Kind::Frame(frame) => asc::frame_line(&mut self.out, r.at, 1, frame),
            Kind::Error(_) => asc::error_line(&mut self.out, r.at, 1),
        }
        self.inner.write_all(self.out.as_bytes())
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
