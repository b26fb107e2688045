//! A bridge between the hub and a SocketCAN interface (vcan0, can0): the emulated nodes' frames
//! go out on the interface, and frames from real devices on it come in to the emulated nodes
//! through their acceptance filters.
//!
//! The hub still schedules and times the emulated nodes (in real time); the bridge is one more
//! controller on its bus. Frames read from the interface are submitted through that controller
//! the moment they arrive; what the emulated nodes send is written to the interface as it ends on
//! the emulated bus. The socket does not receive its own frames, so nothing loops. Error frames
//! the interface reports are logged and counted.

use crate::Error;
use crate::hub::{Attach, Hub, Submit, Subscribe};
use actix::Addr;
use bus::engine::{ControllerConfig, Filter};
use bus::{Frame, Id};
use socketcan::embedded_can::Frame as _;
use socketcan::{CanFrame, SocketOptions};
use std::cell::RefCell;
use std::rc::Rc;
use tokio::sync::mpsc;

/// Counters of a running bridge.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BridgeStats {
    /// Frames read from the interface and put on the emulated bus.
    pub received: u64,
    /// Frames of the emulated nodes written to the interface.
    pub sent: u64,
    /// Error frames the interface reported.
    pub error_frames: u64,
    /// Frames that could not be written (interface down, buffer full).
    pub write_errors: u64,
    /// Frames received with a kernel timestamp.
    pub kernel_stamped: u64,
    /// Longest time a frame waited between its kernel timestamp and the bridge, µs.
    pub max_wait_us: u64,
}

/// A running bridge.
pub struct Bridge {
    stats: Rc<RefCell<BridgeStats>>,
}

impl Bridge {
    /// Its counters.
    pub fn stats(&self) -> BridgeStats {
        self.stats.borrow().clone()
    }
}

/// Explains why an interface cannot be opened, in the user's terms.
fn open_error(iface: &str, e: std::io::Error) -> Error {
    let hint = open_hint(iface, e.raw_os_error());
    Error::Interface {
        iface: iface.to_string(),
        hint,
        source: e,
    }
}

/// What to do about errno `code` when opening `iface`. A virtual interface (`vcan*`) is made
/// with `ip link add`; a real one (can0) comes with its controller's driver and needs a bitrate,
/// so it is never told to become a vcan.
fn open_hint(iface: &str, code: Option<i32>) -> String {
    let virtual_iface = iface.starts_with("vcan");
    match code {
        Some(97) => " (this kernel has no CAN support: load the can and can-raw modules, or run inside a VM)".into(),
        Some(19) if virtual_iface => format!(
            " (no such interface: create it, e.g. `ip link add dev {iface} type vcan && ip link set {iface} up`)"
        ),
        Some(19) => " (no such interface: `ip -details link show type can` lists this machine's CAN interfaces; a controller's interface appears once its driver is loaded)".into(),
        Some(100) if virtual_iface => format!(" (the interface is down: `ip link set {iface} up`)"),
        Some(100) => format!(" (the interface is down: `ip link set {iface} up type can bitrate 250000`)"),
        _ => String::new(),
    }
}

fn to_socketcan(f: &Frame) -> Option<CanFrame> {
    if f.is_remote() {
        CanFrame::new_remote(f.id(), usize::from(f.dlc()))
    } else {
        CanFrame::new(f.id(), f.data())
    }
}

fn from_socketcan(f: &CanFrame) -> Option<Frame> {
    let id: Id = f.id();
    if f.is_remote_frame() {
        Frame::new_remote(id, f.dlc()).ok()
    } else {
        Frame::new_data(id, f.data()).ok()
    }
}

/// Checks that `iface` can be opened, before anything is started.
pub fn check(iface: &str) -> Result<(), Error> {
    <socketcan::CanSocket as socketcan::Socket>::open(iface)
        .map(drop)
        .map_err(|e| open_error(iface, e))
}

