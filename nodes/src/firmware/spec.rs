//! The firmware node file: which image runs on which CPU, which CAN controllers it drives
//! (SJA1000s in its external data space, each in a window of its own, and the AT89C51CC03's
//! own), and which plant signals its analog inputs and port pins are wired to.

use super::wires::{self, AnalogFile, AnalogWire, At, DacFile, DacWire, PinFile, PinWire};
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
    #[serde(default, deserialize_with = "present")]
    address: Option<u8>,
    #[serde(default)]
    start_up_ms: u64,
    image: String,
    #[serde(default, deserialize_with = "present")]
    sources: Option<String>,
    #[serde(default)]
    entry: Option<u16>,
    #[serde(default, deserialize_with = "present")]
    config: Option<ConfigFile>,
    cpu: CpuFile,
    #[serde(default)]
    controllers: Vec<ControllerFile>,
    #[serde(default)]
    analog: Vec<AnalogFile>,
    #[serde(default)]
    pins: Vec<PinFile>,
    #[serde(default)]
    dacs: Vec<DacFile>,
}

/// A field written as its value (`address: 0xD0`), absent when left out.
fn present<'de, D: serde::Deserializer<'de>, T: Deserialize<'de>>(d: D) -> Result<Option<T>, D::Error> {
    T::deserialize(d).map(Some)
}

/// Bytes the node file places in code memory beside the image: the node's own settings
/// (address, identifiers, channel wiring) for an image that serves every node of its kind.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ConfigFile {
    at: u16,
    bytes: Vec<u8>,
}

/// The longest configuration block taken, bytes.
pub const MAX_CONFIG: usize = 256;

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
    At89c51cc03 {
        clock_hz: u64,
        #[serde(default = "full_code")]
        code_bytes: u32,
        #[serde(default = "vref")]
        vref_mv: u32,
    },
}

fn vref() -> u32 {
    5000
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
    /// The AT89C51CC03's own CAN controller, reached through its SFRs.
    OnChip,
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

/// A CAN controller of a firmware node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChipSpec {
    /// An SJA1000 in the CPU's external data space.
    Sja1000 {
        /// First address of its window: the CPU reaches register `r` at `base + r`.
        base: u16,
        /// Its crystal.
        xtal_hz: u32,
        /// The CPU pin its INT output drives, if wired.
        irq: Option<Pin>,
    },
    /// The AT89C51CC03's CAN controller, on chip: SFRs, its own interrupt source, clocked by
    /// the CPU's oscillator.
    OnChip,
}

impl ChipSpec {
    /// Whether the bus returns it from bus off by itself (the on-chip controller) rather than
    /// when its firmware asks (the SJA1000).
    pub fn recovers_by_itself(&self) -> bool {
        matches!(self, ChipSpec::OnChip)
    }
}

/// The bytes of external data space an SJA1000's chip select decodes: its 8-bit multiplexed
/// address takes the low byte, so the chip answers a whole 256-byte page from its base.
pub const CHIP_WINDOW: u32 = 0x100;

/// A checked firmware node.
#[derive(Clone, Debug)]
pub struct FirmwareSpec {
    /// Node name (traces, `--without`, state dumps).
    pub name: String,
    /// The harvester address its firmware uses, when the node file says: no two nodes of a
    /// harvester may claim one.
    pub address: Option<u8>,
    /// Power-on to the end of its boot, ms, as the node file says (0 when it does not): from
    /// then on the reference monitor expects to hear it (its missing-module alarm). It describes
    /// what the firmware does; the firmware is not told.
    pub start_up_ms: u64,
    /// The node file, for messages.
    pub file: String,
    /// The image, with the node file's configuration block in place.
    pub image: Arc<mcs51::Image>,
    /// The image's file, as named in messages.
    pub image_file: String,
    /// SHA-256 of what the image's file writes (each stretch's address, then its bytes), before
    /// the configuration block, in hex: what tells one image from another in coverage reports.
    pub image_sha256: String,
    /// Debug information found beside the image ([`super::beside`]), for coverage reports.
    pub debug: Option<Arc<super::beside::Debug>>,
    /// Why debug files beside the image were not taken (they do not belong to it): a run that
    /// counts coverage refuses them; any other run goes on without them.
    pub debug_problems: Vec<Problem>,
    /// Where execution starts after reset.
    pub entry: u16,
    /// 80C51, 8052 or AT89C51CC03.
    pub variant: mcs51::Variant,
    /// Oscillator, Hz.
    pub clock_hz: u64,
    /// One oscillator period, exactly.
    pub clock: BusDuration,
    /// The CAN controllers, in the node file's order: each is a controller of its own on the
    /// bus ([`FirmwareSpec::controller_name`]).
    pub chips: Vec<ChipSpec>,
    /// The ADC's reference voltage, mV (AT89C51CC03).
    pub vref_mv: u32,
    /// ADC channels wired to plant signals.
    pub analog: Vec<AnalogWire>,
    /// Port pins wired to the plant.
    pub pins: Vec<PinWire>,
    /// DACs on whole ports driving plant inputs.
    pub dacs: Vec<DacWire>,
    /// Skip work that changes nothing: loops whose whole state repeats, and frames the
    /// on-chip controller would not take (always, but for a benchmark or a test that measures
    /// or checks what the skipping saves).
    pub skip_idle_loops: bool,
}

