//! The harvester's application identifier and its node addresses.
//!
//! The 4MZ-6A protocol splits the 29-bit extended identifier into four fields:
//!
//! | bits      | ID28–ID24 | ID23–ID16  | ID15–ID8    | ID7–ID0 |
//! |-----------|-----------|------------|-------------|---------|
//! | meaning   | priority  | frame type | destination | source  |
//!
//! [`AppId`] is the validated representation, with [`AppId::parse`] and [`AppId::emit`] in the
//! manner of smoltcp's `Repr`s. Frame types other than broadcast and point-to-point survive a
//! round trip as [`FrameType::Unknown`].

use crate::Error;
use bus::extended_id;
use bus::filter::{CAN_EFF_FLAG, SocketCanFilter};
use embedded_can::{ExtendedId, Id};
use serde::{Deserialize, Serialize};

/// A node address (the destination and source fields).
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Address(pub u8);

impl Address {
    /// The cab monitor, the central controller.
    pub const MONITOR: Address = Address(0xF5);
    /// CanModuleA, the automatic row-alignment module.
    pub const ROW_ALIGNMENT: Address = Address(0xA0);
    /// The travel speed control module. The source leaves its address open; harvemu assigns E0,
    /// the next letter after the D flow sensors, a range no other node uses.
    pub const SPEED_CONTROL: Address = Address(0xE0);

    /// CanModuleB number `n` (0–7): B0–B7.
    pub const fn parameter(n: u8) -> Address {
        Address(0xB0 + n)
    }
    /// CanModuleC number `n` (0–3): C0–C3.
    pub const fn alarm(n: u8) -> Address {
        Address(0xC0 + n)
    }
    /// Flow sensor of row `n` (0–5): D0–D5.
    pub const fn flow_sensor(n: u8) -> Address {
        Address(0xD0 + n)
    }

    /// Which kind of node has this address, if the harvester has one there.
    pub fn kind(self) -> Option<NodeKind> {
        Some(match self.0 {
            0xF5 => NodeKind::Monitor,
            0xA0 => NodeKind::RowAlignment,
            0xB0..=0xB7 => NodeKind::Parameter,
            0xC0..=0xC3 => NodeKind::Alarm,
            0xD0..=0xD5 => NodeKind::FlowSensor,
            0xE0 => NodeKind::SpeedControl,
            _ => return None,
        })
    }

    /// A short human name, e.g. "monitor" or "flow sensor D3"; `None` for an unknown address.
    pub fn name(self) -> Option<String> {
        let kind = self.kind()?;
        Some(match kind {
            NodeKind::Monitor | NodeKind::RowAlignment | NodeKind::SpeedControl => kind.name().to_string(),
            _ => format!("{} {self}", kind.name()),
        })
    }

    /// Every address of the harvester: the monitor first, then the 20 field nodes.
    pub fn all() -> impl Iterator<Item = Address> {
        [Address::MONITOR, Address::ROW_ALIGNMENT]
            .into_iter()
            .chain((0..8).map(Address::parameter))
            .chain((0..4).map(Address::alarm))
            .chain((0..6).map(Address::flow_sensor))
            .chain([Address::SPEED_CONTROL])
    }
}

impl core::fmt::Display for Address {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{:02X}", self.0)
    }
}

impl core::fmt::Debug for Address {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "Address({:02X})", self.0)
    }
}

/// The kinds of node on the harvester network.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Debug, Serialize, Deserialize)]
pub enum NodeKind {
    /// Cab monitor F5.
    Monitor,
    /// CanModuleA A0, automatic row alignment.
    RowAlignment,
    /// CanModuleB B0–B7, pulse and parameter acquisition.
    Parameter,
    /// CanModuleC C0–C3, switch and analog alarm monitoring.
    Alarm,
    /// Near-infrared cotton flow sensors D0–D5.
    FlowSensor,
    /// Travel speed control module E0.
    SpeedControl,
}