/// Opens `iface` and bridges it to `hub`. Must run inside the actor system.
pub async fn bridge(hub: Addr<Hub>, iface: &str) -> Result<Bridge, Error> {
    let socket = socketcan::tokio::CanSocket::open(iface).map_err(|e| open_error(iface, e))?;
    // Error frames of every class, so that bus errors on the real bus are seen.
    socket
        .set_error_filter_accept_all()
        .map_err(|e| open_error(iface, e))?;
    // The kernel stamps each frame as it arrives (SO_TIMESTAMPNS): the statistics then say how
    // long frames waited before the bridge read them. Without it no frame carries a stamp.
    socket
        .set_recv_timestamp(true)
        .map_err(|e| open_error(iface, e))?;
    let socket = Rc::new(socket);
    let controller = ControllerConfig {
        tx_queue_len: 256,
        ..ControllerConfig::named(iface)
    }
    .with_filter(Filter::Nothing);
    let node = hub
        .send(Attach {
            controller,
            node: None,
            reaction: std::time::Duration::ZERO,
        })
        .await?;
    let (tx, mut rx) = mpsc::channel(4096);
    hub.send(Subscribe(tx)).await?;
    let stats = Rc::new(RefCell::new(BridgeStats::default()));

    let (out, st) = (socket.clone(), stats.clone());
    actix::spawn(async move {
        while let Some(o) = rx.recv().await {
            if o.node == node {
                continue; // came from the interface: it is already there
            }
            let Some(frame) = to_socketcan(&o.frame) else {
                continue;
            };
            match out.write_frame(frame).await {
                Ok(()) => st.borrow_mut().sent += 1,
                Err(e) => {
                    let mut s = st.borrow_mut();
                    s.write_errors += 1;
                    if s.write_errors.is_power_of_two() {
                        tracing::warn!(error = %e, "writing to the CAN interface failed");
                    }
                }
            }
        }
    });

    let (input, st) = (socket, stats.clone());
    let name = iface.to_string();
    actix::spawn(async move {
        let mut failures = 0u32;
        loop {
            // Frames enter the emulated bus at once, so their bus time is their arrival; the
            // kernel's receive time goes to the log and the latency statistics.
            match input.read_frame_with_timestamps().await {
                Ok((CanFrame::Error(e), at)) => {
                    failures = 0;
                    st.borrow_mut().error_frames += 1;
                    tracing::warn!(iface = %name, error = ?e, kernel_time = ?at.socket, "error frame on the interface");
                }
                Ok((f, at)) => {
                    failures = 0;
                    if let Some(kernel) = at.socket {
                        // How long the frame waited between the kernel and the bridge.
                        let waited = std::time::SystemTime::now()
                            .duration_since(kernel)
                            .unwrap_or_default();
                        let mut s = st.borrow_mut();
                        s.kernel_stamped += 1;
                        s.max_wait_us = s.max_wait_us.max(waited.as_micros() as u64);
                    }
                    if let Some(frame) = from_socketcan(&f) {
                        st.borrow_mut().received += 1;
                        let _ = hub.send(Submit { node, frame }).await;
                    }
                }
                Err(e) => {
                    // One odd read must not cut off all inbound traffic; a dead interface
                    // fails every time, and then the bridge gives up.
                    failures += 1;
                    tracing::warn!(iface = %name, error = %e, "reading the CAN interface failed");
                    if failures >= 100 {
                        tracing::error!(iface = %name, "the CAN interface keeps failing; the bridge stops reading");
                        break;
                    }
                }
            }
        }
    });
    Ok(Bridge { stats })
}

#[cfg(test)]
mod tests {
    use super::*;
    use bus::candump::parse_frame;

    #[test]
    fn frames_convert_both_ways() {
        for text in [
            "0601F5D0#200D0002FFBFFF00",
            "123#DEADBEEF",
            "7FF#",
            "123#R",
            "0300A0F5#R8",
        ] {
            let f = parse_frame(text).unwrap();
            let back = from_socketcan(&to_socketcan(&f).unwrap()).unwrap();
            assert_eq!(back, f, "{text}");
        }
    }

    #[test]
    fn hints_fit_the_kind_of_interface() {
        let missing_real = open_hint("can0", Some(19));
        assert!(
            missing_real.contains("ip -details link show type can"),
            "{missing_real}"
        );
        assert!(!missing_real.contains("vcan"), "{missing_real}");
        assert!(open_hint("vcan1", Some(19)).contains("ip link add dev vcan1 type vcan"));
        assert!(open_hint("can1", Some(100)).contains("ip link set can1 up type can bitrate 250000"));
        assert!(open_hint("vcan0", Some(100)).contains("ip link set vcan0 up`"));
        assert!(open_hint("can0", Some(97)).contains("no CAN support"));
        assert_eq!(open_hint("can0", Some(1)), "");
    }

    #[test]
    fn a_kernel_without_can_gets_a_clear_error() {
        // This host's kernel has no AF_CAN; elsewhere there is no such interface. Either way the
        // error says what to do.
        let e = socketcan::tokio::CanSocket::open("harvemu-none");
        let msg = match e {
            Ok(_) => panic!("an interface named harvemu-none exists: nothing to check"),
            Err(e) => {
                let e = open_error("harvemu-none", e);
                let source = std::error::Error::source(&e).map(|s| s.to_string());
                assert!(source.is_some(), "{e}: the io::Error is its source");
                e.to_string()
            }
        };
        assert!(msg.starts_with("cannot open CAN interface harvemu-none"), "{msg}");
        assert!(
            msg.contains("no CAN support")
                || msg.contains("no such interface")
                || msg.contains("No such device"),
            "{msg}"
        );
    }
}
