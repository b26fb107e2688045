//! Lines of a trace read with a bounded buffer.
//!
//! Contract: [`Lines`] gives the lines of a [`BufRead`] one at a time, without the line break
//! (`\n` or `\r\n`), and never holds more than `limit` + 1 bytes of a line. A line longer than
//! `limit` bytes is [`LineError::TooLong`] as soon as its `limit` + 1st byte is seen: nothing more
//! of it is read then, so input without line breaks (`/dev/zero`) ends at once. Asking for the
//! next line after that first skips the rest of the long one, reading it in the reader's own
//! chunks without keeping it. Line numbers count from 1, long lines included.

use std::io::{self, BufRead, Read};

/// The longest trace line read, in bytes (line break not counted): 64 KiB. Real candump and
/// ASC lines are under 200 bytes; ASC system-variable lines with arrays are the longest.
pub const MAX_LINE: usize = 64 * 1024;

/// How much of a long line [`LineError::TooLong`] keeps, bytes.
const START: usize = 128;

/// How much of the rest of a long line is read at a time when it is skipped, bytes.
const SKIP_CHUNK: u64 = 64 * 1024;

/// Why a line could not be had.
#[derive(Debug)]
pub enum LineError {
    /// Longer than the limit; `start` is its first bytes (at most 128, and never more than the
    /// limit), as text where they are UTF-8.
    TooLong {
        /// The beginning of the line.
        start: String,
    },
    /// The reader failed.
    Io(io::Error),
}

/// The lines of a reader, each at most `limit` bytes.
#[derive(Debug)]
pub struct Lines<R> {
    input: R,
    limit: usize,
    buf: Vec<u8>,
    number: usize,
    /// The previous line was too long and its rest has not been read yet.
    skipping: bool,
}

impl<R: BufRead> Lines<R> {
    /// Lines of `input` of at most `limit` bytes each.
    pub fn new(input: R, limit: usize) -> Lines<R> {
        Lines {
            input,
            limit,
            buf: Vec::new(),
            number: 0,
            skipping: false,
        }
    }

    /// The number of the line last given (or refused); 0 before the first.
    pub fn number(&self) -> usize {
        self.number
    }

    /// The next line; `None` at the end of the input.
    pub fn next_line(&mut self) -> Option<Result<&[u8], LineError>> {
        if self.skipping {
            match self.skip_rest() {
                Ok(true) => self.skipping = false,
                // The long line was the last one.
                Ok(false) => return None,
                Err(e) => return Some(Err(LineError::Io(e))),
            }
        }
        self.buf.clear();
        // The limit, one byte for a `\r` and one for the `\n`: a line that does not end within
        // them is too long whatever follows.
        let most = self.limit as u64 + 2;
        let read = match (&mut self.input).take(most).read_until(b'\n', &mut self.buf) {
            Ok(0) => return None,
            Ok(n) => n as u64,
            Err(e) => {
                self.number += 1;
                return Some(Err(LineError::Io(e)));
            }
        };
        if self.buf.last() == Some(&b'\n') {
            self.buf.pop();
            if self.buf.last() == Some(&b'\r') {
                self.buf.pop();
            }
        } else if read == most {
            // Cut short: the rest of the line is still to come.
            self.skipping = true;
        }
        self.number += 1;
        if self.buf.len() > self.limit {
            let end = START.min(self.limit);
            let start = String::from_utf8_lossy(&self.buf[..end]).into_owned();
            return Some(Err(LineError::TooLong { start }));
        }
        Some(Ok(&self.buf))
    }

