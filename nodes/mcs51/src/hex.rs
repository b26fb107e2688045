//! Intel HEX loader: text to a code memory image.
//!
//! Records 00 (data), 01 (end of file), 02 (extended segment address: base = value × 16) and 04
//! (extended linear address: base = value × 65536) are honoured; 03 and 05 (start addresses) are
//! ignored because an 8051 starts at 0000h (the caller can `set_pc`). Blank lines and trailing
//! whitespace are allowed. A missing EOF record is an error (a truncated file must not run as if it
//! were whole), and so is anything but blank lines after it (records there would be left out).

use crate::error::Error;
use std::ops::Range;

/// A loaded code memory: `code_size` bytes, 0xFF where no record wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    /// The memory, `code_size` bytes long.
    pub code: Vec<u8>,
    /// The written address ranges, sorted, adjacent ranges merged.
    pub written: Vec<Range<u32>>,
}

/// Parses Intel HEX `text` into a code memory of `code_size` bytes (1 to 65536).
pub fn parse(text: &str, code_size: usize) -> Result<Image, Error> {
    if code_size == 0 || code_size > 0x1_0000 {
        return Err(Error::CodeSize(code_size));
    }
    let mut code = vec![0xFF; code_size];
    // The 1-based line that wrote each byte (0: none), to name both lines of an overlap.
    let mut owner = vec![0u32; code_size];
    let mut base: u32 = 0;
    for (index, raw) in text.lines().enumerate() {
        let line = index + 1;
        let record = raw.trim();
        if record.is_empty() {
            continue;
        }
        let bytes = decode(record, line)?;
        let len = bytes[0] as usize;
        let offset = u32::from(bytes[1]) << 8 | u32::from(bytes[2]);
        let kind = bytes[3];
        let data = &bytes[4..4 + len];
        match kind {
            0x00 => {
                for (i, &b) in data.iter().enumerate() {
                    let addr = base + offset + i as u32;
                    let slot = addr as usize;
                    if slot >= code_size {
                        return Err(Error::OutOfRange {
                            line,
                            addr,
                            size: code_size,
                        });
                    }
                    if owner[slot] != 0 {
                        let first = owner[slot] as usize;
                        return Err(Error::Overlap { line, first, addr });
                    }
                    owner[slot] = line as u32;
                    code[slot] = b;
                }
            }
            0x01 => {
                let after = text.lines().enumerate().skip(index + 1);
                if let Some((i, _)) = after.into_iter().find(|(_, l)| !l.trim().is_empty()) {
                    return Err(Error::AfterEof {
                        line: i + 1,
                        eof: line,
                    });
                }
                return Ok(Image {
                    code,
                    written: ranges(&owner),
                });
            }
            0x02 | 0x04 => {
                if len != 2 {
                    return Err(Error::Malformed {
                        line,
                        what: "address record needs 2 data bytes",
                    });
                }
                let value = u32::from(data[0]) << 8 | u32::from(data[1]);
                base = if kind == 0x02 { value << 4 } else { value << 16 };
            }
            0x03 | 0x05 => {}
            _ => return Err(Error::RecordType { line, kind }),
        }
    }
    Err(Error::MissingEof)
}

/// Decodes one record to bytes (length, address, type, data, checksum) and checks its sums.
fn decode(record: &str, line: usize) -> Result<Vec<u8>, Error> {
    let hex = record.strip_prefix(':').ok_or(Error::Malformed {
        line,
        what: "does not start with ':'",
    })?;
    if hex.len() % 2 != 0 {
        return Err(Error::Malformed {
            line,
            what: "odd number of hex digits",
        });
    }
    let mut bytes = Vec::with_capacity(hex.len() / 2);
    for pair in hex.as_bytes().chunks(2) {
        let text = std::str::from_utf8(pair).map_err(|_| Error::Malformed {
            line,
            what: "not ASCII",
        })?;
        let b = u8::from_str_radix(text, 16).map_err(|_| Error::Malformed {
            line,
            what: "not a hex digit",
        })?;
        bytes.push(b);
    }
    if bytes.len() < 5 || bytes.len() != 5 + bytes[0] as usize {
        return Err(Error::Malformed {
            line,
            what: "length byte does not match the record",
        });
    }
    let sum = bytes.iter().fold(0u8, |s, &b| s.wrapping_add(b));
    if sum != 0 {
        return Err(Error::Checksum { line, sum });
    }
    Ok(bytes)
}

