//! A firmware node's wires to the plant: ADC channels and input pins read plant signals, output
//! pins and DACs drive plant inputs. Served at the moments the CPU stops for them (see the
//! node's docs): when it would read inputs whose levels no longer hold, and when it changed an
//! output.
//!
//! A sensor fault injected into the node ([`bus::node::NodeFault`]) acts on the wire that reads
//! the signal, as the scripts' faults act on their readings: stuck, offset, drifting from its
//! start, noisy (Gaussian, from the node's seed), or gone. A sensor that is gone is a cut wire:
//! its ADC channel reads 0 V, its input pin floats high (the port's internal pull-up). Like a
//! value forced on the plant, a fault reaches the firmware at its first read after the plant's
//! next step.

use super::machine::Machine;
use super::spec::FirmwareSpec;
use super::wires::Direction;
use crate::script::{Port, SharedEnv, gaussian};
use bus::node::SensorFault;
use bus::time::BusTime;
use mcs51::Watched;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

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
    /// Faults on the wires of these signals, each from its time.
    faults: Vec<(Port, SensorFault, BusTime)>,
    rng: ChaCha8Rng,
}

impl Wiring {
    pub fn new(env: SharedEnv, spec: &FirmwareSpec, seed: u64) -> Wiring {
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
            faults: Vec::new(),
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_0000_f1e1_d000),
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

    /// Whether an input wire (an ADC channel, its multiplexer's other input, an input pin) reads
    /// `signal`: its port.
    pub fn input_port(&self, spec: &FirmwareSpec, signal: &str) -> Option<Port> {
        let env = self.env.borrow();
        let port = env.port(signal)?;
        let analog = self
            .analog
            .iter()
            .any(|&(a, o)| a == Some(port) || o == Some(port));
        let pin = spec
            .pins
            .iter()
            .zip(&self.pins)
            .any(|(p, &q)| p.direction == Direction::Input && q == Some(port));
        (analog || pin).then_some(port)
    }

    /// The wires of `port` read as `fault` says from `since` on (`None`: true again).
    pub fn set_fault(&mut self, port: Port, fault: Option<SensorFault>, since: BusTime) {
        self.faults.retain(|(p, ..)| *p != port);
        if let Some(f) = fault {
            self.faults.push((port, f, since));
        }
    }

    /// What a wire of `port` reads at `at`, its fault applied; `None` when the sensor is gone.
    fn reading(&mut self, truth: f64, port: Option<Port>, at: BusTime) -> Option<f64> {
        let Some(&(_, fault, since)) = self.faults.iter().find(|(p, ..)| Some(*p) == port) else {
            return Some(truth);
        };
        Some(match fault {
            SensorFault::Stuck(v) => v,
            SensorFault::Offset(o) => truth + o,
            SensorFault::Drift(rate) => truth + rate * at.since(since).as_secs_f64(),
            SensorFault::Noise(sigma) => truth + sigma * gaussian(&mut self.rng),
            SensorFault::Dropout => return None,
        })
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
        let next = env.next_change(at);
        drop(env);
        // The plant through a handle of its own: a fault's noise draws from `self` meanwhile.
        let plant = self.env.clone();
        let plant = plant.borrow();
        let truth = |q: Option<Port>| q.and_then(|q| plant.read(q)).unwrap_or(0.0);
        for (k, a) in spec.analog.iter().enumerate() {
            let (port, other) = self.analog[k];
            // A cut wire reads 0 V.
            let mv = self.reading(truth(port), port, at).map_or(0, |v| a.millivolts(v));
            m.cpu.set_analog_millivolts(a.channel, mv, spec.vref_mv);
            if let Some((p, b, o)) = &a.while_high {
                let mv = self
                    .reading(truth(other), other, at)
                    .map_or(0, |v| o.millivolts(v));
                m.cpu
                    .set_analog_mux(a.channel, *p, *b, mcs51::Cpu::code_of(mv, spec.vref_mv));
            }
        }
        for (k, p) in spec.pins.iter().enumerate() {
            let port = self.pins[k];
            if p.direction == Direction::Input {
                // A cut wire floats high (the port's pull-up).
                let high = match self.reading(truth(port), port, at) {
                    Some(v) => (v >= 0.5) != p.active_low,
                    None => true,
                };
                m.cpu.set_pin(p.port, p.bit, high);
            }
        }
        next
    }
}
