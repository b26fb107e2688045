//! Stopping a run from outside: SIGINT (Ctrl-C), SIGTERM and SIGHUP.
//!
//! Contract: after [`install`] (the first thing `run`, `replay`, `scenario` and `soak` do), each
//! of the three signals is recorded instead of killing the process, whenever it arrives: the
//! first one received is [`received`], and a [`Stop`] made at any later time answers it at once.
//! A run awaits [`Stop::wait`] beside its work, stops where it is, finishes its outputs (saying
//! it was interrupted) and exits with 128 + the signal's number. The other commands keep the
//! signals' default (they end the process). [`ignore_file_size_limit`] (every command) ignores
//! SIGXFSZ, so that a write past the file-size limit fails with an error that names the file
//! instead of killing the process.

use std::sync::atomic::{AtomicI32, Ordering};
use tokio::signal::unix::{SignalKind, signal};

/// A signal that stops a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Signal {
    /// SIGINT: Ctrl-C in a terminal.
    Int,
    /// SIGTERM: `kill`, a service manager, a CI job's timeout.
    Term,
    /// SIGHUP: the terminal went away.
    Hup,
}

impl Signal {
    fn number(self) -> i32 {
        match self {
            Signal::Int => libc::SIGINT,
            Signal::Term => libc::SIGTERM,
            Signal::Hup => libc::SIGHUP,
        }
    }

    fn from_number(n: i32) -> Option<Signal> {
        [Signal::Int, Signal::Term, Signal::Hup]
            .into_iter()
            .find(|s| s.number() == n)
    }

    /// The exit code of a run it stopped: 128 + its number, as a shell reports it.
    pub fn exit_code(self) -> u8 {
        match self {
            Signal::Int => 130,
            Signal::Term => 143,
            Signal::Hup => 129,
        }
    }

    /// Its name, with what it usually means.
    pub fn describe(self) -> &'static str {
        match self {
            Signal::Int => "SIGINT (Ctrl-C)",
            Signal::Term => "SIGTERM",
            Signal::Hup => "SIGHUP",
        }
    }
}

/// The number of the first stop signal received, 0 before any.
static RECEIVED: AtomicI32 = AtomicI32::new(0);

/// Ignores SIGXFSZ: a write past the file-size limit then fails with EFBIG.
pub fn ignore_file_size_limit() -> std::io::Result<()> {
    // SAFETY: SIG_IGN for SIGXFSZ changes no handler Rust code relies on.
    if unsafe { libc::signal(libc::SIGXFSZ, libc::SIG_IGN) } == libc::SIG_ERR {
        return Err(std::io::Error::last_os_error());
    }
    Ok(())
}

/// Records the stop signals from now on.
pub fn install() -> std::io::Result<()> {
    for s in [Signal::Int, Signal::Term, Signal::Hup] {
        let n = s.number();
        // SAFETY: the action only stores into an atomic, which is async-signal-safe.
        unsafe {
            signal_hook_registry::register(n, move || {
                let _ = RECEIVED.compare_exchange(0, n, Ordering::SeqCst, Ordering::SeqCst);
            })?;
        }
    }
    Ok(())
}

/// The first stop signal received so far.
pub fn received() -> Option<Signal> {
    Signal::from_number(RECEIVED.load(Ordering::SeqCst))
}

/// Waits for a stop signal; made inside a tokio runtime.
pub struct Stop {
    int: tokio::signal::unix::Signal,
    term: tokio::signal::unix::Signal,
    hup: tokio::signal::unix::Signal,
}

impl Stop {
    /// Listens from now on (a signal received before is answered by [`Stop::wait`] at once).
    pub fn new() -> std::io::Result<Stop> {
        Ok(Stop {
            int: signal(SignalKind::interrupt())?,
            term: signal(SignalKind::terminate())?,
            hup: signal(SignalKind::hangup())?,
        })
    }

    /// The stop signal, once one has arrived. Cancel-safe: it can be raced against a run step
    /// in `select!` as often as needed.
    pub async fn wait(&mut self) -> Signal {
        loop {
            if let Some(s) = received() {
                return s;
            }
            // Each arrival is also recorded by `install`'s handler, which the next turn reads;
            // without `install` (a test in-process), the arrival itself says which.
            let s = tokio::select! {
                _ = self.int.recv() => Signal::Int,
                _ = self.term.recv() => Signal::Term,
                _ = self.hup.recv() => Signal::Hup,
            };
            let _ = RECEIVED.compare_exchange(0, s.number(), Ordering::SeqCst, Ordering::SeqCst);
        }
    }
}
