//! A firmware node file's wires to the plant: ADC channels and port pins, as written and as
//! checked (every signal the plant's, every channel and pin one the chip has, none twice).

use crate::Problem;
use crate::plant::Plant;
use serde::Deserialize;

/// Makes a problem about a field of the node file.
pub(super) type At<'a> = &'a dyn Fn(&str, String) -> Problem;

/// An ADC channel wired to a plant signal: the pin's voltage in millivolts is the signal times
/// `scale`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct AnalogFile {
    channel: u8,
    signal: String,
    #[serde(default = "unit_scale")]
    scale: f64,
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
