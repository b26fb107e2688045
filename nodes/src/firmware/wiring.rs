//! A firmware node's wires to the plant: ADC channels and input pins read plant signals, output
//! pins drive plant inputs. Sampled at moments the node chooses (see the node's docs).

use super::machine::Machine;
use super::spec::FirmwareSpec;
use super::wires::Direction;
use crate::script::{Port, SharedEnv};
use bus::time::BusTime;

/// The plant, the ports of the wires' signals, and what was last written to it.
pub(crate) struct Wiring {
    env: SharedEnv,
    /// The port of each analog wire's signal, resolved once (the node file's names were
    /// checked when it loaded, so only a spec built in code can leave one unresolved).
    analog: Vec<Option<Port>>,
    /// The port of each pin's signal.
    pins: Vec<Option<Port>>,
    /// The value last written to each output pin's plant input (by index into the pins).
    written: Vec<Option<f64>>,
}

impl Wiring {
    pub fn new(env: SharedEnv, spec: &FirmwareSpec) -> Wiring {
        let (analog, pins) = {
            let e = env.borrow();
            (
                spec.analog.iter().map(|a| e.port(&a.signal)).collect(),
                spec.pins.iter().map(|p| e.port(&p.signal)).collect(),
            )
        };
        Wiring {
            env,
            analog,
            pins,
            written: vec![None; spec.pins.len()],
        }
    }

    /// Reads the plant at `at` into `m`'s analog inputs and input pins, and writes its output
    /// pins' latches to the plant.
    pub fn sample(&mut self, spec: &FirmwareSpec, m: &mut Machine, at: BusTime) {
        let mut env = self.env.borrow_mut();
        env.advance_to(at);
        for (a, port) in spec.analog.iter().zip(&self.analog) {
            let mv = port.and_then(|p| env.read(p)).unwrap_or(0.0) * a.scale;
            // A negative, NaN or huge voltage reads as the converter's end of scale.
            let mv = if mv.is_finite() {
                mv.clamp(0.0, f64::from(u32::MAX))
            } else {
                0.0
            };
            m.cpu
                .set_analog_millivolts(a.channel, mv.round() as u32, spec.vref_mv);
        }
        let latches = m.cpu.sfr();
        for (i, (p, port)) in spec.pins.iter().zip(&self.pins).enumerate() {
            match p.direction {
                Direction::Input => {
                    let on = port.and_then(|port| env.read(port)).is_some_and(|v| v >= 0.5);
                    m.cpu.set_pin(p.port, p.bit, on != p.active_low);
                }
                Direction::Output => {
                    let high = latches[usize::from(p.port) * 0x10] >> p.bit & 1 != 0;
                    let value = if high != p.active_low { 1.0 } else { 0.0 };
                    if self.written[i] != Some(value) {
                        if let Some(port) = *port {
                            env.write(port, value);
                        }
                        self.written[i] = Some(value);
                    }
                }
            }
        }
    }
}
