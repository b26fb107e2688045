//! The TCP side of the gateway, on the actor system's tokio runtime, and the actor that runs the
//! BCM clients' timers on the hub's clock.

use super::backoff::{AcceptBackoff, REPORT_INTERVAL};
use super::bcm::Bcm;
use super::beacon;
use super::protocol::{self, Action, Command, Malformed, Mode, Session, Splitter};
use crate::Error;
use crate::hub::{Attach, Control, GetEpoch, Hub, Observed, Submit, Subscribe};
use crate::node::Wake;
use actix::prelude::*;
use bus::Frame;
use bus::engine::{ControllerConfig, Filter, NodeId};
use bus::node::Report;
use bus::time::{BusTime, Epoch};
use std::cell::RefCell;
use std::collections::VecDeque;
use std::net::SocketAddr;
use std::rc::Rc;
use std::time::Instant;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;

/// How long a client's writer waits after an `< ok >` before it writes anything else.
const OK_PAUSE: std::time::Duration = std::time::Duration::from_millis(20);

/// Kernel send buffer per client, bytes.
const SEND_BUFFER: usize = 64 * 1024;

/// Gateway settings.
#[derive(Clone, Debug)]
pub struct GatewayConfig {
    /// The bus name clients open.
    pub bus_name: String,
    /// Messages queued for one client before its frames are dropped.
    pub client_queue: usize,
    /// Most clients at once.
    pub max_clients: usize,
    /// The UDP port of the discovery beacon ([`beacon::BEACON_PORT`] by default), `None` for
    /// no beacon. It is sent only from a loopback address (see [`super::beacon`]).
    pub beacon_port: Option<u16>,
}

impl Default for GatewayConfig {
    fn default() -> Self {
        GatewayConfig {
            bus_name: "harv0".into(),
            client_queue: 1024,
            max_clients: 256,
            beacon_port: Some(beacon::BEACON_PORT),
        }
    }
}

/// Counters of a running gateway.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct GatewayStats {
    /// Clients connected now.
    pub clients: usize,
    /// Clients accepted since the start.
    pub accepted: u64,
    /// Frames not sent to a client because its queue was full.
    pub dropped: u64,
    /// Frames clients sent onto the bus, cyclic sends included.
    pub sent: u64,
    /// Frames clients sent that the gateway's transmit queue had no room for.
    pub refused: u64,
    /// Messages ignored: malformed, unknown, or not valid in the client's mode.
    pub malformed: u64,
    /// Failed `accept` calls (e.g. out of file descriptors).
    pub accept_errors: u64,
    /// Connections closed at once because `max_clients` were connected.
    pub turned_away: u64,
}

struct Client {
    id: u64,
    /// `None` until the client opened the bus.
    mode: Option<Mode>,
    tx: mpsc::Sender<String>,
    dropped: u64,
    bcm: Bcm,
}

impl Client {
    /// Queues a message; false when the queue was full and it was dropped.
    fn queue(&mut self, line: String) -> bool {
        if self.tx.try_send(line).is_ok() {
            return true;
        }
        self.dropped += 1;
        if self.dropped.is_power_of_two() {
            tracing::warn!(
                client = self.id,
                dropped = self.dropped,
                "gateway client too slow: frames dropped"
            );
        }
        false
    }
}

/// At most one warning per [`REPORT_INTERVAL`] about what clients did wrong, counting the
/// messages since the last one; each is logged at debug level.
#[derive(Default)]
struct LogLimit {
    last: Option<Instant>,
    unreported: u64,
}

impl LogLimit {
    /// Counts one more; the count to report when a warning is due (the first at once, then at
    /// most one per interval), `None` when it is not.
    fn tick(&mut self) -> Option<u64> {
        self.unreported += 1;
        let now = Instant::now();
        if self
            .last
            .is_none_or(|t| now.saturating_duration_since(t) >= REPORT_INTERVAL)
        {
            self.last = Some(now);
            return Some(std::mem::take(&mut self.unreported));
        }
        None
    }

