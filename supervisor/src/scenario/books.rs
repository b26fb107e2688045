//! The books of a run: where every frame addressed to the monitor went, and whether the trace
//! holds every frame that completed on the bus.
//!
//! Contract: plain arithmetic over counters the bus engine, the hub and the monitor keep as they
//! run (no I/O, nothing recomputed from frames). A frame addressed to the monitor that completed
//! on the bus is counted in exactly one reason; [`MonitorBooks::checks`] states each identity
//! between two layers (bus, controller, hub, monitor logic) and whether it holds, so an imbalance
//! says where frames went missing. [`TraceTally`] counts the records the hub hands its trace
//! sinks, apart from the engine's statistics, for the check that every completed frame is in the
//! trace.

use bus::engine::{ControllerCounters, NodeId};
use bus::filter::kernel_can_id;
use bus::trace::{Kind, Record};
use bus_runtime::hub::{Handover, Snapshot};
use nodes::monitor::FrameTally;
use protocol::ident::Address;
use serde::Serialize;

/// True when a kernel can_id (extended flag included) is a harvester identifier whose
/// destination byte is the monitor's.
pub fn to_monitor(can_id: u32) -> bool {
    protocol::ident::destination_of_can_id(can_id) == Some(Address::MONITOR)
}

/// The monitor's counters at the end of a run.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct MonitorBooks {
    /// Frames addressed to the monitor that completed on the bus (per-identifier statistics).
    pub on_bus: u64,
    /// Frames whose identifier the statistics did not track one by one (cannot be attributed).
    pub untracked: u64,
    /// The same count from the trace, when one was counted.
    pub in_trace: Option<u64>,
    /// The monitor's controller.
    pub controller: ControllerCounters,
    /// Frames in its receive FIFO at the end.
    pub in_fifo: u64,
    /// What the hub did with the frames it took from the FIFO.
    pub handover: Handover,
    /// What the monitor's logic did with the frames it got.
    pub tally: FrameTally,
}

/// One identity of the books.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Check {
    /// What should be equal.
    pub what: &'static str,
    /// Left side.
    pub left: u64,
    /// Right side.
    pub right: u64,
}

impl Check {
    /// True when both sides agree.
    pub fn holds(&self) -> bool {
        self.left == self.right
    }
}

impl MonitorBooks {
    /// Every frame addressed to the monitor, by what became of it. The first row is the only
    /// one that is not a loss; the sum of all rows is [`MonitorBooks::on_bus`] when the books
    /// balance.
    pub fn reasons(&self) -> Vec<(&'static str, u64)> {
        let (c, h, t) = (&self.controller, &self.handover, &self.tally);
        vec![
            ("processed by the main loop", t.processed),
            ("sent by the monitor itself", c.rx_own),
            ("missed: monitor off the bus (disconnected, bus off)", c.rx_missed),
            ("lost: receive FIFO overrun", c.rx_overruns),
            (
                "lost: an error only the monitor flagged (error passive)",
                c.rx_errored,
            ),
            ("lost: receive FIFO cleared at a restart", c.rx_cleared),
            ("lost: in a wake the logic crashed on", h.crashed),
            ("lost: held for a logic that was replaced", h.dropped_at_replace),
            ("lost: receive queue full", t.queue_full),
            (
                "lost: in the queue of a logic that was replaced",
                t.dropped_at_restart,
            ),
            ("still in the receive FIFO at the end", self.in_fifo),
            ("still held by the hub at the end", h.held),
            ("still in a wake at the end", h.in_flight),
            ("still in the receive queue at the end", t.queued),
        ]
    }

    /// Sum of the reasons.
    pub fn accounted(&self) -> u64 {
        self.reasons().iter().map(|(_, n)| n).sum()
    }

