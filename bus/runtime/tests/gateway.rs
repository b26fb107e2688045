//! The socketcand gateway against clients written here, on loopback, in real time.

mod common;

use actix::prelude::*;
use bus::time::BusTime;
use bus_runtime::gateway::{Gateway, GatewayConfig};
use bus_runtime::hub::{Hub, HubConfig, RunUntil, runtime};
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

async fn bus_with_ticker(period_us: u64) -> (Addr<Hub>, Gateway) {
    let hub = common::hub_with_ticker("0601F5D0#200D0002FFBFFF00", period_us).await;
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
                .unwrap_or_else(|_| panic!("no answer after {out:?}, pending {:?}", self.pending))
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
fn malformed_input_gets_no_answer_and_the_connection_goes_on() {
    in_real_time(async {
        let (_hub, gw) = bus_with_ticker(1_000_000).await;
        let mut s = connect(gw.addr, None).await;
        s.read(1).await;
        // Before the bus is open: ignored (socketcand would answer `< error ... >`).
        s.write(b"< rawmode >").await;
        s.write(b"< open harv0 >").await;
        assert_eq!(s.read(1).await, ["< ok >"], "nothing came before the ok");
        s.write(b"< rawmode >").await;
        assert_eq!(s.read(1).await, ["< ok >"]);
        let bad: &[&[u8]] = &[
            b"hello",
            b"< send 123 9 1 2 >",
            b"< send 123 2 1 >",
            b"< foo >",
            b"< send XYZ 0 >",
            b"< \xff >",
            b"< rawmode >",
            b"< add 0 0 123 0 >",
            b"< open harv0 >",
        ];
        for line in bad {
            s.write(line).await;
        }
        let mut long = vec![b'<'];
        long.extend(std::iter::repeat_n(b'a', 100_000));
        long.extend(b"> < echo >");
        s.write(&long).await;
        // The echo is the next message: nothing was answered to the ten bad ones.
        assert_eq!(s.read(1).await, ["< echo >"]);
        for _ in 0..100 {
            if gw.stats().malformed == 11 {
                break;
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        // The rawmode before open, the nine above and the one too long.
        assert_eq!(gw.stats().malformed, 11, "{:?}", gw.stats());
        assert_eq!(gw.stats().sent, 0);
    });
}

/// What python-can writes: data bytes in as few hex digits as they need.
#[test]
fn sends_as_python_can_writes_them_reach_the_bus() {
    in_real_time(async {
        let (_hub, gw) = bus_with_ticker(1_000_000).await;
        let mut a = handshake(gw.addr).await;
        let mut b = handshake(gw.addr).await;
        a.write(b"< send 0300A0F5 2 1 1 >< send 7FF 3 a 0 ff >< send 300A0F5 0 >")
            .await;
        let want = [
            "< frame 0300A0F5 ",
            " 0101 >",
            "< frame 7FF ",
            " 0A00FF >",
            "< frame 0300A0F5 ",
            "  >",
        ];
        let mut got = Vec::new();
        while got.len() < 3 {
            let m = b.read(1).await.remove(0);
            if !m.starts_with("< frame 0601F5D0 ") {
                got.push(m);
            }
        }
        for (m, w) in got.iter().zip(want.chunks(2)) {
            assert!(m.starts_with(w[0]) && m.ends_with(w[1]), "{m} is not {w:?}");
        }
        assert_eq!(gw.stats().sent, 3);
        assert_eq!(gw.stats().malformed, 0);
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
        let before = hub
            .send(bus_runtime::hub::GetSnapshot)
            .await
            .unwrap()
            .stats
            .frames;
        let mut got = 0;
        let start = std::time::Instant::now();
        while start.elapsed() < Duration::from_secs(3) {
            got += live.read(100).await.len();
        }
        let after = hub
            .send(bus_runtime::hub::GetSnapshot)
            .await
            .unwrap()
            .stats
            .frames;
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

/// Reads what came for `c` up to the answer to an `< echo >` sent now (after the runtime had
/// time to hand over every frame the bus produced).
async fn drain(c: &mut Conn) -> Vec<String> {
    tokio::time::sleep(Duration::from_millis(20)).await;
    c.write(b"< echo >").await;
    let mut out = Vec::new();
    loop {
        let m = c.read(1).await.remove(0);
        if m == "< echo >" {
            return out;
        }
        out.push(m);
    }
}

/// A BCM client's frames of `id`: (seconds, data as the message writes it).
fn frames_of(messages: &[String], id: &str) -> Vec<(f64, String)> {
    let head = format!("< frame {id} ");
    messages
        .iter()
        .filter_map(|m| m.strip_prefix(&head))
        .map(|rest| {
            let (t, data) = rest.split_once(' ').unwrap();
            (t.parse().unwrap(), data.trim_end_matches('>').trim().to_string())
        })
        .collect()
}

/// socketcand's BCM mode: a cyclic send, updated, deleted; a subscription throttled to 100 ms; a
/// content filter. The bus runs in steps (`RunUntil`) and stands still in between, while the
/// clients talk, so counts in bus time are exact even though the bus is paced by the real clock
/// (tokio's paused clock, for virtual time, jumps ahead of the TCP connections).
#[test]
fn bcm_mode_runs_on_the_bus_clock() {
    in_real_time(async {
        // Frames are stamped with the hub's epoch: a million seconds after 1970 here.
        let config = HubConfig {
            epoch: bus::time::Epoch::from_secs(1_000_000),
            ..HubConfig::new(true)
        };
        let hub = common::hub_with_ticker_at(config, "0601F5D0#01", 10_000).await;
        let gw = Gateway::start(
            hub.clone(),
            "127.0.0.1:0".parse().unwrap(),
            GatewayConfig::default(),
        )
        .await
        .unwrap();
        let run_to = |ms: u64| hub.send(RunUntil(BusTime::from_millis(ms)));
        run_to(100).await.unwrap().unwrap();
        let open = |addr| async move {
            let mut c = connect(addr, None).await;
            assert_eq!(c.read(1).await, ["< hi >"]);
            c.write(b"< open harv0 >").await;
            assert_eq!(c.read(1).await, ["< ok >"]);
            c
        };
        let (mut a, mut b) = (open(gw.addr).await, open(gw.addr).await);
        b.write(b"< subscribe 0 0 123 >< subscribe 0 100000 0601F5D0 >< filter 0 0 124 1 FF >")
            .await;
        assert!(drain(&mut b).await.is_empty(), "BCM mode sends nothing unasked");
        // Every 20 ms from 100 ms (sent at once, as the kernel's STARTTIMER does).
        a.write(b"< add 0 20000 123 4 42 42 42 42 >").await;
        assert!(
            drain(&mut a).await.is_empty(),
            "no answer to add, and nothing unsubscribed"
        );
        run_to(1100).await.unwrap().unwrap();
        let got = drain(&mut b).await;
        let cyclic = frames_of(&got, "123");
        // Frames sent at 100, 120, ... 1080 ms; the one of 1100 ms has not ended yet.
        assert_eq!(cyclic.len(), 50, "{got:?}");
        assert!(cyclic.iter().all(|(_, d)| d == "42 42 42 42"), "{cyclic:?}");
        for w in cyclic.windows(2) {
            let gap = w[1].0 - w[0].0;
            assert!((gap - 0.020).abs() < 0.001, "{gap}");
        }
        // BCM frames are written with a space after each byte.
        assert!(got.iter().any(|m| m.ends_with(" 42 42 42 42  >")), "{got:?}");
        let ticks = frames_of(&got, "0601F5D0");
        // 100 ticks in the second, throttled to one per 100 ms.
        assert!((9..=11).contains(&ticks.len()), "{ticks:?}");
        for w in ticks.windows(2) {
            assert!(w[1].0 - w[0].0 > 0.089, "{ticks:?}");
        }

        // update: new content from the next send on, same timing.
        a.write(b"< update 123 3 11 22 33 >").await;
        drain(&mut a).await;
        run_to(1500).await.unwrap().unwrap();
        let cyclic = frames_of(&drain(&mut b).await, "123");
        assert_eq!(cyclic.len(), 20, "1100 to 1480 ms: {cyclic:?}");
        assert!(cyclic.iter().all(|(_, d)| d == "11 22 33"), "{cyclic:?}");
        // The first of them at 1.1 s of bus time, written as epoch + bus time.
        assert!((cyclic[0].0 - 1_000_001.1).abs() < 0.001, "{cyclic:?}");

        // delete, and a content filter on byte 0 of 124.
        a.write(b"< delete 123 >< add 0 10000 124 2 1 0 >").await;
        drain(&mut a).await;
        run_to(1600).await.unwrap().unwrap();
        let got = drain(&mut b).await;
        assert!(frames_of(&got, "123").is_empty(), "{got:?}");
        assert_eq!(
            frames_of(&got, "124").iter().map(|f| &f.1).collect::<Vec<_>>(),
            ["01 00"]
        );
        a.write(b"< update 124 2 1 FF >").await;
        drain(&mut a).await;
        run_to(1700).await.unwrap().unwrap();
        assert!(
            frames_of(&drain(&mut b).await, "124").is_empty(),
            "byte 1 is not under the mask"
        );
        a.write(b"< update 124 2 2 FF >").await;
        drain(&mut a).await;
        run_to(1800).await.unwrap().unwrap();
        let got = frames_of(&drain(&mut b).await, "124");
        assert_eq!(got.iter().map(|f| &f.1).collect::<Vec<_>>(), ["02 FF"]);

        // unsubscribe, and rawmode ends the client's jobs.
        b.write(b"< unsubscribe 124 >< unsubscribe 0601F5D0 >").await;
        drain(&mut b).await;
        a.write(b"< rawmode >").await;
        assert_eq!(a.read(1).await, ["< ok >"]);
        drain(&mut a).await;
        run_to(1900).await.unwrap().unwrap();
        assert!(drain(&mut b).await.is_empty());
        let raw = drain(&mut a).await;
        assert!(raw.iter().all(|m| m.starts_with("< frame 0601F5D0 ")), "{raw:?}");
        // 50 + 20 cyclic frames of 123 (100 to 1480 ms), 30 of 124 (1500 to 1790 ms).
        assert_eq!(gw.stats().sent, 100, "{:?}", gw.stats());
        assert_eq!(gw.stats().malformed, 0);
    });
}

/// The beacon goes to socketcand's port by default, checked on the real port. A machine where
/// another program holds 127.0.0.1:42000 (a socketcand client listening for beacons) cannot run
/// this check, and the test then fails saying so rather than pass unchecked. The beacon's content
/// and its way to python-can are checked on a free port (`gateway_python_can.rs`).
#[test]
fn the_beacon_goes_to_port_42000_by_default() {
    assert_eq!(GatewayConfig::default().beacon_port, Some(42000));
    let listener = match std::net::UdpSocket::bind("127.0.0.1:42000") {
        Ok(l) => l,
        Err(e) => panic!(
            "cannot listen on 127.0.0.1:42000 ({e}): another program holds socketcand's beacon \
             port, so the default beacon cannot be checked here; stop it and run again"
        ),
    };
    listener
        .set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    in_real_time(async move {
        let (_hub, gw) = bus_with_ticker(1_000_000).await;
        let want = format!("<URL>can://{}</URL>", gw.addr);
        let start = std::time::Instant::now();
        let mut buf = [0u8; 1024];
        // Beacons of other gateways started alongside may come too.
        while start.elapsed() < Duration::from_secs(10) {
            tokio::time::sleep(Duration::from_millis(50)).await;
            if let Ok(n) = listener.recv(&mut buf)
                && String::from_utf8_lossy(&buf[..n]).contains(&want)
            {
                return;
            }
        }
        panic!("no beacon for {} on port 42000", gw.addr);
    });
}

/// What a fmt subscriber writes, kept for the test to read.
#[derive(Clone, Default)]
struct Captured(std::sync::Arc<std::sync::Mutex<Vec<u8>>>);

impl std::io::Write for Captured {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[test]
fn a_burst_of_300_connections_gets_256_served_and_44_closed_at_once() {
    let log = Captured::default();
    let writer = log.clone();
    let subscriber = tracing_subscriber::fmt()
        .with_max_level(tracing::Level::WARN)
        .with_ansi(false)
        .with_writer(move || writer.clone())
        .finish();
    let _guard = tracing::subscriber::set_default(subscriber);
    in_real_time(async {
        let (_hub, gw) = bus_with_ticker(5_000).await;
        // All 300 connect at once: the kernel completes the connections in the listener's
        // backlog (1024), and the accept loop finds them there in a burst.
        let connects = (0..300).map(|_| connect(gw.addr, None));
        let mut clients = futures_util::future::join_all(connects).await;
        let mut greeted = 0;
        let mut closed = 0;
        for c in &mut clients {
            let mut buf = [0u8; 64];
            let n = tokio::time::timeout(Duration::from_secs(10), c.s.read(&mut buf))
                .await
                .unwrap_or_else(|_| {
                    panic!(
                        "neither a greeting nor a close within 10 s: {greeted} {closed} {:?}",
                        gw.stats()
                    )
                });
            match n {
                Ok(0) | Err(_) => closed += 1,
                Ok(n) => {
                    assert!(String::from_utf8_lossy(&buf[..n]).starts_with("< hi >"));
                    greeted += 1;
                }
            }
        }
        assert_eq!((greeted, closed), (256, 44));
        let stats = gw.stats();
        assert_eq!((stats.clients, stats.accepted, stats.turned_away), (256, 256, 44));
    });
    let text = String::from_utf8(log.0.lock().unwrap().clone()).unwrap();
    let warnings: Vec<&str> = text.lines().filter(|l| l.contains("gateway full")).collect();
    // Rate-limited: the first at once, the rest counted for the next (10 s away).
    assert_eq!(warnings.len(), 1, "{text}");
    assert!(
        warnings[0].contains("(256 clients): 1 connection closed"),
        "{text}"
    );
}
