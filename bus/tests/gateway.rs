//! The socketcand gateway against clients written here, on loopback, in real time.

mod common;

use actix::prelude::*;
use bus::engine::ControllerConfig;
use bus::gateway::{Gateway, GatewayConfig};
use bus::hub::{Attach, Hub, HubConfig, RunUntil, runtime};
use bus::node::NodeActor;
use bus::time::BusTime;
use common::Periodic;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

async fn bus_with_ticker(period_us: u64) -> (Addr<Hub>, Gateway) {
    let hub = Hub::new(HubConfig::default(), None).unwrap().start();
    let logic = Periodic::every_us("0601F5D0#200D0002FFBFFF00", period_us, 0);
    let node = NodeActor::new("ticker", Box::new(logic)).start();
    hub.send(Attach {
        controller: ControllerConfig::named("ticker"),
        node: Some(node.recipient()),
        reaction: Duration::ZERO,
    })
    .await
    .unwrap();
    // Someone must acknowledge the gateway's and the ticker's frames.
    hub.send(Attach {
        controller: ControllerConfig::named("listener"),
        node: None,
        reaction: Duration::ZERO,
    })
    .await
    .unwrap();
    let gateway = Gateway::start(
        hub.clone(),
        "127.0.0.1:0".parse().unwrap(),
        GatewayConfig::default(),
    )
    .await
    .unwrap();
    hub.do_send(RunUntil(BusTime::NEVER));
    (hub, gateway)
}

/// A client connection that keeps what it read past the last message.
struct Conn {
    s: TcpStream,
    pending: String,
}

impl Conn {
    /// The next `n` messages.
    async fn read(&mut self, n: usize) -> Vec<String> {
        let mut out = Vec::new();
        let mut buf = [0u8; 4096];
        while out.len() < n {
            if let Some(end) = self.pending.find('>') {
                let m: String = self.pending.drain(..=end).collect();
                out.push(m.trim().to_string());
                continue;
            }
            let k = tokio::time::timeout(Duration::from_secs(10), self.s.read(&mut buf))
                .await
                .expect("no answer")
                .unwrap();
            assert!(k > 0, "closed after {out:?}");
            self.pending.push_str(&String::from_utf8_lossy(&buf[..k]));
        }
        out
    }
    async fn write(&mut self, bytes: &[u8]) {
        self.s.write_all(bytes).await.unwrap();
    }
}

async fn connect(addr: std::net::SocketAddr, recv_buffer: Option<u32>) -> Conn {
    let socket = tokio::net::TcpSocket::new_v4().unwrap();
    if let Some(size) = recv_buffer {
        socket.set_recv_buffer_size(size).unwrap();
    }
    Conn {
        s: socket.connect(addr).await.unwrap(),
        pending: String::new(),
    }
}

async fn handshake_with(addr: std::net::SocketAddr, recv_buffer: Option<u32>) -> Conn {
    let mut c = connect(addr, recv_buffer).await;
    assert_eq!(c.read(1).await, ["< hi >"]);
    c.write(b"< open harv0 >").await;
    assert_eq!(c.read(1).await, ["< ok >"]);
    c.write(b"< rawmode >").await;
    assert_eq!(c.read(1).await, ["< ok >"]);
    c
}

async fn handshake(addr: std::net::SocketAddr) -> Conn {
    handshake_with(addr, None).await
}

fn in_real_time<F: Future>(f: F) -> F::Output {
    System::with_tokio_rt(|| runtime(false).unwrap()).block_on(f)
}

