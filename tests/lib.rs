//! End-to-end tests of harvemu; the tests live in `tests/tests/`, one file per concern. This
//! library holds what they share: running the default harvester in virtual time and reading its
//! trace back.

pub mod cc03;

use actix::prelude::*;
use bus::Frame;
use bus::time::{BusTime, Epoch};
use bus::trace::{CandumpWriter, Sink};
use bus_runtime::hub::{GetSnapshot, RunUntil, Snapshot, runtime};
use std::cell::RefCell;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use supervisor::harvester::{self, Harvester, Running};

/// A `Write` the test can read back.
#[derive(Clone, Default)]
pub struct Shared(pub Rc<RefCell<Vec<u8>>>);

impl Write for Shared {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.borrow_mut().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// The trace as a candump log into `out`, stamped as the hub of `h` stamps it: with its epoch,
/// else the fixed one of virtual time.
pub fn candump(out: Shared, h: &Harvester) -> Box<dyn Sink> {
    Box::new(CandumpWriter::new(out, h.epoch.unwrap_or(Epoch::FIXED)))
}

/// The repository's root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The default harvester config.
pub fn default_harvester() -> Harvester {
    Harvester::load(&root().join("configs/harvester.ron")).expect("the default config loads")
}

/// One frame of a trace.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Line {
    /// Candump timestamp (end of frame).
    pub at: BusTime,
    /// The frame.
    pub frame: Frame,
}

/// Where a virtual-time trace starts: 2024-01-01T00:00:00Z (54 years of 365 days and the 13 leap
/// days 1972..=2020), in seconds since 1970.
pub const VIRTUAL_EPOCH_S: u64 = (54 * 365 + 13) * 86_400;

/// Reads a virtual-time candump log back (error frames are skipped), its times back to bus time.
pub fn parse_trace(text: &str) -> Vec<Line> {
    text.lines()
        .filter_map(|l| {
            let (time, rest) = l.strip_prefix('(')?.split_once(") ")?;
            let (_iface, frame) = rest.split_once(' ')?;
            let (secs, micros) = time.split_once('.')?;
            let secs = secs.parse::<u64>().ok()?.checked_sub(VIRTUAL_EPOCH_S)?;
            let at = BusTime::from_nanos(secs * 1_000_000_000 + micros.parse::<u64>().ok()? * 1000);
            // Error frames (CAN_ERR_FLAG in the identifier) are not frames: they fail to parse.
            let frame = bus::candump::parse_frame(frame).ok()?;
            Some(Line { at, frame })
        })
        .collect()
}

/// Runs `h` in virtual time until `until`, calling `setup` once the nodes are attached and
/// `check` at the end; returns the trace and what `check` returned.
pub fn run_virtual<T: 'static>(
    h: Harvester,
    until: BusTime,
    setup: impl FnOnce(&Running) + 'static,
    check: impl FnOnce(&Running, &Snapshot) -> T + 'static,
) -> (Vec<Line>, T) {
    let trace = Shared::default();
    let t = trace.clone();
    let result = System::with_tokio_rt(|| runtime(true).expect("runtime")).block_on(async move {
        let running = harvester::start(&h, false, vec![candump(t, &h)])
            .await
            .expect("the harvester starts");
        setup(&running);
        running
            .hub
            .send(RunUntil(until))
            .await
            .expect("hub")
            .expect("run");
        let snap = running.hub.send(GetSnapshot).await.expect("snapshot");
        check(&running, &snap)
    });
    let text = String::from_utf8(trace.0.take()).expect("utf-8 trace");
    (parse_trace(&text), result)
}

/// Starts `h` in virtual time with its trace recorded and lets `script` drive it (run it, inject
/// faults, read its hardware); returns the candump trace with what `script` returned.
pub fn drive<T: 'static>(h: Harvester, script: impl AsyncFnOnce(&mut Running) -> T + 'static) -> (String, T) {
    let trace = Shared::default();
    let t = trace.clone();
    let result = System::with_tokio_rt(|| runtime(true).expect("runtime")).block_on(async move {
        let mut running = harvester::start(&h, false, vec![candump(t, &h)])
            .await
            .expect("the harvester starts");
        script(&mut running).await
    });
    (String::from_utf8(trace.0.take()).expect("utf-8 trace"), result)
}