fn ranges(owner: &[u32]) -> Vec<Range<u32>> {
    let mut out: Vec<Range<u32>> = Vec::new();
    for (addr, &line) in owner.iter().enumerate() {
        if line == 0 {
            continue;
        }
        let addr = addr as u32;
        match out.last_mut() {
            Some(r) if r.end == addr => r.end = addr + 1,
            _ => out.push(addr..addr + 1),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loads_data_and_ranges() {
        // Checksums computed by hand: 0x100 - (sum of bytes) mod 0x100.
        let text = ":03000000020040BB\n:02004000E4FFDB\n:00000001FF\n";
        let img = parse(text, 4096).unwrap();
        assert_eq!(&img.code[0..4], &[0x02, 0x00, 0x40, 0xFF]);
        assert_eq!(&img.code[0x40..0x42], &[0xE4, 0xFF]);
        assert_eq!(img.written, vec![0..3, 0x40..0x42]);
    }

    #[test]
    fn extended_addresses() {
        // 02: segment 0100h -> base 1000h; 04: upper 0000h.
        let text = ":020000020100FB\n:01000000AA55\n:020000040000FA\n:01000000BB44\n:00000001FF\n";
        let img = parse(text, 0x10000).unwrap();
        assert_eq!(img.code[0x1000], 0xAA);
        assert_eq!(img.code[0], 0xBB);
    }

    #[test]
    fn errors_name_the_line() {
        assert_eq!(
            parse(":03000000020040BC\n:00000001FF\n", 4096),
            Err(Error::Checksum { line: 1, sum: 1 })
        );
        assert!(matches!(
            parse("\n03000000020040BB\n", 4096),
            Err(Error::Malformed { line: 2, .. })
        ));
        assert!(matches!(
            parse(":0300000002004BB\n", 4096),
            Err(Error::Malformed { line: 1, .. })
        ));
        assert!(matches!(
            parse(":04000000020040BA\n", 4096),
            Err(Error::Malformed { line: 1, .. })
        ));
        assert_eq!(parse(":03000000020040BB\n", 4096), Err(Error::MissingEof));
        // A data record after the end-of-file record is not left out silently.
        assert_eq!(
            parse(":00000001FF\n\n:03000000020040BB\n", 4096),
            Err(Error::AfterEof { line: 3, eof: 1 })
        );
        assert!(
            parse(":00000001FF\n  \n\n", 4096).is_ok(),
            "blank lines may follow"
        );
        let overlap = ":03000000020040BB\n:01000200AA53\n:00000001FF\n";
        assert_eq!(
            parse(overlap, 4096),
            Err(Error::Overlap {
                line: 2,
                first: 1,
                addr: 2
            })
        );
        // Linear base FFFF0000h plus offset FFFFh: the top of the 32-bit space, no overflow.
        assert_eq!(
            parse(":02000004FFFFFC\n:02FFFF00AABB9B\n:00000001FF\n", 0x10000),
            Err(Error::OutOfRange {
                line: 2,
                addr: 0xFFFF_FFFF,
                size: 0x10000
            })
        );
        // One byte at 1000h into a 4 KB memory.
        assert_eq!(
            parse(":01100000AA45\n:00000001FF\n", 4096),
            Err(Error::OutOfRange {
                line: 1,
                addr: 0x1000,
                size: 4096
            })
        );
        assert_eq!(parse(":00000001FF\n", 0), Err(Error::CodeSize(0)));
    }
}