    /// Reads up to and including the next `\n`, keeping at most a buffer of it; false at the end
    /// of the input.
    fn skip_rest(&mut self) -> io::Result<bool> {
        loop {
            self.buf.clear();
            let n = (&mut self.input)
                .take(SKIP_CHUNK)
                .read_until(b'\n', &mut self.buf)?;
            if n == 0 {
                return Ok(false);
            }
            if self.buf.last() == Some(&b'\n') {
                return Ok(true);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::io::BufReader;

    /// Every line of `input` with the limit, as `Ok(text)` or `Err(start)`.
    fn all(input: impl BufRead, limit: usize) -> Vec<Result<Vec<u8>, String>> {
        let mut lines = Lines::new(input, limit);
        let mut out = Vec::new();
        while let Some(l) = lines.next_line() {
            out.push(match l {
                Ok(bytes) => Ok(bytes.to_vec()),
                Err(LineError::TooLong { start }) => Err(start),
                Err(LineError::Io(e)) => panic!("{e}"),
            });
            assert_eq!(lines.number(), out.len());
        }
        out
    }

    #[test]
    fn lines_up_to_the_limit_are_given_longer_ones_refused() {
        let got = all(&b"abc\r\nabcd\nabcde\r\n\nab\rc\nxyz"[..], 4);
        let want: Vec<Result<Vec<u8>, String>> = vec![
            Ok(b"abc".to_vec()),
            Ok(b"abcd".to_vec()),
            Err("abcd".into()),
            Ok(vec![]),
            Ok(b"ab\rc".to_vec()),
            Ok(b"xyz".to_vec()),
        ];
        assert_eq!(got, want);
        // Exactly the limit with `\r\n`: the `\r` is the one byte over, and it goes.
        assert_eq!(all(&b"abcd\r\n"[..], 4), vec![Ok(b"abcd".to_vec())]);
        assert_eq!(all(&b"abcd\r"[..], 4), vec![Err("abcd".into())]);
        assert_eq!(all(&b""[..], 4), vec![]);
    }

    #[test]
    fn input_without_line_breaks_stops_at_the_limit() {
        // An endless line: the first call refuses it after limit + 1 bytes.
        let mut zeros = std::io::repeat(0);
        let mut lines = Lines::new(BufReader::with_capacity(100, &mut zeros), 1000);
        match lines.next_line() {
            Some(Err(LineError::TooLong { start })) => assert_eq!(start, "\0".repeat(128)),
            other => panic!("{other:?}"),
        }
        assert_eq!(lines.number(), 1);
        // The rest of a long but finite line is skipped on the next call, kept nowhere.
        let long = [vec![b'x'; 10_000_000], b"\nnext\n".to_vec()].concat();
        let mut lines = Lines::new(BufReader::new(&long[..]), 100);
        assert!(matches!(lines.next_line(), Some(Err(LineError::TooLong { .. }))));
        assert_eq!(
            lines.next_line().map(|l| l.unwrap().to_vec()),
            Some(b"next".to_vec())
        );
        assert!(lines.next_line().is_none());
        // Skipped in chunks: the buffer stays far below the 10 MB of the line.
        assert!(
            lines.buf.capacity() <= 4 * SKIP_CHUNK as usize,
            "{}",
            lines.buf.capacity()
        );
    }

    /// The lines of `input` as `BufRead::split` would give them, with `\r` before `\n` removed.
    fn reference(input: &[u8]) -> Vec<Vec<u8>> {
        let mut out = Vec::new();
        let mut rest = input;
        while !rest.is_empty() {
            let (line, next) = match rest.iter().position(|&b| b == b'\n') {
                Some(i) => (
                    rest[..i].strip_suffix(b"\r").unwrap_or(&rest[..i]),
                    &rest[i + 1..],
                ),
                None => (rest, &rest[rest.len()..]),
            };
            out.push(line.to_vec());
            rest = next;
        }
        out
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(512))]

        /// Arbitrary bytes, limits and read sizes: no panic, no line over the limit, every line
        /// within the limit exactly as written and every longer one refused, with its number.
        #[test]
        fn lines_agree_with_a_plain_split(
            pieces in prop::collection::vec(
                (prop::collection::vec(prop_oneof![Just(b'\n'), Just(b'\r'), any::<u8>()], 0..12), 0usize..40),
                0..20,
            ),
            limit in 0usize..64,
            chunk in 1usize..70,
        ) {
            // Pieces repeated, so that lines cross the limit and the read size often.
            let input: Vec<u8> = pieces.iter().flat_map(|(p, n)| p.repeat(*n)).collect();
            let got = all(BufReader::with_capacity(chunk, &input[..]), limit);
            let want = reference(&input);
            prop_assert_eq!(got.len(), want.len());
            for (g, w) in got.iter().zip(&want) {
                match g {
                    Ok(line) => {
                        prop_assert!(line.len() <= limit);
                        prop_assert_eq!(line, w);
                    }
                    Err(start) => {
                        prop_assert!(w.len() > limit);
                        let cut = START.min(limit);
                        prop_assert_eq!(start, &String::from_utf8_lossy(&w[..cut]).into_owned());
                    }
                }
            }
        }
    }

    #[test]
    fn a_failing_reader_is_an_error_not_a_panic() {
        struct Broken;
        impl Read for Broken {
            fn read(&mut self, _: &mut [u8]) -> std::io::Result<usize> {
                Err(std::io::Error::other("disk on fire"))
            }
        }
        let mut lines = Lines::new(BufReader::new(Broken), 10);
        assert!(matches!(lines.next_line(), Some(Err(LineError::Io(_)))));
    }
}
