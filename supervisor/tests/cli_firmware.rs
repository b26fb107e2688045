//! `harvemu run` with firmware nodes: the shipped seed lab from the command line (from the
//! repository and from anywhere), its state dump, and bad firmware input refused before anything
//! starts, with the file and line.

mod common;

use common::{harvemu, root, scratch};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn text(out: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

/// A dump's hex string as bytes.
fn bytes(hex: &Value) -> Vec<u8> {
    let s = hex.as_str().expect("a hex string");
    (0..s.len() / 2)
        .map(|i| u8::from_str_radix(&s[2 * i..2 * i + 2], 16).expect("hex"))
        .collect()
}

fn check_lab_dump(path: &Path) {
    let dump: Value = serde_json::from_str(&std::fs::read_to_string(path).expect("the dump")).expect("JSON");
    let receiver = &dump["nodes"]["RECEIVER"];
    let iram = bytes(&receiver["cpu"]["iram"]);
    assert_eq!(iram.len(), 256);
    assert_eq!(
        &iram[0x30..0x38],
        [0xAA, 0xBB, 0xCC, 0xD4, 0xE5, 0xF6, 0x97, 0x18]
    );
    // An 80C51 has no internal RAM above 7Fh.
    assert!(iram[0x80..].iter().all(|&b| b == 0));
    assert_eq!(bytes(&receiver["cpu"]["sfr"]).len(), 128);
    // A second at 12 MHz is a million machine cycles; the run stops at an instruction's end.
    let cycles = receiver["cpu"]["cycles"].as_u64().expect("cycles");
    assert!((1_000_000..1_000_004).contains(&cycles), "{cycles}");
    let chip = &receiver["controllers"][0];
    assert_eq!(chip["kind"], "SJA1000");
    assert_eq!(chip["base"], 0xD400);
    assert_eq!(chip["mode"], "PeliCAN");
    assert_eq!(chip["state"], "active");
    let registers = bytes(&chip["registers"]);
    assert_eq!(registers.len(), 32);
    // MOD: operating mode, single filter (08h); IER 0Dh; BTR0 03h, BTR1 FFh; OCR AAh; CDR 88h.
    assert_eq!(
        [
            registers[0],
            registers[4],
            registers[6],
            registers[7],
            registers[8],
            registers[31]
        ],
        [0x08, 0x0D, 0x03, 0xFF, 0xAA, 0x88]
    );
    assert!(dump["nodes"]["SENDER"]["cpu"]["pc"].is_u64());
}

#[test]
fn the_seed_lab_runs_from_the_command_line_and_dumps_its_state() {
    let dir = scratch("cli-firmware", "lab");
    let (log, dump) = (dir.join("lab.log"), dir.join("state.json"));
    let out = harvemu(&[
        "run",
        "configs/firmware/seed_lab.ron",
        "--fast",
        "--for",
        "1s",
        "--record",
        log.to_str().unwrap(),
        "--dump-state",
        dump.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out));
    assert!(text(&out).contains("seed lab (2 nodes)"), "{}", text(&out));
    let frames = std::fs::read_to_string(&log).expect("the trace");
    // The sender's first attempt comes before the receiver has integrated into the bus: one ACK
    // error on the sender's interface (tests/tests/firmware_seed_lab.rs works the times out),
    // then eleven frames.
    let lines: Vec<&str> = frames.lines().collect();
    assert_eq!(lines.len(), 12, "{frames}");
    assert!(lines[0].contains(" harv0.SENDER 200002A8#"), "{frames}");
    assert!(
        lines[1..]
            .iter()
            .all(|l| l.ends_with(" harv0 5DF#AABBCCD4E5F69718")),
        "{frames}"
    );
    check_lab_dump(&dump);

    // The lab is built in: it runs from a directory without configs/ too.
    let elsewhere = scratch("cli-firmware", "elsewhere");
    let out = Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(&elsewhere)
        .args([
            "run",
            "configs/firmware/seed_lab.ron",
            "--fast",
            "--for",
            "1s",
            "--dump-state",
            "s.json",
        ])
        .output()
        .expect("run harvemu");
    assert!(out.status.success(), "{}", text(&out));
    check_lab_dump(&elsewhere.join("s.json"));
}

/// A scratch folder `tag` with copies of the seed lab's `files` (from configs/firmware/).
fn lab_copy(tag: &str, files: &[&str]) -> PathBuf {
    let dir = scratch("cli-firmware", tag);
    let lab = root().join("configs/firmware");
    for f in files {
        std::fs::copy(lab.join(f), dir.join(f)).expect("copy");
    }
    dir
}

/// A lab whose receiver file is `receiver` and whose image is `hex`; runs it and returns the
/// output.
fn run_bad(tag: &str, receiver: &str, hex: &str) -> Output {
    let dir = lab_copy(tag, &["seed_lab.ron", "sender.ron", "can_seed.hex"]);
    std::fs::write(dir.join("receiver.ron"), receiver).expect("write");
    std::fs::write(dir.join("bad.hex"), hex).expect("write");
    harvemu(&[
        "run",
        dir.join("seed_lab.ron").to_str().unwrap(),
        "--fast",
        "--for",
        "1s",
    ])
}

fn receiver(image: &str, cpu: &str, controllers: &str) -> String {
    format!(
        "Firmware(\n    name: \"RECEIVER\",\n    image: \"{image}\",\n    entry: Some(0x4000),\n    \
         cpu: {cpu},\n    controllers: [\n{controllers}\n    ],\n)\n"
    )
}

const CHIP: &str = "        Sja1000(base: 0xD400, xtal_hz: 6000000, irq: None),";
const CPU: &str = "I80C51(clock_hz: 12000000)";

fn shipped_hex() -> String {
    std::fs::read_to_string(root().join("configs/firmware/can_seed.hex")).expect("HEX")
}

fn assert_refused(out: &Output, wanted: &[&str]) {
    let t = text(out);
    assert_eq!(out.status.code(), Some(2), "{t}");
    for w in wanted {
        assert!(t.contains(w), "wanted {w:?} in:\n{t}");
    }
    assert!(!t.contains("virtual time"), "nothing starts:\n{t}");
}

#[test]
fn bad_hex_files_are_refused_with_file_and_line() {
    let hex = shipped_hex();
    let lines: Vec<&str> = hex.lines().collect();
    // Line 3's checksum, one off: the record no longer sums to zero.
    let mut bad = lines.clone();
    let l3 = bad[2].to_string();
    let (body, sum) = l3.split_at(l3.len() - 2);
    let wrong = format!(
        "{body}{:02X}",
        (u8::from_str_radix(sum, 16).unwrap()).wrapping_add(1)
    );
    bad[2] = &wrong;
    let out = run_bad("checksum", &receiver("bad.hex", CPU, CHIP), &bad.join("\n"));
    assert_refused(&out, &["bad.hex", "HEX line 3", "checksum", "RECEIVER"]);

    // Line 2 again as line 3: the same addresses written twice.
    let mut twice = lines.clone();
    twice.insert(2, lines[1]);
    let out = run_bad("overlap", &receiver("bad.hex", CPU, CHIP), &twice.join("\n"));
    assert_refused(&out, &["bad.hex", "HEX line 3", "already written by line 2"]);

    // The image starts at 4000h; a 4 KB code memory ends at 0FFFh.
    let small = "I80C51(clock_hz: 12000000, code_bytes: 4096)";
    let out = run_bad("beyond", &receiver("can_seed.hex", small, CHIP), "");
    assert_refused(
        &out,
        &["can_seed.hex", "HEX line 1", "beyond the 4096-byte code memory"],
    );
    // A record after the end-of-file record would be left out of the image.
    let after = format!("{}\n:03000000020040BB\n", hex.trim_end());
    let out = run_bad("after-eof", &receiver("bad.hex", CPU, CHIP), &after);
    let eof = lines.len();
    assert_refused(
        &out,
        &[
            "bad.hex",
            &format!(
                "HEX line {}: text after the end-of-file record of line {eof}",
                eof + 1
            ),
        ],
    );
}

/// `receiver` starts at 4000h; with a 16 KB code memory (0000h to 3FFFh) that is nowhere, and
/// the program counter would wrap. The image (irq_receiver.hex, from 0000h) fits.
#[test]
fn an_entry_outside_code_memory_is_refused() {
    let hex = std::fs::read_to_string(root().join("configs/firmware/irq_receiver.hex")).expect("HEX");
    let cpu = "I80C51(clock_hz: 12000000, code_bytes: 16384)";
    let out = run_bad("entry", &receiver("bad.hex", cpu, CHIP), &hex);
    assert_refused(
        &out,
        &[
            "receiver.ron",
            "entry",
            "4000h is outside the chip's 16384-byte code memory",
        ],
    );
}

#[test]
fn bad_node_files_are_refused_with_file_and_line() {
    let hex = shipped_hex();
    let two = "        Sja1000(base: 0xD400, xtal_hz: 6000000, irq: None),\n        \
               Sja1000(base: 0xD480, xtal_hz: 6000000, irq: None),";
    let out = run_bad("overlap-chips", &receiver("can_seed.hex", CPU, two), &hex);
    // The second controller's base: line 8, column 17 of the file `receiver` writes.
    assert_refused(
        &out,
        &[
            "receiver.ron:8:17:",
            "controllers[1].base",
            "overlaps controllers[0]",
        ],
    );

    let int2 = "        Sja1000(base: 0xD400, xtal_hz: 6000000, irq: Some(Int2)),";
    let out = run_bad("pin", &receiver("can_seed.hex", CPU, int2), &hex);
    // The line and column of the unknown pin: line 7 of the file `receiver` writes.
    assert_refused(&out, &["receiver.ron:7:", "Int2"]);

    let odd_clock = "I80C51(clock_hz: 33000000)";
    let out = run_bad("clock", &receiver("can_seed.hex", odd_clock, CHIP), &hex);
    assert_refused(&out, &["receiver.ron", "cpu.clock_hz", "33000000 Hz"]);

    let out = run_bad("missing", &receiver("nothing.hex", CPU, CHIP), &hex);
    assert_refused(&out, &["receiver.ron", "image", "nothing.hex"]);

    // A control character in the name (as PROMISES.md says of every name): line 2, column 5.
    let named = receiver("can_seed.hex", CPU, CHIP).replace("RECEIVER", "RE\u{1F}CEIVER");
    let out = run_bad("control", &named, &hex);
    assert_refused(
        &out,
        &[
            "receiver.ron:2:5:",
            "name",
            "holds the control character '\\u{1f}'",
        ],
    );
}

/// The lab's receiver with two more SJA1000s, at D500h and D600h, which the lab program never
/// touches: they stay in reset mode (BasicCAN, off the bus, data sheet reset values) while the
/// D400h chip takes the sender's frames as in the lab; the dump lists the three, each at its base.
#[test]
fn three_chips_are_three_controllers_in_the_state_dump() {
    let chips = "        Sja1000(base: 0xD400, xtal_hz: 6000000, irq: None),\n        \
                 Sja1000(base: 0xD500, xtal_hz: 6000000, irq: Some(Int0)),\n        \
                 Sja1000(base: 0xD600, xtal_hz: 6000000, irq: Some(Int0)),";
    let dir = lab_copy("three-chips", &["seed_lab.ron", "sender.ron", "can_seed.hex"]);
    std::fs::write(dir.join("receiver.ron"), receiver("can_seed.hex", CPU, chips)).expect("write");
    let dump = dir.join("state.json");
    let out = harvemu(&[
        "run",
        dir.join("seed_lab.ron").to_str().unwrap(),
        "--fast",
        "--for",
        "1s",
        "--dump-state",
        dump.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out));
    let dump: Value = serde_json::from_str(&std::fs::read_to_string(&dump).expect("the dump")).expect("JSON");
    let receiver = &dump["nodes"]["RECEIVER"];
    assert_eq!(
        &bytes(&receiver["cpu"]["iram"])[0x30..0x38],
        [0xAA, 0xBB, 0xCC, 0xD4, 0xE5, 0xF6, 0x97, 0x18]
    );
    let chips = receiver["controllers"].as_array().expect("a list");
    let seen: Vec<(u64, &str, &str)> = chips
        .iter()
        .map(|c| {
            (
                c["base"].as_u64().expect("base"),
                c["kind"].as_str().expect("kind"),
                c["mode"].as_str().expect("mode"),
            )
        })
        .collect();
    assert_eq!(
        seen,
        [
            (0xD400, "SJA1000", "PeliCAN"),
            (0xD500, "SJA1000", "BasicCAN"),
            (0xD600, "SJA1000", "BasicCAN"),
        ]
    );
    // An untouched chip: CR 21h (reset request, and bit 5, which reads 1), SR 0Ch (transmit
    // buffer free, transmission complete), as data sheet Table 5 gives them after a reset.
    for c in &chips[1..] {
        let registers = bytes(&c["registers"]);
        assert_eq!((registers[0], registers[2]), (0x21, 0x0C), "{c}");
    }
}

/// A further chip is a controller on the bus named `NODE.k`: a node already called that is
/// refused, as two nodes of one name are.
#[test]
fn a_further_chip_may_not_take_another_nodes_name() {
    let two = "        Sja1000(base: 0xD400, xtal_hz: 6000000, irq: None),\n        \
               Sja1000(base: 0xD500, xtal_hz: 6000000, irq: None),";
    let dir = lab_copy("chip-name", &["seed_lab.ron", "can_seed.hex"]);
    let sender = std::fs::read_to_string(root().join("configs/firmware/sender.ron")).expect("sender.ron");
    let renamed = sender.replacen("\"SENDER\"", "\"RECEIVER.1\"", 1);
    assert_ne!(renamed, sender, "the sender's name is in its file");
    std::fs::write(dir.join("sender.ron"), renamed).expect("write");
    std::fs::write(dir.join("receiver.ron"), receiver("can_seed.hex", CPU, two)).expect("write");
    let out = harvemu(&[
        "run",
        dir.join("seed_lab.ron").to_str().unwrap(),
        "--fast",
        "--for",
        "1s",
    ]);
    assert_refused(
        &out,
        &["node RECEIVER", "its controllers[1] is RECEIVER.1 on the bus"],
    );
}

/// An AT89C51CC03 receiver whose wires are `wires` (RON fields after `controllers`).
fn cc03_receiver(controllers: &str, wires: &str) -> String {
    format!(
        "Firmware(\n    name: \"RECEIVER\",\n    image: \"can_seed.hex\",\n    entry: Some(0x4000),\n    \
         cpu: At89c51cc03(clock_hz: 12000000),\n    controllers: [{controllers}],\n{wires})\n"
    )
}

#[test]
fn bad_wiring_is_refused_with_file_and_line() {
    let hex = shipped_hex();
    // An ADC channel wired to a signal the plant does not have: named at its line (line 7).
    let wires = "    analog: [(channel: 0, signal: \"duct.vacum\", scale: 1.0)],\n";
    let out = run_bad("adc-signal", &cc03_receiver("OnChip", wires), &hex);
    assert_refused(
        &out,
        &[
            "receiver.ron:7:",
            "analog[0].signal",
            "\"duct.vacum\" is no plant signal",
        ],
    );

    // Channel 8 does not exist; a pin named P5.1 neither; an output to a read-only signal.
    let wires = "    analog: [(channel: 8, signal: \"duct.vacuum\")],\n    \
                 pins: [Input(pin: \"P5.1\", signal: \"door1.open\"), Output(pin: \"P3.5\", input: \"duct.vacuum\")],\n";
    let out = run_bad("adc-channel", &cc03_receiver("OnChip", wires), &hex);
    assert_refused(
        &out,
        &[
            "analog[0].channel",
            "8: the ADC has channels 0 to 7",
            "pins[0].pin",
            "\"P5.1\"",
            "receiver.ron:8:",
            "\"duct.vacuum\" is no plant input",
        ],
    );

    // The on-chip controller and the ADC on an 80C51, which has neither.
    let text = receiver("can_seed.hex", CPU, "        OnChip,").replace(
        "\n)\n",
        "\n    analog: [(channel: 0, signal: \"duct.vacuum\")],\n)\n",
    );
    let out = run_bad("not-cc03", &text, &hex);
    assert_refused(
        &out,
        &[
            "controllers[0]",
            "only the AT89C51CC03 has a CAN controller on chip",
            "only the AT89C51CC03 has an ADC",
        ],
    );
}

#[test]
fn bad_blocks_dacs_multiplexers_and_addresses_are_refused() {
    let hex = shipped_hex();
    // The image writes 4000h–4002h and from 4080h: a block there would patch the program.
    let wires = "    config: (at: 0x4081, bytes: [1, 2]),\n";
    let out = run_bad("block-over-code", &cc03_receiver("OnChip", wires), &hex);
    assert_refused(&out, &["config.at", "4081h to 4082h overlaps what", "at 4080h"]);

    // Past the end of the code memory; an empty block.
    let text = cc03_receiver("OnChip", "    config: (at: 0xFFFF, bytes: [1, 2]),\n").replace(
        "At89c51cc03(clock_hz: 12000000)",
        "At89c51cc03(clock_hz: 12000000, code_bytes: 65536)",
    );
    let out = run_bad("block-past-end", &text, &hex);
    assert_refused(
        &out,
        &[
            "config.at",
            "FFFFh to 10000h: past the end of the chip's 65536-byte code memory",
        ],
    );
    let out = run_bad(
        "block-empty",
        &cc03_receiver("OnChip", "    config: (at: 0xFF00, bytes: []),\n"),
        &hex,
    );
    assert_refused(
        &out,
        &["config.bytes", "0 bytes: a configuration block is 1 to 256 bytes"],
    );

    // A DAC on a port that has a wired pin, one whose high port is its low one, one driving a
    // signal the plant computes, and a multiplexer selected by a pin a plant signal drives.
    let wires = "    analog: [(channel: 0, signal: \"duct.vacuum\", while_high: Some((pin: \"P2.0\", signal: \"clutch.pressure\")))],\n    \
                 pins: [Input(pin: \"P2.0\", signal: \"door1.open\")],\n    \
                 dacs: [(low: \"P2\", input: \"speed.setpoint\"), (low: \"P0\", high: Some(\"P0\"), input: \"row.correction\"),\n           \
                 (low: \"P3\", input: \"duct.vacuum\")],\n";
    let out = run_bad("dacs", &cc03_receiver("OnChip", wires), &hex);
    assert_refused(
        &out,
        &[
            "analog[0].while_high.pin",
            "P2.0 is wired to something else already",
            "dacs[0].low",
            "P2: a pin of this port is wired already",
            "dacs[1].high",
            "P0: the port of the low byte",
            "receiver.ron:10:",
            "\"duct.vacuum\" is no plant input a DAC can drive",
        ],
    );

    // Two nodes claiming one address.
    let dir = lab_copy(
        "address",
        &["seed_lab.ron", "sender.ron", "receiver.ron", "can_seed.hex"],
    );
    for f in ["sender.ron", "receiver.ron"] {
        let text = std::fs::read_to_string(dir.join(f)).expect("read");
        let claimed = text.replacen("Firmware(\n", "Firmware(\n    address: 0xC1,\n", 1);
        assert_ne!(claimed, text, "{f} starts as expected");
        std::fs::write(dir.join(f), claimed).expect("write");
    }
    let out = harvemu(&[
        "run",
        dir.join("seed_lab.ron").to_str().unwrap(),
        "--fast",
        "--for",
        "1s",
    ]);
    assert_refused(&out, &["node RECEIVER", "(node SENDER) has the same address C1"]);
}

/// The first instructions of the lab program, as the listing has them, with the cycle counts of
/// the Intel MCS-51 User's Manual: LJMP, MOV direct,#data and LCALL take 2 cycles, MOV Rn,#data
/// 1. At 12 MHz a machine cycle is 1 µs.
#[test]
fn trace_cpu_writes_the_instructions_of_a_window() {
    let out = harvemu(&[
        "run",
        "configs/firmware/seed_lab.ron",
        "--fast",
        "--for",
        "100ms",
        "--trace-cpu",
        "RECEIVER",
        "--trace-cpu-window",
        "0s..6us",
    ]);
    assert!(out.status.success(), "{}", text(&out));
    let lines: Vec<Vec<String>> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| l.split_whitespace().map(str::to_string).collect())
        .collect();
    // time, cycle, address, then the instruction; the last two words are "N cycle(s)".
    let wanted: [(&str, &str, &str, &str, &str); 4] = [
        ("0", "4000", "02 40 80", "LJMP 4080H", "2"),
        ("2", "4080", "75 83 D3", "MOV DPH,#0D3H", "2"),
        ("4", "4083", "78 AA", "MOV R0,#0AAH", "1"),
        ("5", "4085", "12 40 BE", "LCALL 40BEH", "2"),
    ];
    assert_eq!(lines.len(), wanted.len(), "{:?}", lines);
    for (line, (cycle, pc, bytes, instruction, cycles)) in lines.iter().zip(wanted) {
        let joined = line.join(" ");
        assert_eq!(&line[1], cycle, "{joined}");
        assert_eq!(&line[2], pc, "{joined}");
        assert!(
            joined.contains(&format!("{pc} {bytes} {instruction} {cycles} cycle(s)")),
            "{joined}"
        );
    }
    // An unknown node is bad input; a full disk is a failed output.
    let out = harvemu(&[
        "run",
        "configs/firmware/seed_lab.ron",
        "--fast",
        "--for",
        "1s",
        "--trace-cpu",
        "F5",
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    assert!(
        text(&out).contains("firmware nodes: SENDER, RECEIVER"),
        "{}",
        text(&out)
    );
    let full = Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(root())
        .args([
            "run",
            "configs/firmware/seed_lab.ron",
            "--fast",
            "--for",
            "1s",
            "--trace-cpu",
            "SENDER",
        ])
        .stdout(std::fs::File::create("/dev/full").expect("/dev/full"))
        .output()
        .expect("run harvemu");
    assert_eq!(full.status.code(), Some(3), "{}", text(&full));
}

/// Writes into `dir` the network `net.ron` of one node: `source` assembled into `{file}.hex`, run
/// by an 80C51 at `clock_hz` with no CAN controller, named `name` in `{file}.ron`.
fn lone_node(dir: &Path, file: &str, name: &str, source: &str, clock_hz: u32) {
    assemble_into(dir, file, source);
    std::fs::write(
        dir.join(format!("{file}.ron")),
        format!(
            "Firmware(name: \"{name}\", image: \"{file}.hex\", entry: None, \
             cpu: I80C51(clock_hz: {clock_hz}), controllers: [])"
        ),
    )
    .expect("write");
    std::fs::write(
        dir.join("net.ron"),
        format!("Network(name: \"{file}\", bitrate: 30000, nodes: [\"{file}.ron\"])"),
    )
    .expect("write");
}

/// Runs `source` as node CPU (an 80C51 at 11.0592 MHz with no CAN controller) alone on a
/// network for 20 ms of bus time with `--trace-cpu CPU`: the trace's lines, split into words.
/// No frame or controller event ever reaches the node: only its own deadlines wake it.
fn trace_alone(tag: &str, source: &str) -> Vec<Vec<String>> {
    let dir = scratch("cli-firmware", tag);
    lone_node(&dir, "cpu", "CPU", source, 11_059_200);
    let out = Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(&dir)
        .args(["run", "net.ron", "--fast", "--for", "20ms", "--trace-cpu", "CPU"])
        .output()
        .expect("run harvemu");
    assert!(out.status.success(), "{}", text(&out));
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| l.split_whitespace().map(str::to_string).collect())
        .collect()
}

/// Lines whose instruction (the words after time, cycle, address and bytes) starts with `op`.
fn count_op(lines: &[Vec<String>], op: &str) -> usize {
    lines.iter().filter(|l| l.iter().skip(3).any(|w| w == op)).count()
}

/// `--trace-cpu` follows a firmware node for the whole run, however seldom the bus wakes it: (a)
/// a node that never hears from the bus, busy in a loop whose state never repeats within the
/// instructions a look for idle loops watches; (b) the same kind of node ending in `SJMP $`, a
/// loop that changes nothing, which the node skips when it is not traced.
///
/// By hand: at 11.0592 MHz a machine cycle is 12 clocks, 1.085 µs; 20 ms is 221 184 clocks,
/// 18 432 machine cycles. The trace has every instruction that starts before the run ends.
#[test]
fn trace_cpu_covers_the_whole_run_of_a_node_without_input() {
    // (a) INC direct 1 cycle, SJMP 2: a turn of 3 cycles from cycle 0, and 18 432 / 3 = 6144
    // turns exactly, so 6144 INC and 6144 SJMP lines (the 6145th INC would start at the end).
    let busy = "        .org    0
LOOP:   INC     30H
        SJMP    LOOP
";
    let lines = trace_alone("trace-busy", busy);
    let (inc, sjmp) = (count_op(&lines, "INC"), count_op(&lines, "SJMP"));
    assert!(inc.abs_diff(6144) <= 1, "{inc} INC lines, wanted 6144");
    assert!(sjmp.abs_diff(6144) <= 1, "{sjmp} SJMP lines, wanted 6144");
    let last_cycle: u64 = lines.last().expect("a trace")[1].parse().expect("a cycle count");
    assert!(last_cycle >= 18_432 - 3, "the last line is at cycle {last_cycle}");
    // (b) MOV direct,#data 2 cycles, MOV Rn,#data 1, DJNZ Rn 2 × 100: SJMP $ first starts at
    // cycle 203 and then every 2 cycles: at 203 + 2k < 18 432 for k = 0..=9114, 9115 lines.
    let parked = "        .org    0
        MOV     30H, #55H
        MOV     R7, #100
WAIT:   DJNZ    R7, WAIT
HERE:   SJMP    HERE
";
    let lines = trace_alone("trace-parked", parked);
    assert_eq!(count_op(&lines, "MOV"), 2, "{:?}", lines.first());
    assert_eq!(count_op(&lines, "DJNZ"), 100);
    let sjmp = count_op(&lines, "SJMP");
    assert!(sjmp.abs_diff(9115) <= 1, "{sjmp} SJMP lines, wanted 9115");
    let last = lines.last().expect("a trace");
    let last_cycle: u64 = last[1].parse().expect("a cycle count");
    assert!(
        last_cycle >= 18_432 - 2,
        "the last line is at cycle {last_cycle}: {last:?}"
    );
}

#[test]
fn validate_knows_firmware_nodes_and_networks() {
    let out = harvemu(&[
        "validate",
        "configs/firmware/seed_lab.ron",
        "configs/firmware/sender.ron",
        "configs/firmware/irq_receiver.ron",
    ]);
    assert!(out.status.success(), "{}", text(&out));
    assert_eq!(
        String::from_utf8_lossy(&out.stdout),
        "configs/firmware/seed_lab.ron: ok (network config)\n\
         configs/firmware/sender.ron: ok (firmware node)\n\
         configs/firmware/irq_receiver.ron: ok (firmware node)\n"
    );
}

/// `harvemu run` of the seed lab for 10 ms with `RUST_LOG` set to `filter`: its stderr.
fn lab_log(filter: &str) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(root())
        .env("RUST_LOG", filter)
        .args(["run", "configs/firmware/seed_lab.ron", "--fast", "--for", "10ms"])
        .output()
        .expect("run harvemu");
    assert!(out.status.success(), "{}", text(&out));
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The receiver's register writes, as (time in µs, register, value), from a debug log.
fn receiver_writes(log: &str) -> Vec<(u64, u8, u8)> {
    log.lines()
        .filter(|l| l.contains("node=RECEIVER"))
        .filter_map(|l| {
            let rest = l.split_once("SJA1000 at D400h: register ")?.1;
            let (register, rest) = rest.split_once(" <- ")?;
            let value = rest.get(..2)?;
            let at = l.split_once(" at=")?.1.trim();
            let (secs, frac) = at.split_once('.')?;
            let us = secs.parse::<u64>().ok()? * 1_000_000 + frac.get(..6)?.parse::<u64>().ok()?;
            Some((us, register.parse().ok()?, u8::from_str_radix(value, 16).ok()?))
        })
        .collect()
}

/// At debug level every write of the firmware to its SJA1000 is logged once, with the register,
/// the value and the bus time; at info level none is. The receiver's are INITCAN's writes to
/// its chip at D400h, in the listing's order, each at the end of its `MOVX`, in machine cycles
/// of 1 µs (Intel MCS-51 User's Manual): its chip's INITCAN call starts at cycle 100 (`LJMP`
/// 2, `MOV DPH` 2, `MOV R0` 1, `LCALL` 2, the first INITCAN into nothing 88, then `MOV DPH` 2,
/// `MOV R0` 1, `LCALL` 2); a write with `MOV DPL,#` and `MOV A,#` (or `MOV A,Rn`) before it ends
/// 5 cycles after the one before, one with `INC DPTR` and `MOV A,#` 5, with `INC DPTR` or
/// `MOV DPL,#` alone 4; the OCR write comes 2 cycles later for the `MOVX A,@DPTR` that reads BTR1
/// back.
#[test]
fn the_firmwares_register_writes_are_logged_at_debug_level_only() {
    // (register, value, cycles since the write before), from can_seed.asm's INITCAN.
    let listing: [(u8, u8, u64); 18] = [
        (0x00, 0x09, 5), // MOD: reset mode, single filter
        (0x1F, 0x88, 5), // CDR: PeliCAN, CLKOUT off
        (0x04, 0x0D, 5), // IER
        (0x06, 0x03, 5), // BTR0
        (0x07, 0xFF, 5), // BTR1
        (0x08, 0xAA, 7), // OCR, after reading BTR1 back
        (0x10, 0xBB, 5), // ACR0: the receiver's acceptance code
        (0x11, 0xFF, 5), // ACR1
        (0x12, 0xFF, 4), // ACR2
        (0x13, 0xFF, 4), // ACR3
        (0x14, 0x00, 5), // AMR0
        (0x15, 0xFF, 5), // AMR1
        (0x16, 0xFF, 4), // AMR2
        (0x17, 0xFF, 4), // AMR3
        (0x1E, 0x00, 5), // RBSA
        (0x0F, 0x00, 4), // TXERR
        (0x0C, 0x00, 4), // ECC
        (0x00, 0x08, 5), // MOD: operating mode
    ];
    let mut at = 100;
    let expected: Vec<(u64, u8, u8)> = listing
        .iter()
        .map(|&(r, v, dt)| {
            at += dt;
            (at, r, v)
        })
        .collect();
    let debug = lab_log("nodes::firmware=debug");
    // No frame reaches the receiver's buffer in 10 ms while it waits in DELAY: nothing else.
    assert_eq!(receiver_writes(&debug), expected, "{debug}");
    // The sender's transmission request, CMR (1) = 01h, at cycle 337 (firmware_seed_lab.rs).
    assert!(
        debug.contains("SJA1000 at D300h: register 1 <- 01h node=SENDER at=0.000337"),
        "{debug}"
    );
    let info = lab_log("nodes::firmware=info");
    assert!(!info.contains("SJA1000 at"), "{info}");
    assert!(!lab_log("info").contains("register"));
}

/// Assembles `source` with Debian's `as31` into `dir/name.hex`. Panics naming the package when
/// `as31` is missing: a test that needs it fails, it never passes without it.
fn assemble_into(dir: &Path, name: &str, source: &str) {
    std::fs::write(dir.join(format!("{name}.asm")), source).expect("write the source");
    let out = Command::new("as31")
        .current_dir(dir)
        .args([
            "-Fhex".to_string(),
            format!("-O{name}.hex"),
            format!("{name}.asm"),
        ])
        .output()
        .unwrap_or_else(|e| panic!("cannot run as31 ({e}): install the Debian package as31"));
    assert!(out.status.success(), "as31 failed: {}", text(&out));
}

/// Three lines on the serial port in mode 1, polling TI: "HELLO" (CR LF), 300 'x' (LF), and
/// "TAIL" with no end of line, after which the program waits in a loop for ever.
const SERIAL_ASM: &str = "        .org    0
        MOV     TMOD, #20H      ; timer 1 in mode 2 clocks the serial port
        MOV     TH1, #0FFH
        SETB    TR1
        MOV     SCON, #40H      ; mode 1, 8 bits
        MOV     DPTR, #HELLO
        LCALL   PUTS
        MOV     R7, #0          ; 256 'x'
X1:     MOV     A, #78H
        LCALL   PUT
        DJNZ    R7, X1
        MOV     R7, #44         ; and 44 more
X2:     MOV     A, #78H
        LCALL   PUT
        DJNZ    R7, X2
        MOV     A, #0AH
        LCALL   PUT
        MOV     DPTR, #TAIL
        LCALL   PUTS
HERE:   SJMP    HERE
PUTS:   CLR     A
        MOVC    A, @A+DPTR
        JZ      DONE
        LCALL   PUT
        INC     DPTR
        SJMP    PUTS
DONE:   RET
PUT:    MOV     SBUF, A
WAIT:   JNB     TI, WAIT
        CLR     TI
        RET
HELLO:  .byte   48H, 45H, 4CH, 4CH, 4FH, 0DH, 0AH, 0
TAIL:   .byte   54H, 41H, 49H, 4CH, 0
";

/// Runs `source` as the only node of a network for a second of bus time: the lines its serial
/// port gave the log, and the whole log.
fn serial_lines(tag: &str, source: &str) -> (Vec<String>, String) {
    let dir = scratch("cli-firmware", tag);
    lone_node(&dir, "serial", "TTY", source, 12_000_000);
    let out = Command::new(env!("CARGO_BIN_EXE_harvemu"))
        .current_dir(&dir)
        .env("RUST_LOG", "nodes::firmware=info")
        .args(["run", "net.ron", "--fast", "--for", "1s"])
        .output()
        .expect("run harvemu");
    assert!(out.status.success(), "{}", text(&out));
    let log = String::from_utf8_lossy(&out.stderr).into_owned();
    let lines = log
        .lines()
        .filter_map(|l| l.split_once("serial: ").map(|(_, rest)| rest))
        .map(|rest| rest.trim_end_matches(" node=TTY").to_string())
        .collect();
    (lines, log)
}

/// What the firmware writes to its serial port reaches the log at info level, a line at a time:
/// a line longer than 256 bytes in pieces, the first marked as cut, and the line it had begun
/// when the run ended as it is, marked so.
#[test]
fn serial_lines_reach_the_log_whole_cut_and_unfinished() {
    let (lines, log) = serial_lines("serial", SERIAL_ASM);
    let x = "x".repeat(256);
    let cut = format!("{x} [cut: the line goes on]");
    let rest = "x".repeat(44);
    assert_eq!(
        lines,
        [
            "HELLO",
            cut.as_str(),
            rest.as_str(),
            "TAIL [no end of line: the node stopped]"
        ],
        "{log}"
    );
    // One byte, then a loop that changes nothing: the node idles in it from then on, and the
    // byte still reaches the log.
    let one = "        .org    0
        MOV     TMOD, #20H
        MOV     TH1, #0FFH
        SETB    TR1
        MOV     SCON, #40H
        MOV     SBUF, #41H
HERE:   SJMP    HERE
";
    let (lines, log) = serial_lines("serial-one", one);
    assert_eq!(lines, ["A [no end of line: the node stopped]"], "{log}");
}
