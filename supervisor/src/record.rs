//! `--record FILE`: where the hub's trace goes.
//!
//! Contract: the format is `--format`'s when given, else the one the file's name asks for
//! ([`FileFormat::of_path`]: `.asc` Vector ASC, `.blf` Vector BLF, `.pcapng` pcapng, `.mf4`
//! MF4, anything else a candump log), written from the hub's trace records ([`bus::trace`])
//! through the format's [`ItemWriter`]. [`create`] gives the hub its sink ([`Feed`]) and the
//! caller the [`Trace`], which [`Trace::finish`] ends once the run is over (a run cut short by
//! SIGTERM or Ctrl-C included): for ASC a comment line when the run was interrupted, then the
//! format's end (ASC's footer, BLF's header counts, MF4's block lengths); then the file is put
//! in place whole ([`crate::output`]: a regular file is replaced only by a complete trace, a
//! stream ends on a whole record). BLF and MF4 go back into the file at its end, so they need a
//! file, not a stream: asking for one on a stream is bad input. The first write that fails
//! stops the trace; `finish` reports it, naming the file. A file that cannot be created is an
//! [`crate::Error::Output`] naming it.
//!
//! Timestamps: bus time stamped with the run's [`Epoch`] ([`epoch`] picks it: `--start-time`,
//! else the wall clock at the start of a real-time run, else [`Epoch::FIXED`]); ASC, BLF and MF4
//! are dated at that epoch and count their times from it.

use crate::output::{Output, failed, is_stream};
use crate::stop::Signal;
use bus::time::{BusTime, Epoch, Stamp};
use bus::trace::{Record, Sink};
use bus::tracefile::{AscWriter, FileFormat, Item, ItemWriter, LogWriter, PcapngWriter, fill};
use std::cell::RefCell;
use std::io::{self, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::rc::Rc;

/// The output, shared by the format's writer and the end of the trace.
#[derive(Clone)]
struct Shared(Rc<RefCell<Output>>);

impl Write for Shared {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0.borrow_mut().write(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.0.borrow_mut().flush()
    }
}

impl Seek for Shared {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.0.borrow_mut().seek(pos)
    }
}

struct State {
    writer: Option<Box<dyn ItemWriter>>,
    /// Taken out by [`Trace::finish`].
    out: Option<Shared>,
    /// The first write that failed.
    error: Option<io::Error>,
    epoch: Epoch,
    /// The item a hub record becomes, reused.
    item: Item,
}

impl State {
    fn guard<T>(&mut self, op: impl FnOnce(&mut State) -> io::Result<T>) -> io::Result<T> {
        if let Some(e) = &self.error {
            return Err(io::Error::new(e.kind(), e.to_string()));
        }
        match op(self) {
            Err(e) => {
                // The trace keeps the first error itself, for `finish`, and hands out copies.
                let copy = io::Error::new(e.kind(), e.to_string());
                self.error = Some(e);
                Err(copy)
            }
            ok => ok,
        }
    }
}

fn ended() -> io::Error {
    io::Error::other("the trace has ended")
}

/// The sink the hub hands its records to.
pub struct Feed(Rc<RefCell<State>>);

impl Sink for Feed {
    fn record(&mut self, r: &Record<'_>) -> io::Result<()> {
        self.0.borrow_mut().guard(|s| {
            fill(&mut s.item, s.epoch, r);
            match s.writer.as_mut() {
                Some(w) => w.write(&s.item),
                None => Err(ended()),
            }
        })
    }
    fn flush(&mut self) -> io::Result<()> {
        self.0.borrow_mut().guard(|s| match s.writer.as_mut() {
            Some(w) => w.flush(),
            None => Ok(()),
        })
    }
}

/// A trace being recorded, to be ended by [`Trace::finish`].
pub struct Trace {
    path: PathBuf,
    state: Rc<RefCell<State>>,
}

