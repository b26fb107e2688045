//! The exit codes of `harvemu`, one meaning each (docs/PROMISES.md has the table).
//!
//! Contract: [`code`] picks one code for how a command ended. A stop signal wins over everything
//! (the run did not end by itself); then an output that failed, then a node that crashed beyond
//! its restart policy, then failed expectations. Bad input stops a command before anything runs,
//! so it meets none of the others.

use crate::stop::Signal;

/// Everything went as asked.
pub const OK: u8 = 0;
/// An expectation of a scenario or soak failed.
pub const EXPECTATIONS_FAILED: u8 = 1;
/// Bad input or usage: arguments, configs, scripts, scenarios, traces to replay.
pub const BAD_INPUT: u8 = 2;
/// An output could not be created or written completely.
pub const OUTPUT_FAILED: u8 = 3;
/// A node crashed more often than its restart policy allows, and stayed down.
pub const NODE_DOWN: u8 = 4;
/// harvemu itself failed (a bug, an actor gone, a runtime that could not start): never the
/// input's fault nor an output's. 70 is EX_SOFTWARE of BSD's sysexits.h.
pub const INTERNAL: u8 = 70;

/// How a command ended, besides an error.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Ended {
    /// Some expectation failed.
    pub expectations_failed: bool,
    /// Some node crashed beyond its restart policy (not by a scenario's own fault injection).
    pub node_down: bool,
}

/// The exit code for a command that returned `result`, with `signal` the stop signal received,
/// if any.
pub fn code(result: &crate::Result<Ended>, signal: Option<Signal>) -> u8 {
    if let Some(s) = signal {
        return s.exit_code();
    }
    match result {
        // Bad input, an output that failed, or the emulator's own failure (an actor gone, a
        // runtime that could not start): the error says which.
        Err(e) => e.exit_code(),
        Ok(e) if e.node_down => NODE_DOWN,
        Ok(e) if e.expectations_failed => EXPECTATIONS_FAILED,
        Ok(_) => OK,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Error;
    use std::io;

    #[test]
    fn each_ending_has_its_code() {
        let ok = |e: Ended| code(&Ok(e), None);
        assert_eq!(ok(Ended::default()), 0);
        let failed = Ended {
            expectations_failed: true,
            node_down: false,
        };
        assert_eq!(ok(failed), 1);
        let down = Ended {
            expectations_failed: true,
            node_down: true,
        };
        assert_eq!(ok(down), 4);
        let err = |e: Error| code(&Err(e), None);
        assert_eq!(err(Error::BadInput("x".into())), 2);
        assert_eq!(err(nodes::Error::Invalid(Vec::new()).into()), 2);
        let missing = || io::Error::from(io::ErrorKind::NotFound);
        let input = Error::Input {
            path: "t.log".into(),
            source: missing(),
        };
        assert_eq!(err(input), 2);
        let output = || Error::Output {
            verb: "write",
            what: "x".into(),
            source: io::Error::from(io::ErrorKind::StorageFull),
        };
        assert_eq!(err(output()), 3);
        // Neither the input's fault nor an output's: not 1, which says an expectation failed.
        assert_eq!(err(Error::Mailbox(actix::MailboxError::Closed)), 70);
        assert_eq!(err(bus_runtime::Error::HubStopped.into()), 70);
        // A trace record later than the reorder window (docs/TRACES.md, "Time order").
        let late = bus::Error::TraceOrder {
            at: bus::time::BusTime::from_micros(1),
            released: bus::time::BusTime::from_micros(2),
            window: bus::time::BusDuration::from_millis(80),
        };
        assert_eq!(err(bus_runtime::Error::Bus(late).into()), 70);
        assert_eq!(err(Error::System(missing())), 70);
        let io: crate::Result<Ended> = Err(output());
        for (s, c) in [(Signal::Int, 130), (Signal::Term, 143), (Signal::Hup, 129)] {
            assert_eq!(code(&io, Some(s)), c);
            assert_eq!(code(&Ok(down), Some(s)), c);
        }
    }
}
