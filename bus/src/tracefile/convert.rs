//! The text formats written from the hub's typed trace records or from [`Item`]s.
//!
//! Contract, ASC: the header, dated at the measurement's epoch, is written on creation; each
//! record becomes one ASC line at its time since that epoch (`ErrorFrame` for an error frame,
//! whose class bits and interface ASC cannot carry). Channels number buses, not interfaces: an
//! interface's bus is its name up to the first `.` (`harv0` for `harv0.D2`), and the buses get
//! channels 1, 2, ... as they first appear (a hub's records are all on channel 1). `flush`
//! flushes the file; the end of the measurement is written by [`AscWriter::finish`] or, at the
//! latest, when the writer is dropped (an interrupted run still gives a complete file). After
//! `finish` records are refused.
//!
//! Contract, candump log ([`LogWriter`]): one line per item, as [`crate::trace::CandumpWriter`]
//! writes a record. An error frame without details (from ASC or BLF) is written with
//! `CAN_ERR_FLAG` and no class bits, the only way the format has to say "an error frame".

use super::{Entry, Item, ItemWriter, asc};
use crate::filter::CAN_ERR_FLAG;
use crate::time::Epoch;
use crate::trace::{ErrorFrame, Kind, Record, Sink};
use std::io::{self, Write};

/// Writes ASC to `W` from trace records.
pub struct AscWriter<W: Write> {
    inner: W,
    epoch: Epoch,
    out: String,
    finished: bool,
    /// The buses seen, channel 1 first.
    buses: Vec<String>,
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
            epoch,
            out,
            finished: false,
            buses: Vec::new(),
        })
    }

    /// Writes a `//` comment line.
    pub fn comment(&mut self, text: &str) -> io::Result<()> {
        self.out.clear();
        self.out.push_str("// ");
        self.out
            .extend(text.chars().map(|c| if c == '\n' { ' ' } else { c }));
        self.out.push('\n');
        self.inner.write_all(self.out.as_bytes())
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

impl<W: Write> ItemWriter for AscWriter<W> {
    fn note(&mut self, text: &str) -> io::Result<()> {
        self.comment(text)
    }
    fn write(&mut self, item: &Item) -> io::Result<()> {
        if self.finished {
            return Err(io::Error::other("the ASC measurement has ended"));
        }
        let bus = item.interface.split('.').next().unwrap_or_default();
        let channel = match self.buses.iter().position(|b| b == bus) {
            Some(i) => i + 1,
            None => {
                self.buses.push(bus.to_string());
                self.buses.len()
            }
        };
        // ASC numbers channels in one byte's worth of text; more buses than that share the last.
        let channel = u8::try_from(channel).unwrap_or(u8::MAX);
        let at = self.epoch.unstamp(item.at);
        self.out.clear();
        match &item.entry {
            Entry::Frame(frame) => asc::frame_line(&mut self.out, at, channel, frame),
            Entry::Error(_) => asc::error_line(&mut self.out, at, channel),
        }
        self.inner.write_all(self.out.as_bytes())
    }
    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
    fn finish(&mut self) -> io::Result<()> {
        AscWriter::finish(self)
    }
}

/// Writes items as a candump log.
pub struct LogWriter<W: Write> {
    inner: W,
    line: String,
    finished: bool,
}

impl<W: Write> LogWriter<W> {
    /// Writes to `inner`.
    pub fn new(inner: W) -> LogWriter<W> {
        LogWriter {
            inner,
            line: String::with_capacity(128),
            finished: false,
        }
    }
}

impl<W: Write> ItemWriter for LogWriter<W> {
    fn write(&mut self, item: &Item) -> io::Result<()> {
        if self.finished {
            return Err(io::Error::other("the log has ended"));
        }
        self.line.clear();
        match &item.entry {
            Entry::Frame(f) => crate::trace::frame_line(&mut self.line, item.at, &item.interface, f),
            Entry::Error(e) => {
                let e = e.unwrap_or(ErrorFrame {
                    can_id: CAN_ERR_FLAG,
                    data: [0; 8],
                });
                crate::trace::error_line(&mut self.line, item.at, &item.interface, &e)
            }
        }
        self.inner.write_all(self.line.as_bytes())
    }
    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
    fn finish(&mut self) -> io::Result<()> {
        self.finished = true;
        self.inner.flush()
    }
}
