//! Fixed lines of the export (identifiers with bit 31 set, signal layouts, cycle times, value
//! tables), the scripts' say over cycle times, and what the generator does with layouts DBC
//! cannot express.

use super::text::{bound, exact, string};
use super::{Network, generate};
use crate::catalogue::{Direction, Field, MESSAGES, MessageDef, Nodes, Trigger};
use crate::ident::{Address, FrameType};
use std::collections::BTreeMap;

fn catalogue() -> String {
    generate(MESSAGES, &Network::catalogue("4MZ-6A", 250_000))
}

/// The lines of the `BO_` block that starts with `head`.
fn block(text: &str, head: &str) -> Vec<String> {
    text.lines()
        .skip_while(|l| !l.starts_with(head))
        .take_while(|l| !l.is_empty())
        .map(str::to_string)
        .collect()
}

#[test]
fn seed_command_frame_has_bit_31_set() {
    // 0x0300A0F5 | 0x80000000 = 2197856501, the source's row alignment command.
    let text = catalogue();
    assert_eq!(
        block(&text, "BO_ 2197856501 "),
        [
            "BO_ 2197856501 row_command_A0: 2 F5",
            " SG_ message_number : 0|8@1+ (1,0) [1|1] \"\" A0",
            " SG_ command : 8|8@1+ (1,0) [0|255] \"\" A0",
        ]
    );
    assert!(
        text.contains(
            "VAL_ 2197856501 command 0 \"stop\" 1 \"start auto alignment\" 2 \"centre and hold\" ;"
        )
    );
    assert!(text.contains("BA_ \"VFrameFormat\" BO_ 2197856501 1;"));
    assert!(
        !text.contains("BA_ \"GenMsgCycleTime\" BO_ 2197856501 "),
        "an event has no cycle time"
    );
}

#[test]
fn signed_scaled_field() {
    let text = catalogue();
    // B5 -> F5, priority 5, broadcast: 0x0500F5B5.
    assert_eq!(
        block(&text, "BO_ 2231432629 "),
        [
            "BO_ 2231432629 param_oil_B5: 3 B5",
            " SG_ message_number : 0|8@1+ (1,0) [37|37] \"\" F5",
            " SG_ oil_temperature : 8|16@1- (0.1,0) [-40|150] \"degC\" F5",
        ]
    );
    assert!(text.contains("BA_ \"GenMsgCycleTime\" BO_ 2231432629 1000;"));
}

#[test]
fn flow_sensor_messages_are_multiplexed_on_data0() {
    let text = catalogue();
    // D0 -> F5, priority 6, point-to-point: 0x0601F5D0.
    let d0 = block(&text, "BO_ 2248275408 ");
    assert_eq!(d0[0], "BO_ 2248275408 flow_D0_to_F5: 8 D0");
    assert_eq!(d0[1], " SG_ message_number M : 0|8@1+ (1,0) [1|48] \"\" F5");
    for line in [
        " SG_ group m32 : 8|8@1+ (1,0) [13|14] \"\" F5",
        " SG_ check m32 : 40|8@1+ (1,0) [190|191] \"\" F5",
        " SG_ unit1 m1 : 16|16@1+ (1,0) [0|65535] \"count\" F5",
        " SG_ aux m2 : 40|24@1+ (1,0) [0|16777215] \"\" F5",
        " SG_ state m48 : 8|8@1+ (1,0) [0|255] \"\" F5",
    ] {
        assert!(d0.iter().any(|l| l == line), "{line}");
    }
    // The two markers share Data0 = 0x20: one set of signals, the group byte names them.
    assert_eq!(d0.iter().filter(|l| l.contains(" group ")).count(), 1);
    assert!(text.contains("VAL_ 2248275408 group 13 \"flow.marker_flow\" 14 \"flow.marker_reference\" ;"));
    assert!(text.contains(
        "VAL_ 2248275408 message_number 1 \"flow.part1\" 2 \"flow.part2\" 32 \"flow.marker_flow, flow.marker_reference\" 48 \"flow.status\" ;"
    ));
    // The catalogue's cycles: groups every 100 ms, status at least every 250 ms.
    assert!(text.contains("BA_ \"GenMsgCycleTime\" BO_ 2248275408 100;"));
    assert!(text.contains("BA_ \"GenSigCycleTime\" SG_ 2248275408 unit1 100;"));
    assert!(text.contains("BA_ \"GenSigCycleTime\" SG_ 2248275408 state 250;"));
}