    fn note(&mut self, client: u64, what: &str) {
        tracing::debug!(client, "gateway ignored a message: {what}");
        if let Some(n) = self.tick() {
            tracing::warn!(
                client,
                ignored = n,
                "gateway ignored {n} client message{}, last: {what}",
                if n == 1 { "" } else { "s" }
            );
        }
    }
}

struct Shared {
    clients: Vec<Client>,
    /// Frames submitted through the gateway's controller, oldest first, with the client that
    /// sent each: the bus sends them in this order, so the head tells whose frame came out.
    in_flight: VecDeque<(u64, Frame)>,
    stats: GatewayStats,
    log: LogLimit,
    /// Warnings about connections turned away, rate-limited apart from `log`.
    full: LogLimit,
    hub: Addr<Hub>,
    /// The gateway's controller on the bus, once attached.
    node: Option<NodeId>,
    /// The timer the hub holds for the gateway: what the last wake reported.
    armed: Option<BusTime>,
    /// The hub was asked for a wake that has not come yet.
    poked: bool,
    /// The hub's epoch: frames go out with their bus time stamped with it, as the trace has them.
    epoch: Epoch,
}

impl Shared {
    fn malformed(&mut self, client: u64, what: &Malformed) {
        self.stats.malformed += 1;
        self.log.note(client, &what.0);
    }

    /// Makes sure the hub wakes the timers by `at` (`None`: at once). The hub learns a node's
    /// next deadline only from its answer to a wake, so a timer set between wakes needs one now:
    /// `SetHung(node, false)`, which on a node that is not hung only wakes it at the present.
    fn wake_by(&mut self, at: Option<BusTime>) {
        let needed = match at {
            None => true,
            Some(t) => self.armed.is_none_or(|a| t < a),
        };
        if needed
            && !self.poked
            && let Some(node) = self.node
        {
            self.poked = true;
            self.hub.do_send(Control::SetHung(node, false));
        }
    }
}

/// A running gateway.
pub struct Gateway {
    /// The address it listens on.
    pub addr: SocketAddr,
    shared: Rc<RefCell<Shared>>,
}

impl Gateway {
    /// Binds `bind`, attaches a controller for the gateway to the hub, and serves in the
    /// background of the current actor system; sends the discovery beacon if the configuration
    /// asks for it and the address allows it.
    pub async fn start(hub: Addr<Hub>, bind: SocketAddr, config: GatewayConfig) -> Result<Gateway, Error> {
        let listener = listen(bind).map_err(|source| Error::Listen { addr: bind, source })?;
        let addr = listener
            .local_addr()
            .map_err(|source| Error::Listen { addr: bind, source })?;
        let epoch = hub.send(GetEpoch).await?;
        let shared = Rc::new(RefCell::new(Shared {
            clients: Vec::new(),
            in_flight: VecDeque::new(),
            stats: GatewayStats::default(),
            log: LogLimit::default(),
            full: LogLimit::default(),
            hub: hub.clone(),
            node: None,
            armed: None,
            poked: false,
            epoch,
        }));
        let timers = Timers {
            shared: shared.clone(),
        }
        .start();
        let node = hub
            .send(Attach {
                controller: ControllerConfig {
                    tx_queue_len: 256,
                    ..ControllerConfig::named("gateway")
                }
                .with_filter(Filter::Nothing),
                node: Some(timers.recipient()),
                reaction: std::time::Duration::ZERO,
            })
            .await?;
        shared.borrow_mut().node = Some(node);
        let (tx, rx) = mpsc::channel(4096);
        hub.send(Subscribe(tx)).await?;
        actix::spawn(distribute(rx, node, shared.clone()));
        actix::spawn(accept(listener, hub, node, config.clone(), shared.clone()));
        match config.beacon_port.map(|port| beacon::target(addr, port)) {
            Some(Some(to)) => {
                actix::spawn(beacon::run(addr, to, config.bus_name));
            }
            Some(None) => {
                tracing::info!(%addr, "no socketcand beacon: it is sent from loopback addresses only")
            }
            None => {}
        }
        Ok(Gateway { addr, shared })
    }

