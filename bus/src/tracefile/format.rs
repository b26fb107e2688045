//! The trace file formats harvemu reads and writes, chosen by a file's name and checked against
//! its first bytes.
//!
//! Contract: [`FileFormat::of_path`] picks the format from the extension (any case): `.asc`,
//! `.blf`, `.pcapng`, `.mf4`; anything else is a candump log. [`FileFormat::sniff`] tells the
//! format from the first bytes of a file (BLF's `LOGG`, pcapng's Section Header Block type,
//! pcap's magic numbers, MF4's `MDF     `, a candump log's `(`, ASC's text), so that a file
//! whose name says one format and whose content is another is named as such, not misread.

use std::fmt;
use std::path::Path;

/// A trace file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FileFormat {
    /// candump log (`candump -L`): `(1704067200.551520) harv0 0200F5E0#1078`.
    Log,
    /// Vector ASC text.
    Asc,
    /// Vector BLF binary logging.
    Blf,
    /// pcapng with LINKTYPE_CAN_SOCKETCAN packets.
    Pcapng,
    /// ASAM MDF 4 with the bus-logging channel groups.
    Mf4,
}

/// What [`FileFormat::sniff`] sees that harvemu cannot read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sniffed {
    /// One of harvemu's formats.
    Format(FileFormat),
    /// A classic pcap file (libpcap's, `tcpdump -w`), not pcapng.
    Pcap,
    /// An MDF file of version 3 or older.
    OldMdf,
    /// Binary bytes of no known trace format.
    Unknown,
}

impl FileFormat {
    /// Every format, in the order the docs list them.
    pub const ALL: [FileFormat; 5] = [
        FileFormat::Log,
        FileFormat::Asc,
        FileFormat::Blf,
        FileFormat::Pcapng,
        FileFormat::Mf4,
    ];

    /// The format `path`'s extension asks for; a candump log for any other name.
    pub fn of_path(path: &Path) -> FileFormat {
        path.extension()
            .and_then(|e| e.to_str())
            .and_then(FileFormat::parse)
            .unwrap_or(FileFormat::Log)
    }

    /// The format named `name` (`log`, `asc`, `blf`, `pcapng`, `mf4`, any case), as `--format`
    /// takes it.
    pub fn parse(name: &str) -> Option<FileFormat> {
        FileFormat::ALL
            .into_iter()
            .find(|f| f.extension().eq_ignore_ascii_case(name))
    }

    /// The extension, without its dot: `log`, `asc`, `blf`, `pcapng`, `mf4`.
    pub fn extension(self) -> &'static str {
        match self {
            FileFormat::Log => "log",
            FileFormat::Asc => "asc",
            FileFormat::Blf => "blf",
            FileFormat::Pcapng => "pcapng",
            FileFormat::Mf4 => "mf4",
        }
    }

    /// Its name in a sentence: `a candump log`, `BLF`.
    pub fn describe(self) -> &'static str {
        match self {
            FileFormat::Log => "a candump log",
            FileFormat::Asc => "Vector ASC",
            FileFormat::Blf => "Vector BLF",
            FileFormat::Pcapng => "pcapng",
            FileFormat::Mf4 => "MF4",
        }
    }

    /// True for the formats that are written by going back into the file at its end (a
    /// header's counts, block lengths): they need a regular file, not a stream.
    pub fn needs_seek(self) -> bool {
        matches!(self, FileFormat::Blf | FileFormat::Mf4)
    }

    /// What the format is, from the first bytes of a file (at least 8 when the file has them).
    pub fn sniff(head: &[u8]) -> Sniffed {
        if head.starts_with(b"LOGG") {
            return Sniffed::Format(FileFormat::Blf);
        }
        if head.starts_with(&[0x0A, 0x0D, 0x0D, 0x0A]) {
            return Sniffed::Format(FileFormat::Pcapng);
        }
        if head.starts_with(b"MDF     ") || head.starts_with(b"UnFinMF ") {
            // The version follows at byte 8: "4.10    ".
            return match head.get(8) {
                Some(b'4') | None => Sniffed::Format(FileFormat::Mf4),
                Some(_) => Sniffed::OldMdf,
            };
        }
        let pcap_magic = [0xA1B2_C3D4u32, 0xA1B2_3C4D];
        if head.len() >= 4 {
            let le = u32::from_le_bytes([head[0], head[1], head[2], head[3]]);
            let be = u32::from_be_bytes([head[0], head[1], head[2], head[3]]);
            if pcap_magic.contains(&le) || pcap_magic.contains(&be) {
                return Sniffed::Pcap;
            }
        }
        // Text: the first character that is not white space.
        let text = head.iter().find(|b| !b.is_ascii_whitespace());
        match text {
            Some(b'(') => Sniffed::Format(FileFormat::Log),
            Some(b) if b.is_ascii_graphic() => Sniffed::Format(FileFormat::Asc),
            None => Sniffed::Format(FileFormat::Log),
            Some(_) => Sniffed::Unknown,
        }
    }
}

impl fmt::Display for FileFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.describe())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_extension_picks_the_format_and_the_bytes_say_what_the_file_is() {
        for (name, format) in [
            ("a.BLF", FileFormat::Blf),
            ("a.pcapng", FileFormat::Pcapng),
            ("a.mf4", FileFormat::Mf4),
            ("a.asc", FileFormat::Asc),
            ("a.log", FileFormat::Log),
            ("a", FileFormat::Log),
            ("blf", FileFormat::Log),
        ] {
            assert_eq!(FileFormat::of_path(Path::new(name)), format, "{name}");
        }
        for (head, seen) in [
            (&b"LOGG\x90\0\0\0"[..], Sniffed::Format(FileFormat::Blf)),
            (
                &[0x0A, 0x0D, 0x0D, 0x0A, 0x1C, 0, 0, 0][..],
                Sniffed::Format(FileFormat::Pcapng),
            ),
            (&b"MDF     4.10    "[..], Sniffed::Format(FileFormat::Mf4)),
            (&b"MDF     3.30    "[..], Sniffed::OldMdf),
            (&[0xD4, 0xC3, 0xB2, 0xA1, 2, 0, 4, 0][..], Sniffed::Pcap),
            (
                &b"(1704067200.000000) harv0 1#"[..],
                Sniffed::Format(FileFormat::Log),
            ),
            (&b"date Mon Jan  1"[..], Sniffed::Format(FileFormat::Asc)),
            (&b""[..], Sniffed::Format(FileFormat::Log)),
            (&[0u8, 1, 2, 3][..], Sniffed::Unknown),
        ] {
            assert_eq!(FileFormat::sniff(head), seen, "{head:?}");
        }
    }
}
