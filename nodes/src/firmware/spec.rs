//! The firmware node file: which image runs on which CPU, which CAN controller it drives (an
//! SJA1000 in its external data space, or the AT89C51CC03's own), and which plant signals its
//! analog inputs and port pins are wired to.

use crate::plant::Plant;
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
    #[serde(default)]
    analog: Vec<AnalogFile>,
    #[serde(default)]
    pins: Vec<PinFile>,
}

/// An ADC channel wired to a plant signal: the pin's voltage in millivolts is the signal times
/// `scale`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct AnalogFile {
    channel: u8,
    signal: String,
    #[serde(default = "unit_scale")]
    scale: f64,
}

fn unit_scale() -> f64 {
    1.0
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
enum PinFile {
    Input {
        pin: String,
        signal: String,
        #[serde(default)]
        active_low: bool,
    },
    Output {
        pin: String,
        input: String,
        #[serde(default)]
        active_low: bool,
    },
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

/// An ADC channel wired to a plant signal.
#[derive(Clone, Debug, PartialEq)]
pub struct AnalogWire {
    /// Channel 0–7 (pin P1.channel).
    pub channel: u8,
    /// The plant signal.
    pub signal: String,
    /// Millivolts at the pin per unit of the signal.
    pub scale: f64,
}

/// A port pin wired to the plant.
#[derive(Clone, Debug, PartialEq)]
pub struct PinWire {
    /// Port 0–3.
    pub port: u8,
    /// Bit 0–7.
    pub bit: u8,
    /// The plant signal (an input pin) or plant input (an output pin).
    pub signal: String,
    /// The firmware reads the pin (a switch), or the plant follows its latch (an actuator).
    pub direction: Direction,
    /// Low is "on" (1): a switch that pulls the pin to ground, an actuator driven low.
    pub active_low: bool,
}

/// Which way a wired pin goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// The plant drives the pin: high while the signal is 0.5 or more (unless active low).
    Input,
    /// The pin's latch drives a plant input: 1 while high (unless active low), else 0.
    Output,
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
    /// 80C51, 8052 or AT89C51CC03.
    pub variant: mcs51::Variant,
    /// Oscillator, Hz.
    pub clock_hz: u64,
    /// One oscillator period, exactly.
    pub clock: BusDuration,
    /// The CAN controllers.
    pub chips: Vec<ChipSpec>,
    /// The ADC's reference voltage, mV (AT89C51CC03).
    pub vref_mv: u32,
    /// ADC channels wired to plant signals.
    pub analog: Vec<AnalogWire>,
    /// Port pins wired to the plant.
    pub pins: Vec<PinWire>,
    /// Skip work that changes nothing: loops whose whole state repeats, and frames the
    /// on-chip controller would not take (always, but for a benchmark or a test that measures
    /// or checks what the skipping saves).
    pub skip_idle_loops: bool,
}

/// Reads a file beside the node file (the image): its name for messages and its text.
pub type Reader<'a> = &'a dyn Fn(&Path) -> Result<(String, String), Error>;

/// The highest oscillator frequency taken: 60 MHz, above any 80C51 derivative's.
pub const MAX_CLOCK_HZ: u64 = 60_000_000;
/// The SJA1000's highest crystal frequency (data sheet, limiting values): 24 MHz.
pub const MAX_XTAL_HZ: u32 = 24_000_000;

/// Parses and checks a firmware node file; `path` is where it was read (the image is relative to
/// it), `file` its name in messages, `read` reads the image. Every problem is reported at once;
/// a wire to a signal the plant does not have names the line it is on.
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
    let chips = controllers(&f, cc03, &at, &mut problems);
    let analog = analog(&f, cc03, text, &at, &mut problems);
    let pins = pins(&f, &chips, text, &at, &mut problems);
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
    match (image, clock) {
        (Some(image), Some(clock)) if problems.is_empty() => Ok(FirmwareSpec {
            name: f.name,
            file: file.to_string(),
            image: Arc::new(image),
            entry: f.entry.unwrap_or(0),
            variant,
            clock_hz,
            clock,
            chips,
            vref_mv,
            analog,
            pins,
            skip_idle_loops: true,
        }),
        _ => Err(Error::Invalid(problems)),
    }
}

/// The highest ADC reference taken, mV.
pub const MAX_VREF_MV: u32 = 10_000;

type At<'a> = &'a dyn Fn(&str, String) -> Problem;