    /// Its counters.
    pub fn stats(&self) -> GatewayStats {
        self.shared.borrow().stats.clone()
    }
}

/// Connections the kernel completes and keeps for `accept`. The usual 128 would let a burst of
/// clients overflow it: the kernel then drops or answers with SYN cookies, and a connection the
/// client thinks is made may never reach the gateway, neither served nor closed.
const BACKLOG: u32 = 1024;

/// A listener on `bind` with [`BACKLOG`], reusing the address as servers do.
fn listen(bind: SocketAddr) -> std::io::Result<TcpListener> {
    let socket = match bind {
        SocketAddr::V4(_) => tokio::net::TcpSocket::new_v4()?,
        SocketAddr::V6(_) => tokio::net::TcpSocket::new_v6()?,
    };
    socket.set_reuseaddr(true)?;
    socket.bind(bind)?;
    socket.listen(BACKLOG)
}

/// Runs the BCM clients' cyclic sends and throttle timers when the hub wakes it, at the bus's
/// time; the frames it sends go out through the gateway's controller.
struct Timers {
    shared: Rc<RefCell<Shared>>,
}

impl Actor for Timers {
    type Context = Context<Self>;
}

impl Handler<Wake> for Timers {
    type Result = ();

    fn handle(&mut self, wake: Wake, _: &mut Context<Self>) {
        let Wake { now, inputs, reply } = wake;
        // One controller: its slot is the node's, and its frames are all handled (dropped: the
        // gateway's clients hear of frames as observers).
        let slot = inputs.first().map_or(0, |i| i.slot);
        let frames: u64 = inputs.iter().map(|i| i.frames.len() as u64).sum();
        let mut sh = self.shared.borrow_mut();
        let sh = &mut *sh;
        let mut transmit = Vec::new();
        let mut deliver = Vec::new();
        let mut next: Option<BusTime> = None;
        let mut dropped = 0;
        let epoch = sh.epoch;
        for c in &mut sh.clients {
            let first = transmit.len();
            c.bcm.run(now, &mut transmit, &mut deliver);
            for f in &transmit[first..] {
                sh.in_flight.push_back((c.id, *f));
            }
            for (at, f) in deliver.drain(..) {
                dropped += u64::from(!c.queue(protocol::bcm_frame_message(epoch.stamp(at), &f)));
            }
            next = [next, c.bcm.deadline()].into_iter().flatten().min();
        }
        sh.stats.sent += transmit.len() as u64;
        sh.stats.dropped += dropped;
        sh.armed = next;
        sh.poked = false;
        let report = Report {
            transmit,
            next_timeout: next,
            frames_handled: frames,
            ..Report::default()
        };
        reply.finish(slot, report);
    }
}

/// Fans every frame on the bus out to the clients in raw mode and to the subscriptions of those
/// in BCM mode.
async fn distribute(mut rx: mpsc::Receiver<Observed>, gateway: NodeId, shared: Rc<RefCell<Shared>>) {
    while let Some(o) = rx.recv().await {
        let mut sh = shared.borrow_mut();
        let origin = if o.node == gateway {
            // Frames the bus dropped (bus off) never come out: skip past them.
            while sh.in_flight.front().is_some_and(|(_, f)| *f != o.frame) {
                sh.in_flight.pop_front();
            }
            sh.in_flight.pop_front().map(|(c, _)| c)
        } else {
            None
        };
        let mut raw_line = None;
        let mut dropped = 0;
        let mut timer: Option<BusTime> = None;
        let epoch = sh.epoch;
        for c in &mut sh.clients {
            let line = match c.mode {
                // A raw client does not get its own frames back, as with a raw CAN socket.
                Some(Mode::Raw) if Some(c.id) != origin => raw_line
                    .get_or_insert_with(|| protocol::frame_message(epoch.stamp(o.at), &o.frame))
                    .clone(),
                // A BCM client gets the frames it subscribed to, its own included, as the
                // kernel's broadcast manager delivers them.
                Some(Mode::Bcm) => {
                    let (now, started) = c.bcm.frame(o.at, &o.frame);
                    timer = [timer, started].into_iter().flatten().min();
                    match now {
                        Some((at, f)) => protocol::bcm_frame_message(epoch.stamp(at), &f),
                        None => continue,
                    }
                }
                _ => continue,
            };
            dropped += u64::from(!c.queue(line));
        }
        sh.stats.dropped += dropped;
        if let Some(t) = timer {
            sh.wake_by(Some(t));
        }
    }
}

