//! `harvemu inspect` as a user runs it: the binary, its output and its exit codes.

use serde_json::Value;
use std::process::{Command, Output};

fn harvemu(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .args(args)
        .output()
        .expect("run harvemu")
}

fn inspect_json(frame: &str, extra: &[&str]) -> Value {
    let mut args = vec!["inspect", frame, "--json"];
    args.extend_from_slice(extra);
    let out = harvemu(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

/// Left-aligned register bytes of an extended data frame's identifier (ID28..0 then 3 zero bits),
/// which is both the SJA1000 single-filter ACR layout and Atmel's CANIDT layout.
fn left_aligned(id: u32) -> String {
    (id << 3)
        .to_be_bytes()
        .iter()
        .map(|b| format!("{b:02X}"))
        .collect()
}

#[test]
fn seed_command_frame() {
    let j = inspect_json("0300A0F5#0102030405060708", &[]);
    assert_eq!(j["id"], "0300A0F5");
    assert_eq!(j["extended"], true);
    assert_eq!(
        (j["priority"].as_u64(), j["frame_type"].as_u64()),
        (Some(3), Some(0))
    );
    assert_eq!(
        (j["destination"].as_str(), j["source"].as_str()),
        (Some("A0"), Some("F5"))
    );
    // The test vector docs/CAN.md gives for this frame (section 2).
    assert_eq!(j["crc"], 0x6311);
    assert_eq!(j["stuff_bits"], 11);
    assert_eq!(
        (
            j["bits_exact"].as_u64(),
            j["bits_worst_case"].as_u64(),
            j["bits_no_stuffing"].as_u64()
        ),
        (Some(142), Some(160), Some(131))
    );
    // 142 bits of 4 us at 250 kbit/s.
    assert_eq!(j["duration_us"].as_f64(), Some(142.0 * 4.0));
    // The seed's register bytes.
    assert_eq!(j["atmel_canidt"], "180507A8");
    assert_eq!(j["atmel_canidt"], left_aligned(0x0300A0F5));
    assert_eq!(j["sja1000_acr"], left_aligned(0x0300A0F5));
    // Data0 = 01 is row.command, but 8 bytes break its 2-byte layout.
    assert!(j["message"].is_null());
    assert!(j["message_error"].as_str().unwrap().contains("row.command"));
}

#[test]
fn seed_flow_marker_is_decoded() {
    let j = inspect_json("0601F5D0#200D0002FFBFFF00", &["--bitrate", "125000"]);
    assert_eq!(j["message"]["name"], "flow.marker_flow");
    assert_eq!(j["message"]["node"], "D0");
    assert_eq!(j["message"]["fields"]["group"]["raw"], 0x0D);
    assert_eq!(j["source_name"], "flow sensor D0");
    let bits = j["bits_exact"].as_f64().unwrap();
    assert_eq!(j["duration_us"].as_f64(), Some(bits * 8.0));
}

#[test]
fn base_frame_has_no_harvester_fields() {
    let j = inspect_json("123#DEADBEEF", &[]);
    assert_eq!(j["extended"], false);
    assert!(j["priority"].is_null() && j["destination"].is_null() && j["message"].is_null());
    assert_eq!(
        (j["crc"].as_u64(), j["bits_exact"].as_u64()),
        (Some(0x4E6B), Some(81))
    );
    assert_eq!(
        j["bitstream"],
        "00010010001100001001101111010101101101111100111011111000111001101011"
    );
}

#[test]
fn text_output_names_everything() {
    let out = harvemu(&["inspect", "0601F5D0#0101341EEA2BEF2C"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    for needle in [
        "flow.part1",
        "unit1",
        "7732",
        "flow sensor D0",
        "monitor",
        "CRC-15",
        "us at 250000 bit/s",
        "300FAE80",
    ] {
        assert!(text.contains(needle), "missing {needle} in:\n{text}");
    }
}

#[test]
fn bad_input_is_one_line_and_exit_2() {
    for bad in [
        "xyz",
        "1FFFFFFFF#00",
        "20000000#00",
        "800#00",
        "123#000102030405060708",
        "123#ABC",
        "0601F5D0",
    ] {
        let out = harvemu(&["inspect", bad]);
        assert_eq!(out.status.code(), Some(2), "{bad}");
        assert!(out.stdout.is_empty(), "{bad}");
        let err = String::from_utf8(out.stderr).unwrap();
        assert_eq!(err.lines().count(), 1, "{bad}: {err}");
        assert!(err.starts_with("harvemu: error: frame '"), "{bad}: {err}");
    }
    let out = harvemu(&["inspect", "123#00", "--bitrate", "0"]);
    assert_eq!(out.status.code(), Some(2));
    assert_eq!(String::from_utf8(out.stderr).unwrap().lines().count(), 1);
}
