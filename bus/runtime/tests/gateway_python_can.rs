//! The socketcand gateway against python-can itself (its `socketcand` interface, its
//! `can.Notifier`, its `detect_beacon`) and against a BCM-mode client written in python from
//! socketcand's `doc/protocol.md`, on loopback, in real time.
//!
//! The python is `HARVEMU_PYTHON` (scripts/test points it at a virtual environment it makes with
//! python-can), else `python3`. Without python-can the tests fail: a cross-check that cannot run
//! has checked nothing.

mod common;

use actix::prelude::*;
use bus::Frame;
use bus::candump::parse_frame;
use bus::time::BusTime;
use bus_runtime::gateway::{Gateway, GatewayConfig, GatewayStats};
use bus_runtime::hub::{RunUntil, Subscribe, runtime};
use std::collections::HashMap;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The frame the ticker sends every 10 ms.
const TICK: &str = "0601F5D0#200D0002FFBFFF00";

/// Connects with python-can and sends the frames of `FRAMES`, then reads five.
const SEND_AND_RECEIVE: &str = r#"
import sys, time, can
bus = can.Bus(interface="socketcand", channel="harv0", host=sys.argv[1], port=int(sys.argv[2]))
msgs = [
    # The README's example frame (python-can's default is an extended identifier).
    can.Message(arbitration_id=0x0300A0F5, data=[1, 1]),
    can.Message(arbitration_id=0x123, is_extended_id=False, data=[]),
    can.Message(arbitration_id=0x7FF, is_extended_id=False, data=[0, 0x0A, 0xFF]),
    can.Message(arbitration_id=0x1FFFFFFF, data=range(0xF8, 0x100)),
    can.Message(arbitration_id=0x5, data=[0x10]),
] + [can.Message(arbitration_id=0x600 + n, is_extended_id=False, data=range(n)) for n in range(9)]
for m in msgs:
    bus.send(m)
time.sleep(0.3)
for _ in range(5):
    m = bus.recv(5)
    print("recv", f"{m.arbitration_id:X}", int(m.is_extended_id), bytes(m.data).hex(), m.timestamp)
bus.shutdown()
"#;

/// What SEND_AND_RECEIVE sends, in candump form.
const FRAMES: &[&str] = &[
    "0300A0F5#0101",
    "123#",
    "7FF#000AFF",
    "1FFFFFFF#F8F9FAFBFCFDFEFF",
    "00000005#10",
    "600#",
    "601#00",
    "602#0001",
    "603#000102",
    "604#00010203",
    "605#0001020304",
    "606#000102030405",
    "607#00010203040506",
    "608#0001020304050607",
];

/// A `can.Notifier` whose listener counts frames while malformed lines go to the server, then
/// for a run of three seconds.
const NOTIFIER: &str = r#"
import sys, time, can
class Counter(can.Listener):
    def __init__(self):
        self.n, self.errors = 0, []
    def on_message_received(self, m):
        self.n += 1
    def on_error(self, e):
        self.errors.append(repr(e))
bus = can.Bus(interface="socketcand", channel="harv0", host=sys.argv[1], port=int(sys.argv[2]))
counter = Counter()
notifier = can.Notifier(bus, [counter], timeout=0.1)
time.sleep(0.5)
print("before", counter.n)
for line in ["< send 123 9 1 2 >", "< foo >", "garbage", "< send XYZ 0 >", "< rawmode >",
             "< send 123 2 1 >", "< open harv0 >", "<>", "< send 123 1 1FF >"]:
    bus._tcp_send(line)
time.sleep(1.0)
print("after", counter.n)
bus.send(can.Message(arbitration_id=0x0300A0F5, data=[1, 1]))
time.sleep(3.0)
print("end", counter.n)
notifier.stop()
bus.shutdown()
print("errors", len(counter.errors), *counter.errors[:1])
"#;

/// python-can's `detect_beacon`, listening on the port given instead of 42000.
const DETECT: &str = r#"
import sys
import can.interfaces.socketcand.socketcand as socketcand
socketcand.DEFAULT_SOCKETCAND_DISCOVERY_PORT = int(sys.argv[1])
for c in socketcand.detect_beacon(6000):
    print("found", c["interface"], c["host"], c["port"], c["channel"])
"#;

/// A BCM-mode client speaking socketcand's text protocol: a cyclic send every 20 ms, updated
/// and deleted, a subscription throttled to 200 ms, a content filter. Prints counts.
const BCM: &str = r#"
import socket, sys, time
class Client:
    def __init__(self):
        self.s = socket.create_connection((sys.argv[1], int(sys.argv[2])))
        self.s.settimeout(0.05)
        self.buf = ""
        assert self.collect(0.3) == ["< hi >"]
        self.send("< open harv0 >")
        assert self.collect(0.3) == ["< ok >"]
    def send(self, line):
        self.s.sendall(line.encode())
    def collect(self, seconds):
        out, end = [], time.time() + seconds
        while time.time() < end:
            try:
                data = self.s.recv(4096)
            except socket.timeout:
                continue
            self.buf += data.decode()
            while ">" in self.buf:
                m, self.buf = self.buf.split(">", 1)
                out.append(m.strip() + " >")
        return out