impl NodeKind {
    /// A short human name.
    pub fn name(self) -> &'static str {
        match self {
            NodeKind::Monitor => "monitor",
            NodeKind::RowAlignment => "row alignment",
            NodeKind::Parameter => "parameter module",
            NodeKind::Alarm => "alarm module",
            NodeKind::FlowSensor => "flow sensor",
            NodeKind::SpeedControl => "speed control",
        }
    }

    /// The priority class of the traffic between this kind and the monitor (SEEDS: 00010 speed
    /// control, 00011 row alignment, 00100 alarms, 00101 parameters, 00110 flow sensors).
    /// The monitor itself has no class of its own: it uses its peer's.
    pub fn priority(self) -> Option<Priority> {
        match self {
            NodeKind::Monitor => None,
            NodeKind::SpeedControl => Some(Priority::SPEED_CONTROL),
            NodeKind::RowAlignment => Some(Priority::ROW_ALIGNMENT),
            NodeKind::Alarm => Some(Priority::ALARM),
            NodeKind::Parameter => Some(Priority::PARAMETER),
            NodeKind::FlowSensor => Some(Priority::FLOW_SENSOR),
        }
    }
}

/// The 5-bit priority field: lower is more urgent.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Debug, Serialize, Deserialize)]
#[serde(try_from = "u8", into = "u8")]
pub struct Priority(u8);

impl Priority {
    /// Monitor <-> travel speed control: manual-drive switch-over and speed control.
    pub const SPEED_CONTROL: Priority = Priority(2);
    /// Monitor <-> CanModuleA commands and data.
    pub const ROW_ALIGNMENT: Priority = Priority(3);
    /// CanModuleC -> monitor fault alarms.
    pub const ALARM: Priority = Priority(4);
    /// CanModuleB -> monitor machine parameters.
    pub const PARAMETER: Priority = Priority(5);
    /// Flow sensors <-> monitor, the lowest class.
    pub const FLOW_SENSOR: Priority = Priority(6);

    /// A checked priority, 0 to 31.
    pub fn new(value: u8) -> Result<Priority, Error> {
        if value > 31 {
            Err(Error::BadPriority(value))
        } else {
            Ok(Priority(value))
        }
    }
    /// The value, 0 to 31.
    pub fn value(self) -> u8 {
        self.0
    }
    /// The identifier bits and the mask (29-bit, no flags) that select the frames of this
    /// priority, whatever their other fields.
    pub fn id_and_mask(self) -> (u32, u32) {
        (
            u32::from(self.0) << field::PRIORITY_SHIFT,
            0x1F << field::PRIORITY_SHIFT,
        )
    }
    /// 0 and 1 are reserved by the protocol for later use.
    pub fn is_reserved(self) -> bool {
        self.0 < 2
    }
    /// The name of the class this priority belongs to, if any.
    pub fn class_name(self) -> &'static str {
        match self.0 {
            0 | 1 => "reserved",
            2 => "speed control",
            3 => "row alignment",
            4 => "alarm",
            5 => "parameter",
            6 => "flow sensor",
            _ => "unassigned",
        }
    }
}

impl TryFrom<u8> for Priority {
    type Error = Error;
    fn try_from(value: u8) -> Result<Self, Error> {
        Priority::new(value)
    }
}

impl From<Priority> for u8 {
    fn from(p: Priority) -> u8 {
        p.0
    }
}

/// The frame-type field.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Serialize, Deserialize)]
pub enum FrameType {
    /// 00: producer/consumer traffic, unacknowledged.
    Broadcast,
    /// 01: connection-oriented traffic (monitor <-> flow sensors), acknowledged.
    PointToPoint,
    /// Any other value, kept so that nothing is lost in a round trip.
    Unknown(u8),
}

impl From<u8> for FrameType {
    fn from(raw: u8) -> FrameType {
        match raw {
            0x00 => FrameType::Broadcast,
            0x01 => FrameType::PointToPoint,
            other => FrameType::Unknown(other),
        }
    }
}

impl From<FrameType> for u8 {
    fn from(t: FrameType) -> u8 {
        match t {
            FrameType::Broadcast => 0x00,
            FrameType::PointToPoint => 0x01,
            FrameType::Unknown(raw) => raw,
        }
    }
}

impl core::fmt::Display for FrameType {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FrameType::Broadcast => f.write_str("broadcast"),
            FrameType::PointToPoint => f.write_str("point-to-point"),
            FrameType::Unknown(raw) => write!(f, "type {raw:02X}"),
        }
    }
}