/// The epoch of a run: `start_time` when given (`--start-time`), else the wall clock now for a
/// real-time (`paced`) run, as `candump -l` stamps frames, else [`Epoch::FIXED`], so that a
/// virtual-time run's trace is the same bytes for the same seed.
pub fn epoch(start_time: Option<Epoch>, paced: bool) -> Epoch {
    start_time.unwrap_or_else(|| bus_runtime::hub::default_epoch(paced))
}

/// Reads `--start-time`: RFC 3339 (`2024-01-01T00:00:00Z`) or seconds since 1970.
pub fn parse_start_time(text: &str) -> Result<Epoch, String> {
    Epoch::parse(text)
}

/// The format of a trace written to `path`: `format` when given (`--format`), else the one its
/// name asks for.
pub fn format_for(path: &Path, format: Option<FileFormat>) -> FileFormat {
    format.unwrap_or_else(|| FileFormat::of_path(path))
}

/// Starts the trace file at `path` in `format` (else the one its name asks for), for a run
/// whose trace is stamped with `epoch`: the hub's sink and the trace to finish.
pub fn create(
    path: &Path,
    format: Option<FileFormat>,
    epoch: Epoch,
) -> crate::Result<(Box<dyn Sink>, Trace)> {
    let trace = start(path, format, epoch.stamp(BusTime::ZERO), epoch)?;
    Ok((Box::new(Feed(trace.state.clone())), trace))
}

/// Starts a trace file of items (`harvemu convert`): dated `start`.
pub fn create_items(path: &Path, format: FileFormat, start: Stamp) -> crate::Result<Trace> {
    // The epoch only turns hub records into items; items come stamped already.
    start_at(path, format, start, Epoch::UNIX)
}

fn start(path: &Path, format: Option<FileFormat>, start: Stamp, epoch: Epoch) -> crate::Result<Trace> {
    start_at(path, format_for(path, format), start, epoch)
}

fn start_at(path: &Path, format: FileFormat, start: Stamp, epoch: Epoch) -> crate::Result<Trace> {
    if format.needs_seek() && is_stream(path) {
        return Err(crate::Error::BadInput(format!(
            "{}: {format} is finished by going back into the file at its end, which a stream \
             cannot do: record to a file (or choose --format log, asc or pcapng)",
            path.display()
        )));
    }
    let out = Shared(Rc::new(RefCell::new(Output::create(path)?)));
    let made: io::Result<Box<dyn ItemWriter>> = match format {
        FileFormat::Log => Ok(Box::new(LogWriter::new(out.clone()))),
        // ASC dates its measurement to the millisecond and counts from there: from the start
        // cut to its millisecond, so that the date and the times together are exact.
        FileFormat::Asc => AscWriter::new(
            out.clone(),
            Epoch::from_micros(start.as_nanos() / 1_000_000 * 1000),
        )
        .map(|w| Box::new(w) as Box<dyn ItemWriter>),
        FileFormat::Pcapng => {
            PcapngWriter::new(out.clone(), Epoch::UNIX).map(|w| Box::new(w) as Box<dyn ItemWriter>)
        }
        FileFormat::Blf => bus::tracefile::blf::BlfWriter::new(out.clone(), start)
            .map(|w| Box::new(w) as Box<dyn ItemWriter>),
        FileFormat::Mf4 => bus::tracefile::mf4::Mf4Writer::new(out.clone(), start)
            .map(|w| Box::new(w) as Box<dyn ItemWriter>),
    };
    let writer = made.map_err(|e| failed("write", path, e))?;
    let state = Rc::new(RefCell::new(State {
        writer: Some(writer),
        out: Some(out),
        error: None,
        epoch,
        item: Item {
            at: Stamp(0),
            interface: String::new(),
            entry: bus::tracefile::Entry::Error(None),
        },
    }));
    Ok(Trace {
        path: path.to_path_buf(),
        state,
    })
}