#[test]
fn handshake_stream_and_send() {
    in_real_time(async {
        let (_hub, gw) = bus_with_ticker(10_000).await;
        let mut a = handshake(gw.addr).await;
        let mut b = handshake(gw.addr).await;
        let frames = a.read(3).await;
        for f in &frames {
            let words: Vec<&str> = f.split_whitespace().collect();
            assert_eq!(
                (words[0], words[1], words[2], words[4], words[5]),
                ("<", "frame", "0601F5D0", "200D0002FFBFFF00", ">"),
                "{f}"
            );
            assert!(words[3].parse::<f64>().is_ok(), "{f}");
        }
        a.write(b"< send 123 2 AB CD >").await;
        // b sees a's frame among the ticker's; a does not get its own back.
        let mut seen = false;
        for _ in 0..50 {
            if b.read(1)
                .await
                .iter()
                .any(|m| m.starts_with("< frame 123 ") && m.ends_with(" ABCD >"))
            {
                seen = true;
                break;
            }
        }
        assert!(seen);
        let own = a.read(20).await;
        assert!(own.iter().all(|m| !m.contains("frame 123 ")), "{own:?}");
        assert_eq!(gw.stats().sent, 1);
    });
}

#[test]
fn garbage_and_oversized_input_get_errors_not_a_panic() {
    in_real_time(async {
        let (_hub, gw) = bus_with_ticker(1_000_000).await;
        let mut s = connect(gw.addr, None).await;
        s.read(1).await;
        s.write(b"< rawmode >").await;
        assert!(s.read(1).await[0].starts_with("< error open a bus first"));
        s.write(b"< open can9 >").await;
        assert!(s.read(1).await[0].starts_with("< error no bus 'can9'"));
        s.write(b"< open harv0 >").await;
        assert_eq!(s.read(1).await, ["< ok >"]);
        for bad in [
            &b"hello"[..],
            b"< send 123 9 1 2 >",
            b"< bcmmode >",
            b"< send XYZ 0 >",
            b"< \xff >",
        ] {
            s.write(bad).await;
            let m = s.read(1).await;
            assert!(m[0].starts_with("< error "), "{bad:?}: {m:?}");
        }
        let mut long = vec![b'<'];
        long.extend(std::iter::repeat_n(b'a', 100_000));
        long.extend(b"> < echo >");
        s.write(&long).await;
        let m = s.read(2).await;
        assert!(m[0].contains("longer than 256"), "{m:?}");
        assert_eq!(m[1], "< echo >", "the connection goes on");
        // Five bad messages and one too long (refusals of the protocol order are answers, not errors).
        assert_eq!(gw.stats().errors, 6);
    });
}