impl FirmwareSpec {
    /// The name of its controller `k` on the bus (traces, reports): the node's name for the
    /// first, `NAME.k` for the others.
    pub fn controller_name(&self, k: usize) -> String {
        if k == 0 {
            self.name.clone()
        } else {
            format!("{}.{k}", self.name)
        }
    }
}

/// Reads a file beside the node file (the image): its name for messages and its text.
pub type Reader<'a> = &'a dyn Fn(&Path) -> Result<(String, String), Error>;

/// The highest oscillator frequency taken: 60 MHz, above any 80C51 derivative's.
pub const MAX_CLOCK_HZ: u64 = 60_000_000;
/// The SJA1000's highest crystal frequency (data sheet, limiting values): 24 MHz.
pub const MAX_XTAL_HZ: u32 = 24_000_000;

/// Parses and checks a firmware node file; `path` is where it was read (the image is relative to
/// it), `file` its name in messages, `read` reads the image. Every problem is reported at once;
/// a wire to a signal the plant does not have, and a controller whose window overlaps another's,
/// name the line they are on.
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
    // As for a script's name: it goes into traces, reports and terminal lines, which a NUL, a
    // line break or an escape would break or garble.
    if let Some(ch) = f.name.chars().find(|ch| ch.is_control()) {
        problems.push(Problem {
            position: crate::ron_path::position(text, "name"),
            ..at("name", format!("{:?} holds the control character {ch:?}", f.name))
        });
    }
    let (variant, clock_hz, code_bytes, vref_mv) = match f.cpu {
        CpuFile::I80C51 { clock_hz, code_bytes } => (mcs51::Variant::I8051, clock_hz, code_bytes, 0),
        CpuFile::I80C52 { clock_hz, code_bytes } => (mcs51::Variant::I8052, clock_hz, code_bytes, 0),
        CpuFile::At89c51cc03 {
            clock_hz,
            code_bytes,
            vref_mv,
        } => (mcs51::Variant::At89c51cc03, clock_hz, code_bytes, vref_mv),
    };
    let cc03 = variant == mcs51::Variant::At89c51cc03;
    // The period must hold 12 times over (a machine cycle) as well as once.
    let clock = BusDuration::period_of(clock_hz)
        .filter(|p| (1..=MAX_CLOCK_HZ).contains(&clock_hz) && p.checked_mul(12).is_some());
    if clock.is_none() {
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
    if cc03 && !(1..=MAX_VREF_MV).contains(&vref_mv) {
        problems.push(at(
            "cpu.vref_mv",
            format!("{vref_mv} mV: the ADC's reference is 1 to {MAX_VREF_MV} mV"),
        ));
    }
    let chips = controllers(&f, cc03, text, &at, &mut problems);
    let analog = wires::analog(&f.analog, cc03, text, &at, &mut problems);
    // Pins a CAN controller's interrupt output drives: no plant signal may drive them too.
    let irq_pins: Vec<(u8, u8)> = chips
        .iter()
        .filter_map(|c| match c {
            ChipSpec::Sja1000 { irq: Some(p), .. } => Some(p.port_bit()),
            _ => None,
        })
        .collect();
    let pins = wires::pins(&f.pins, &irq_pins, text, &at, &mut problems);
    // A multiplexer's select pin is the firmware's: no plant signal may drive it, nor a DAC. An
    // analog channel k is pin P1.k.
    let mut taken: Vec<(u8, u8)> = pins.iter().map(|p| (p.port, p.bit)).collect();
    taken.extend(analog.iter().map(|a| (1, a.channel)));
    // One select pin may switch several multiplexers (one line to every select input).
    let selects: Vec<(u8, u8)> = analog
        .iter()
        .filter_map(|a| a.while_high.as_ref().map(|(port, bit, _)| (*port, *bit)))
        .collect();
    for (i, a) in analog.iter().enumerate() {
        if let Some((port, bit, _)) = &a.while_high
            && (taken.contains(&(*port, *bit)) || irq_pins.contains(&(*port, *bit)))
        {
            problems.push(at(
                &format!("analog[{i}].while_high.pin"),
                format!("P{port}.{bit} is wired to something else already"),
            ));
        }
    }
    taken.extend(selects);
    let dacs = wires::dacs(&f.dacs, &taken, text, &at, &mut problems);
    let image_path = path.parent().unwrap_or(Path::new("")).join(&f.image);
    let mut found = None;
    let image = match read(&image_path) {
        Err(e) => {
            problems.push(at("image", format!("cannot read it: {e}")));
            None
        }
        Ok((name, hex)) => match mcs51::hex::parse(&hex, code_bytes.clamp(1, 0x10000) as usize) {
            Ok(image) => {
                use sha2::Digest;
                // What the file writes, address and bytes: the image, however large its code
                // memory.
                let mut digest = sha2::Sha256::new();
                for r in &image.written {
                    digest.update(r.start.to_be_bytes());
                    digest.update(
                        image
                            .code
                            .get(r.start as usize..r.end as usize)
                            .unwrap_or_default(),
                    );
                }
                let sha: String = digest.finalize().iter().map(|b| format!("{b:02x}")).collect();
                let dir = path.parent().unwrap_or(Path::new(""));
                let sources = f.sources.as_ref().map_or_else(
                    || image_path.parent().unwrap_or(dir).to_path_buf(),
                    |s| dir.join(s),
                );
                let mut refused = Vec::new();
                let debug = super::beside::read(&image_path, &image, &sources, read, &mut refused);
                found = Some((name.clone(), sha, debug.map(Arc::new), refused));
                configure(image, f.config.as_ref(), &name, &at, &mut problems)
            }
            Err(e) => {
                problems.push(Problem {
                    node: Some(f.name.clone()),
                    ..Problem::at(&name, "image", e.to_string())
                });
                None
            }
        },
    };
    if let (Some(entry), Some(image)) = (f.entry, image.as_ref())
        && usize::from(entry) >= image.code.len()
    {
        // The program counter would wrap to an address the program does not mean.
        problems.push(Problem {
            node: Some(f.name.clone()),
            position: crate::ron_path::position(text, "entry"),
            ..Problem::at(
                file,
                "entry",
                format!(
                    "{entry:04X}h is outside the chip's {}-byte code memory (0000h to {:04X}h)",
                    image.code.len(),
                    image.code.len() - 1
                ),
            )
        });
    }
    match (image, clock, found) {
        (Some(image), Some(clock), Some((image_file, image_sha256, debug, debug_problems)))
            if problems.is_empty() =>
        {
            Ok(FirmwareSpec {
                name: f.name,
                address: f.address,
                start_up_ms: f.start_up_ms,
                file: file.to_string(),
                image: Arc::new(image),
                image_file,
                image_sha256,
                debug,
                debug_problems,
                entry: f.entry.unwrap_or(0),
                variant,
                clock_hz,
                clock,
                chips,
                vref_mv,
                analog,
                pins,
                dacs,
                skip_idle_loops: true,
            })
        }
        _ => Err(Error::Invalid(problems)),
    }
}

