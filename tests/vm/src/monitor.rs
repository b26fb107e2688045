//! An outside monitor for the six flow sensors, written from `docs/PROTOCOL.md` alone (no harvemu
//! code): it takes the place of harvemu's own monitor (F5) on the interface.
//!
//! Contract, as the protocol's "Flow sensors" section says a monitor behaves:
//! - a sensor reporting `flow.status` "awaiting calibration" (state 1) gets `flow.calibrate`
//!   "start calibration" (command 1) with the target reference level [`TARGET`] and the sample
//!   count [`SAMPLES`];
//! - every complete group (marker `20 0D`/`20 0E`, then `01 ..`, then `02 ..`, in that order) is
//!   acknowledged with `flow.ack` carrying the group code and the running count of complete groups
//!   from that sensor (modulo 256, the first being 1); a group broken off is counted as lost;
//! - after [`SAMPLES`] complete reference groups during calibration it sends "accept and run"
//!   (command 2) with the same target and count;
//! - a sensor reporting "no acknowledgement" (state 4) is noted, and answered with "accept and
//!   run", as the protocol says the reference monitor does.
//!
//! It is sans-IO: [`Monitor::handle`] takes a received frame and returns the frames to send.

use socketcan::{CanFrame, EmbeddedFrame, ExtendedId, Id};

/// The target reference level sent with the calibration commands (counts).
pub const TARGET: u16 = 10_000;

/// How many reference groups calibration averages.
pub const SAMPLES: u8 = 5;

/// `flow.status` state: awaiting calibration.
const AWAITING_CALIBRATION: u8 = 1;

/// `flow.status` state: no acknowledgement (the sensor gave up).
pub const NO_ACKNOWLEDGEMENT: u8 = 4;

/// Where a sensor is, as the monitor sees it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Phase {
    /// Not calibrated yet.
    #[default]
    Waiting,
    /// Start sent; counting reference groups.
    Calibrating,
    /// Accept sent.
    Running,
}

/// One sensor's session.
#[derive(Clone, Debug, Default)]
struct Sensor {
    phase: Phase,
    /// The group being received: its code and the next part expected (1 or 2).
    building: Option<(u8, u8)>,
    /// Complete groups received, modulo 256: the next acknowledgement's sequence byte.
    sequence: u8,
    /// Complete reference groups since calibration started.
    references: u8,
}

/// What the monitor saw of one sensor.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Tally {
    /// When "accept and run" was sent (seconds, as given to `handle`).
    pub accepted_at: Option<f64>,
    /// Complete groups acknowledged.
    pub acknowledged: u64,
    /// Groups broken off (a part missing or out of order).
    pub lost: u64,
    /// When the sensor reported "no acknowledgement".
    pub gave_up: Vec<f64>,
    /// `flow.status` frames received.
    pub statuses: u64,
}

/// The monitor of sensors D0–D5.
#[derive(Clone, Debug, Default)]
pub struct Monitor {
    sensors: [Sensor; 6],
    /// What it saw, per sensor.
    pub tally: [Tally; 6],
}

/// The sensor (0–5) a frame comes from: `0601F5Dx`, flow sensor Dx to the monitor.
pub fn sensor_of(frame: &CanFrame) -> Option<usize> {
    match frame.id() {
        Id::Extended(id) if id.as_raw() & 0xFFFF_FFF0 == 0x0601_F5D0 && id.as_raw() & 0xF < 6 => {
            Some((id.as_raw() & 0xF) as usize)
        }
        _ => None,
    }
}

/// A frame from the monitor to sensor `x`: `0601DxF5`.
fn to_sensor(x: usize, data: &[u8]) -> Option<CanFrame> {
    let id = ExtendedId::new(0x0601_D0F5 | (x as u32) << 8)?;
    CanFrame::new(id, data)
}

/// `flow.calibrate` with `command` (1 start, 2 accept and run).
fn calibrate(x: usize, command: u8) -> Option<CanFrame> {
    let [lo, hi] = TARGET.to_le_bytes();
    to_sensor(x, &[0x10, command, lo, hi, SAMPLES])
}

