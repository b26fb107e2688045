//! What every trace format reads and writes: a time since 1970, the interface that saw it, and
//! the frame or error frame.
//!
//! Contract: an [`Item`] is format-neutral. Frames are on the bus's interface (`harv0`), a
//! controller's error frames on its own (`harv0.D2`), as harvemu's candump logs name them. An
//! [`ItemWriter`] takes items in time order and is ended by [`ItemWriter::finish`], which
//! writes whatever the format keeps for its end (an ASC footer, a BLF header's counts, an MF4's
//! block lengths); after `finish` items are refused. [`Stamped`] makes any item writer a trace
//! [`Sink`] for the hub, stamping bus time with the run's epoch.

use super::Entry;
use crate::time::{Epoch, Stamp};
use crate::trace::{Kind, Record, Sink, Source};
use std::io;

/// One entry of a trace, whatever its format.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Item {
    /// Nanoseconds since 1970.
    pub at: Stamp,
    /// The interface: `harv0` for a frame, `harv0.D2` for controller D2's error frame.
    pub interface: String,
    /// The frame or error frame.
    pub entry: Entry,
}

/// Writes items in one format.
pub trait ItemWriter {
    /// Takes the next item (items come in time order).
    fn write(&mut self, item: &Item) -> io::Result<()>;
    /// Passes on what is buffered, as far as the format allows before its end.
    fn flush(&mut self) -> io::Result<()>;
    /// Keeps a remark where the format has room for one (an ASC `//` comment); the others
    /// leave it out.
    fn note(&mut self, _text: &str) -> io::Result<()> {
        Ok(())
    }
    /// Ends the file: what the format writes last or goes back to fill in. Items given after
    /// it are refused. Calling it again does nothing.
    fn finish(&mut self) -> io::Result<()>;
}

/// An [`ItemWriter`] as a hub [`Sink`]: each record stamped with the run's epoch.
pub struct Stamped<W> {
    writer: W,
    epoch: Epoch,
    item: Item,
}

impl<W: ItemWriter> Stamped<W> {
    /// `writer`, with bus time zero at `epoch`.
    pub fn new(writer: W, epoch: Epoch) -> Stamped<W> {
        Stamped {
            writer,
            epoch,
            item: Item {
                at: Stamp(0),
                interface: String::with_capacity(32),
                entry: Entry::Error(None),
            },
        }
    }

    /// The writer.
    pub fn writer(&mut self) -> &mut W {
        &mut self.writer
    }
}

/// The item a record gives, in `item` (whose interface string is reused).
pub fn fill(item: &mut Item, epoch: Epoch, r: &Record<'_>) {
    item.at = epoch.stamp(r.at);
    item.interface.clear();
    item.interface.push_str(r.bus);
    if let Source::Controller { name, .. } = r.source {
        item.interface.push('.');
        // One word, as an interface name would be (as the candump writer does).
        item.interface
            .extend(name.chars().map(|c| if c.is_ascii_graphic() { c } else { '_' }));
    }
    item.entry = match r.kind {
        Kind::Frame(f) => Entry::Frame(f),
        Kind::Error(e) => Entry::Error(Some(e)),
    };
}

impl<W: ItemWriter> Sink for Stamped<W> {
    fn record(&mut self, r: &Record<'_>) -> io::Result<()> {
        fill(&mut self.item, self.epoch, r);
        self.writer.write(&self.item)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.writer.flush()
    }
}

impl<W: ItemWriter + ?Sized> ItemWriter for Box<W> {
    fn write(&mut self, item: &Item) -> io::Result<()> {
        (**self).write(item)
    }
    fn flush(&mut self) -> io::Result<()> {
        (**self).flush()
    }
    fn note(&mut self, text: &str) -> io::Result<()> {
        (**self).note(text)
    }
    fn finish(&mut self) -> io::Result<()> {
        (**self).finish()
    }
}