/// Places the configuration block in the image: it must fit the code memory and leave every
/// byte the image writes alone (a block over code would patch the program).
fn configure(
    mut image: mcs51::Image,
    config: Option<&ConfigFile>,
    image_name: &str,
    at: At,
    problems: &mut Vec<Problem>,
) -> Option<mcs51::Image> {
    let Some(c) = config else {
        return Some(image);
    };
    let start = u32::from(c.at);
    let end = start + c.bytes.len() as u32;
    let size = image.code.len() as u32;
    if c.bytes.is_empty() || c.bytes.len() > MAX_CONFIG {
        problems.push(at(
            "config.bytes",
            format!(
                "{} bytes: a configuration block is 1 to {MAX_CONFIG} bytes",
                c.bytes.len()
            ),
        ));
        return None;
    }
    if end > size {
        problems.push(at(
            "config.at",
            format!(
                "{:04X}h to {:04X}h: past the end of the chip's {size}-byte code memory",
                start,
                end - 1
            ),
        ));
        return None;
    }
    if let Some(r) = image.written.iter().find(|r| r.start < end && start < r.end) {
        problems.push(at(
            "config.at",
            format!(
                "{:04X}h to {:04X}h overlaps what {image_name} writes at {:04X}h to {:04X}h",
                start,
                end - 1,
                r.start,
                r.end - 1
            ),
        ));
        return None;
    }
    image.code[start as usize..end as usize].copy_from_slice(&c.bytes);
    image.written.push(start..end);
    image.written.sort_by_key(|r| r.start);
    Some(image)
}

