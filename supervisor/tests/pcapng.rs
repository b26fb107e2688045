//! `--record x.pcapng`, read by Wireshark's tshark (scripts/test installs it): every packet of a
//! run with error frames decodes as SocketCAN CAN, with the candump log's time, interface, id,
//! flags and data; error frames with their classes and details.

use std::path::{Path, PathBuf};
use std::process::Command;

fn record(path: &Path) {
    let out = Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join(".."))
        .args([
            "scenario",
            "configs/scenarios/bus_off.ron",
            "--seed",
            "3",
            "--record",
        ])
        .arg(path)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("harvemu-pcapng-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The error classes of linux/can/error.h, bit 0 first, as tshark names them.
const CLASSES: [&str; 9] = [
    "can.err.tx_timeout",
    "can.err.lostarb",
    "can.err.ctrl",
    "can.err.prot",
    "can.err.trx",
    "can.err.ack",
    "can.err.busoff",
    "can.err.buserror",
    "can.err.restarted",
];

/// What tshark makes of each packet: time (µs since 1970), interface, and the CAN fields.
fn tshark(path: &Path) -> Vec<String> {
    let out = Command::new("tshark")
        .arg("-r")
        .arg(path)
        .args(["-T", "fields", "-E", "separator=|"])
        .args([
            "-e",
            "frame.time_epoch",
            "-e",
            "frame.interface_name",
            "-e",
            "can.id",
        ])
        .args([
            "-e",
            "can.flags.xtd",
            "-e",
            "can.flags.rtr",
            "-e",
            "can.flags.err",
        ])
        .args(["-e", "can.len", "-e", "data.data", "-e", "can.err.prot.location"])
        .args(["-e", "can.err.ctrl_specific"])
        .args(CLASSES.iter().flat_map(|c| ["-e", c]))
        .output()
        .expect("tshark is needed (scripts/test installs it)");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| {
            let f: Vec<&str> = l.split('|').collect();
            // 1704067200.551520000: whole microseconds.
            let (s, ns) = f[0].split_once('.').unwrap();
            let us = s.parse::<u64>().unwrap() * 1_000_000 + ns[..6].parse::<u64>().unwrap();
            let bytes = |t: &str| t.replace([':', ' '], "").to_lowercase();
            let classes: String = f[10..]
                .iter()
                .map(|c| if c.is_empty() { "" } else { c })
                .collect::<Vec<_>>()
                .join(",");
            format!(
                "{us}|{}|{}|{}|{}|{}|{}|{}|{}|{}|{classes}",
                f[1],
                f[2],
                f[3],
                f[4],
                f[5],
                f[6],
                bytes(f[7]),
                f[8],
                bytes(f[9])
            )
        })
        .collect()
}

/// The same from the candump log, by hand: SocketCAN's id and flags (linux/can.h), the classes
/// of an error frame in its id, its location in data[3] and TEC/REC in data[6], data[7]
/// (linux/can/error.h; tshark shows data[5..8] as "controller specific").
fn expected(log: &str) -> Vec<String> {
    log.lines()
        .map(|l| {
            let mut w = l.split_whitespace();
            let time = w.next().unwrap().trim_matches(|c| c == '(' || c == ')');
            let (s, us) = time.split_once('.').unwrap();
            let us = s.parse::<u64>().unwrap() * 1_000_000 + us.parse::<u64>().unwrap();
            let iface = w.next().unwrap();
            let (id, data) = w.next().unwrap().split_once('#').unwrap();
            let raw = u32::from_str_radix(id, 16).unwrap();
            let data = data.to_lowercase();
            if raw & 0x2000_0000 != 0 {
                let bytes: Vec<u8> = (0..8)
                    .map(|i| u8::from_str_radix(&data[2 * i..2 * i + 2], 16).unwrap())
                    .collect();
                let class = raw & 0x1FFF_FFFF;
                let specific: String = bytes[5..8].iter().map(|b| format!("{b:02x}")).collect();
                let location = if class & 0x08 != 0 {
                    bytes[3].to_string()
                } else {
                    String::new()
                };
                // tshark decodes an error frame's id as its classes, not as an id.
                let classes: Vec<String> = (0..9).map(|b| ((class >> b) & 1).to_string()).collect();
                format!("{us}|{iface}||||1|8||{location}|{specific}|{}", classes.join(","))
            } else if let Some(dlc) = data.strip_prefix('r') {
                let xtd = u8::from(id.len() == 8);
                format!(
                    "{us}|{iface}|{raw}|{xtd}|1|0|{}|||{NO_CLASSES}",
                    dlc.parse::<u8>().unwrap_or(0)
                )
            } else {
                let xtd = u8::from(id.len() == 8);
                format!(
                    "{us}|{iface}|{raw}|{xtd}|0|0|{}|{data}|||{NO_CLASSES}",
                    data.len() / 2
                )
            }
        })
        .collect()
}

/// A frame's classes: none, nine empty fields.
const NO_CLASSES: &str = ",,,,,,,,";

#[test]
fn tshark_reads_every_packet_as_the_candump_log_has_it() {
    let d = dir();
    let (pcapng, log) = (d.join("bus_off.pcapng"), d.join("bus_off.log"));
    record(&pcapng);
    record(&log);
    let text = std::fs::read_to_string(&log).unwrap();
    let want = expected(&text);
    let got = tshark(&pcapng);
    // Error frames on every controller's interface, as well as the frames.
    assert!(want.iter().filter(|l| l.contains("|harv0.")).count() > 1000);
    assert_eq!(got.len(), want.len());
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        assert_eq!(g, w, "packet {}", i + 1);
    }
    let _ = std::fs::remove_dir_all(&d);
}