#[test]
fn scripts_decide_the_cycle_times_of_their_nodes() {
    let mut network = Network::catalogue("test", 125_000);
    network.scripted.insert(
        Address::parameter(0),
        BTreeMap::from([(
            "param.ground_speed".to_string(),
            Trigger::Periodic { period_ms: 40 },
        )]),
    );
    // B1 runs a script that never sends its message.
    network.scripted.insert(Address::parameter(1), BTreeMap::new());
    let text = generate(MESSAGES, &network);
    assert!(text.contains("BA_ \"GenMsgCycleTime\" BO_ 2231432624 40;"));
    assert!(!text.contains("BA_ \"GenMsgCycleTime\" BO_ 2231432625 "));
    // B2 has no script: the catalogue's 100 ms.
    assert!(text.contains("BA_ \"GenMsgCycleTime\" BO_ 2231432626 100;"));
    assert!(text.contains("BA_ \"Baudrate\" 125000;"));
    // The monitor's messages follow the catalogue whatever the scripts say.
    assert!(text.contains("BA_ \"GenMsgCycleTime\" BO_ 2181095669 200;"));
}

static CLASHING: &[MessageDef] = &[
    MessageDef {
        name: "x.small",
        number: 1,
        selector: None,
        nodes: Nodes::One(Address::parameter(0)),
        direction: Direction::ToMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 2,
        trigger: Trigger::Event,
        fields: &[Field::u8("level", 1, "a \"quoted\" word \u{2013} and a dash")],
        doc: "small",
    },
    MessageDef {
        name: "x.wide",
        number: 2,
        selector: Some((1, 7)),
        nodes: Nodes::One(Address::parameter(0)),
        direction: Direction::ToMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 4,
        trigger: Trigger::Event,
        fields: &[Field::u8("kind", 1, "kind"), Field::u16("level", 2, "level")],
        doc: "wide",
    },
    MessageDef {
        name: "x.other",
        number: 2,
        selector: Some((1, 8)),
        nodes: Nodes::One(Address::parameter(0)),
        direction: Direction::ToMonitor,
        frame_type: FrameType::Broadcast,
        dlc: 3,
        trigger: Trigger::Event,
        fields: &[Field::u16("other", 1, "other")],
        doc: "other",
    },
];

#[test]
fn what_dbc_cannot_say_is_said_in_comments() {
    let text = generate(CLASHING, &Network::catalogue("test", 250_000));
    // 0x0500F5B0 | bit 31.
    assert_eq!(
        block(&text, "BO_ 2231432624 "),
        [
            "BO_ 2231432624 x_B0_to_F5: 4 B0",
            " SG_ message_number M : 0|8@1+ (1,0) [1|2] \"\" F5",
            " SG_ small_level m1 : 8|8@1+ (1,0) [0|255] \"\" F5",
            " SG_ kind m2 : 8|8@1+ (1,0) [0|255] \"\" F5",
            " SG_ wide_level m2 : 16|16@1+ (1,0) [0|65535] \"\" F5",
        ],
        "same-named fields are told apart; x.other's layout has no signals"
    );
    assert!(text.contains(
        "x.other shares Data0 = 0x02 with x.wide but lays out its fields differently; DBC multiplexing on Data0 cannot tell them apart, so its fields are not given here."
    ));
    assert!(text.contains("x.other (Data0 = 0x02, Data1 = 0x08, DLC 3, event): other"));
    assert!(text.contains("VAL_ 2231432624 kind 7 \"x.wide\" 8 \"x.other\" ;"));
    assert!(text.contains("CM_ SG_ 2231432624 small_level \"a 'quoted' word - and a dash\";"));
}

#[test]
fn numbers_and_strings() {
    assert_eq!(exact(0.01), "0.01");
    assert_eq!(exact(-40.0), "-40");
    assert_eq!(exact(0.0), "0");
    assert_eq!(exact(1e-7), "0.0000001");
    assert_eq!(bound(65535.0 * 0.01), "655.35");
    assert_eq!(bound(-0.0), "0");
    assert_eq!(bound(-32768.0), "-32768");
    assert_eq!(string("µs \\ \"x\""), "?s / 'x'");
}

#[test]
fn the_same_input_gives_the_same_text() {
    assert_eq!(catalogue(), catalogue());
    assert!(catalogue().is_ascii());
}
