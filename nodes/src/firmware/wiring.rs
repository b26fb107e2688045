//! A firmware node's wires to the plant: ADC channels and input pins read plant signals, output
//! pins and DACs drive plant inputs. Served at the moments the CPU stops for them (see the
//! node's docs): when it would read inputs whose levels no longer hold, and when it changed an
//! output.

use super::machine::Machine;
use super::spec::FirmwareSpec;
use super::wires::Direction;
use crate::script::{Port, SharedEnv};
use bus::time::BusTime;
use mcs51::Watched;

/// The plant, the ports of the wires' signals, and what was last written to it.
pub(crate) struct Wiring {
    env: SharedEnv,
    /// The port of each analog wire's signal, and of its multiplexer's other signal, resolved
    /// once (the node file's names were checked when it loaded, so only a spec built in code can
    /// leave one unresolved).
    analog: Vec<(Option<Port>, Option<Port>)>,
    /// The port of each pin's signal.
    pins: Vec<Option<Port>>,
    /// The port of each DAC's input.
    dacs: Vec<Option<Port>>,
    /// The value last written to each output pin's and each DAC's plant input.
    written: Vec<Option<f64>>,
}

impl Wiring {
    pub fn new(env: SharedEnv, spec: &FirmwareSpec) -> Wiring {
        let (analog, pins, dacs) = {
            let e = env.borrow();
            (
                spec.analog
                    .iter()
                    .map(|a| {
                        let other = a.while_high.as_ref().and_then(|(_, _, o)| e.port(&o.signal));
                        (e.port(&a.signal), other)
                    })
                    .collect(),
                spec.pins.iter().map(|p| e.port(&p.signal)).collect(),
                spec.dacs.iter().map(|d| e.port(&d.input)).collect(),
            )
        };
        let mut w = Wiring {
            env,
            analog,
            pins,
            dacs,
            written: Vec::new(),
        };
        // What the ports' reset latches (FFh) would drive counts as written: an output reaches
        // the plant when the firmware first changes it, not at power-on.
        w.written = w.outputs(spec, &[0xFF; 128]).map(|(_, v)| Some(v)).collect();
        w
    }

    /// Each output pin's and DAC's plant input (its port) and the value the latches in `sfr`
    /// drive it to.
    fn outputs<'a>(
        &'a self,
        spec: &'a FirmwareSpec,
        sfr: &'a [u8; 128],
    ) -> impl Iterator<Item = (Option<Port>, f64)> + 'a {
        let pins = spec
            .pins
            .iter()
            .zip(&self.pins)
            .filter(|(p, _)| p.direction == Direction::Output)
            .map(|(p, port)| {
                let high = sfr[usize::from(p.port) * 0x10] >> p.bit & 1 != 0;
                (*port, if high != p.active_low { 1.0 } else { 0.0 })
            });
        let dacs = spec
            .dacs
            .iter()
            .zip(&self.dacs)
            .map(|(d, port)| (*port, d.offset + d.scale * f64::from(d.code(sfr))));
        pins.chain(dacs)
    }

    /// What the CPU must stop for: the input pins and channels the plant drives, and the latch
    /// bits that drive it.
    pub fn watched(spec: &FirmwareSpec) -> Watched {
        let mut w = Watched::default();
        for a in &spec.analog {
            w.channels |= 1 << a.channel;
        }
        for p in &spec.pins {
            match p.direction {
                Direction::Input => w.pins[usize::from(p.port)] |= 1 << p.bit,
                Direction::Output => w.outputs[usize::from(p.port)] |= 1 << p.bit,
            }
        }
        for d in &spec.dacs {
            w.outputs[usize::from(d.low)] = 0xFF;
            if let Some(h) = d.high {
                w.outputs[usize::from(h)] = 0xFF;
            }
        }
        w
    }

    /// Drives the plant from `m`'s output latches and sets `m`'s inputs from the plant, at `at`:
    /// returns the next time the plant may change on its own (its next step).
    pub fn serve(&mut self, spec: &FirmwareSpec, m: &mut Machine, at: BusTime) -> BusTime {
        let mut env = self.env.borrow_mut();
        env.advance_to(at);
        let latches = m.cpu.sfr();
        let changed: Vec<(usize, Option<Port>, f64)> = self
            .outputs(spec, &latches)
            .enumerate()
            .filter(|(i, (_, v))| self.written[*i] != Some(*v))
            .map(|(i, (port, v))| (i, port, v))
            .collect();
        for (i, port, value) in changed {
            if let Some(port) = port {
                env.write(port, value);
            }
            self.written[i] = Some(value);
        }
        for (a, (port, other)) in spec.analog.iter().zip(&self.analog) {
            let mv = a.millivolts(port.and_then(|p| env.read(p)).unwrap_or(0.0));
            m.cpu.set_analog_millivolts(a.channel, mv, spec.vref_mv);
            if let Some((p, b, o)) = &a.while_high {
                let mv = o.millivolts(other.and_then(|p| env.read(p)).unwrap_or(0.0));
                m.cpu
                    .set_analog_mux(a.channel, *p, *b, mcs51::Cpu::code_of(mv, spec.vref_mv));
            }
        }
        for (p, port) in spec.pins.iter().zip(&self.pins) {
            if p.direction == Direction::Input {
                let on = port.and_then(|port| env.read(port)).is_some_and(|v| v >= 0.5);
                m.cpu.set_pin(p.port, p.bit, on != p.active_low);
            }
        }
        env.next_change(at)
    }
}