/// A checked firmware node file: its text, read as `file`, whose image `image` is `hex`.
pub fn firmware_spec(
    file: &str,
    text: &str,
    image: &str,
    hex: &str,
) -> std::sync::Arc<nodes::firmware::FirmwareSpec> {
    let (image, hex) = (image.to_string(), hex.to_string());
    let read = move |_: &Path| Ok((image.clone(), hex.clone()));
    let spec = nodes::firmware::load(file, Path::new(file), text, &read).expect("the node file");
    std::sync::Arc::new(spec)
}

/// Internal RAM bytes `from..from + n` of a firmware node's hardware.
pub fn iram(hw: &bus::node::HardwareState, from: usize, n: usize) -> Vec<u8> {
    (from..from + n)
        .map(|i| u8::from_str_radix(&hw.cpu.iram[2 * i..2 * i + 2], 16).expect("hex"))
        .collect()
}

/// Runs the default harvester in virtual time and lets `script` drive it (run to a time, send
/// controls, submit frames); returns the trace, decoded through the catalogue, as (time, message)
/// for `node`.
pub fn traffic_of(
    node: protocol::ident::Address,
    script: impl AsyncFnOnce(&Running),
) -> Vec<(BusTime, protocol::catalogue::Decoded)> {
    let trace = Shared::default();
    let t = trace.clone();
    System::with_tokio_rt(|| runtime(true).expect("runtime")).block_on(async move {
        let h = default_harvester();
        let running = harvester::start(&h, false, vec![candump(t, &h)])
            .await
            .expect("the harvester starts");
        script(&running).await;
    });
    let text = String::from_utf8(trace.0.take()).expect("utf-8 trace");
    parse_trace(&text)
        .iter()
        .filter_map(|l| {
            protocol::catalogue::decode(&l.frame)
                .ok()
                .flatten()
                .map(|d| (l.at, d))
        })
        .filter(|(_, d)| d.node == node)
        .collect()
}

/// Runs the hub of `running` to bus time `t`.
pub async fn run_to(running: &Running, t: BusTime) {
    running.hub.send(RunUntil(t)).await.expect("hub").expect("run");
}

/// Assembles 8051 source with Debian's `as31` and returns the Intel HEX. Panics naming the
/// package when `as31` is missing (a test that needs it fails; it never passes without it).
pub fn assemble(source: &str) -> String {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static N: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "harvemu-as31-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch directory");
    std::fs::write(dir.join("prog.asm"), source).expect("write the source");
    let out = std::process::Command::new("as31")
        .current_dir(&dir)
        .args(["-Fhex", "-Oprog.hex", "prog.asm"])
        .output()
        .unwrap_or_else(|e| panic!("cannot run as31 ({e}): install the Debian package as31"));
    assert!(
        out.status.success(),
        "as31 failed:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let hex = std::fs::read_to_string(dir.join("prog.hex")).expect("as31 wrote prog.hex");
    let _ = std::fs::remove_dir_all(&dir);
    hex
}

/// Firmware nodes on a 30 kbit/s bus, driven through the hub in virtual time, as harvemu drives
/// every node. `benches` are (node file text, HEX) pairs; the node file names its image
/// `lab.hex`. Returns the trace, each node's hardware at the end (`None` for a node that
/// crashed) and the crashes.
pub fn run_firmware(benches: &[(String, String)], seconds: u64) -> FirmwareRun {
    run_firmware_with(benches, BusTime::from_secs(seconds), None)
}

/// Every frame node `node` sends is corrupted (a bit error) from `from` to `to`.
#[derive(Clone, Copy, Debug)]
pub struct BitErrorsOf {
    /// The node's index in the benches.
    pub node: usize,
    /// When the corruption begins.
    pub from: BusTime,
    /// When it ends.
    pub to: BusTime,
}

