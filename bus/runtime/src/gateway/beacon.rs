//! socketcand's discovery beacon: a UDP datagram to port [`BEACON_PORT`] every
//! [`BEACON_INTERVAL`], an XML `<CANBeacon>` naming the server's address and its bus, which
//! python-can's `detect_beacon` (and Kayak) listen for.
//!
//! socketcand sends it to the broadcast address of the network its server is bound to. harvemu
//! sends it only where that cannot reach another machine: a server bound to a loopback address
//! sends its beacon to that address (a listener on the same machine bound to any address gets
//! it); a server bound to any other address sends none, since the broadcast address of a network
//! needs the interface's netmask, and a server bound to every address belongs to no one network.

use std::net::{IpAddr, SocketAddr};
use std::time::Duration;

/// The port socketcand's beacon goes to (`BROADCAST_PORT`).
pub const BEACON_PORT: u16 = 42000;
/// Time between beacons; socketcand's protocol asks for at most three seconds.
pub const BEACON_INTERVAL: Duration = Duration::from_secs(2);

/// Where the beacon of a server bound to `server` goes: its own address if it is a loopback
/// one, else nowhere.
pub fn target(server: SocketAddr, port: u16) -> Option<SocketAddr> {
    match server.ip() {
        IpAddr::V4(ip) if ip.is_loopback() => Some(SocketAddr::new(server.ip(), port)),
        _ => None,
    }
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace('\'', "&apos;")
}

/// The beacon of a server at `server` serving `bus`, as socketcand's `beacon.c` builds it.
pub fn message(server: SocketAddr, bus: &str) -> String {
    format!(
        "<CANBeacon name=\"harvemu\" type=\"SocketCAN\" description=\"harvemu emulated bus\">\n\
         <URL>can://{}:{}</URL><Bus name=\"{}\"/></CANBeacon>",
        server.ip(),
        server.port(),
        escape(bus)
    )
}

/// Sends the beacon from `server`'s address to `to` for ever.
pub async fn run(server: SocketAddr, to: SocketAddr, bus: String) {
    let socket = match tokio::net::UdpSocket::bind(SocketAddr::new(server.ip(), 0)).await {
        Ok(s) => s,
        Err(e) => {
            tracing::warn!(error = %e, "socketcand beacon: no UDP socket; no beacon");
            return;
        }
    };
    let text = message(server, &bus);
    let mut tick = tokio::time::interval(BEACON_INTERVAL);
    let mut failed = false;
    loop {
        tick.tick().await;
        // Nobody listening is the usual case (a refusal may come back as an error): log once.
        if let Err(e) = socket.send_to(text.as_bytes(), to).await
            && !std::mem::replace(&mut failed, true)
        {
            tracing::debug!(error = %e, %to, "socketcand beacon not sent");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beacons_stay_on_loopback() {
        let at = |s: &str| s.parse::<SocketAddr>().unwrap();
        assert_eq!(target(at("127.0.0.1:29536"), 42000), Some(at("127.0.0.1:42000")));
        assert_eq!(target(at("127.3.2.1:1"), 5), Some(at("127.3.2.1:5")));
        for elsewhere in ["0.0.0.0:29536", "192.168.1.4:29536", "[::1]:29536", "[::]:1"] {
            assert_eq!(target(at(elsewhere), 42000), None, "{elsewhere}");
        }
    }

    #[test]
    fn the_beacon_is_socketcands_xml() {
        let m = message("127.0.0.1:29536".parse().unwrap(), "a\"<b>");
        assert!(
            m.starts_with("<CANBeacon name=\"harvemu\" type=\"SocketCAN\""),
            "{m}"
        );
        assert!(m.contains("<URL>can://127.0.0.1:29536</URL>"), "{m}");
        assert!(m.contains("<Bus name=\"a&quot;&lt;b&gt;\"/>"), "{m}");
        assert!(m.ends_with("</CANBeacon>"), "{m}");
    }
}