def frames(msgs, ident):
    # "< frame ID SECS.USECS B0 B1 ... >"
    return [m.split()[4:-1] for m in msgs if m.startswith("< frame " + ident + " ")]
a, b = Client(), Client()
b.send("< subscribe 0 0 123 >")
a.send("< add 0 20000 123 4 42 42 42 42 >")
got = frames(b.collect(1.0), "123")
print("cyclic", len(got), len({" ".join(f) for f in got}), " ".join(got[0]))
a.send("< update 123 3 11 22 33 >")
b.collect(0.1)
got = frames(b.collect(1.0), "123")
print("updated", len(got), sorted({" ".join(f) for f in got}))
a.send("< delete 123 >")
b.collect(0.2)
print("deleted", len(frames(b.collect(0.5), "123")))
b.send("< subscribe 0 200000 0601F5D0 >")
print("throttled", len(frames(b.collect(2.0), "0601F5D0")))
b.send("< unsubscribe 0601F5D0 >")
b.collect(0.2)
b.send("< filter 0 0 124 1 FF >")
a.send("< add 0 10000 124 2 1 0 >")
print("filter first", [" ".join(f) for f in frames(b.collect(0.5), "124")])
a.send("< update 124 2 1 FF >")
print("filter unmasked", [" ".join(f) for f in frames(b.collect(0.5), "124")])
a.send("< update 124 2 2 FF >")
print("filter masked", [" ".join(f) for f in frames(b.collect(0.5), "124")])
print("quiet", len(a.collect(0.2)))
"#;

/// The python to run: `HARVEMU_PYTHON`, else `python3`.
fn interpreter() -> PathBuf {
    std::env::var_os("HARVEMU_PYTHON").map_or_else(|| "python3".into(), PathBuf::from)
}

/// Runs `script` with `args`; its output, one line a word list. Fails the test, saying how to
/// get python-can, when python-can cannot be imported.
fn python(script: &str, args: &[String]) -> Vec<Vec<String>> {
    let python = interpreter();
    let out = Command::new(&python)
        .args(["-c", script])
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", python.display()));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !err.contains("No module named 'can'"),
        "python-can cannot be imported with {}: run scripts/test, which makes a virtual \
         environment with it, or set HARVEMU_PYTHON to a python that has it",
        python.display()
    );
    assert!(out.status.success(), "{err}");
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| l.split_whitespace().map(str::to_string).collect())
        .collect()
}

/// The lines of `out` that start with `key`, without it.
fn lines<'a>(out: &'a [Vec<String>], key: &str) -> Vec<&'a [String]> {
    out.iter()
        .filter(|l| l.first().is_some_and(|k| k == key))
        .map(|l| &l[1..])
        .collect()
}

/// A bus with a ticker, a node that acknowledges, and a gateway, on a thread of its own.
struct Bench {
    addr: SocketAddr,
    /// Every frame on the bus but the ticker's.
    frames: Arc<Mutex<Vec<Frame>>>,
    stats: Arc<Mutex<GatewayStats>>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Bench {
    fn start(config: GatewayConfig) -> Bench {
        let frames = Arc::new(Mutex::new(Vec::new()));
        let stats = Arc::new(Mutex::new(GatewayStats::default()));
        let stop = Arc::new(AtomicBool::new(false));
        let (tx, rx) = std::sync::mpsc::channel();
        let (f, s, st) = (frames.clone(), stats.clone(), stop.clone());
        let thread = std::thread::spawn(move || {
            System::with_tokio_rt(|| runtime(false).unwrap()).block_on(async move {
                let hub = common::hub_with_ticker(TICK, 10_000).await;
                let gw = Gateway::start(hub.clone(), "127.0.0.1:0".parse().unwrap(), config)
                    .await
                    .unwrap();
                let (otx, mut orx) = tokio::sync::mpsc::channel(1 << 16);
                hub.send(Subscribe(otx)).await.unwrap();
                hub.do_send(RunUntil(BusTime::NEVER));
                tx.send(gw.addr).unwrap();
                let tick = parse_frame(TICK).unwrap();
                while !st.load(Ordering::Relaxed) {
                    while let Ok(o) = orx.try_recv() {
                        if o.frame != tick {
                            f.lock().unwrap().push(o.frame);
                        }
                    }
                    *s.lock().unwrap() = gw.stats();
                    tokio::time::sleep(Duration::from_millis(20)).await;
                }
            });
        });
        Bench {
            addr: rx.recv().unwrap(),
            frames,
            stats,
            stop,
            thread: Some(thread),
        }
    }

    fn args(&self) -> Vec<String> {
        vec![self.addr.ip().to_string(), self.addr.port().to_string()]
    }

    /// Stops the bus; its last counters.
    fn finish(mut self) -> GatewayStats {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            t.join().unwrap();
        }
        self.stats.lock().unwrap().clone()
    }
}