/// [`run_firmware`] to bus time `end`, with `fault` on the way.
pub fn run_firmware_with(
    benches: &[(String, String)],
    end: BusTime,
    fault: Option<BitErrorsOf>,
) -> FirmwareRun {
    run_firmware_specs(bench_specs(benches), end, fault)
}

/// The checked node files of `benches` (as [`run_firmware`] takes them), for a test that
/// changes a spec before running them with [`run_firmware_specs`].
pub fn bench_specs(benches: &[(String, String)]) -> Vec<std::sync::Arc<nodes::firmware::FirmwareSpec>> {
    benches
        .iter()
        .map(|(text, hex)| firmware_spec("bench.ron", text, "lab.hex", hex))
        .collect()
}

/// Collects the end-of-frame time of every frame, exactly (a candump line has microseconds).
struct FrameEnds(Rc<RefCell<Vec<BusTime>>>);

impl Sink for FrameEnds {
    fn record(&mut self, r: &bus::trace::Record<'_>) -> std::io::Result<()> {
        if let bus::trace::Kind::Frame(_) = r.kind {
            self.0.borrow_mut().push(r.at);
        }
        Ok(())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// [`run_firmware_with`] for nodes already checked.
pub fn run_firmware_specs(
    specs: Vec<std::sync::Arc<nodes::firmware::FirmwareSpec>>,
    end: BusTime,
    fault: Option<BitErrorsOf>,
) -> FirmwareRun {
    run_firmware_covered(specs, end, fault, false).0
}

/// [`run_firmware_specs`], with each node's code coverage when `cover` (else empty counts): the
/// nodes are told the run ends at `end`, so that their counts reach it.
pub fn run_firmware_covered(
    specs: Vec<std::sync::Arc<nodes::firmware::FirmwareSpec>>,
    end: BusTime,
    fault: Option<BitErrorsOf>,
    cover: bool,
) -> (FirmwareRun, Vec<nodes::firmware::coverage::Counts>) {
    use bus::engine::{BitPosition, BusConfig, ControllerConfig, NodeId, Recovery, Rule, Schedule, Target};
    use bus_runtime::hub::{AttachControllers, Control, GetCrashed, GetSnapshot, Hub, HubConfig};
    use bus_runtime::node::{NodeActor, ReadHardware};
    use nodes::firmware::FirmwareNode;
    let trace = Shared::default();
    let t = trace.clone();
    let ends = Rc::new(RefCell::new(Vec::new()));
    let e = ends.clone();
    let counts: Vec<nodes::firmware::coverage::SharedCounts> = specs.iter().map(|_| Rc::default()).collect();
    let c = counts.clone();
    let (states, crashed, controllers) =
        System::with_tokio_rt(|| runtime(true).expect("runtime")).block_on(async move {
            let config = HubConfig {
                bus: BusConfig {
                    bitrate: bus::bits::BitRate::new(30_000).expect("30 kbit/s"),
                    ..BusConfig::default()
                },
                ..HubConfig::new(false)
            };
            let sinks: Vec<Box<dyn Sink>> = vec![
                Box::new(CandumpWriter::new(t, Epoch::FIXED)),
                Box::new(FrameEnds(e)),
            ];
            let hub = Hub::new(config, sinks).expect("hub").start();
            let mut actors = Vec::new();
            // Each bench's controller ids, one a chip.
            let mut ids: Vec<Vec<NodeId>> = Vec::new();
            for (spec, counts) in specs.into_iter().zip(c) {
                let mut logic = FirmwareNode::new(spec.clone(), BusTime::ZERO, 30_000.0);
                if cover {
                    logic = logic.with_coverage(counts);
                }
                let actor = NodeActor::new(spec.name.clone(), Box::new(logic)).start();
                let controllers = (0..spec.chips.len().max(1))
                    .map(|k| ControllerConfig {
                        recovery: Recovery::OnRequest,
                        ..ControllerConfig::handing_over(spec.controller_name(k))
                    })
                    .collect();
                let attached = hub
                    .send(AttachControllers {
                        controllers,
                        node: Some(actor.clone().recipient()),
                        reaction: std::time::Duration::ZERO,
                    })
                    .await
                    .expect("hub")
                    .expect("attach");
                ids.push(attached);
                actors.push(actor);
            }
            let bench_of = |id: NodeId| {
                ids.iter()
                    .position(|b| b.contains(&id))
                    .expect("a bench's controller")
            };
            if let Some(f) = fault.filter(|f| f.from < end) {
                hub.send(RunUntil(f.from)).await.expect("hub").expect("run");
                let target = Target::Node(ids[f.node][0]);
                let rule = Rule::bit_errors(target, Schedule::Always, BitPosition::Random);
                let id = hub
                    .send(Control::AddRule(rule))
                    .await
                    .expect("hub")
                    .expect("rule");
                hub.send(RunUntil(f.to.min(end)))
                    .await
                    .expect("hub")
                    .expect("run");
                if let Some(id) = id {
                    hub.send(Control::RemoveRule(id))
                        .await
                        .expect("hub")
                        .expect("rule");
                }
            }
            hub.send(RunUntil(end)).await.expect("hub").expect("run");
            for a in &actors {
                a.send(bus_runtime::node::RunEnds(end)).await.expect("the node");
            }
            // A bench crashes as a whole: once, however many chips it has.
            let mut crashed: Vec<(usize, String)> = hub
                .send(GetCrashed)
                .await
                .expect("crashes")
                .into_iter()
                .map(|(id, why)| (bench_of(id), why.to_string()))
                .collect();
            crashed.dedup_by_key(|(bench, _)| *bench);
            let snapshot = hub.send(GetSnapshot).await.expect("snapshot");
            let controllers: Vec<Vec<bus_runtime::hub::NodeSnapshot>> = ids
                .iter()
                .map(|b| b.iter().map(|id| snapshot.nodes[id.index()].clone()).collect())
                .collect();
            let mut states = Vec::new();
            for a in actors {
                states.push(a.send(ReadHardware(end)).await.ok().flatten());
            }
            (states, crashed, controllers)
        });
    let run = FirmwareRun {
        trace: String::from_utf8(trace.0.take()).expect("utf-8"),
        ends: ends.take(),
        states,
        crashed,
        controllers,
    };
    (run, counts.iter().map(|c| c.borrow().clone()).collect())
}

/// What [`run_firmware`] gives back.
pub struct FirmwareRun {
    /// The candump trace.
    pub trace: String,
    /// Every frame's end-of-frame time, exactly, in trace order.
    pub ends: Vec<BusTime>,
    /// Each node's hardware at the end.
    pub states: Vec<Option<bus::node::HardwareState>>,
    /// Crashed nodes by index, and why.
    pub crashed: Vec<(usize, String)>,
    /// Each node's controllers on the bus at the end, as the hub sees them, one a chip.
    pub controllers: Vec<Vec<bus_runtime::hub::NodeSnapshot>>,
}

impl FirmwareRun {
    /// Internal RAM bytes `from..from + n` of node `node`.
    pub fn iram(&self, node: usize, from: usize, n: usize) -> Vec<u8> {
        iram(self.states[node].as_ref().expect("the node's hardware"), from, n)
    }
}

/// A bench's node file: an 80C51 at 12 MHz starting at `entry`, one SJA1000 at `base` on a
/// crystal of `xtal_hz`, its INT wired as `irq` (RON: `None`, `Some(Int0)`).
pub fn bench_file(name: &str, entry: u16, base: u16, xtal_hz: u32, irq: &str) -> String {
    format!(
        "Firmware(name: \"{name}\", image: \"lab.hex\", entry: Some({entry}), \
         cpu: I80C51(clock_hz: 12000000), \
         controllers: [Sja1000(base: {base}, xtal_hz: {xtal_hz}, irq: {irq})])"
    )
}
