//! A firmware node file's wires to the plant: ADC channels (each with an optional analog
//! multiplexer in front), port pins and DACs on whole ports, as written and as checked (every
//! signal the plant's, every channel, pin and port one the chip has, none wired twice).

use crate::Problem;
use crate::plant::Plant;
use serde::Deserialize;

/// Makes a problem about a field of the node file.
pub(super) type At<'a> = &'a dyn Fn(&str, String) -> Problem;

/// An ADC channel wired to a plant signal: the pin's voltage in millivolts is `offset_mv` plus
/// the signal times `scale`. With `while_high`, an analog multiplexer in front of the channel
/// passes another signal while a port pin's latch is high.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct AnalogFile {
    channel: u8,
    signal: String,
    #[serde(default = "unit_scale")]
    scale: f64,
    #[serde(default)]
    offset_mv: f64,
    #[serde(default)]
    while_high: Option<MuxFile>,
}

/// The multiplexer's other input and the pin that selects it.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MuxFile {
    pin: String,
    signal: String,
    #[serde(default = "unit_scale")]
    scale: f64,
    #[serde(default)]
    offset_mv: f64,
}

/// A DAC on one or two ports driving a plant input, as written.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct DacFile {
    low: String,
    #[serde(default)]
    high: Option<String>,
    input: String,
    #[serde(default = "unit_scale")]
    scale: f64,
    #[serde(default)]
    offset: f64,
}

fn unit_scale() -> f64 {
    1.0
}

/// A port pin wired to the plant, as written.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) enum PinFile {
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

/// An ADC channel wired to a plant signal.
#[derive(Clone, Debug, PartialEq)]
pub struct AnalogWire {
    /// Channel 0–7 (pin P1.channel).
    pub channel: u8,
    /// The plant signal.
    pub signal: String,
    /// Millivolts at the pin per unit of the signal.
    pub scale: f64,
    /// Millivolts at the pin with the signal at 0.
    pub offset_mv: f64,
    /// The multiplexer's other input: the port and bit whose latch selects it while high, and
    /// that input's signal, scale and offset.
    pub while_high: Option<(u8, u8, Box<AnalogWire>)>,
}

impl AnalogWire {
    /// The voltage at the pin, mV, with the signal at `value`: a negative, NaN or huge voltage
    /// reads as the converter's end of scale.
    pub fn millivolts(&self, value: f64) -> u32 {
        let mv = self.offset_mv + value * self.scale;
        if mv.is_finite() {
            mv.clamp(0.0, f64::from(u32::MAX)).round() as u32
        } else {
            0
        }
    }
}

/// Ports 0–3 as one DAC (a latch and a resistor ladder, or a converter chip behind the port)
/// driving a plant input: the input is `offset + scale × code`, the code being the low port's
/// latch, plus 256 × the high port's when there is one.
#[derive(Clone, Debug, PartialEq)]
pub struct DacWire {
    /// The port of the low byte.
    pub low: u8,
    /// The port of the high byte, for a 16-bit DAC.
    pub high: Option<u8>,
    /// The plant input.
    pub input: String,
    /// Units of the input per step of the code.
    pub scale: f64,
    /// The input at code 0.
    pub offset: f64,
}

