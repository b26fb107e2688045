//! `--realtime`: what keeps a real-time run from stalling on a bench machine, and the line that
//! reports real-time overruns at the end of a run.
//!
//! Contract: [`enter`] asks the kernel for the `SCHED_FIFO` policy at [`PRIORITY`] for the calling
//! thread (threads it starts afterwards, such as the hub's wall timer, inherit it) and locks the
//! process's memory (`mlockall(MCL_CURRENT | MCL_FUTURE)`), so that neither other processes nor
//! page faults hold the emulated bus up. Either may be refused (no `CAP_SYS_NICE` or `RLIMIT_RTPRIO`,
//! no `CAP_IPC_LOCK` or a small `RLIMIT_MEMLOCK`): the run goes on at normal priority, and each
//! refusal is one warning line that says what to grant. Call it before the runtime is built.

use bus_runtime::hub::Snapshot;

/// The `SCHED_FIFO` priority asked for: above every normal process, below the kernel's threaded
/// interrupt handlers (50), so the CAN controller's interrupts still come first.
pub const PRIORITY: i32 = 40;

/// Switches to real-time scheduling and locks memory; returns the lines to print (what was set,
/// or a warning per refusal).
pub fn enter() -> Vec<String> {
    describe(set_fifo(PRIORITY), lock_memory())
}

/// The lines about the outcome of the two requests.
pub fn describe(fifo: std::io::Result<()>, lock: std::io::Result<()>) -> Vec<String> {
    let refused = |e: &std::io::Error| e.kind() == std::io::ErrorKind::PermissionDenied;
    let mut lines = Vec::new();
    match &fifo {
        Ok(()) => lines.push(format!("harvemu: real-time scheduling: SCHED_FIFO priority {PRIORITY}")),
        Err(e) if refused(e) => lines.push(format!(
            "harvemu: warning: --realtime: SCHED_FIFO priority {PRIORITY} not permitted ({e}); running at normal priority. Run as root, grant CAP_SYS_NICE (setcap cap_sys_nice+ep), or raise RLIMIT_RTPRIO (`ulimit -r {PRIORITY}`, rtprio in /etc/security/limits.conf)"
        )),
        Err(e) => lines.push(format!(
            "harvemu: warning: --realtime: cannot set SCHED_FIFO priority {PRIORITY} ({e}); running at normal priority"
        )),
    }
    match &lock {
        Ok(()) => lines.push("harvemu: real-time scheduling: memory locked (mlockall)".to_string()),
        Err(e) if refused(e) || e.raw_os_error() == Some(12) => lines.push(format!(
            "harvemu: warning: --realtime: cannot lock memory ({e}); pages may be swapped out. Run as root, grant CAP_IPC_LOCK, or raise RLIMIT_MEMLOCK (`ulimit -l unlimited`, memlock in /etc/security/limits.conf)"
        )),
        Err(e) => lines.push(format!("harvemu: warning: --realtime: cannot lock memory ({e})")),
    }
    lines
}

#[cfg(target_os = "linux")]
fn set_fifo(priority: i32) -> std::io::Result<()> {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: plain system call on the calling thread with a valid, initialised parameter.
    let r = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if r == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

#[cfg(target_os = "linux")]
fn lock_memory() -> std::io::Result<()> {
    // SAFETY: plain system call with constant flags.
    let r = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
    if r == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

#[cfg(not(target_os = "linux"))]
fn set_fifo(_: i32) -> std::io::Result<()> {
    Err(std::io::Error::other("only on Linux"))
}

#[cfg(not(target_os = "linux"))]
fn lock_memory() -> std::io::Result<()> {
    Err(std::io::Error::other("only on Linux"))
}

/// The closing line about real-time overruns, when there were any: how many, how far bus time is
/// behind the wall clock, the longest stall.
pub fn overruns_line(s: &Snapshot) -> Option<String> {
    let o = s.overruns;
    (o.count > 0).then(|| {
        format!(
            "harvemu: real time: {} overruns, bus time {:.3} s behind the wall clock (longest {} ms)",
            o.count,
            o.slipped_ns as f64 / 1e9,
            o.longest_ns / 1_000_000
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{Error, ErrorKind};

    #[test]
    fn refusals_say_what_to_grant() {
        let lines = describe(
            Err(Error::from(ErrorKind::PermissionDenied)),
            Err(Error::from_raw_os_error(12)),
        );
        assert_eq!(lines.len(), 2);
        assert!(
            lines[0].contains("warning") && lines[0].contains("CAP_SYS_NICE"),
            "{}",
            lines[0]
        );
        assert!(
            lines[1].contains("warning") && lines[1].contains("RLIMIT_MEMLOCK"),
            "{}",
            lines[1]
        );
        let ok = describe(Ok(()), Ok(()));
        assert_eq!(
            ok,
            [
                "harvemu: real-time scheduling: SCHED_FIFO priority 40",
                "harvemu: real-time scheduling: memory locked (mlockall)"
            ]
        );
    }
}
