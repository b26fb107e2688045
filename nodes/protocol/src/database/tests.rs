use super::*;

fn signal(start_bit: u16, bits: u8, byte_order: ByteOrder, signed: bool) -> Signal {
    Signal {
        name: "s".into(),
        start_bit,
        bits,
        byte_order,
        signed,
        factor: 1.0,
        offset: 0.0,
        min: 0.0,
        max: 0.0,
        unit: String::new(),
        receivers: Vec::new(),
        mux: Mux::Plain,
        values: Vec::new(),
        start_raw: None,
        comment: None,
    }
}

fn put(s: &Signal, raw: i128, len: usize) -> Vec<u8> {
    let mut data = vec![0; len];
    s.insert(&mut data, raw);
    assert_eq!(s.extract(&data), Some(raw), "{s:?}");
    data
}

// Expected bytes worked out by hand from the DBC bit numbering (the module docs).
#[test]
fn intel_signals_go_low_byte_first() {
    let s = signal(8, 16, ByteOrder::Intel, false);
    assert_eq!(put(&s, 0x1234, 3), [0x00, 0x34, 0x12]);
    let s = signal(4, 12, ByteOrder::Intel, false);
    // Bits 4..15: the low nibble of 0xABC in byte 0's top, 0xAB in byte 1.
    assert_eq!(put(&s, 0xABC, 2), [0xC0, 0xAB]);
}

#[test]
fn motorola_signals_go_high_byte_first_from_the_start_bit() {
    let s = signal(7, 16, ByteOrder::Motorola, false);
    assert_eq!(put(&s, 0x1234, 2), [0x12, 0x34]);
    // MSB at byte 0 bit 3: byte 0's low nibble, then byte 1 whole.
    let s = signal(3, 12, ByteOrder::Motorola, false);
    assert_eq!(put(&s, 0xABC, 2), [0x0A, 0xBC]);
    // 64 bits from bit 7: the whole payload, big-endian.
    let s = signal(7, 64, ByteOrder::Motorola, false);
    assert_eq!(put(&s, 0x0102_0304_0506_0708, 8), [1, 2, 3, 4, 5, 6, 7, 8]);
    assert_eq!(s.bytes_needed(), Some(8));
    // From byte 7 bit 0 onward there is no room: no positions.
    assert_eq!(signal(56, 2, ByteOrder::Motorola, false).positions(), None);
}

#[test]
fn signed_values_are_twos_complement_of_their_width() {
    let s = signal(0, 8, ByteOrder::Intel, true);
    assert_eq!(put(&s, -2, 1), [0xFE]);
    let s = signal(15, 12, ByteOrder::Motorola, true);
    assert_eq!(put(&s, -1, 3), [0x00, 0xFF, 0xF0]);
    assert_eq!(s.raw_range(), (-2048, 2047));
}

#[test]
fn physical_values_are_limited_to_the_range_and_the_bits() {
    let mut s = signal(0, 8, ByteOrder::Intel, false);
    s.factor = 0.5;
    s.offset = -10.0;
    s.min = -10.0;
    s.max = 100.0;
    assert_eq!(s.to_raw(0.0), Some(20));
    assert_eq!(s.to_raw(1000.0), Some(220));
    assert_eq!(s.to_raw(-50.0), Some(0));
    assert_eq!(s.to_raw(f64::NAN), None);
    // No range: only the bits limit it.
    s.min = 0.0;
    s.max = 0.0;
    assert_eq!(s.to_raw(1000.0), Some(255));
    // Rounding half a step below the range's bottom goes back in.
    s.factor = 1.0;
    s.offset = 0.0;
    s.min = 0.3;
    s.max = 9.0;
    assert_eq!(s.to_raw(0.3), Some(1));
}

const SAMPLE: &str = r#"VERSION ""

NS_ :

BS_:

BU_: ENGINE BRAKE DASH

BO_ 2566844926 EEC1: 8 ENGINE
 SG_ EngineSpeed : 24|16@1+ (0.125,0) [0|8031.875] "rpm" DASH
 SG_ Torque : 16|8@1- (1,-125) [-125|125] "%" DASH,BRAKE