    /// Each layer's identity.
    pub fn checks(&self) -> Vec<Check> {
        let (c, h, t) = (&self.controller, &self.handover, &self.tally);
        let mut v = vec![
            Check {
                what: "on the bus = accounted for",
                left: self.on_bus,
                right: self.accounted(),
            },
            Check {
                what: "on the bus = own + missed + overrun + errored + stored (controller)",
                left: self.on_bus,
                right: c.rx_own + c.rx_missed + c.rx_overruns + c.rx_errored + c.rx_frames,
            },
            Check {
                what: "stored = read + cleared + in FIFO (controller)",
                left: c.rx_frames,
                right: c.rx_read + c.rx_cleared + self.in_fifo,
            },
            Check {
                what: "read = handled + crashed + dropped + held + in a wake (hub)",
                left: c.rx_read,
                right: h.handled + h.crashed + h.dropped_at_replace + h.held + h.in_flight,
            },
            Check {
                what: "handled by the hub = received by the interrupt (monitor)",
                left: h.handled,
                right: t.received,
            },
            Check {
                what: "received = processed + queue full + queued + dropped (monitor)",
                left: t.received,
                right: t.processed + t.queue_full + t.queued + t.dropped_at_restart,
            },
            Check {
                what: "frames of untracked identifiers",
                left: self.untracked,
                right: 0,
            },
        ];
        if let Some(n) = self.in_trace {
            v.push(Check {
                what: "on the bus = addressed to the monitor in the trace",
                left: self.on_bus,
                right: n,
            });
        }
        v
    }

    /// True when every identity holds.
    pub fn balance(&self) -> bool {
        self.checks().iter().all(Check::holds)
    }

    /// The table the soak prints.
    pub fn table(&self) -> String {
        let mut s = format!(
            "{:>12}  frames addressed to F5 that completed on the bus\n",
            self.on_bus
        );
        for (what, n) in self.reasons() {
            s += &format!("{n:>12}  {what}\n");
        }
        s += &format!("{:>12}  accounted for\n", self.accounted());
        for c in self.checks() {
            let mark = if c.holds() { "ok  " } else { "FAIL" };
            s += &format!("  {mark} {}: {} vs {}\n", c.what, c.left, c.right);
        }
        s
    }
}

/// The books of a whole run.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Books {
    /// Frames that completed on the bus (the engine's statistics).
    pub frames: u64,
    /// Error frames on the bus.
    pub error_frames: u64,
    /// The trace's lines, when they were counted.
    pub trace: Option<TraceTally>,
    /// The monitor's books, when the monitor is emulated.
    pub monitor: Option<MonitorBooks>,
}

impl Books {
    /// Gathers the books from the hub's last snapshot, the monitor's node and tally, and the
    /// trace's count.
    pub fn gather(
        snap: &Snapshot,
        monitor: Option<(NodeId, FrameTally)>,
        trace: Option<TraceTally>,
    ) -> Books {
        let monitor = monitor.and_then(|(id, tally)| {
            let node = snap.nodes.get(id.index())?;
            let on_bus = snap
                .stats
                .per_id
                .iter()
                .filter(|(id, _)| to_monitor(**id))
                .map(|(_, s)| s.count)
                .sum();
            Some(MonitorBooks {
                on_bus,
                untracked: snap.stats.untracked_frames,
                in_trace: trace.map(|t| t.to_monitor),
                controller: node.counters,
                in_fifo: node.rx_queued,
                handover: node.handover,
                tally,
            })
        });
        Books {
            frames: snap.stats.frames,
            error_frames: snap.stats.error_frames,
            trace,
            monitor,
        }
    }

    /// The trace holds as many frame records as frames completed on the bus (None when the trace
    /// was not counted).
    pub fn trace_complete(&self) -> Option<bool> {
        self.trace.map(|t| t.frames == self.frames)
    }
}

/// The trace's records, counted as the hub hands them over.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct TraceTally {
    /// Data and remote frames.
    pub frames: u64,
    /// Of those, addressed to the monitor.
    pub to_monitor: u64,
    /// Error frames (each controller's, as it reported them).
    pub error_frames: u64,
}

impl TraceTally {
    /// Counts one record.
    pub fn record(&mut self, r: &Record<'_>) {
        match &r.kind {
            Kind::Frame(frame) => {
                self.frames += 1;
                self.to_monitor += u64::from(to_monitor(kernel_can_id(frame)));
            }
            Kind::Error(_) => self.error_frames += 1,
        }
    }
}

#[cfg(test)]
mod tests;
