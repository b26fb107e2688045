//! The monitor's side of the connection-oriented flow sensor traffic: calibration, group
//! assembly and acknowledgement (docs/PROTOCOL.md, "the six-frame exchange").

use bus::Frame;
use protocol::catalogue::{Decoded, by_name};
use protocol::ident::Address;

/// Group codes of the two markers.
pub const FLOW_GROUP: u8 = 0x0D;
/// Reference group code.
pub const REFERENCE_GROUP: u8 = 0x0E;

/// Sensor states as `flow.status` codes them.
pub mod state {
    /// Waiting for the monitor to calibrate it.
    pub const AWAITING_CALIBRATION: i64 = 1;
    /// Measuring its references.
    pub const CALIBRATING: i64 = 2;
    /// Streaming.
    pub const RUNNING: i64 = 3;
    /// Stopped streaming for lack of acknowledgements.
    pub const NO_ACK: i64 = 4;
}

/// A complete group: five unit values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Group {
    /// 0x0D flow or 0x0E reference.
    pub code: u8,
    /// Units 1–5, raw counts.
    pub units: [u16; 5],
    /// The part-2 bytes the source leaves unexplained.
    pub aux: u32,
}

/// Where the assembly of the current group stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Expect {
    Marker,
    Part1(u8),
    Part2(u8, [u16; 3]),
}

/// Calibration settings the monitor sends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Calibration {
    /// Reference level the emitters are driven to, counts.
    pub target_reference: f64,
    /// Reference groups averaged before accepting.
    pub samples: u8,
}

impl Default for Calibration {
    fn default() -> Self {
        Calibration {
            target_reference: 10_000.0,
            samples: 5,
        }
    }
}

/// One flow sensor as the monitor tracks it.
#[derive(Clone, Debug)]
pub struct FlowSession {
    sensor: Address,
    expect: Expect,
    calibrating: bool,
    reference_groups: u32,
    /// Groups received complete.
    pub groups: u64,
    /// Groups broken (a frame missing or out of order): counted as lost.
    pub broken: u64,
    /// Last reference values.
    pub references: Option<[u16; 5]>,
    /// Last flow values.
    pub flow: Option<[u16; 5]>,
    /// True once calibration has been accepted.
    pub calibrated: bool,
}

impl FlowSession {
    /// A session with sensor `sensor` (D0–D5).
    pub fn new(sensor: Address) -> FlowSession {
        FlowSession {
            sensor,
            expect: Expect::Marker,
            calibrating: false,
            reference_groups: 0,
            groups: 0,
            broken: 0,
            references: None,
            flow: None,
            calibrated: false,
        }
    }

    fn command(&self, name: &str, values: &[(&str, f64)]) -> Option<Frame> {
        by_name(name)?
            .encode(self.sensor, |f| {
                values.iter().find(|(n, _)| *n == f).map(|(_, v)| *v)
            })
            .ok()
    }

    /// Takes one decoded frame from this sensor; returns a completed group, and pushes any
    /// answer onto `out`.
    pub fn handle(&mut self, d: &Decoded, cal: Calibration, out: &mut Vec<Frame>) -> Option<Group> {
        let raw = |name: &str| d.get(name).map_or(0, |v| v.raw);
        match d.message.name {
            "flow.status" => {
                match raw("state") {
                    state::AWAITING_CALIBRATION if !self.calibrating => {
                        self.calibrating = true;
                        self.calibrated = false;
                        self.reference_groups = 0;
                        out.extend(self.command(
                            "flow.calibrate",
                            &[
                                ("command", 1.0),
                                ("target_reference", cal.target_reference),
                                ("samples", f64::from(cal.samples)),
                            ],
                        ));
                    }
                    state::NO_ACK => {
                        // Resume a sensor that gave up on us.
                        out.extend(self.command(
                            "flow.calibrate",
                            &[
                                ("command", 2.0),
                                ("target_reference", cal.target_reference),
                                ("samples", f64::from(cal.samples)),
                            ],
                        ));
                    }
                    _ => {}
                }
                None
            }
            "flow.marker_flow" | "flow.marker_reference" => {
                if self.expect != Expect::Marker {
                    self.broken += 1;
                }
                self.expect = Expect::Part1(raw("group") as u8);
                None
            }
            "flow.part1" => {
                if let Expect::Part1(code) = self.expect {
                    let u = |n| raw(n) as u16;
                    self.expect = Expect::Part2(code, [u("unit1"), u("unit2"), u("unit3")]);
                } else {
                    self.broken += 1;
                    self.expect = Expect::Marker;
                }
                None
            }
            "flow.part2" => {
                let Expect::Part2(code, first) = self.expect else {
                    self.broken += 1;
                    self.expect = Expect::Marker;
                    return None;
                };
                self.expect = Expect::Marker;
                self.groups += 1;
                let units = [
                    first[0],
                    first[1],
                    first[2],
                    raw("unit4") as u16,
                    raw("unit5") as u16,
                ];
                let group = Group {
                    code,
                    units,
                    aux: raw("aux") as u32,
                };
                out.extend(self.command(
                    "flow.ack",
                    &[
                        ("group", f64::from(code)),
                        ("sequence", (self.groups % 256) as f64),
                    ],
                ));
                if code == REFERENCE_GROUP {
                    self.references = Some(units);
                    if self.calibrating {
                        self.reference_groups += 1;
                        if self.reference_groups >= u32::from(cal.samples) {
                            self.calibrating = false;
                            self.calibrated = true;
                            out.extend(self.command(
                                "flow.calibrate",
                                &[
                                    ("command", 2.0),
                                    ("target_reference", cal.target_reference),
                                    ("samples", f64::from(cal.samples)),
                                ],
                            ));
                        }
                    }
                } else {
                    self.flow = Some(units);
                }
                Some(group)
            }
            _ => None,
        }
    }
}