async fn accept(
    listener: TcpListener,
    hub: Addr<Hub>,
    node: NodeId,
    config: GatewayConfig,
    shared: Rc<RefCell<Shared>>,
) {
    let mut next_id = 1;
    let mut backoff = AcceptBackoff::default();
    loop {
        let (stream, peer) = match listener.accept().await {
            Ok(x) => {
                if let Some(n) = backoff.succeeded(Instant::now()) {
                    tracing::warn!(errors = n, "gateway accepting again after {n} more accept errors");
                }
                x
            }
            Err(e) => {
                // The connection stays queued and the listener ready: retrying at once would
                // fail again at once. Wait, and log at a bounded rate; the clients already
                // connected are served meanwhile.
                shared.borrow_mut().stats.accept_errors += 1;
                let (wait, report) = backoff.failed(Instant::now());
                match report {
                    Some(1) => tracing::warn!(error = %e, "gateway accept failed; backing off"),
                    Some(n) => tracing::warn!(
                        error = %e,
                        errors = n,
                        "{n} gateway accept errors in the last {} s",
                        REPORT_INTERVAL.as_secs()
                    ),
                    None => {}
                }
                tokio::time::sleep(wait).await;
                continue;
            }
        };
        // Counted here, before the next accept, so that a burst of connections cannot pass
        // the limit while the ones before it are still starting.
        let mut sh = shared.borrow_mut();
        if sh.clients.len() >= config.max_clients {
            // Closed at once (the stream is dropped): socketcand's clients have no message
            // for this.
            sh.stats.turned_away += 1;
            tracing::debug!(%peer, "gateway full: connection closed");
            if let Some(n) = sh.full.tick() {
                tracing::warn!(
                    %peer,
                    closed = n,
                    "gateway full ({} clients): {n} connection{} closed",
                    config.max_clients,
                    if n == 1 { "" } else { "s" }
                );
            }
            continue;
        }
        let _ = stream.set_nodelay(true);
        // A bounded kernel buffer too: what a client does not read piles up in its queue, where
        // it is counted and dropped, not in the kernel.
        let _ = socket2::SockRef::from(&stream).set_send_buffer_size(SEND_BUFFER);
        let id = next_id;
        next_id += 1;
        let (tx, rx) = mpsc::channel::<String>(config.client_queue.max(1));
        sh.clients.push(Client {
            id,
            mode: None,
            tx: tx.clone(),
            dropped: 0,
            bcm: Bcm::default(),
        });
        sh.stats.clients += 1;
        sh.stats.accepted += 1;
        drop(sh);
        tracing::info!(client = id, %peer, "gateway client connected");
        let link = Link { tx, rx };
        actix::spawn(serve(
            stream,
            id,
            link,
            hub.clone(),
            node,
            config.bus_name.clone(),
            shared.clone(),
        ));
    }
}

/// The queue of one client's outgoing messages, made when it was counted in.
struct Link {
    tx: mpsc::Sender<String>,
    rx: mpsc::Receiver<String>,
}

