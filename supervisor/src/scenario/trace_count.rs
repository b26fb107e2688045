//! A trace writer that counts the candump lines passing through it ([`TraceTally`]) and hands
//! them on unchanged, to a file or to nowhere.
//!
//! Contract: lines may arrive split across writes; a line is counted once its newline has
//! arrived. The counts are shared (`Rc`): the hub owns the writer, the runner reads the counts.

use super::books::TraceTally;
use std::cell::RefCell;
use std::io::{self, Write};
use std::rc::Rc;

/// Counts, then writes on.
pub struct CountingWriter {
    inner: Option<Box<dyn Write>>,
    partial: Vec<u8>,
    tally: Rc<RefCell<TraceTally>>,
}

impl CountingWriter {
    /// Counts what is written and passes it to `inner` (when there is one).
    pub fn new(inner: Option<Box<dyn Write>>) -> (CountingWriter, Rc<RefCell<TraceTally>>) {
        let tally = Rc::new(RefCell::new(TraceTally::default()));
        let w = CountingWriter {
            inner,
            partial: Vec::new(),
            tally: tally.clone(),
        };
        (w, tally)
    }

    fn count(tally: &mut TraceTally, line: &[u8]) {
        match std::str::from_utf8(line) {
            Ok(text) => tally.line(text),
            Err(_) => tally.other += 1,
        }
    }
}

impl Write for CountingWriter {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = match self.inner.as_mut() {
            Some(w) => w.write(buf)?,
            None => buf.len(),
        };
        let mut tally = self.tally.borrow_mut();
        let mut rest = &buf[..n];
        while let Some(i) = rest.iter().position(|&b| b == b'\n') {
            if self.partial.is_empty() {
                Self::count(&mut tally, &rest[..i]);
            } else {
                self.partial.extend_from_slice(&rest[..i]);
                Self::count(&mut tally, &self.partial);
                self.partial.clear();
            }
            rest = &rest[i + 1..];
        }
        self.partial.extend_from_slice(rest);
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        match self.inner.as_mut() {
            Some(w) => w.flush(),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Clone, Default)]
    struct Shared(Rc<RefCell<Vec<u8>>>);
    impl Write for Shared {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            self.0.borrow_mut().extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn lines_split_across_writes_are_counted_once_and_passed_on_unchanged() {
        let text = "(0000000001.000100) harv0 0601F5D0#200D0002FFBFFF00\n\
                    (0000000001.000700) harv0 20000088#0000800000000800\n\
                    (0000000001.001200) harv0 0500A0F5#01\n";
        let out = Shared::default();
        let (mut w, tally) = CountingWriter::new(Some(Box::new(out.clone())));
        for chunk in text.as_bytes().chunks(7) {
            w.write_all(chunk).unwrap();
        }
        // Half a line is not a line yet.
        w.write_all(b"(0000000002.000000) harv0 0601F5").unwrap();
        let t = *tally.borrow();
        assert_eq!((t.frames, t.to_monitor, t.error_frames, t.other), (2, 1, 1, 0));
        w.write_all(b"D0#01\n").unwrap();
        assert_eq!(tally.borrow().to_monitor, 2);
        assert!(
            String::from_utf8(out.0.borrow().clone())
                .unwrap()
                .starts_with(text)
        );
    }
}
