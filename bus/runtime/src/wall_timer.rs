//! A wall-clock timer for paced hubs.
//!
//! tokio's timers resolve whole milliseconds (a deadline is rounded up to the next tick of its
//! wheel, and the driver sleeps in milliseconds), so a hub paced by them lets frames out up to a
//! millisecond or two off their bus time. A thread that waits on a channel with a timeout sleeps
//! on the kernel's high-resolution timers instead and wakes within tens of microseconds.
//!
//! Contract: [`WallTimer::set`] replaces the one pending deadline; when it passes, the timer calls
//! `fire` with that deadline's id, on its own thread. The thread ends when the `WallTimer` is
//! dropped.

use std::sync::mpsc::{self, RecvTimeoutError, Sender};
use std::time::Instant;

/// The handle of a timer thread.
pub(crate) struct WallTimer {
    tx: Sender<(u64, Instant)>,
}

impl WallTimer {
    /// Starts the thread.
    pub(crate) fn start(fire: impl Fn(u64) + Send + 'static) -> std::io::Result<WallTimer> {
        let (tx, rx) = mpsc::channel::<(u64, Instant)>();
        std::thread::Builder::new()
            .name("harvemu-wall-timer".into())
            .spawn(move || {
                let mut pending: Option<(u64, Instant)> = None;
                loop {
                    let next = match pending {
                        None => match rx.recv() {
                            Ok(p) => p,
                            Err(_) => return,
                        },
                        Some((id, at)) => {
                            let now = Instant::now();
                            let result = if now >= at {
                                Err(RecvTimeoutError::Timeout)
                            } else {
                                rx.recv_timeout(at - now)
                            };
                            match result {
                                Ok(p) => p,
                                Err(RecvTimeoutError::Timeout) => {
                                    fire(id);
                                    pending = None;
                                    continue;
                                }
                                Err(RecvTimeoutError::Disconnected) => return,
                            }
                        }
                    };
                    pending = Some(next);
                }
            })?;
        Ok(WallTimer { tx })
    }

    /// Sets the deadline (replacing any pending one); false when the thread is gone.
    pub(crate) fn set(&self, id: u64, at: Instant) -> bool {
        self.tx.send((id, at)).is_ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc::channel;
    use std::time::Duration;

    #[test]
    fn a_later_deadline_replaces_the_pending_one_and_fires_once() {
        let (tx, rx) = channel();
        let timer = WallTimer::start(move |id| {
            let _ = tx.send((id, Instant::now()));
        })
        .unwrap();
        let t0 = Instant::now();
        assert!(timer.set(1, t0 + Duration::from_millis(30)));
        assert!(timer.set(2, t0 + Duration::from_millis(5)));
        let (id, at) = rx.recv_timeout(Duration::from_secs(5)).unwrap();
        assert_eq!(id, 2);
        assert!(at >= t0 + Duration::from_millis(5), "never early");
        // Deadline 1 was replaced: nothing else fires.
        assert!(rx.recv_timeout(Duration::from_millis(60)).is_err());
        drop(timer);
    }
}