impl Monitor {
    /// Takes a frame received at `at` (seconds) and returns what to send in answer.
    pub fn handle(&mut self, at: f64, frame: &CanFrame) -> Vec<CanFrame> {
        let Some(x) = sensor_of(frame) else {
            return Vec::new();
        };
        let (s, tally) = (&mut self.sensors[x], &mut self.tally[x]);
        let data = frame.data();
        let mut out = Vec::new();
        match (data.first(), data.get(1)) {
            (Some(0x30), Some(&state)) => {
                tally.statuses += 1;
                if state == AWAITING_CALIBRATION {
                    s.phase = Phase::Calibrating;
                    s.references = 0;
                    out.extend(calibrate(x, 1));
                } else if state == NO_ACKNOWLEDGEMENT {
                    tally.gave_up.push(at);
                    s.phase = Phase::Running;
                    out.extend(calibrate(x, 2));
                }
            }
            (Some(0x20), Some(&code)) if data.len() == 8 => {
                if s.building.is_some() {
                    tally.lost += 1;
                }
                s.building = Some((code, 1));
            }
            (Some(&part @ (0x01 | 0x02)), _) => match s.building {
                Some((code, 1)) if part == 1 => s.building = Some((code, 2)),
                Some((code, 2)) if part == 2 => {
                    s.building = None;
                    s.sequence = s.sequence.wrapping_add(1);
                    tally.acknowledged += 1;
                    out.extend(to_sensor(x, &[0x21, code, s.sequence]));
                    if code == 0x0E && s.phase == Phase::Calibrating {
                        s.references += 1;
                        if s.references >= SAMPLES {
                            s.phase = Phase::Running;
                            tally.accepted_at = Some(at);
                            out.extend(calibrate(x, 2));
                        }
                    }
                }
                Some(_) => {
                    s.building = None;
                    tally.lost += 1;
                }
                None => {}
            },
            _ => {}
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{format_frame, parse_frame};

    fn feed(m: &mut Monitor, at: f64, text: &str) -> Vec<String> {
        let frame = parse_frame(text).expect("valid frame");
        m.handle(at, &frame).iter().map(format_frame).collect()
    }

    fn group(m: &mut Monitor, at: f64, sensor: u8, code: u8) -> Vec<String> {
        let id = format!("0601F5D{sensor}");
        let check = 0xCC - code;
        let mut out = feed(m, at, &format!("{id}#20{code:02X}0002FF{check:02X}FF00"));
        out.extend(feed(m, at, &format!("{id}#0101341EEA2BEF2C")));
        out.extend(feed(m, at, &format!("{id}#028921982C44D46E")));
        out
    }

    #[test]
    fn calibrates_acknowledges_and_accepts_as_the_protocol_says() {
        let mut m = Monitor::default();
        // 10000 = 0x2710, little-endian 10 27; five samples.
        assert_eq!(feed(&mut m, 0.1, "0601F5D2#30010300"), ["0601D2F5#1001102705"]);
        for n in 1..=4u8 {
            assert_eq!(group(&mut m, 0.2, 2, 0x0E), [format!("0601D2F5#210E{n:02X}")]);
        }
        assert_eq!(
            group(&mut m, 0.6, 2, 0x0E),
            ["0601D2F5#210E05", "0601D2F5#1002102705"]
        );
        assert_eq!(m.tally[2].accepted_at, Some(0.6));
        assert_eq!(group(&mut m, 0.7, 2, 0x0D), ["0601D2F5#210D06"]);
        // Other sensors and other senders are not its business.
        assert!(feed(&mut m, 0.7, "0601F5D6#30010300").is_empty());
        assert!(feed(&mut m, 0.7, "0601D2F5#210D06").is_empty());
        assert_eq!(m.tally[2].acknowledged, 6);
    }

    #[test]
    fn broken_groups_are_lost_and_giving_up_is_noted() {
        let mut m = Monitor::default();
        assert!(feed(&mut m, 0.1, "0601F5D0#200D0002FFBFFF00").is_empty());
        assert!(feed(&mut m, 0.1, "0601F5D0#0201000000906EFF").is_empty());
        assert_eq!(m.tally[0].lost, 1);
        assert!(feed(&mut m, 0.2, "0601F5D0#200D0002FFBFFF00").is_empty());
        assert!(feed(&mut m, 0.2, "0601F5D0#200D0002FFBFFF00").is_empty());
        assert_eq!(m.tally[0].lost, 2);
        assert_eq!(feed(&mut m, 0.5, "0601F5D0#30040303"), ["0601D0F5#1002102705"]);
        assert_eq!(m.tally[0].gave_up, [0.5]);
        assert_eq!(m.tally[0].acknowledged, 0);
    }
}