/// The harvester's application identifier, validated.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub struct AppId {
    /// Priority, 0–31; lower wins arbitration.
    pub priority: Priority,
    /// Broadcast or point-to-point.
    pub frame_type: FrameType,
    /// Destination node.
    pub destination: Address,
    /// Source node.
    pub source: Address,
}

mod field {
    pub const PRIORITY_SHIFT: u32 = 24;
    pub const TYPE_SHIFT: u32 = 16;
    pub const DEST_SHIFT: u32 = 8;
}

impl AppId {
    /// The identifier for traffic between a field node and the monitor, with the node's class.
    pub fn new(priority: Priority, frame_type: FrameType, destination: Address, source: Address) -> AppId {
        AppId {
            priority,
            frame_type,
            destination,
            source,
        }
    }

    /// Reads the fields of a raw 29-bit identifier.
    pub fn from_raw(raw: u32) -> Result<AppId, Error> {
        Ok(AppId::parse(extended_id(raw)?))
    }

    /// Reads the fields of an extended identifier. Every 29-bit value is a valid `AppId`.
    pub fn parse(id: ExtendedId) -> AppId {
        let raw = id.as_raw();
        AppId {
            // A 29-bit value shifted right by 24 has at most 5 bits.
            priority: Priority((raw >> field::PRIORITY_SHIFT) as u8),
            frame_type: FrameType::from((raw >> field::TYPE_SHIFT) as u8),
            destination: Address((raw >> field::DEST_SHIFT) as u8),
            source: Address(raw as u8),
        }
    }

    /// Reads the fields of any identifier; base identifiers are not harvester identifiers.
    pub fn from_id(id: Id) -> Result<AppId, Error> {
        match id {
            Id::Extended(id) => Ok(AppId::parse(id)),
            Id::Standard(id) => Err(Error::NotExtended(id.as_raw())),
        }
    }

    /// The raw 29-bit identifier.
    pub fn raw(&self) -> u32 {
        (u32::from(self.priority.0) << field::PRIORITY_SHIFT)
            | (u32::from(u8::from(self.frame_type)) << field::TYPE_SHIFT)
            | (u32::from(self.destination.0) << field::DEST_SHIFT)
            | u32::from(self.source.0)
    }

    /// The extended identifier.
    pub fn emit(&self) -> ExtendedId {
        // Priority is at most 31, so the value has at most 29 bits.
        ExtendedId::new(self.raw()).unwrap_or(ExtendedId::MAX)
    }
}

impl core::fmt::Display for AppId {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{:08X} (priority {}, {}, {} -> {})",
            self.raw(),
            self.priority.0,
            self.frame_type,
            self.source,
            self.destination
        )
    }
}

/// A SocketCAN filter that keeps every extended frame addressed to `node` (its destination field,
/// ID15..8), whatever its priority, frame type and source: what a PC-side interface in a node's
/// place filters on.
pub fn to_node_filter(node: Address) -> SocketCanFilter {
    let destination = 0xFF << field::DEST_SHIFT;
    SocketCanFilter::new(
        CAN_EFF_FLAG | (u32::from(node.0) << field::DEST_SHIFT),
        CAN_EFF_FLAG | destination,
    )
}

/// The destination of a frame given as a kernel `can_id` (with [`CAN_EFF_FLAG`] for an extended
/// identifier, as the engine's per-identifier statistics key it); `None` for a base frame, which
/// is no harvester identifier.
pub fn destination_of_can_id(can_id: u32) -> Option<Address> {
    (can_id & CAN_EFF_FLAG != 0).then_some(Address((can_id >> field::DEST_SHIFT) as u8))
}

