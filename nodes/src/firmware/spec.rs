//! The firmware node file: which image runs on which CPU, and which CAN controllers sit where in
//! its external data space.

use crate::{Error, Problem, parse_ron};
use bus::time::BusDuration;
use serde::Deserialize;
use std::path::Path;
use std::sync::Arc;

/// A firmware node file as written.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, rename = "Firmware")]
struct File {
    name: String,
    image: String,
    #[serde(default)]
    entry: Option<u16>,
    cpu: CpuFile,
    #[serde(default)]
    controllers: Vec<ControllerFile>,
}

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
enum CpuFile {
    I80C51 {
        clock_hz: u64,
        #[serde(default = "full_code")]
        code_bytes: u32,
    },
    I80C52 {
        clock_hz: u64,
        #[serde(default = "full_code")]
        code_bytes: u32,
    },
}

fn full_code() -> u32 {
    0x10000
}

#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
enum ControllerFile {
    Sja1000 {
        base: u16,
        xtal_hz: u32,
        #[serde(default)]
        irq: Option<Pin>,
    },
}

/// A CPU pin a peripheral's interrupt output can drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, serde::Serialize)]
pub enum Pin {
    /// INT0, port 3 bit 2.
    Int0,
    /// INT1, port 3 bit 3.
    Int1,
}

impl Pin {
    /// Port and bit.
    pub fn port_bit(self) -> (u8, u8) {
        match self {
            Pin::Int0 => (3, 2),
            Pin::Int1 => (3, 3),
        }
    }
}

/// An SJA1000 in the CPU's external data space.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChipSpec {
    /// First address of its window: the CPU reaches register `r` at `base + r`.
    pub base: u16,
    /// Its crystal.
    pub xtal_hz: u32,
    /// The CPU pin its INT output drives, if wired.
    pub irq: Option<Pin>,
}

/// The bytes of external data space an SJA1000's chip select decodes: its 8-bit multiplexed
/// address takes the low byte, so the chip answers a whole 256-byte page from its base.
pub const CHIP_WINDOW: u32 = 0x100;

/// A checked firmware node.
#[derive(Clone, Debug)]
pub struct FirmwareSpec {
    /// Node name (traces, `--without`, state dumps).
    pub name: String,
    /// The node file, for messages.
    pub file: String,
    /// The image.
    pub image: Arc<mcs51::Image>,
    /// Where execution starts after reset.
    pub entry: u16,
    /// 80C51 or 8052.
    pub variant: mcs51::Variant,
    /// Oscillator, Hz.
    pub clock_hz: u64,
    /// One machine cycle (12 oscillator periods), exactly.
    pub cycle: BusDuration,
    /// The CAN controllers.
    pub chips: Vec<ChipSpec>,
    /// Look for loops that change nothing and skip them (always, but for a benchmark that
    /// measures what the skipping saves).
    pub skip_idle_loops: bool,
}

/// Reads a file beside the node file (the image): its name for messages and its text.
pub type Reader<'a> = &'a dyn Fn(&Path) -> Result<(String, String), Error>;

/// The highest oscillator frequency taken: 60 MHz, above any 80C51 derivative's.
pub const MAX_CLOCK_HZ: u64 = 60_000_000;
/// The SJA1000's highest crystal frequency (data sheet, limiting values): 24 MHz.
pub const MAX_XTAL_HZ: u32 = 24_000_000;

/// Parses and checks a firmware node file; `path` is where it was read (the image is relative to
/// it), `file` its name in messages, `read` reads the image. Every problem is reported at once.
pub fn load(file: &str, path: &Path, text: &str, read: Reader) -> Result<FirmwareSpec, Error> {
    let f: File = parse_ron(file, text)?;
    let mut problems = Vec::new();
    let at = |field: &str, message: String| Problem {
        node: Some(f.name.clone()),
        ..Problem::at(file, field, message)
    };
    if f.name.is_empty() {
        problems.push(at("name", "empty".into()));
    }
    let (variant, clock_hz, code_bytes) = match f.cpu {
        CpuFile::I80C51 { clock_hz, code_bytes } => (mcs51::Variant::I8051, clock_hz, code_bytes),
        CpuFile::I80C52 { clock_hz, code_bytes } => (mcs51::Variant::I8052, clock_hz, code_bytes),
    };
    let cycle = match BusDuration::period_of(clock_hz) {
        Some(p) if (1..=MAX_CLOCK_HZ).contains(&clock_hz) => p.checked_mul(12),
        _ => None,
    };
    if cycle.is_none() {
        problems.push(at(
            "cpu.clock_hz",
            format!(
                "{clock_hz} Hz: a clock must be 1 Hz to {MAX_CLOCK_HZ} Hz with a period the bus clock \
                 holds exactly (it must divide 3456000000000, as 6, 11.0592, 12, 16, 20 and 24 MHz do)"
            ),
        ));
    }
    if !(1..=0x10000).contains(&code_bytes) {
        problems.push(at(
            "cpu.code_bytes",
            format!("{code_bytes}: code memory is 1 to 65536 bytes"),
        ));
    }
    let mut chips = Vec::new();
    for (i, c) in f.controllers.iter().enumerate() {
        let ControllerFile::Sja1000 { base, xtal_hz, irq } = *c;
        let field = format!("controllers[{i}]");
        if !(1..=MAX_XTAL_HZ).contains(&xtal_hz) {
            problems.push(at(
                &format!("{field}.xtal_hz"),
                format!("{xtal_hz} Hz: the SJA1000 takes a crystal of 1 Hz to {MAX_XTAL_HZ} Hz"),
            ));
        }
        if u32::from(base) + CHIP_WINDOW > 0x10000 {
            problems.push(at(
                &format!("{field}.base"),
                format!("{base:#06X}: its {CHIP_WINDOW}-byte window runs past FFFFh"),
            ));
        }
        for (j, other) in chips.iter().enumerate() {
            let ChipSpec { base: b, .. } = *other;
            let (lo, hi) = (u32::from(base.min(b)), u32::from(base.max(b)));
            if hi < lo + CHIP_WINDOW {
                problems.push(at(
                    &format!("{field}.base"),
                    format!(
                        "{base:#06X}: its window overlaps controllers[{j}] at {b:#06X} \
                         (each decodes {CHIP_WINDOW} bytes)"
                    ),
                ));
            }
        }
        chips.push(ChipSpec { base, xtal_hz, irq });
    }
    if chips.len() > 1 {
        problems.push(at(
            "controllers",
            format!(
                "{} controllers: a firmware node has at most one CAN controller so far",
                chips.len()
            ),
        ));
    }
    let image_path = path.parent().unwrap_or(Path::new("")).join(&f.image);
    let image = match read(&image_path) {
        Err(e) => {
            problems.push(at("image", format!("cannot read it: {e}")));
            None
        }
        Ok((name, hex)) => match mcs51::hex::parse(&hex, code_bytes.clamp(1, 0x10000) as usize) {
            Ok(image) => Some(image),
            Err(e) => {
                problems.push(Problem {
                    node: Some(f.name.clone()),
                    ..Problem::at(&name, "image", e.to_string())
                });
                None
            }
        },
    };
    match (image, cycle) {
        (Some(image), Some(cycle)) if problems.is_empty() => Ok(FirmwareSpec {
            name: f.name,
            file: file.to_string(),
            image: Arc::new(image),
            entry: f.entry.unwrap_or(0),
            variant,
            clock_hz,
            cycle,
            chips,
            skip_idle_loops: true,
        }),
        _ => Err(Error::Invalid(problems)),
    }
}