BO_ 256 Brake: 4 BRAKE
 SG_ Mode M : 7|8@0+ (1,0) [0|2] "" DASH
 SG_ Pressure m1 : 15|16@0+ (0.1,0) [0|250] "bar" DASH
 SG_ Temp m2 : 15|8@0- (1,0) [-40|125] "C" DASH

BO_ 512 Dash: 2 DASH
 SG_ Lamp : 0|1@1+ (1,0) [0|1] "" ENGINE

CM_ "A test network";
CM_ BO_ 256 "Brake status";
CM_ SG_ 256 Pressure "Line pressure";
BA_DEF_ BO_ "GenMsgCycleTime" INT 0 65535;
BA_DEF_ BO_ "GenMsgSendType" ENUM "Cyclic","Event";
BA_DEF_ SG_ "GenSigStartValue" INT 0 65535;
BA_DEF_ "Baudrate" INT 0 1000000;
BA_DEF_DEF_ "GenMsgCycleTime" 0;
BA_DEF_DEF_ "GenMsgSendType" "Cyclic";
BA_DEF_DEF_ "GenSigStartValue" 0;
BA_DEF_DEF_ "Baudrate" 500000;
BA_ "GenMsgCycleTime" BO_ 2566844926 20;
BA_ "GenMsgCycleTime" BO_ 256 100;
BA_ "GenMsgSendType" BO_ 512 1;
BA_ "GenSigStartValue" SG_ 2566844926 Torque 125;
VAL_ 256 Mode 1 "pressure" 2 "temperature" ;
"#;

#[test]
fn a_dbc_reads_into_messages_signals_and_attributes() {
    let db = Database::parse("sample.dbc", SAMPLE).unwrap();
    assert_eq!(db.nodes, ["ENGINE", "BRAKE", "DASH"]);
    assert_eq!(db.bitrate, Some(500_000));
    assert_eq!(db.comment.as_deref(), Some("A test network"));
    assert_eq!(db.warnings, []);
    let eec1 = db.message("EEC1").unwrap();
    assert_eq!((eec1.id, eec1.extended, eec1.dlc), (0x18FE_F1FE, true, 8));
    assert_eq!(eec1.cycle_ms, Some(20));
    assert_eq!(eec1.send_type.as_deref(), Some("Cyclic"));
    let torque = eec1.signal("Torque").unwrap();
    assert!(torque.signed);
    assert_eq!(torque.receivers, ["DASH", "BRAKE"]);
    assert_eq!(torque.start_raw, Some(125.0));
    assert_eq!(torque.initial(), 0.0);
    let brake = db.message("Brake").unwrap();
    assert_eq!(
        (brake.id, brake.extended, brake.cycle_ms),
        (256, false, Some(100))
    );
    assert_eq!(brake.comment.as_deref(), Some("Brake status"));
    assert_eq!(brake.multiplexor().unwrap().name, "Mode");
    assert_eq!(brake.mux_values(), [1, 2]);
    let mode = brake.signal("Mode").unwrap();
    assert_eq!(
        mode.values,
        [(1, "pressure".to_string()), (2, "temperature".to_string())]
    );
    assert_eq!(mode.byte_order, ByteOrder::Motorola);
    assert_eq!(
        brake.signal("Pressure").unwrap().comment.as_deref(),
        Some("Line pressure")
    );
    let dash = db.message("Dash").unwrap();
    assert_eq!((dash.cycle_ms, dash.send_type.as_deref()), (None, Some("Event")));
    assert_eq!(
        db.sent_by("BRAKE").map(|m| m.name.as_str()).collect::<Vec<_>>(),
        ["Brake"]
    );
}

