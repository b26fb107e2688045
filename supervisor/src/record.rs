//! `--record FILE`: where the hub's trace goes.
//!
//! Contract: a file whose name ends in `.asc` (any case) gets Vector ASC, one ending in
//! `.pcapng` a pcapng capture (LINKTYPE_CAN_SOCKETCAN, an interface per controller), any other
//! file a candump log, all written from the hub's trace records ([`bus::trace`]). [`create`] gives the
//! hub its sink ([`Feed`]) and the caller the
//! [`Trace`], which [`Trace::finish`] ends once the run is over: for ASC a comment line when the
//! run was interrupted, then the `End TriggerBlock` footer; then the file is put in place whole
//! ([`crate::output`]: a regular file is replaced only by a complete trace, a stream ends on a
//! whole line). The first write that fails stops the trace; `finish` reports it, naming the file.
//! A file that cannot be created is an [`crate::Error::Output`] naming it.
//!
//! Timestamps: a candump log has bus time stamped with the run's [`Epoch`] ([`epoch`] picks it:
//! `--start-time`, else the wall clock at the start of a real-time run, else
//! [`Epoch::FIXED`]); an ASC file is dated at that epoch and its times count from it.

use crate::output::{Output, failed};
use crate::stop::Signal;
use bus::time::Epoch;
use bus::trace::{CandumpWriter, Record, Sink};
use bus::tracefile::{AscWriter, PcapngWriter};
use std::cell::RefCell;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::rc::Rc;

/// True when `path` names an ASC file.
pub fn is_asc(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("asc"))
}

/// True when `path` names a pcapng file.
pub fn is_pcapng(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("pcapng"))
}

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

enum Format {
    Log(CandumpWriter<Shared>),
    Asc(AscWriter<Shared>),
    Pcapng(PcapngWriter<Shared>),
}

struct State {
    format: Option<Format>,
    /// Taken out by [`Trace::finish`].
    out: Option<Shared>,
    /// The first write that failed.
    error: Option<io::Error>,
}

/// The sink the hub hands its records to.
pub struct Feed(Rc<RefCell<State>>);

impl Feed {
    fn guard<T>(&mut self, op: impl FnOnce(&mut State) -> io::Result<T>) -> io::Result<T> {
        let mut s = self.0.borrow_mut();
        if let Some(e) = &s.error {
            return Err(io::Error::new(e.kind(), e.to_string()));
        }
        match op(&mut s) {
            Err(e) => {
                // The trace keeps the first error itself, for `finish`, and hands out copies.
                let copy = io::Error::new(e.kind(), e.to_string());
                s.error = Some(e);
                Err(copy)
            }
            ok => ok,
        }
    }
}

impl Sink for Feed {
    fn record(&mut self, r: &Record<'_>) -> io::Result<()> {
        self.guard(|s| match s.format.as_mut() {
            Some(Format::Log(c)) => c.record(r),
            Some(Format::Asc(a)) => a.record(r),
            Some(Format::Pcapng(p)) => p.record(r),
            None => Err(io::Error::other("the trace has ended")),
        })
    }
    fn flush(&mut self) -> io::Result<()> {
        self.guard(|s| match s.format.as_mut() {
            Some(Format::Log(c)) => c.flush(),
            Some(Format::Asc(a)) => a.flush(),
            Some(Format::Pcapng(p)) => Sink::flush(p),
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

/// Starts the trace file at `path`, in the format its name asks for, for a run whose trace is
/// stamped with `epoch`: the hub's sink and the trace to finish.
pub fn create(path: &Path, epoch: Epoch) -> crate::Result<(Box<dyn Sink>, Trace)> {
    let out = Shared(Rc::new(RefCell::new(Output::create(path)?)));
    let format = if is_asc(path) {
        let asc = AscWriter::new(out.clone(), epoch).map_err(|e| failed("write", path, e))?;
        Format::Asc(asc)
    } else if is_pcapng(path) {
        let pcapng = PcapngWriter::new(out.clone(), epoch).map_err(|e| failed("write", path, e))?;
        Format::Pcapng(pcapng)
    } else {
        Format::Log(CandumpWriter::new(out.clone(), epoch))
    };
    let state = Rc::new(RefCell::new(State {
        format: Some(format),
        out: Some(out),
        error: None,
    }));
    let trace = Trace {
        path: path.to_path_buf(),
        state: state.clone(),
    };
    Ok((Box::new(Feed(state)), trace))
}

/// The hub's sink and the trace to finish, when there is a trace.
pub type Recording = (Option<Box<dyn Sink>>, Option<Trace>);

/// [`create`] for an optional `--record`.
pub fn create_opt(path: Option<&PathBuf>, epoch: Epoch) -> crate::Result<Recording> {
    match path {
        Some(p) => {
            let (w, t) = create(p, epoch)?;
            Ok((Some(w), Some(t)))
        }
        None => Ok((None, None)),
    }
}

impl Trace {
    /// Ends the trace: for ASC an `interrupted` comment when the run was, and the footer; then
    /// the file is flushed and put in place. An error names the file; the file is then left as
    /// it was (a regular file) or ends where writing failed (a stream).
    pub fn finish(self, interrupted: Option<Signal>) -> crate::Result<()> {
        let mut s = self.state.borrow_mut();
        let format = s.format.take();
        let out = s.out.take();
        if let Some(e) = s.error.take() {
            return Err(failed("write", &self.path, e));
        }
        drop(s);
        let Some(mut out) = out else {
            return Ok(());
        };
        // The format's writer holds the output too: it is done with before the output is.
        if let Some(Format::Log(mut log)) = format {
            log.flush().map_err(|e| failed("write", &self.path, e))?;
        } else if let Some(Format::Pcapng(mut pcapng)) = format {
            Sink::flush(&mut pcapng).map_err(|e| failed("write", &self.path, e))?;
        } else if let Some(Format::Asc(mut asc)) = format {
            let mut end = || -> io::Result<()> {
                asc.flush()?;
                if let Some(sig) = interrupted {
                    let note = format!(
                        "// harvemu: interrupted by {}: the measurement ends here\n",
                        sig.describe()
                    );
                    out.write_all(note.as_bytes())?;
                }
                asc.finish()
            };
            end().map_err(|e| failed("write", &self.path, e))?;
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
    fn the_name_picks_the_format() {
        for (name, asc) in [
            ("run.asc", true),
            ("RUN.ASC", true),
            ("dir.asc/run.log", false),
            ("run.log", false),
            ("asc", false),
            ("run.asc.log", false),
        ] {
            assert_eq!(is_asc(Path::new(name)), asc, "{name}");
        }
    }

    #[test]
    fn an_interrupted_asc_says_so_before_its_footer_and_appears_only_when_finished() {
        let dir = std::env::temp_dir().join(format!("harvemu-record-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.asc");
        let (mut feed, trace) = create(&path, Epoch::UNIX).unwrap();
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