/// The hub's sink and the trace to finish, when there is a trace.
pub type Recording = (Option<Box<dyn Sink>>, Option<Trace>);

/// [`create`] for an optional `--record`.
pub fn create_opt(
    path: Option<&PathBuf>,
    format: Option<FileFormat>,
    epoch: Epoch,
) -> crate::Result<Recording> {
    match path {
        Some(p) => {
            let (w, t) = create(p, format, epoch)?;
            Ok((Some(w), Some(t)))
        }
        None => Ok((None, None)),
    }
}

impl Trace {
    /// Writes one item (`harvemu convert`); after an error nothing more is written and
    /// [`Trace::finish`] reports it.
    pub fn write(&self, item: &Item) -> crate::Result<()> {
        self.state
            .borrow_mut()
            .guard(|s| match s.writer.as_mut() {
                Some(w) => w.write(item),
                None => Err(ended()),
            })
            .map_err(|e| failed("write", &self.path, e))
    }

    /// Ends the trace: for ASC an `interrupted` comment when the run was; the format's end;
    /// then the file is flushed and put in place. An error names the file; the file is then
    /// left as it was (a regular file) or ends where writing failed (a stream).
    pub fn finish(self, interrupted: Option<Signal>) -> crate::Result<()> {
        let mut s = self.state.borrow_mut();
        let writer = s.writer.take();
        let out = s.out.take();
        if let Some(e) = s.error.take() {
            return Err(failed("write", &self.path, e));
        }
        drop(s);
        let Some(out) = out else {
            return Ok(());
        };
        if let Some(mut writer) = writer {
            let mut end = || -> io::Result<()> {
                if let Some(sig) = interrupted {
                    writer.note(&format!(
                        "harvemu: interrupted by {}: the measurement ends here",
                        sig.describe()
                    ))?;
                }
                writer.finish()
            };
            end().map_err(|e| failed("write", &self.path, e))?;
            // The format's writer holds the output too: it is done with before the output is.
            drop(writer);
        }
        let out = Rc::try_unwrap(out.0)
            .map_err(|_| failed("write", &self.path, io::Error::other("still in use")))?;
        out.into_inner().commit()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_name_picks_the_format_unless_one_is_given() {
        for (name, format) in [
            ("run.asc", FileFormat::Asc),
            ("RUN.ASC", FileFormat::Asc),
            ("dir.asc/run.log", FileFormat::Log),
            ("run.log", FileFormat::Log),
            ("asc", FileFormat::Log),
            ("run.asc.log", FileFormat::Log),
            ("run.Mf4", FileFormat::Mf4),
        ] {
            assert_eq!(format_for(Path::new(name), None), format, "{name}");
        }
        assert_eq!(
            format_for(Path::new("run.log"), Some(FileFormat::Blf)),
            FileFormat::Blf
        );
    }

    #[test]
    fn an_interrupted_asc_says_so_before_its_footer_and_appears_only_when_finished() {
        let dir = std::env::temp_dir().join(format!("harvemu-record-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.asc");
        let (mut feed, trace) = create(&path, None, Epoch::UNIX).unwrap();
        let frame = bus::candump::parse_frame("0601F5D0#200D0002FFBFFF00").unwrap();
        let record = Record {
            at: bus::time::BusTime::from_millis(1000),
            bus: "harv0",
            source: bus::trace::Source::Bus,
            kind: bus::trace::Kind::Frame(frame),
        };
        feed.record(&record).unwrap();
        assert!(!path.exists(), "not there before it is complete");
        trace.finish(Some(Signal::Term)).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.last(), Some(&"End TriggerBlock"), "{text}");
        assert!(
            lines[lines.len() - 2].starts_with("// harvemu: interrupted by SIGTERM"),
            "{text}"
        );
        assert!(text.contains("0601F5D0x"), "{text}");
        assert!(feed.record(&record).is_err(), "nothing after the end");
    }
}
