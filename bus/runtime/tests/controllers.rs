//! A node with two controllers on one bus (a board with two CAN chips): each has its own place on
//! the bus, its inputs reach the node tagged with its index, the node's commands reach the
//! controller they name, and the node crashes as a whole. In virtual time.

mod common;

use actix::prelude::*;
use bus::Frame;
use bus::candump::parse_frame;
use bus::engine::{ControllerConfig, NodeId};
use bus::node::{ControllerCommand, NodeLogic};
use bus::time::BusTime;
use bus_runtime::hub::{
    Attach, AttachControllers, GetCrashed, GetSnapshot, Hub, HubConfig, RunUntil, runtime,
};
use bus_runtime::node::NodeActor;
use common::Periodic;
use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;
use std::time::Duration;

/// What the two-controller node heard: (controller, frame) in order.
type Heard = Rc<RefCell<Vec<(usize, Frame)>>>;

/// At its first wake, controller 1 sends `send`; then it only listens. Fails at `fail_at`.
struct Board {
    heard: Heard,
    commands: VecDeque<(usize, ControllerCommand)>,
    fail_at: Option<BusTime>,
    failed: Option<String>,
    next: Option<BusTime>,
}

impl Board {
    fn new(heard: Heard, send: &str, fail_at: Option<BusTime>) -> Board {
        let frame = parse_frame(send).unwrap();
        Board {
            heard,
            commands: VecDeque::from([(1, ControllerCommand::Transmit(frame))]),
            fail_at,
            failed: None,
            next: fail_at,
        }
    }
}

impl NodeLogic for Board {
    fn handle_frame(&mut self, now: BusTime, frame: &Frame) {
        self.handle_frame_on(0, now, frame);
    }
    fn handle_frame_on(&mut self, controller: usize, _: BusTime, frame: &Frame) {
        self.heard.borrow_mut().push((controller, *frame));
    }
    fn handle_timeout(&mut self, now: BusTime) {
        if self.fail_at.is_some_and(|t| t <= now) {
            self.failed = Some("board failed".into());
            self.next = None;
        }
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        None
    }
    fn poll_command(&mut self) -> Option<(usize, ControllerCommand)> {
        self.commands.pop_front()
    }
    fn poll_timeout(&self) -> Option<BusTime> {
        self.next
    }
    fn failed(&self) -> Option<String> {
        self.failed.clone()
    }
}

/// What a run gives back.
struct Run {
    /// What the board heard, by controller.
    heard: Vec<(usize, Frame)>,
    snap: bus_runtime::hub::Snapshot,
    crashed: Vec<NodeId>,
    /// The board's controllers.
    ids: Vec<NodeId>,
}

/// A hub with a node `p` sending 123#11 every 10 ms from 1 ms, and `board`, whose controllers
/// `board` and `board.1` are attached together; runs for 25 ms.
fn run(fail_at: Option<BusTime>) -> Run {
    let heard = Heard::default();
    let h = heard.clone();
    let (snap, crashed, ids) = System::with_tokio_rt(|| runtime(true).unwrap()).block_on(async move {
        let hub = Hub::new(HubConfig::new(false), Vec::new()).unwrap().start();
        let p = NodeActor::new("p", Box::new(Periodic::new("123#11", 10, 1000))).start();
        hub.send(Attach {
            controller: ControllerConfig::named("p"),
            node: Some(p.recipient()),
            reaction: Duration::ZERO,
        })
        .await
        .unwrap();
        let board = NodeActor::new("board", Box::new(Board::new(h, "456#22", fail_at))).start();
        let ids = hub
            .send(AttachControllers {
                controllers: vec![
                    ControllerConfig::named("board"),
                    ControllerConfig::named("board.1"),
                ],
                node: Some(board.recipient()),
                reaction: Duration::ZERO,
            })
            .await
            .unwrap()
            .unwrap();
        hub.send(RunUntil(BusTime::from_millis(25)))
            .await
            .unwrap()
            .unwrap();
        let crashed = hub.send(GetCrashed).await.unwrap();
        let snap = hub.send(GetSnapshot).await.unwrap();
        (snap, crashed.into_iter().map(|(id, _)| id).collect(), ids)
    });
    let heard = heard.borrow().clone();
    Run {
        heard,
        snap,
        crashed,
        ids,
    }
}

#[test]
fn two_controllers_of_one_node_are_two_places_on_the_bus() {
    let Run {
        heard,
        snap,
        crashed,
        ids,
    } = run(None);
    assert!(crashed.is_empty(), "{crashed:?}");
    assert_eq!(ids, [NodeId(1), NodeId(2)]);
    let (ours, theirs) = (parse_frame("456#22").unwrap(), parse_frame("123#11").unwrap());
    // Controller 1's frame reaches controller 0 as any other node's would, and not controller 1
    // itself; p's frames at 1, 11 and 21 ms reach both.
    let of = |k: usize| -> Vec<Frame> { heard.iter().filter(|(c, _)| *c == k).map(|(_, f)| *f).collect() };
    let mut zero = of(0);
    zero.sort_by_key(|f| f.raw_id());
    assert_eq!(zero, [theirs, theirs, theirs, ours]);
    assert_eq!(of(1), [theirs, theirs, theirs]);
    let names: Vec<&str> = snap.nodes.iter().map(|n| n.name.as_str()).collect();
    assert_eq!(names, ["p", "board", "board.1"]);
    let sent: Vec<u64> = snap.nodes.iter().map(|n| n.counters.tx_frames).collect();
    assert_eq!(sent, [3, 0, 1]);
    let received: Vec<u64> = snap.nodes.iter().map(|n| n.counters.rx_frames).collect();
    assert_eq!(received, [1, 4, 3]);
}

#[test]
fn a_node_with_two_controllers_crashes_as_a_whole() {
    let r = run(Some(BusTime::from_millis(5)));
    assert_eq!(r.crashed, r.ids);
}