fn controllers(f: &File, cc03: bool, at: At, problems: &mut Vec<Problem>) -> Vec<ChipSpec> {
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
                        problems.push(at(
                            &format!("{field}.base"),
                            format!(
                                "{base:#06X}: its window overlaps controllers[{j}] at {b:#06X} \
                                 (each decodes {CHIP_WINDOW} bytes)"
                            ),
                        ));
                    }
                }
                windows.push((i, base));
                chips.push(ChipSpec::Sja1000 { base, xtal_hz, irq });
            }
        }
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
    chips
}

/// Where `needle` first appears as a quoted string in `text` after `section:` (the list that
/// holds it): the line and column of the problem about it.
fn locate(mut p: Problem, text: &str, section: &str, needle: &str) -> Problem {
    let from = text.find(&format!("{section}:")).unwrap_or(0);
    if let Some(offset) = text[from..].find(&format!("\"{needle}\"")) {
        p.position = Some(crate::script::position_of(text, from + offset));
    }
    p
}

fn analog(f: &File, cc03: bool, text: &str, at: At, problems: &mut Vec<Problem>) -> Vec<AnalogWire> {
    let mut wires: Vec<AnalogWire> = Vec::new();
    for (i, a) in f.analog.iter().enumerate() {
        let field = format!("analog[{i}]");
        if !cc03 {
            problems.push(at(&field, "only the AT89C51CC03 has an ADC".into()));
        }
        if a.channel > 7 {
            problems.push(at(
                &format!("{field}.channel"),
                format!("{}: the ADC has channels 0 to 7", a.channel),
            ));
        }
        if wires.iter().any(|w| w.channel == a.channel) {
            problems.push(at(
                &format!("{field}.channel"),
                format!("channel {} is wired twice", a.channel),
            ));
        }
        if !Plant::signal_names().contains(&a.signal) {
            problems.push(locate(
                at(
                    &format!("{field}.signal"),
                    format!(
                        "\"{}\" is no plant signal (docs/BEHAVIOUR.md lists them)",
                        a.signal
                    ),
                ),
                text,
                "analog",
                &a.signal,
            ));
        }
        if !a.scale.is_finite() {
            problems.push(at(
                &format!("{field}.scale"),
                format!("{}: a scale is a finite number", a.scale),
            ));
        }
        wires.push(AnalogWire {
            channel: a.channel,
            signal: a.signal.clone(),
            scale: a.scale,
        });
    }
    wires
}

fn pins(f: &File, chips: &[ChipSpec], text: &str, at: At, problems: &mut Vec<Problem>) -> Vec<PinWire> {
    let mut wires: Vec<PinWire> = Vec::new();
    for (i, p) in f.pins.iter().enumerate() {
        let field = format!("pins[{i}]");
        let (pin, signal, direction, active_low) = match p {
            PinFile::Input {
                pin,
                signal,
                active_low,
            } => (pin, signal, Direction::Input, *active_low),
            PinFile::Output {
                pin,
                input,
                active_low,
            } => (pin, input, Direction::Output, *active_low),
        };
        let Some((port, bit)) = parse_pin(pin) else {
            problems.push(at(
                &format!("{field}.pin"),
                format!("\"{pin}\": a pin is written P0.0 to P3.7"),
            ));
            continue;
        };
        let known = match direction {
            Direction::Input => Plant::signal_names().contains(signal),
            Direction::Output => Plant::is_input(signal),
        };
        if !known {
            let what = match direction {
                Direction::Input => "no plant signal",
                Direction::Output => "no plant input an actuator can drive",
            };
            problems.push(locate(
                at(
                    &field,
                    format!("\"{signal}\" is {what} (docs/BEHAVIOUR.md lists them)"),
                ),
                text,
                "pins",
                signal,
            ));
        }
        if wires.iter().any(|w| (w.port, w.bit) == (port, bit)) {
            problems.push(at(&format!("{field}.pin"), format!("{pin} is wired twice")));
        }
        let irq = chips.iter().any(|c| match c {
            ChipSpec::Sja1000 { irq: Some(p), .. } => p.port_bit() == (port, bit),
            _ => false,
        });
        if irq {
            problems.push(at(
                &format!("{field}.pin"),
                format!("{pin} is driven by a CAN controller's interrupt output"),
            ));
        }
        wires.push(PinWire {
            port,
            bit,
            signal: signal.clone(),
            direction,
            active_low,
        });
    }
    wires
}

/// `P2.5` → (2, 5).
fn parse_pin(pin: &str) -> Option<(u8, u8)> {
    let rest = pin.strip_prefix('P').or_else(|| pin.strip_prefix('p'))?;
    let (port, bit) = rest.split_once('.')?;
    let (port, bit) = (port.parse::<u8>().ok()?, bit.parse::<u8>().ok()?);
    (port <= 3 && bit <= 7).then_some((port, bit))
}