#[test]
fn a_multiplexed_message_writes_the_signals_of_its_multiplexor_value() {
    let db = Database::parse("sample.dbc", SAMPLE).unwrap();
    let brake = db.message("Brake").unwrap();
    let values = |pairs: &[(&str, f64)]| pairs.iter().map(|(k, v)| (k.to_string(), *v)).collect();
    // Mode 1: Pressure 12.3 bar = raw 123 = 0x007B, big-endian from byte 1.
    let data = brake.encode(&values(&[("Mode", 1.0), ("Pressure", 12.3), ("Temp", -5.0)]));
    assert_eq!(data.unwrap(), [1, 0x00, 0x7B, 0]);
    // Mode 2: Temp -5 in byte 1.
    let data = brake.encode(&values(&[("Mode", 2.0), ("Pressure", 12.3), ("Temp", -5.0)]));
    assert_eq!(data.unwrap(), [2, 0xFB, 0, 0]);
    assert_eq!(brake.encode(&values(&[("Temp", f64::NAN), ("Mode", 2.0)])), None);
}

#[test]
fn what_cannot_run_as_written_is_a_warning_naming_message_and_signal() {
    let text = SAMPLE.replace(
        " SG_ Lamp : 0|1@1+ (1,0) [0|1] \"\" ENGINE",
        " SG_ Lamp : 0|1@1+ (1,0) [0|1] \"\" ENGINE\n SG_ Wide : 8|16@1+ (1,0) [0|1] \"\" ENGINE\n SG_ Over : 0|4@1+ (1,0) [0|1] \"\" ENGINE",
    );
    let db = Database::parse("w.dbc", &text).unwrap();
    let said: Vec<String> = db
        .warnings
        .iter()
        .map(|w| format!("{}: {}", w.at, w.reason))
        .collect();
    assert_eq!(said.len(), 2, "{said:?}");
    assert!(
        said[0]
            .starts_with("Dash (0x200) signal Wide: 16 bits from bit 8 do not fit in the message's 2 bytes"),
        "{said:?}"
    );
    assert!(
        said[1].starts_with("Dash (0x200) signal Over: shares bit 0 with signal Lamp"),
        "{said:?}"
    );
}

#[test]
fn a_syntax_error_is_refused_at_its_line_and_column() {
    let text = SAMPLE.replace("(0.125,0)", "(0.125,x)");
    let e = Database::parse("bad.dbc", &text).unwrap_err().to_string();
    assert_eq!(e, "bad.dbc:10:36: expected offset");
    let text = SAMPLE.replace("BO_ 512 Dash", "BO_ 4095 Dash");
    let e = Database::parse("bad.dbc", &text).unwrap_err().to_string();
    assert!(
        e.starts_with("bad.dbc:18:1: message Dash: identifier 4095 is over 0x7FF"),
        "{e}"
    );
}

#[test]
fn written_back_it_reads_as_the_same_database() {
    let db = Database::parse("sample.dbc", SAMPLE).unwrap();
    let cycles: BTreeMap<String, u32> = [("EEC1".to_string(), 20), ("Dash".to_string(), 50)].into();
    let text = db.to_dbc(&Written {
        name: "Sample",
        bitrate: 250_000,
        cycles: &cycles,
    });
    let again = Database::parse("again.dbc", &text).unwrap_or_else(|e| panic!("{e}\n{text}"));
    assert_eq!(again.nodes, db.nodes);
    assert_eq!(again.bitrate, Some(250_000));
    assert_eq!(again.name.as_deref(), Some("Sample"));
    assert_eq!(again.comment, db.comment);
    assert_eq!(again.messages.len(), db.messages.len());
    for (a, b) in again.messages.iter().zip(&db.messages) {
        let mut want = b.clone();
        want.cycle_ms = cycles.get(&b.name).copied();
        assert_eq!(a, &want, "{text}");
    }
}

#[test]
fn infinities_saturate_and_a_factor_of_zero_sends_raw_zero() {
    let mut s = signal(0, 8, ByteOrder::Intel, true);
    assert_eq!(s.to_raw(f64::INFINITY), Some(127));
    assert_eq!(s.to_raw(f64::NEG_INFINITY), Some(-128));
    s.factor = 0.0;
    s.offset = 5.0;
    assert_eq!(s.to_raw(5.0), Some(0));
    assert_eq!(s.to_raw(1e9), Some(0));
    assert_eq!(s.to_raw(f64::NAN), None);
}
