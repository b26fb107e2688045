//! Shared pieces of the fuzz targets: the real configs as in-memory inputs, and small reference
//! implementations that the targets hold the code under test to.
//!
//! Contract: nothing here touches the file system after the first call (the real configs are
//! read once, at start-up); the fuzzed inputs never name a file that gets opened.

use bus::Frame;
use nodes::environment::PlantSignals;
use nodes::script::NodeScript;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use supervisor::harvester::Harvester;

/// The repository's `configs/` directory.
pub fn configs_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs")
}

/// Where the fuzzed harvester config pretends to live: scripts resolve next to it.
pub const HARVESTER_PATH: &str = "configs/harvester.ron";

/// The real node scripts, parsed once, by the path a config at [`HARVESTER_PATH`] names them
/// with (`configs/nodes/d0.ron`).
pub fn scripts() -> &'static BTreeMap<PathBuf, NodeScript> {
    static SCRIPTS: OnceLock<BTreeMap<PathBuf, NodeScript>> = OnceLock::new();
    SCRIPTS.get_or_init(|| {
        let dir = configs_dir().join("nodes");
        let mut map = BTreeMap::new();
        for entry in std::fs::read_dir(&dir).expect("configs/nodes is readable") {
            let path = entry.expect("a directory entry").path();
            // templates/ holds what the instances expand from, not scripts of their own.
            if path.is_dir() {
                continue;
            }
            let script = nodes::script::load(&path, &PlantSignals).expect("the real scripts are valid");
            let name = path.file_name().expect("a file name");
            map.insert(Path::new("configs/nodes").join(name), script);
        }
        map
    })
}

/// Reads a node script from [`scripts`] instead of the disk; any other path is "not found".
pub fn script(path: &Path) -> Result<NodeScript, nodes::Error> {
    scripts().get(path).cloned().ok_or_else(|| nodes::Error::Io {
        path: path.display().to_string(),
        source: std::io::ErrorKind::NotFound.into(),
    })
}

/// The real harvester, loaded once from `configs/harvester.ron`.
pub fn harvester() -> &'static Harvester {
    static HARVESTER: OnceLock<Harvester> = OnceLock::new();
    HARVESTER.get_or_init(|| {
        Harvester::load(&configs_dir().join("harvester.ron")).expect("the real harvester loads")
    })
}

/// The value of a hex digit, by a table rather than arithmetic on the character.
pub fn hex_digit(c: u8) -> Option<u8> {
    b"0123456789abcdef"
        .iter()
        .position(|&d| d == c.to_ascii_lowercase())
        .map(|v| v as u8)
}

/// Reference reading of the `ID#DATA` data bytes: hex pairs, dots allowed anywhere, at most 8.
pub fn reference_hex_bytes(text: &str) -> Option<Vec<u8>> {
    let digits: Vec<u8> = text
        .bytes()
        .filter(|&b| b != b'.')
        .map(hex_digit)
        .collect::<Option<_>>()?;
    if !digits.len().is_multiple_of(2) || digits.len() > 16 {
        return None;
    }
    Some(digits.chunks(2).map(|p| p[0] * 16 + p[1]).collect())
}

/// Reference reading of an `ID#DATA` identifier: (raw, extended).
pub fn reference_id(text: &str) -> Option<(u32, bool)> {
    if text.len() != 3 && text.len() != 8 {
        return None;
    }
    let value = text
        .bytes()
        .try_fold(0u64, |acc, c| Some(acc * 16 + u64::from(hex_digit(c)?)))?;
    match text.len() {
        3 if value <= 0x7FF => Some((value as u32, false)),
        8 if value <= 0x1FFF_FFFF => Some((value as u32, true)),
        _ => None,
    }
}

/// The payload bits a message's layout covers: Data0 and every field.
pub fn covered_bits(message: &protocol::catalogue::MessageDef) -> u64 {
    let mut mask = 0xFFu64;
    for f in message.fields {
        for bit in f.start_bit..f.start_bit + f.bits {
            mask |= 1 << bit;
        }
    }
    mask
}

/// A payload as one little-endian word.
pub fn word(frame: &Frame) -> u64 {
    let mut w = [0u8; 8];
    w[..frame.data().len()].copy_from_slice(frame.data());
    u64::from_le_bytes(w)
}

/// A binary trace reader (BLF, pcapng, MF4) on any bytes: it never panics; it gives items and
/// then at most one error, which names a record and a byte offset inside the input (or two
/// records whose times go backwards) in one short line; and whatever it reads whole, written
/// back in the same format, reads back as the same items (MF4's times exactly while the trace
/// spans under 2^52 ns, its float seconds' exact range).
pub fn binary_trace(format: bus::tracefile::FileFormat, input: &[u8]) {
    use bus::tracefile::{ErrorFrames, FileFormat, Item, ItemWriter, items};
    use std::io::Cursor;
    let read = |bytes: &[u8]| -> (Vec<Item>, Option<bus::Error>) {
        let mut got = Vec::new();
        match items(Cursor::new(bytes.to_vec()), format, ErrorFrames::Keep) {
            Err(e) => (got, Some(e)),
            Ok(it) => {
                let mut error = None;
                for r in it {
                    assert!(error.is_none(), "a record after the error {error:?}");
                    match r {
                        Ok((_, item)) => got.push(item),
                        Err(e) => error = Some(e),
                    }
                }
                (got, error)
            }
        }
    };
    let (got, error) = read(input);
    if let Some(e) = error {
        let shown = e.to_string();
        assert!(shown.chars().count() < 300 && !shown.contains('\n'), "{shown}");
        match e {
            bus::Error::TraceRecord { offset, .. } => {
                assert!(offset <= input.len() as u64, "{shown}")
            }
            bus::Error::TraceTime { .. } => {}
            other => panic!("{format}: {other:?}"),
        }
        return;
    }
    let start = got.first().map_or(bus::time::Stamp(0), |i| i.at);
    let mut out = Cursor::new(Vec::new());
    {
        let mut writer: Box<dyn ItemWriter + '_> = match format {
            FileFormat::Pcapng => {
                Box::new(bus::tracefile::PcapngWriter::new(&mut out, bus::time::Epoch::UNIX).unwrap())
            }
            FileFormat::Blf => Box::new(bus::tracefile::blf::BlfWriter::new(&mut out, start).unwrap()),
            FileFormat::Mf4 => Box::new(bus::tracefile::mf4::Mf4Writer::new(&mut out, start).unwrap()),
            other => panic!("{other} is not binary"),
        };
        for item in &got {
            writer.write(item).unwrap();
        }
        writer.finish().unwrap();
    }
    let (back, error) = read(out.get_ref());
    assert!(error.is_none(), "{format}: written back, it fails: {error:?}");
    let span = got.last().map_or(0, |l| l.at.0 - start.0);
    if format != FileFormat::Mf4 || span < 1 << 52 {
        assert_eq!(back, got, "{format}: written back, it reads otherwise");
    } else {
        assert_eq!(back.len(), got.len());
    }
}