#[test]
fn python_can_sends_and_receives() {
    let bench = Bench::start(GatewayConfig::default());
    let out = python(SEND_AND_RECEIVE, &bench.args());
    let sent = bench.frames.lock().unwrap().clone();
    let stats = bench.finish();
    let want: Vec<Frame> = FRAMES.iter().map(|t| parse_frame(t).unwrap()).collect();
    assert_eq!(sent, want, "{stats:?}");
    assert_eq!((stats.sent, stats.malformed), (14, 0), "{stats:?}");
    let received = lines(&out, "recv");
    assert_eq!(received.len(), 5, "{out:?}");
    let mut last = -1.0;
    for r in received {
        assert_eq!(r[..3], ["601F5D0", "1", "200d0002ffbfff00"], "{r:?}");
        let t: f64 = r[3].parse().unwrap();
        assert!(t > last, "{out:?}");
        last = t;
    }
}

/// python-can takes any `< error ... >` for an error frame and raises when it cannot read one,
/// which ends a `can.Notifier`: malformed lines must get no answer at all.
#[test]
fn a_python_can_notifier_survives_malformed_lines_and_a_full_run() {
    let bench = Bench::start(GatewayConfig::default());
    let out = python(NOTIFIER, &bench.args());
    let sent = bench.frames.lock().unwrap().clone();
    let stats = bench.finish();
    let count = |key: &str| -> u64 { lines(&out, key)[0][0].parse().unwrap() };
    assert_eq!(lines(&out, "errors")[0], ["0"], "{out:?}");
    // A frame every 10 ms: 50 in half a second, 100 in the second after the bad lines, 300 in
    // the last three. Wide margins: the machine may be busy.
    assert!(count("before") >= 10, "{out:?}");
    assert!(count("after") >= count("before") + 30, "{out:?}");
    assert!(count("end") >= count("after") + 100, "{out:?}");
    let want: Vec<Frame> = ["123#FF", "0300A0F5#0101"]
        .iter()
        .map(|t| parse_frame(t).unwrap())
        .collect();
    assert_eq!(sent, want);
    // Nine bad lines; "garbage" is bytes outside a message; `< send 123 1 1FF >` is a good one
    // (1FF is read as FF) but python-can's Notifier does not see it, as it is the client's own.
    assert_eq!((stats.malformed, stats.sent), (8, 2), "{stats:?}");
}

/// The beacon, on a port of its own for this test: python-can's `detect_beacon` listens on
/// 42000, which another program (another gateway's test) may hold at the same time, so the test
/// points python-can at a port the system just gave out as free instead. (The port could be
/// taken again between the check and python binding it; the system hands out ephemeral ports
/// in turn, so that would take thousands of bindings in between.)
#[test]
fn python_can_detects_the_beacon() {
    let port = std::net::UdpSocket::bind("0.0.0.0:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let bench = Bench::start(GatewayConfig {
        beacon_port: Some(port),
        ..GatewayConfig::default()
    });
    let out = python(DETECT, &[port.to_string()]);
    let addr = bench.addr;
    bench.finish();
    let found = lines(&out, "found");
    let want = [
        "socketcand".to_string(),
        "127.0.0.1".into(),
        addr.port().to_string(),
        "harv0".into(),
    ];
    assert_eq!(found, [&want[..]], "{out:?}");
}

#[test]
fn a_bcm_client_written_from_the_protocol() {
    let bench = Bench::start(GatewayConfig::default());
    let out = python(BCM, &bench.args());
    let stats = bench.finish();
    let get: HashMap<&str, &[String]> = out.iter().map(|l| (l[0].as_str(), &l[1..])).collect();
    let num = |key: &str, i: usize| -> usize { get[key][i].parse().unwrap() };
    // Every 20 ms for a second: 50.
    assert!((35..=65).contains(&num("cyclic", 0)), "{out:?}");
    assert_eq!(get["cyclic"][1..], ["1", "42", "42", "42", "42"], "{out:?}");
    assert!((35..=65).contains(&num("updated", 0)), "{out:?}");
    assert_eq!(get["updated"][1..], ["['11", "22", "33']"], "{out:?}");
    assert_eq!(num("deleted", 0), 0, "{out:?}");
    // 200 frames in two seconds, throttled to one per 200 ms: 10.
    assert!((6..=14).contains(&num("throttled", 0)), "{out:?}");
    let filters: Vec<&Vec<String>> = out.iter().filter(|l| l[0] == "filter").collect();
    assert_eq!(filters[0][1..], ["first", "['01", "00']"], "{out:?}");
    assert_eq!(filters[1][1..], ["unmasked", "[]"], "{out:?}");
    assert_eq!(filters[2][1..], ["masked", "['02", "FF']"], "{out:?}");
    assert_eq!(
        num("quiet", 0),
        0,
        "a BCM client gets only what it subscribed to: {out:?}"
    );
    assert_eq!(stats.malformed, 0, "{stats:?}");
}