impl DacWire {
    /// The code the ports' latches (`sfr[port × 10h]`, SFRs from 80h) give.
    pub fn code(&self, sfr: &[u8; 128]) -> u16 {
        let latch = |port: u8| u16::from(sfr[usize::from(port) * 0x10]);
        latch(self.low) | self.high.map_or(0, |h| latch(h) << 8)
    }
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

/// Where `needle` first appears as a quoted string in `text` after `section:` (the list that
/// holds it): the line and column of the problem about it.
fn locate(mut p: Problem, text: &str, section: &str, needle: &str) -> Problem {
    let from = text.find(&format!("{section}:")).unwrap_or(0);
    if let Some(offset) = text[from..].find(&format!("\"{needle}\"")) {
        p.position = Some(crate::script::position_of(text, from + offset));
    }
    p
}

pub(super) fn analog(
    files: &[AnalogFile],
    cc03: bool,
    text: &str,
    at: At,
    problems: &mut Vec<Problem>,
) -> Vec<AnalogWire> {
    let mut wires: Vec<AnalogWire> = Vec::new();
    for (i, a) in files.iter().enumerate() {
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
        if !Plant::is_signal(&a.signal) {
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
        finite(at, &format!("{field}.scale"), a.scale, problems);
        finite(at, &format!("{field}.offset_mv"), a.offset_mv, problems);
        let while_high = a.while_high.as_ref().and_then(|m| {
            let field = format!("{field}.while_high");
            if !Plant::is_signal(&m.signal) {
                problems.push(locate(
                    at(
                        &format!("{field}.signal"),
                        format!(
                            "\"{}\" is no plant signal (docs/BEHAVIOUR.md lists them)",
                            m.signal
                        ),
                    ),
                    text,
                    "analog",
                    &m.signal,
                ));
            }
            finite(at, &format!("{field}.scale"), m.scale, problems);
            finite(at, &format!("{field}.offset_mv"), m.offset_mv, problems);
            let Some((port, bit)) = parse_pin(&m.pin) else {
                problems.push(at(
                    &format!("{field}.pin"),
                    format!("\"{}\": a pin is written P0.0 to P3.7", m.pin),
                ));
                return None;
            };
            let other = AnalogWire {
                channel: a.channel,
                signal: m.signal.clone(),
                scale: m.scale,
                offset_mv: m.offset_mv,
                while_high: None,
            };
            Some((port, bit, Box::new(other)))
        });
        wires.push(AnalogWire {
            channel: a.channel,
            signal: a.signal.clone(),
            scale: a.scale,
            offset_mv: a.offset_mv,
            while_high,
        });
    }
    wires
}

fn finite(at: At, field: &str, value: f64, problems: &mut Vec<Problem>) {
    if !value.is_finite() {
        problems.push(at(field, format!("{value}: this must be a finite number")));
    }
}

/// The DACs, checked against the pins already wired (`taken`: port and bit of every pin wire
/// and of every multiplexer's select pin).
pub(super) fn dacs(
    files: &[DacFile],
    taken: &[(u8, u8)],
    text: &str,
    at: At,
    problems: &mut Vec<Problem>,
) -> Vec<DacWire> {
    let mut wires: Vec<DacWire> = Vec::new();
    for (i, d) in files.iter().enumerate() {
        let field = format!("dacs[{i}]");
        let mut port_of = |name: &str, part: &str| {
            let port = name
                .strip_prefix('P')
                .or_else(|| name.strip_prefix('p'))
                .and_then(|p| p.parse::<u8>().ok())
                .filter(|&p| p <= 3);
            let Some(port) = port else {
                problems.push(at(
                    &format!("{field}.{part}"),
                    format!("\"{name}\": a port is written P0 to P3"),
                ));
                return None;
            };
            let used = taken.iter().any(|&(p, _)| p == port)
                || wires.iter().any(|w| w.low == port || w.high == Some(port));
            if used {
                problems.push(at(
                    &format!("{field}.{part}"),
                    format!("{name}: a pin of this port is wired already"),
                ));
            }
            Some(port)
        };
        let low = port_of(&d.low, "low");
        let high = match &d.high {
            None => Some(None),
            Some(h) => port_of(h, "high").map(Some),
        };
        if !Plant::is_input(&d.input) {
            problems.push(locate(
                at(
                    &format!("{field}.input"),
                    format!(
                        "\"{}\" is no plant input a DAC can drive (docs/BEHAVIOUR.md lists them)",
                        d.input
                    ),
                ),
                text,
                "dacs",
                &d.input,
            ));
        }
        finite(at, &format!("{field}.scale"), d.scale, problems);
        finite(at, &format!("{field}.offset"), d.offset, problems);
        match (low, high) {
            (Some(low), Some(Some(high))) if high == low => {
                problems.push(at(
                    &format!("{field}.high"),
                    format!("P{high}: the port of the low byte"),
                ));
            }
            (Some(low), Some(high)) => wires.push(DacWire {
                low,
                high,
                input: d.input.clone(),
                scale: d.scale,
                offset: d.offset,
            }),
            _ => {}
        }
    }
    wires
}

pub(super) fn pins(
    files: &[PinFile],
    irq_pins: &[(u8, u8)],
    text: &str,
    at: At,
    problems: &mut Vec<Problem>,
) -> Vec<PinWire> {
    let mut wires: Vec<PinWire> = Vec::new();
    for (i, p) in files.iter().enumerate() {
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
            Direction::Input => Plant::is_signal(signal),
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
        if irq_pins.contains(&(port, bit)) {
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
