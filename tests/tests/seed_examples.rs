//! The worked examples of the source paper, end to end through the public API: every catalogue
//! message of every node is encoded, put through the receivers' acceptance filters, and decoded.

use bus::filter::{AcceptanceFilter, AtmelFilter, Sja1000Filter};
use bus::{Frame, Id};
use protocol::catalogue::{self, Direction, MESSAGES};
use protocol::ident::Address;

fn every_catalogue_frame() -> Vec<Frame> {
    let mut frames = Vec::new();
    for m in MESSAGES {
        for node in Address::all().filter(|a| m.nodes.contains(*a)) {
            let mid = |name: &str| m.field(name).map(|f| (f.min + f.max) / 2.0).map(f64::round);
            frames.push(m.encode(node, mid).expect("mid-range values encode"));
        }
    }
    frames
}

#[test]
fn a0_filter_from_the_seed_accepts_only_its_command() {
    // CANIDT1..4 = 18 05 07 A8 as the source sets them, all identifier bits compared.
    let id = Id::Extended(bus::ExtendedId::new(0x0300A0F5).unwrap());
    let filter = AtmelFilter::exact(id);
    assert_eq!(filter.idt, [0x18, 0x05, 0x07, 0xA8]);
    let accepted: Vec<&str> = every_catalogue_frame()
        .iter()
        .filter(|f| filter.accepts(f))
        .map(|f| catalogue::decode(f).unwrap().unwrap().message.name)
        .collect();
    assert_eq!(accepted, ["row.command"]);
}

#[test]
fn monitor_receives_everything_sent_to_it() {
    // The monitor's SJA1000 in single-filter mode: destination byte (ID15..8) must be F5, the rest
    // don't care. ACR bytes hold ID28..21, ID20..13, ID12..5, ID4..0: ID15..8 straddles ACR1 bits
    // 2..0 and ACR2 bits 7..3.
    let dest_bits: u32 = 0xFF << 8;
    let acr = ((0xF5u32 << 8) << 3).to_be_bytes();
    let amr = (!(dest_bits << 3)).to_be_bytes();
    let monitor = Sja1000Filter {
        mode: bus::filter::Sja1000Mode::Single,
        acr,
        amr,
    };
    for frame in every_catalogue_frame() {
        let decoded = catalogue::decode(&frame).unwrap().unwrap();
        let to_monitor = decoded.message.direction == Direction::ToMonitor;
        assert_eq!(monitor.accepts(&frame), to_monitor, "{}", decoded.message.name);
    }
}

#[test]
fn d0_stream_of_the_seed_decodes_to_the_stated_units() {
    let frames = [
        "0601F5D0#200D0002FFBFFF00",
        "0601F5D0#0101000000000000",
        "0601F5D0#0200000000906EFF",
        "0601F5D0#200E0002FFBEFF00",
        "0601F5D0#0101341EEA2BEF2C",
        "0601F5D0#028921982C44D46E",
    ];
    let decoded: Vec<_> = frames
        .iter()
        .map(|t| {
            catalogue::decode(&bus::candump::parse_frame(t).unwrap())
                .unwrap()
                .unwrap()
        })
        .collect();
    let units: Vec<i64> = ["unit1", "unit2", "unit3"]
        .iter()
        .map(|u| decoded[4].get(u).unwrap().raw)
        .chain(["unit4", "unit5"].iter().map(|u| decoded[5].get(u).unwrap().raw))
        .collect();
    assert_eq!(units, [0x1E34, 0x2BEA, 0x2CEF, 0x2189, 0x2C98]);
    assert!(decoded.iter().all(|d| d.node == Address::flow_sensor(0)));
}
