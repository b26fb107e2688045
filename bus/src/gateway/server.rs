//! The TCP side of the gateway, on the actor system's tokio runtime.

use super::backoff::{AcceptBackoff, REPORT_INTERVAL};
use super::protocol::{self, Command, Splitter};
use crate::engine::{ControllerConfig, Filter, NodeId};
use crate::hub::{Attach, Hub, Observed, Submit, Subscribe};
use crate::{Error, Frame};
use actix::Addr;
use std::cell::RefCell;
use std::collections::VecDeque;
use std::net::SocketAddr;
use std::rc::Rc;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;

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
}

impl Default for GatewayConfig {
    fn default() -> Self {
        GatewayConfig {
            bus_name: "harv0".into(),
            client_queue: 1024,
            max_clients: 256,
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
    /// Frames clients sent onto the bus.
    pub sent: u64,
    /// Malformed messages answered with an error.
    pub errors: u64,
    /// Failed `accept` calls (e.g. out of file descriptors).
    pub accept_errors: u64,
}

struct Client {
    id: u64,
    raw: bool,
    tx: mpsc::Sender<String>,
    dropped: u64,
}

struct Shared {
    clients: Vec<Client>,
    /// Frames submitted through the gateway's controller, oldest first, with the client that
    /// sent each: the bus sends them in this order, so the head tells whose frame came out.
    in_flight: VecDeque<(u64, Frame)>,
    stats: GatewayStats,
}

/// A running gateway.
pub struct Gateway {
    /// The address it listens on.
    pub addr: SocketAddr,
    shared: Rc<RefCell<Shared>>,
}

impl Gateway {
    /// Binds `bind`, attaches a controller for the gateway to the hub, and serves in the
    /// background of the current actor system.
    pub async fn start(hub: Addr<Hub>, bind: SocketAddr, config: GatewayConfig) -> Result<Gateway, Error> {
        let listener = TcpListener::bind(bind)
            .await
            .map_err(|e| Error::Syntax(format!("cannot listen on {bind}: {e}")))?;
        let addr = listener.local_addr().map_err(|e| Error::Syntax(e.to_string()))?;
        let node = hub
            .send(Attach {
                controller: ControllerConfig {
                    tx_queue_len: 256,
                    ..ControllerConfig::named("gateway")
                }
                .with_filter(Filter::Nothing),
                node: None,
                reaction: std::time::Duration::ZERO,
            })
            .await
            .map_err(|e| Error::Syntax(e.to_string()))?;
        let (tx, rx) = mpsc::channel(4096);
        hub.send(Subscribe(tx))
            .await
            .map_err(|e| Error::Syntax(e.to_string()))?;
        let shared = Rc::new(RefCell::new(Shared {
            clients: Vec::new(),
            in_flight: VecDeque::new(),
            stats: GatewayStats::default(),
        }));
        actix::spawn(distribute(rx, node, shared.clone()));
        actix::spawn(accept(listener, hub, node, config, shared.clone()));
        Ok(Gateway { addr, shared })
    }

    /// Its counters.
    pub fn stats(&self) -> GatewayStats {
        self.shared.borrow().stats.clone()
    }
}

/// Fans every frame on the bus out to the clients in raw mode.
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
        let line = protocol::frame_message(o.at, &o.frame);
        let mut dropped = 0;
        for c in sh.clients.iter_mut().filter(|c| c.raw && Some(c.id) != origin) {
            if c.tx.try_send(line.clone()).is_err() {
                c.dropped += 1;
                dropped += 1;
                if c.dropped.is_power_of_two() {
                    tracing::warn!(
                        client = c.id,
                        dropped = c.dropped,
                        "gateway client too slow: frames dropped"
                    );
                }
            }
        }
        sh.stats.dropped += dropped;
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
                if let Some(n) = backoff.succeeded(std::time::Instant::now()) {
                    tracing::warn!(errors = n, "gateway accepting again after {n} more accept errors");
                }
                x
            }
            Err(e) => {
                // The connection stays queued and the listener ready: retrying at once would
                // fail again at once. Wait, and log at a bounded rate; the clients already
                // connected are served meanwhile.
                shared.borrow_mut().stats.accept_errors += 1;
                let (wait, report) = backoff.failed(std::time::Instant::now());
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
        let _ = stream.set_nodelay(true);
        // A bounded kernel buffer too: what a client does not read piles up in its queue, where
        // it is counted and dropped, not in the kernel.
        let _ = socket2::SockRef::from(&stream).set_send_buffer_size(SEND_BUFFER);
        if shared.borrow().clients.len() >= config.max_clients {
            actix::spawn(async move {
                let mut stream = stream;
                let _ = stream
                    .write_all(protocol::error_message("too many clients").as_bytes())
                    .await;
            });
            continue;
        }
        let id = next_id;
        next_id += 1;
        tracing::info!(client = id, %peer, "gateway client connected");
        actix::spawn(serve(
            stream,
            id,
            hub.clone(),
            node,
            config.clone(),
            shared.clone(),
        ));
    }
}

async fn serve(
    stream: TcpStream,
    id: u64,
    hub: Addr<Hub>,
    node: NodeId,
    config: GatewayConfig,
    shared: Rc<RefCell<Shared>>,
) {
    let (mut reader, mut writer) = stream.into_split();
    let (tx, mut rx) = mpsc::channel::<String>(config.client_queue.max(1));
    {
        let mut sh = shared.borrow_mut();
        sh.clients.push(Client {
            id,
            raw: false,
            tx: tx.clone(),
            dropped: 0,
        });
        sh.stats.clients += 1;
        sh.stats.accepted += 1;
    }
    // The writer: one write per message, as python-can reads the greeting and each `< ok >`
    // separately.
    let write = actix::spawn(async move {
        while let Some(line) = rx.recv().await {
            if writer.write_all(line.as_bytes()).await.is_err() {
                break;
            }
        }
    });
    let reply = |text: String| {
        // Replies go through the same bounded queue; a client that does not read loses them.
        let _ = tx.try_send(text);
    };
    reply("< hi >".into());
    let mut splitter = Splitter::default();
    let mut opened = false;
    let mut buf = [0u8; 1024];
    loop {
        let n = match reader.read(&mut buf).await {
            Ok(0) | Err(_) => break,
            Ok(n) => n,
        };
        for message in splitter.push(&buf[..n]) {
            let command = message.and_then(|m| protocol::parse(&m));
            match command {
                Ok(Command::Open(bus)) if bus == config.bus_name => {
                    opened = true;
                    reply("< ok >".into());
                }
                Ok(Command::Open(bus)) => reply(protocol::error_message(&format!(
                    "no bus '{bus}' (this server has '{}')",
                    config.bus_name
                ))),
                Ok(Command::Echo) => reply("< echo >".into()),
                Ok(_) if !opened => reply(protocol::error_message("open a bus first")),
                Ok(Command::RawMode) => {
                    if let Some(c) = shared.borrow_mut().clients.iter_mut().find(|c| c.id == id) {
                        c.raw = true;
                    }
                    reply("< ok >".into());
                }
                Ok(Command::Send(frame)) => {
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
                        drop(sh);
                        reply(protocol::error_message("transmit queue full or bus gone"));
                    }
                }
                Err(e) => {
                    shared.borrow_mut().stats.errors += 1;
                    reply(protocol::error_message(&e));
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
