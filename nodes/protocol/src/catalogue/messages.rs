//! The table itself. Keep `docs/PROTOCOL.md` in step with it (a test checks that every message
//! name appears there).

use super::{Direction::*, Field, MessageDef, Nodes, Trigger::*};
use crate::ident::{Address, FrameType, NodeKind};

const FLOW: Nodes = Nodes::Kind(NodeKind::FlowSensor);
const ROW: Nodes = Nodes::Kind(NodeKind::RowAlignment);
const SPEED: Nodes = Nodes::Kind(NodeKind::SpeedControl);

const fn b(n: u8) -> Nodes {
    Nodes::One(Address::parameter(n))
}
const fn c(n: u8) -> Nodes {
    Nodes::One(Address::alarm(n))
}

/// Speed in 0.01 km/h, 0 to 40 km/h.
const fn speed(name: &'static str, byte: u8, doc: &'static str) -> Field {
    Field::u16(name, byte, doc)
        .scaled(0.01, 0.0, "km/h")
        .range(0.0, 40.0)
}

/// One near-infrared detection unit, raw counts.
const fn unit(name: &'static str, byte: u8) -> Field {
    Field::u16(name, byte, "16-bit value of one emitter/receiver detection unit (flow group: light attenuation by cotton; reference group: the unit's calibrated reference)")
        .scaled(1.0, 0.0, "count")
}

/// Marker frame opening a group of two frames. Every byte is fixed by the source; byte 5 is the
/// same in both examples after adding the group code (0xBF + 0x0D = 0xBE + 0x0E = 0xCC), which is
/// all the source shows of it.
const fn marker(group: u32, check: u32) -> [Field; 6] {
    [
        Field::u8(
            "group",
            1,
            "0x0D: the next two frames are flow data; 0x0E: the next two are calibration reference values",
        )
        .constant(group),
        Field::u8("reserved2", 2, "fixed 0x00").constant(0x00),
        Field::u8(
            "frames_following",
            3,
            "fixed 2: the number of frames in the group after the marker",
        )
        .constant(2),
        Field::u8("fixed4", 4, "fixed 0xFF").constant(0xFF),
        Field::u8(
            "check",
            5,
            "fixed; 0xCC minus the group code in both of the source's examples",
        )
        .constant(check),
        Field::u16("fixed6", 6, "fixed FF 00").constant(0x00FF),
    ]
}

const MARKER_FLOW: [Field; 6] = marker(0x0D, 0xBF);
const MARKER_REFERENCE: [Field; 6] = marker(0x0E, 0xBE);

const FLOW_STATES: &[(u32, &str)] = &[
    (0, "boot"),
    (1, "awaiting calibration"),
    (2, "calibrating"),
    (3, "running"),
    (4, "no acknowledgement"),
    (5, "fault"),
];

