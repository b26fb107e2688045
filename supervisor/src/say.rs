//! Standard error: harvemu's messages to the person at the terminal (startup lines, warnings,
//! the final error) and its log.
//!
//! Contract: a line that standard error does not take (`2>/dev/full`, a closed pipe) is not a
//! panic: the run goes on, its outputs are written as usual, and [`failed`] says so afterwards,
//! so that `main` can turn a clean exit into exit code 3 (an output failed). Use [`say!`]
//! (`crate::say!`) where `eprintln!` would be, and [`Log`] as the log's writer.

use std::io::{self, Write};
use std::sync::atomic::{AtomicBool, Ordering};

static FAILED: AtomicBool = AtomicBool::new(false);

/// Writes one line to standard error; a failure is remembered, not raised.
pub fn line(args: std::fmt::Arguments<'_>) {
    let mut err = io::stderr().lock();
    if writeln!(err, "{args}").and_then(|()| err.flush()).is_err() {
        FAILED.store(true, Ordering::Relaxed);
    }
}

/// True when standard error refused something written to it.
pub fn failed() -> bool {
    FAILED.load(Ordering::Relaxed)
}

/// Remembers that standard error (or standard output, for what clap prints) refused a write.
pub fn refused() {
    FAILED.store(true, Ordering::Relaxed);
}

/// `eprintln!` that does not panic: see the module contract.
#[macro_export]
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::say::line(format_args!($($arg)*))
    };
}

/// The log's writer: standard error, with failures remembered as [`line`]'s are.
#[derive(Clone, Copy, Debug, Default)]
pub struct Log;

/// One write to the log.
pub struct LogWriter(io::Stderr);

impl Write for LogWriter {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0.write(buf).inspect_err(|_| refused())
    }
    fn flush(&mut self) -> io::Result<()> {
        self.0.flush().inspect_err(|_| refused())
    }
}

impl<'a> tracing_subscriber::fmt::MakeWriter<'a> for Log {
    type Writer = LogWriter;
    fn make_writer(&'a self) -> LogWriter {
        LogWriter(io::stderr())
    }
}