#[test]
fn a_hundred_clients_at_once() {
    in_real_time(async {
        let (_hub, gw) = bus_with_ticker(5_000).await;
        let mut clients = Vec::new();
        for _ in 0..100 {
            clients.push(handshake(gw.addr).await);
        }
        assert_eq!(gw.stats().clients, 100);
        for c in &mut clients {
            let m = c.read(2).await;
            assert!(m.iter().all(|x| x.starts_with("< frame 0601F5D0 ")), "{m:?}");
        }
        drop(clients);
        for _ in 0..100 {
            if gw.stats().clients == 0 {
                break;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        assert_eq!(gw.stats().clients, 0, "closed connections are forgotten");
    });
}

#[test]
fn a_client_that_never_reads_cannot_stall_the_bus() {
    in_real_time(async {
        // A frame every 600 us: about as fast as the bus goes.
        let (hub, gw) = bus_with_ticker(600).await;
        let _silent = handshake_with(gw.addr, Some(4096)).await;
        let mut live = handshake(gw.addr).await;
        let before = hub.send(bus::hub::GetSnapshot).await.unwrap().stats.frames;
        let mut got = 0;
        let start = std::time::Instant::now();
        while start.elapsed() < Duration::from_secs(3) {
            got += live.read(100).await.len();
        }
        let after = hub.send(bus::hub::GetSnapshot).await.unwrap().stats.frames;
        // The bus kept going and the live client kept receiving...
        assert!(after - before > 1000, "{before} -> {after}");
        assert!(got > 1000, "{got}");
        // ...while the silent one's queue overflowed and its frames were dropped and counted.
        assert!(gw.stats().dropped > 0, "{:?}", gw.stats());
    });
}

/// Time this process has run on a CPU, read from `stat`, an open `/proc/self/stat` (reading it
/// anew needs no descriptor, so it works when they have run out).
#[cfg(target_os = "linux")]
fn cpu_time(stat: &std::fs::File) -> Duration {
    use std::os::unix::fs::FileExt;
    let mut buf = [0u8; 1024];
    let n = stat.read_at(&mut buf, 0).unwrap();
    let text = String::from_utf8_lossy(&buf[..n]);
    // The fields after the command name, which is in parentheses: utime and stime are the
    // 14th and 15th of the line, in clock ticks of 1/100 s.
    let fields: Vec<&str> = text[text.rfind(')').unwrap() + 1..].split_whitespace().collect();
    let ticks: u64 = fields[11].parse::<u64>().unwrap() + fields[12].parse::<u64>().unwrap();
    Duration::from_millis(ticks * 10)
}

/// With no file descriptor left, `accept` fails while the connection waits in the listen
/// queue, so the listener stays ready. The gateway must wait between attempts instead of
/// spinning, go on serving its clients, and accept again once descriptors are free.
///
/// The test runs in a child process of this test binary with a low descriptor limit, so that
/// running out of them does not disturb the tests running alongside.
#[cfg(target_os = "linux")]
#[test]
fn out_of_file_descriptors_the_gateway_backs_off_and_serves_on() {
    const CHILD: &str = "BUS_GATEWAY_TEST_FD_CHILD";
    const NAME: &str = "out_of_file_descriptors_the_gateway_backs_off_and_serves_on";
    if std::env::var_os(CHILD).is_none() {
        let out = std::process::Command::new("sh")
            .args(["-c", "ulimit -n 128 && exec \"$0\" \"$@\""])
            .arg(std::env::current_exe().unwrap())
            .args([NAME, "--exact", "--test-threads=1"])
            .env(CHILD, "1")
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stdout}\n{stderr}");
        assert!(stdout.contains("1 passed"), "{stdout}\n{stderr}");
        return;
    }
    in_real_time(async {
        let (_hub, gw) = bus_with_ticker(10_000).await;
        let mut old = handshake(gw.addr).await;
        old.read(2).await;
        let stat = std::fs::File::open("/proc/self/stat").unwrap();

        // Take every descriptor but one, and connect with that one: the gateway cannot accept.
        let mut hog = Vec::new();
        while let Ok(f) = std::fs::File::open("/dev/null") {
            hog.push(f);
        }
        assert!(hog.len() > 10, "{} descriptors taken", hog.len());
        hog.pop();
        let pending = tokio::net::TcpStream::connect(gw.addr).await.unwrap();
        assert!(std::fs::File::open("/dev/null").is_err(), "no descriptor left");
        for _ in 0..200 {
            if gw.stats().accept_errors > 0 {
                break;
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        assert!(gw.stats().accept_errors > 0, "{:?}", gw.stats());

        // For a second, the connected client goes on receiving frames, and the process
        // (the gateway, the bus and this client) stays nearly idle.
        let (cpu_before, errors_before) = (cpu_time(&stat), gw.stats().accept_errors);
        let start = std::time::Instant::now();
        let mut got = 0;
        while start.elapsed() < Duration::from_secs(1) {
            let frames = old.read(10).await;
            assert!(
                frames.iter().all(|m| m.starts_with("< frame 0601F5D0 ")),
                "{frames:?}"
            );
            got += frames.len();
        }
        let cpu = cpu_time(&stat) - cpu_before;
        let errors = gw.stats().accept_errors - errors_before;
        assert!(got >= 50, "{got} frames in a second");
        assert!(cpu < Duration::from_millis(300), "{cpu:?} of CPU in a second");
        assert!(errors <= 10, "{errors} accept attempts in a second");

        // ...and can send.
        old.write(b"< send 123 2 AB CD >").await;
        for _ in 0..200 {
            if gw.stats().sent == 1 {
                break;
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        assert_eq!(gw.stats().sent, 1);

        // Descriptors free again: the waiting connection and new ones are accepted.
        drop(hog);
        let mut pending = Conn {
            s: pending,
            pending: String::new(),
        };
        assert_eq!(pending.read(1).await, ["< hi >"]);
        let mut new = handshake(gw.addr).await;
        new.read(2).await;
        assert_eq!(gw.stats().clients, 3, "{:?}", gw.stats());
    });
}