/// Carries out one action for client `id`, whose session is now in `mode`; what the connection
/// does next.
fn apply(sh: &mut Shared, id: u64, mode: Option<Mode>, action: Action) -> Action {
    let Some(c) = sh.clients.iter_mut().find(|c| c.id == id) else {
        return Action::Close;
    };
    c.mode = mode;
    let refused = match &action {
        Action::Switch(_) => {
            // Leaving BCM mode closes socketcand's BCM socket, which ends its jobs.
            c.bcm = Bcm::default();
            None
        }
        Action::Bcm(command) => match *command {
            Command::Add { interval, frame } => {
                let ok = c.bcm.add(interval, frame);
                if ok {
                    sh.wake_by(None);
                }
                (!ok).then_some("too many cyclic sends")
            }
            // The kernel sets up an idle job for an update without one: nothing to see.
            Command::Update(frame) => {
                c.bcm.update(frame);
                None
            }
            Command::Delete(ident) => {
                c.bcm.delete(ident);
                None
            }
            Command::Subscribe { throttle, id } => {
                (!c.bcm.subscribe(id, throttle, None)).then_some("too many subscriptions")
            }
            Command::Filter { throttle, id, mask } => {
                (!c.bcm.subscribe(id, throttle, Some(mask))).then_some("too many subscriptions")
            }
            Command::Unsubscribe(ident) => {
                c.bcm.unsubscribe(ident);
                None
            }
            Command::Open(_) | Command::Mode(_) | Command::Echo | Command::Send(_) => None,
        },
        Action::Ignore(why) => {
            sh.malformed(id, why);
            None
        }
        Action::Close => {
            tracing::info!(client = id, "gateway client asked for another bus: closed");
            None
        }
        Action::Reply(_) | Action::Send(_) => None,
    };
    if let Some(why) = refused {
        sh.malformed(id, &Malformed(why.into()));
    }
    action
}

/// Serves client `id`, already among the shared clients, until it goes; then forgets it.
async fn serve(
    stream: TcpStream,
    id: u64,
    link: Link,
    hub: Addr<Hub>,
    node: NodeId,
    bus_name: String,
    shared: Rc<RefCell<Shared>>,
) {
    let (mut reader, mut writer) = stream.into_split();
    let Link { tx, mut rx } = link;
    // The writer: one write per message, as python-can reads the greeting and each `< ok >`
    // separately; and a pause after each `< ok >`, since python-can takes the next read for the
    // `< ok >` alone and fails when a frame came with it (TCP joins writes that a slow reader
    // finds waiting together).
    let write = actix::spawn(async move {
        while let Some(line) = rx.recv().await {
            if writer.write_all(line.as_bytes()).await.is_err() {
                break;
            }
            if line == "< ok >" {
                tokio::time::sleep(OK_PAUSE).await;
            }
        }
    });
    let reply = |text: &str| {
        // Replies go through the same bounded queue; a client that does not read loses them.
        let _ = tx.try_send(text.to_string());
    };
    reply("< hi >");
    let mut splitter = Splitter::default();
    let mut session = Session::default();
    let mut buf = [0u8; 1024];
    'read: loop {
        let n = match reader.read(&mut buf).await {
            Ok(0) | Err(_) => break,
            Ok(n) => n,
        };
        for message in splitter.push(&buf[..n]) {
            let action = session.handle(&bus_name, message);
            // Bound first: a borrow in the match's head would last through the arms.
            let action = apply(&mut shared.borrow_mut(), id, session.mode, action);
            match action {
                Action::Reply(text) => reply(text),
                Action::Switch(_) => reply("< ok >"),
                Action::Close => break 'read,
                Action::Bcm(_) | Action::Ignore(_) => {}
                Action::Send(frame) => {
                    // Noted before it is submitted: the bus may send it before `send` returns.
                    shared.borrow_mut().in_flight.push_back((id, frame));
                    let queued = matches!(hub.send(Submit { node, frame }).await, Ok(Ok(true)));
                    let mut sh = shared.borrow_mut();
                    if queued {
                        sh.stats.sent += 1;
                    } else {
                        if let Some(i) = sh.in_flight.iter().rposition(|(c, f)| *c == id && *f == frame) {
                            sh.in_flight.remove(i);
                        }
                        sh.stats.refused += 1;
                        sh.log.note(id, "transmit queue full: frame not sent");
                    }
                }
            }
        }
    }
    drop(tx);
    write.abort();
    let mut sh = shared.borrow_mut();
    sh.clients.retain(|c| c.id != id);
    sh.stats.clients -= 1;
    tracing::info!(client = id, "gateway client gone");
}