/// The highest ADC reference taken, mV.
pub const MAX_VREF_MV: u32 = 10_000;

fn controllers(f: &File, cc03: bool, text: &str, at: At, problems: &mut Vec<Problem>) -> Vec<ChipSpec> {
    let mut chips = Vec::new();
    let mut windows: Vec<(usize, u16)> = Vec::new();
    for (i, c) in f.controllers.iter().enumerate() {
        let field = format!("controllers[{i}]");
        match *c {
            ControllerFile::OnChip => {
                if !cc03 {
                    problems.push(at(
                        &field,
                        "OnChip: only the AT89C51CC03 has a CAN controller on chip".into(),
                    ));
                }
                chips.push(ChipSpec::OnChip);
            }
            ControllerFile::Sja1000 { base, xtal_hz, irq } => {
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
                for &(j, b) in &windows {
                    let (lo, hi) = (u32::from(base.min(b)), u32::from(base.max(b)));
                    if hi < lo + CHIP_WINDOW {
                        let p = at(
                            &format!("{field}.base"),
                            format!(
                                "{base:#06X}: its window overlaps controllers[{j}] at {b:#06X} \
                                 (each decodes {CHIP_WINDOW} bytes)"
                            ),
                        );
                        problems.push(locate_controller(p, text, i, "base"));
                    }
                }
                windows.push((i, base));
                chips.push(ChipSpec::Sja1000 { base, xtal_hz, irq });
            }
        }
    }
    let on_chip = chips.iter().filter(|c| **c == ChipSpec::OnChip).count();
    if on_chip > 1 {
        problems.push(at(
            "controllers",
            format!("OnChip {on_chip} times: the AT89C51CC03 has one CAN controller on chip"),
        ));
    }
    chips
}

/// Where the node file writes the `index`th controller's `field` (or the controller itself,
/// when it does not): the line and column of the problem about it. Controllers are counted by
/// their names (`Sja1000(...)`, `OnChip`) after `controllers:`, outside `//` comments.
fn locate_controller(mut p: Problem, text: &str, index: usize, field: &str) -> Problem {
    let Some(from) = text.find("controllers:") else {
        return p;
    };
    let mut starts: Vec<usize> = ["Sja1000", "OnChip"]
        .iter()
        .flat_map(|name| text[from..].match_indices(name).map(|(o, _)| from + o))
        .filter(|&o| !in_comment(text, o))
        .collect();
    starts.sort_unstable();
    let Some(&start) = starts.get(index) else {
        return p;
    };
    let end = starts.get(index + 1).copied().unwrap_or(text.len());
    let at = text[start..end]
        .find(&format!("{field}:"))
        .map_or(start, |o| start + o);
    p.position = Some(crate::script::position_of(text, at));
    p
}

/// Whether `offset` falls after a `//` on its line.
fn in_comment(text: &str, offset: usize) -> bool {
    let line_start = text[..offset].rfind('\n').map_or(0, |p| p + 1);
    text[line_start..offset].contains("//")
}