/// Every message of the 4MZ-6A protocol.
pub static MESSAGES: &[MessageDef] = &[
    // ---- Travel speed control E0, priority 00010 ----
    MessageDef {
        name: "speed.mode",
        number: 0x01,
        selector: None,
        nodes: SPEED,
        direction: FromMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 2,
        trigger: Event,
        fields: &[Field::u8("mode", 1, "requested drive mode").values(&[(0, "manual"), (1, "cruise")])],
        doc: "Cruise switch: the operator (or the monitor on a fault) switches between manual drive and cruise.",
    },
    MessageDef {
        name: "speed.setpoint",
        number: 0x02,
        selector: None,
        nodes: SPEED,
        direction: FromMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 3,
        trigger: OnChange { heartbeat_ms: 200 },
        fields: &[speed(
            "setpoint",
            1,
            "travel speed the controller is to hold in cruise mode",
        )
        .range(0.0, 12.0)],
        doc: "Speed set-point from the monitor's cruise logic. Repeated every 200 ms in cruise: the controller returns to manual when it hears none for 1 s.",
    },
    MessageDef {
        name: "speed.unload",
        number: 0x03,
        selector: None,
        nodes: SPEED,
        direction: FromMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 2,
        trigger: Event,
        fields: &[Field::u8("command", 1, "basket unload").values(&[(0, "lower basket"), (1, "unload")])],
        doc: "Unload command: the controller brings the machine to a stop and raises the basket; 'lower basket' ends it.",
    },
    MessageDef {
        name: "speed.status",
        number: 0x10,
        selector: None,
        nodes: SPEED,
        direction: ToMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 7,
        trigger: Periodic { period_ms: 50 },
        fields: &[
            speed("actual", 1, "measured travel speed"),
            speed("setpoint", 3, "set-point in force").range(0.0, 12.0),
            Field::u8("mode", 5, "drive mode in force").values(&[
                (0, "manual"),
                (1, "cruise"),
                (2, "unloading"),
            ]),
            Field::flag(
                "operator_override",
                6,
                0,
                "the operator moved the drive lever: cruise is suspended",
            ),
            Field::flag(
                "setpoint_timeout",
                6,
                1,
                "no set-point for 1 s: fell back to manual",
            ),
        ],
        doc: "Speed controller status, the highest-priority periodic traffic on the bus.",
    },
    // ---- Row alignment A0, priority 00011 ----
    MessageDef {
        name: "row.command",
        number: 0x01,
        selector: None,
        nodes: ROW,
        direction: FromMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 2,
        trigger: Event,
        fields: &[Field::u8("command", 1, "row alignment command").values(&[
            (0, "stop"),
            (1, "start auto alignment"),
            (2, "centre and hold"),
        ])],
        doc: "Start or stop automatic row alignment; the monitor starts it when cruise begins. This is the source's example frame 0x0300A0F5.",
    },
    MessageDef {
        name: "row.status",
        number: 0x10,
        selector: None,
        nodes: ROW,
        direction: ToMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 5,
        trigger: Periodic { period_ms: 200 },
        fields: &[
            Field::u8("state", 1, "alignment state").values(&[
                (0, "idle"),
                (1, "seeking row"),
                (2, "locked"),
                (3, "fault"),
            ]),
            Field::i16(
                "offset",
                2,
                "lateral offset of the picker heads from the rows, positive to the right",
            )
            .scaled(1.0, 0.0, "mm")
            .range(-500.0, 500.0),
            Field::i8(
                "correction",
                4,
                "steering correction being applied, positive to the right",
            )
            .scaled(1.0, 0.0, "%")
            .range(-100.0, 100.0),
        ],
        doc: "Row alignment status back to the monitor (identifier 0x0300F5A0).",
    },
    // ---- Parameter modules B0–B7, priority 00101 ----
    MessageDef {
        name: "param.ground_speed",
        number: 0x20,
        selector: None,
        nodes: b(0),
        direction: ToMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 5,
        trigger: Periodic { period_ms: 100 },
        fields: &[
            speed("ground_speed", 1, "travel speed from the wheel pulse sensor"),
            Field::u16("wheel_pulses", 3, "wheel pulse frequency")
                .scaled(1.0, 0.0, "Hz")
                .range(0.0, 2000.0),
        ],
        doc: "B0: travel speed measured at the wheel.",
    },
    MessageDef {
        name: "param.engine",
        number: 0x21,
        selector: None,
        nodes: b(1),
        direction: ToMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 3,
        trigger: Periodic { period_ms: 100 },
        fields: &[Field::u16("engine_rpm", 1, "engine speed")
            .scaled(1.0, 0.0, "rpm")
            .range(0.0, 3000.0)],
        doc: "B1: engine speed.",
    },
    MessageDef {
        name: "param.fan",
        number: 0x22,
        selector: None,
        nodes: b(2),
        direction: ToMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 3,
        trigger: Periodic { period_ms: 100 },
        fields: &[Field::u16("fan_rpm", 1, "conveying fan speed")
            .scaled(1.0, 0.0, "rpm")
            .range(0.0, 5000.0)],
        doc: "B2: speed of the fan that carries picked cotton to the basket.",
    },
    MessageDef {
        name: "param.drums",
        number: 0x23,
        selector: None,
        nodes: b(3),
        direction: ToMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 5,
        trigger: Periodic { period_ms: 100 },
        fields: &[
            Field::u16("front_drum_rpm", 1, "front picking drum speed")
                .scaled(1.0, 0.0, "rpm")
                .range(0.0, 1000.0),
            Field::u16("rear_drum_rpm", 3, "rear picking drum speed")
                .scaled(1.0, 0.0, "rpm")
                .range(0.0, 1000.0),
        ],
        doc: "B3: picking drum speeds.",
    },
    MessageDef {
        name: "param.water",
        number: 0x24,
        selector: None,
        nodes: b(4),
        direction: ToMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 4,
        trigger: Periodic { period_ms: 500 },
        fields: &[
            Field::u16("water_pressure", 1, "spindle moistening water pressure")
                .scaled(1.0, 0.0, "kPa")
                .range(0.0, 1000.0),
            Field::u8("water_level", 3, "water tank level")
                .scaled(1.0, 0.0, "%")
                .range(0.0, 100.0),
        ],
        doc: "B4: water system of the spindle moisteners.",
    },
    MessageDef {
        name: "param.oil",
        number: 0x25,
        selector: None,
        nodes: b(5),
        direction: ToMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 3,
        trigger: Periodic { period_ms: 1000 },
        fields: &[Field::i16("oil_temperature", 1, "hydraulic oil temperature")
            .scaled(0.1, 0.0, "degC")
            .range(-40.0, 150.0)],
        doc: "B5: hydraulic oil temperature.",
    },
    MessageDef {
        name: "param.lubricant",
        number: 0x26,
        selector: None,
        nodes: b(6),
        direction: ToMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 4,
        trigger: Periodic { period_ms: 1000 },
        fields: &[
            Field::u16("lubricant_rate", 1, "spindle grease injection rate")
                .scaled(0.1, 0.0, "mL/min")
                .range(0.0, 500.0),
            Field::u8("lubricant_level", 3, "grease tank level")
                .scaled(1.0, 0.0, "%")
                .range(0.0, 100.0),
        ],
        doc: "B6: lubricant injection.",
    },
    MessageDef {
        name: "param.conveyor",
        number: 0x27,
        selector: None,
        nodes: b(7),
        direction: ToMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 4,
        trigger: Periodic { period_ms: 200 },
        fields: &[
            Field::u16("belt_speed", 1, "cotton conveyor belt speed")
                .scaled(0.01, 0.0, "m/s")
                .range(0.0, 5.0),
            Field::u8("basket_fill", 3, "basket fill level")
                .scaled(1.0, 0.0, "%")
                .range(0.0, 100.0),
        ],
        doc: "B7: conveyor belt and basket.",
    },
    // ---- Alarm modules C0–C3, priority 00100 ----
    MessageDef {
        name: "alarm.suction_doors",
        number: 0x30,
        selector: None,
        nodes: c(0),
        direction: ToMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 4,
        trigger: OnChange { heartbeat_ms: 1000 },
        fields: &[
            Field::flag(
                "door1_open",
                1,
                0,
                "suction door of row 1 open (cotton is not reaching the duct)",
            ),
            Field::flag("door2_open", 1, 1, "suction door of row 2 open"),
            Field::flag("door3_open", 1, 2, "suction door of row 3 open"),
            Field::flag("door4_open", 1, 3, "suction door of row 4 open"),
            Field::flag("door5_open", 1, 4, "suction door of row 5 open"),
            Field::flag("door6_open", 1, 5, "suction door of row 6 open"),
            Field::u16("duct_vacuum", 2, "duct vacuum sensor voltage")
                .scaled(1.0, 0.0, "mV")
                .range(0.0, 5000.0),
        ],
        doc: "C0: suction door switches, one per row, and the duct vacuum sensor.",
    },
    MessageDef {
        name: "alarm.clutches",
        number: 0x31,
        selector: None,
        nodes: c(1),
        direction: ToMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 4,
        trigger: OnChange { heartbeat_ms: 1000 },
        fields: &[
            Field::flag("row1_clutch_slip", 1, 0, "row unit 1 clutch slipping"),
            Field::flag("row2_clutch_slip", 1, 1, "row unit 2 clutch slipping"),
            Field::flag("row3_clutch_slip", 1, 2, "row unit 3 clutch slipping"),
            Field::flag("row4_clutch_slip", 1, 3, "row unit 4 clutch slipping"),
            Field::flag("row5_clutch_slip", 1, 4, "row unit 5 clutch slipping"),
            Field::flag("row6_clutch_slip", 1, 5, "row unit 6 clutch slipping"),
            Field::flag("main_clutch_open", 1, 6, "main picking clutch disengaged"),
            Field::u16("clutch_pressure", 2, "clutch hydraulic pressure sensor voltage")
                .scaled(1.0, 0.0, "mV")
                .range(0.0, 5000.0),
        ],
        doc: "C1: clutch states.",
    },
    MessageDef {
        name: "alarm.conveyor",
        number: 0x32,
        selector: None,
        nodes: c(2),
        direction: ToMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 4,
        trigger: OnChange { heartbeat_ms: 1000 },
        fields: &[
            Field::flag("belt_stopped", 1, 0, "cotton conveyor belt stopped while picking"),
            Field::flag("basket_full", 1, 1, "basket full switch"),
            Field::flag("basket_raised", 1, 2, "basket raised (unloading)"),
            Field::flag("duct_blocked", 1, 3, "cotton duct blockage switch"),
            Field::u16("basket_level", 2, "basket level sensor voltage")
                .scaled(1.0, 0.0, "mV")
                .range(0.0, 5000.0),
        ],
        doc: "C2: conveyor belt and basket switches.",
    },
    MessageDef {
        name: "alarm.hydraulics",
        number: 0x33,
        selector: None,
        nodes: c(3),
        direction: ToMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 4,
        trigger: OnChange { heartbeat_ms: 1000 },
        fields: &[
            Field::flag(
                "low_water_pressure",
                1,
                0,
                "spindle water pressure below its switch point",
            ),
            Field::flag("oil_overheat", 1, 1, "hydraulic oil over temperature"),
            Field::flag("engine_overheat", 1, 2, "engine coolant over temperature"),
            Field::flag("low_lubricant", 1, 3, "grease tank low"),
            Field::u16("supply_voltage", 2, "supply voltage")
                .scaled(1.0, 0.0, "mV")
                .range(0.0, 32000.0),
        ],
        doc: "C3: pressure, temperature and supply alarms.",
    },
    // ---- Flow sensors D0–D5, priority 00110, point-to-point ----
    MessageDef {
        name: "flow.marker_flow",
        number: 0x20,
        selector: Some((1, 0x0D)),
        nodes: FLOW,
        direction: ToMonitor,
        frame_type: FrameType::PointToPoint,
        dlc: 8,
        trigger: Group { period_ms: 100 },
        fields: &MARKER_FLOW,
        doc: "Fixed marker 20 0D 00 02 FF BF FF 00: the next two frames (flow.part1, flow.part2) carry flow data.",
    },
    MessageDef {
        name: "flow.marker_reference",
        number: 0x20,
        selector: Some((1, 0x0E)),
        nodes: FLOW,
        direction: ToMonitor,
        frame_type: FrameType::PointToPoint,
        dlc: 8,
        trigger: Group { period_ms: 100 },
        fields: &MARKER_REFERENCE,
        doc: "Fixed marker 20 0E 00 02 FF BE FF 00: the next two frames carry calibration reference values.",
    },
    MessageDef {
        name: "flow.part1",
        number: 0x01,
        selector: None,
        nodes: FLOW,
        direction: ToMonitor,
        frame_type: FrameType::PointToPoint,
        dlc: 8,
        trigger: Group { period_ms: 100 },
        fields: &[
            Field::u8(
                "status",
                1,
                "sensor status byte; 0x01 in every frame of the source (1 = running)",
            )
            .values(&[(0, "not ready"), (1, "running")]),
            unit("unit1", 2),
            unit("unit2", 4),
            unit("unit3", 6),
        ],
        doc: "First frame after a marker: units 1–3 at bytes 3–4, 5–6, 7–8 (1-based), low byte first.",
    },
    MessageDef {
        name: "flow.part2",
        number: 0x02,
        selector: None,
        nodes: FLOW,
        direction: ToMonitor,
        frame_type: FrameType::PointToPoint,
        dlc: 8,
        trigger: Group { period_ms: 100 },
        fields: &[
            unit("unit4", 1),
            unit("unit5", 3),
            Field::u24(
                "aux",
                5,
                "bytes 6–8 (1-based); the source does not explain them (90 6E FF and 44 D4 6E in its examples); carried verbatim",
            ),
        ],
        doc: "Second frame after a marker: units 4–5 at bytes 2–3, 4–5 (1-based), low byte first.",
    },
    MessageDef {
        name: "flow.status",
        number: 0x30,
        selector: None,
        nodes: FLOW,
        direction: ToMonitor,
        frame_type: FrameType::PointToPoint,
        dlc: 4,
        trigger: OnChange { heartbeat_ms: 250 },
        fields: &[
            Field::u8("state", 1, "sensor state").values(FLOW_STATES),
            Field::u8("firmware", 2, "firmware version"),
            Field::u8("missed_acks", 3, "groups overdue for acknowledgement"),
        ],
        doc: "Sensor state: sent when it changes and at least every 250 ms, so that the monitor sees a sensor waiting for calibration or one that gave up for lack of acknowledgements.",
    },
    MessageDef {
        name: "flow.calibrate",
        number: 0x10,
        selector: None,
        nodes: FLOW,
        direction: FromMonitor,
        frame_type: FrameType::PointToPoint,
        dlc: 5,
        trigger: Event,
        fields: &[
            Field::u8("command", 1, "calibration command").values(&[
                (0, "stop"),
                (1, "start calibration"),
                (2, "accept and run"),
            ]),
            Field::u16(
                "target_reference",
                2,
                "reference level each unit's emitter is to be driven to",
            )
            .scaled(1.0, 0.0, "count"),
            Field::u8("samples", 4, "reference groups to average while calibrating").range(1.0, 255.0),
        ],
        doc: "Calibration exchange, monitor side: 'start calibration' makes the sensor measure its empty-duct reference and send reference groups; 'accept and run' starts the flow stream.",
    },
    MessageDef {
        name: "flow.ack",
        number: 0x21,
        selector: None,
        nodes: FLOW,
        direction: FromMonitor,
        frame_type: FrameType::PointToPoint,
        dlc: 3,
        trigger: Event,
        fields: &[
            Field::u8("group", 1, "group code acknowledged").values(&[(0x0D, "flow"), (0x0E, "reference")]),
            Field::u8(
                "sequence",
                2,
                "count of groups the monitor has received from this sensor, modulo 256",
            ),
        ],
        doc: "Acknowledgement of a complete group (marker and both parts). A sensor that sees three groups in a row go unacknowledged stops streaming and reports 'no acknowledgement'.",
    },
];