/// The engine's latency class of a frame ([`bus::engine::LatencyClass`]): the identifier's
/// priority field (0–31) for the protocol's extended frames, 32 for base frames, which the
/// protocol does not use.
pub fn latency_class(frame: &bus::Frame) -> usize {
    match AppId::from_id(frame.id()) {
        Ok(id) => usize::from(id.priority.value()),
        Err(_) => 32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_node_filter_keeps_exactly_the_frames_addressed_to_the_node() {
        use bus::filter::AcceptanceFilter;
        // The protocol's worked identifier 0x0300A0F5 goes from F5 to A0 (destination byte A0).
        let to_a0 = bus::Frame::new_data(extended_id(0x0300_A0F5).unwrap(), &[1]).unwrap();
        let from_a0 = bus::Frame::new_data(extended_id(0x0300_F5A0).unwrap(), &[1]).unwrap();
        let base = bus::Frame::new_data(bus::standard_id(0x0A0).unwrap(), &[1]).unwrap();
        let a0 = to_node_filter(Address(0xA0));
        assert!(a0.accepts(&to_a0));
        assert!(!a0.accepts(&from_a0));
        assert!(!a0.accepts(&base));
        assert!(to_node_filter(Address::MONITOR).accepts(&from_a0));
        assert_eq!(destination_of_can_id(0x8300_A0F5), Some(Address(0xA0)));
        assert_eq!(destination_of_can_id(0x0000_00A0), None);
        // Priority 3 (the row-alignment class) is bits 28..24 = 00011.
        assert_eq!(Priority::ROW_ALIGNMENT.id_and_mask(), (0x0300_0000, 0x1F00_0000));
    }

    #[test]
    fn seed_identifiers() {
        let d0 = AppId::from_raw(0x0601F5D0).unwrap();
        assert_eq!(d0.priority, Priority::FLOW_SENSOR);
        assert_eq!(d0.frame_type, FrameType::PointToPoint);
        assert_eq!(d0.destination, Address::MONITOR);
        assert_eq!(d0.source, Address::flow_sensor(0));

        let cmd = AppId::new(
            Priority::new(0b00011).unwrap(),
            FrameType::Broadcast,
            Address::ROW_ALIGNMENT,
            Address::MONITOR,
        );
        assert_eq!(cmd.raw(), 0x0300A0F5);
        let back = AppId::new(
            cmd.priority,
            FrameType::Broadcast,
            Address::MONITOR,
            Address::ROW_ALIGNMENT,
        );
        assert_eq!(back.raw(), 0x0300F5A0);
        assert_eq!(cmd.to_string(), "0300A0F5 (priority 3, broadcast, F5 -> A0)");
    }

    #[test]
    fn unknown_frame_type_round_trips() {
        let raw = 0x1F7FB0C1;
        let id = AppId::from_raw(raw).unwrap();
        assert_eq!(id.frame_type, FrameType::Unknown(0x7F));
        assert_eq!(id.priority.value(), 31);
        assert_eq!(id.raw(), raw);
        assert_eq!(id.emit().as_raw(), raw);
    }

    #[test]
    fn rejects_bad_input() {
        assert_eq!(Priority::new(32), Err(Error::BadPriority(32)));
        assert!(AppId::from_raw(0x2000_0000).is_err());
        let base = Id::Standard(embedded_can::StandardId::new(0x123).unwrap());
        assert_eq!(AppId::from_id(base), Err(Error::NotExtended(0x123)));
    }

    #[test]
    fn address_table() {
        let all: Vec<Address> = Address::all().collect();
        assert_eq!(all.len(), 21);
        let mut unique = all.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), 21, "addresses are distinct");
        assert_eq!(
            all.iter()
                .filter(|a| a.kind() == Some(NodeKind::FlowSensor))
                .count(),
            6
        );
        assert_eq!(
            all.iter()
                .filter(|a| a.kind() == Some(NodeKind::Parameter))
                .count(),
            8
        );
        assert_eq!(
            all.iter().filter(|a| a.kind() == Some(NodeKind::Alarm)).count(),
            4
        );
        assert_eq!(Address(0xD3).name().as_deref(), Some("flow sensor D3"));
        assert_eq!(Address(0x42).kind(), None);
    }

    #[test]
    fn priority_classes_follow_the_seed() {
        let order = [
            NodeKind::SpeedControl,
            NodeKind::RowAlignment,
            NodeKind::Alarm,
            NodeKind::Parameter,
            NodeKind::FlowSensor,
        ];
        let values: Vec<u8> = order.iter().map(|k| k.priority().unwrap().value()).collect();
        assert_eq!(values, [0b00010, 0b00011, 0b00100, 0b00101, 0b00110]);
        assert!(Priority::new(0).unwrap().is_reserved() && Priority::new(1).unwrap().is_reserved());
    }
}
