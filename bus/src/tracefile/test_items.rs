//! Items for the trace format tests: a frame, a remote frame or an error frame at a time on an
//! interface.

use super::{Entry, Item};
use crate::Frame;
use crate::time::Stamp;
use crate::trace::ErrorFrame;

pub(super) fn item(at: u64, interface: &str, entry: Entry) -> Item {
    Item {
        at: Stamp(at),
        interface: interface.to_string(),
        entry,
    }
}

pub(super) fn data(id: u32, extended: bool, bytes: &[u8]) -> Entry {
    Entry::Frame(if extended {
        Frame::extended(id, bytes).unwrap()
    } else {
        Frame::base(id as u16, bytes).unwrap()
    })
}

pub(super) fn remote(id: u32, extended: bool, dlc: usize) -> Entry {
    let id: crate::Id = if extended {
        crate::extended_id(id).unwrap().into()
    } else {
        crate::standard_id(id as u16).unwrap().into()
    };
    Entry::Frame(Frame::new_remote(id, dlc).unwrap())
}

pub(super) fn error(classes: u32, details: [u8; 8]) -> Entry {
    Entry::Error(Some(ErrorFrame {
        can_id: crate::filter::CAN_ERR_FLAG | classes,
        data: details,
    }))
}
