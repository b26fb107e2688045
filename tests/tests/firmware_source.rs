//! The lab firmware of `configs/firmware/`: the shipped `can_seed.hex` is what Debian's as31
//! makes of `can_seed.asm`, its bytes hold what the listing says (checked against addresses and
//! opcodes worked out by hand from the Intel MCS-51 instruction set), and the frame it sends
//! lasts as long on the bus as a hand computation of the frame says.

use bus::Frame;
use bus::bits::{self, BitRate};
use bus::filter::{AcceptanceFilter, Sja1000Filter, Sja1000Mode};
use bus::time::BusDuration;
use harvemu_e2e::root;
use std::collections::{BTreeMap, BTreeSet};
use std::process::Command;

/// A HEX image: address to byte.
type Image = BTreeMap<u16, u8>;

/// Reads Intel HEX text (data and end-of-file records, 16-bit addresses), checking every
/// record's checksum and that no address is given twice.
fn parse_hex(text: &str, name: &str) -> Image {
    let mut image = Image::new();
    let mut ended = false;
    for (n, line) in text.lines().enumerate() {
        let line = line.trim_end();
        if line.is_empty() {
            continue;
        }
        let at = format!("{name} line {}", n + 1);
        assert!(!ended, "{at}: a record after the end-of-file record");
        let hex = line.strip_prefix(':').unwrap_or_else(|| panic!("{at}: no ':'"));
        assert!(hex.len() % 2 == 0 && hex.len() >= 10, "{at}: bad length");
        let bytes: Vec<u8> = (0..hex.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&hex[i..i + 2], 16).unwrap_or_else(|_| panic!("{at}: not hex")))
            .collect();
        let sum = bytes.iter().fold(0u8, |s, b| s.wrapping_add(*b));
        assert_eq!(sum, 0, "{at}: bad checksum");
        let count = usize::from(bytes[0]);
        assert_eq!(
            bytes.len(),
            count + 5,
            "{at}: byte count {count} does not fit the record"
        );
        let address = u16::from_be_bytes([bytes[1], bytes[2]]);
        match bytes[3] {
            0x00 => {
                for (i, b) in bytes[4..4 + count].iter().enumerate() {
                    let a = address
                        .checked_add(i as u16)
                        .unwrap_or_else(|| panic!("{at}: data past FFFFH"));
                    assert!(image.insert(a, *b).is_none(), "{at}: {a:04X}H given twice");
                }
            }
            0x01 => ended = true,
            t => panic!("{at}: record type {t:02X} (only 00 and 01 are expected from as31)"),
        }
    }
    assert!(ended, "{name}: no end-of-file record");
    image
}

/// `len` bytes from `address`, every one of them present.
fn bytes_at(image: &Image, address: u16, len: u16) -> Vec<u8> {
    (address..address + len)
        .map(|a| *image.get(&a).unwrap_or_else(|| panic!("nothing at {a:04X}H")))
        .collect()
}

fn shipped() -> Image {
    let path = root().join("configs/firmware/can_seed.hex");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    parse_hex(&text, "can_seed.hex")
}

#[test]
fn as31_makes_the_shipped_hex_from_the_source() {
    let dir = std::env::temp_dir().join(format!("harvemu-firmware-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(
        root().join("configs/firmware/can_seed.asm"),
        dir.join("can_seed.asm"),
    )
    .unwrap();
    // The command configs/firmware/README.md gives.
    let out = Command::new("as31")
        .current_dir(&dir)
        .args(["-Fhex", "-Ocan_seed.hex", "can_seed.asm"])
        .output()
        .unwrap_or_else(|e| {
            panic!("cannot run as31 ({e}): install the Debian package as31 (scripts/test does)")
        });
    assert!(
        out.status.success(),
        "as31 failed on can_seed.asm:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let made = std::fs::read_to_string(dir.join("can_seed.hex")).unwrap();
    let made = parse_hex(&made, "can_seed.hex made by as31");
    std::fs::remove_dir_all(&dir).unwrap();
    let shipped = shipped();
    if made != shipped {
        let addresses: BTreeSet<&u16> = made.keys().chain(shipped.keys()).collect();
        let differ: Vec<String> = addresses
            .into_iter()
            .filter(|a| made.get(a) != shipped.get(a))
            .take(8)
            .map(|a| {
                format!(
                    "{a:04X}H: as31 {:02X?}, shipped {:02X?}",
                    made.get(a),
                    shipped.get(a)
                )
            })
            .collect();
        panic!("the shipped can_seed.hex is not what as31 makes of can_seed.asm: {differ:?}");
    }
}

#[test]
fn the_reset_jump_leads_to_the_main_program() {
    let image = shipped();
    // LJMP is 02 followed by the 16-bit address, high byte first.
    assert_eq!(bytes_at(&image, 0x4000, 3), [0x02, 0x40, 0x80]);
    // Nothing between the jump and the main program, nothing below the monitor's jump target.
    assert!(
        image
            .keys()
            .all(|&a| (0x4000..0x4003).contains(&a) || a >= 0x4080)
    );
    // START: MOV DPH,#0D3H (75 83 D3); MOV R0,#0AAH (78 AA).
    assert_eq!(bytes_at(&image, 0x4080, 5), [0x75, 0x83, 0xD3, 0x78, 0xAA]);
}

#[test]
fn txdata_holds_the_frame_data() {
    let image = shipped();
    // Worked out by hand from the listing: START at 4080H, then 3+2+3 +3+2+3 +2+2 bytes to
    // MOV DPTR,#TXDATA at 4094H; the loop SS1 (1+1+1+1+1+3), LOOP (3+2+3+3+3+2+3+1), HALT (3)
    // put TXDATA at 40B6H.
    assert_eq!(bytes_at(&image, 0x4094, 3), [0x90, 0x40, 0xB6]);
    assert_eq!(
        bytes_at(&image, 0x40B6, 8),
        [0xAA, 0xBB, 0xCC, 0xD4, 0xE5, 0xF6, 0x97, 0x18]
    );
}

/// Length of each instruction INITCAN uses, from its opcode (Intel MCS-51 instruction set).
fn length(opcode: u8) -> u16 {
    match opcode {
        0x75 => 3,               // MOV direct,#data
        0x74 => 2,               // MOV A,#data
        0xF0 | 0xE0 => 1,        // MOVX @DPTR,A / MOVX A,@DPTR
        0xE8 | 0xA3 | 0x22 => 1, // MOV A,R0 / INC DPTR / RET
        other => panic!("INITCAN holds opcode {other:02X}, which its listing does not use"),
    }
}

#[test]
fn initcan_loads_the_registers_the_listing_gives() {
    let image = shipped();
    // INITCAN follows TXDATA (40B6H + 8) and both LCALLs (12 hi lo) of START go there.
    let initcan = 0x40BE;
    assert_eq!(bytes_at(&image, 0x4085, 3), [0x12, 0x40, 0xBE]);
    assert_eq!(bytes_at(&image, 0x408D, 3), [0x12, 0x40, 0xBE]);
    let mut at = initcan;
    let mut immediates = Vec::new();
    let mut registers = Vec::new();
    loop {
        let op = bytes_at(&image, at, 1)[0];
        match op {
            0x74 => immediates.push(bytes_at(&image, at + 1, 1)[0]),
            // MOV DPL,#data: the SJA1000 register the next access goes to.
            0x75 => {
                let [_, direct, data] = bytes_at(&image, at, 3)[..] else {
                    unreachable!()
                };
                assert_eq!(direct, 0x82, "INITCAN sets only DPL with MOV direct,#data");
                registers.push(data);
            }
            _ => {}
        }
        at += length(op);
        if op == 0x22 {
            break;
        }
    }
    // MOD 09H (reset, single filter), CDR 88H (PeliCAN, CLKOUT off), IER 0DH, BTR0 03H,
    // BTR1 FFH, OCR AAH, then ACR1 FFH, AMR0 00H, AMR1 FFH, RBSA 00H, MOD 08H (operating).
    assert_eq!(
        immediates,
        [0x09, 0x88, 0x0D, 0x03, 0xFF, 0xAA, 0xFF, 0x00, 0xFF, 0x00, 0x08]
    );
    // MOD, CDR, IER, BTR0, BTR1, OCR, ACR0, AMR0, RBSA, TXERR, ECC, MOD.
    assert_eq!(
        registers,
        [
            0x00, 0x1F, 0x04, 0x06, 0x07, 0x08, 0x10, 0x14, 0x1E, 0x0F, 0x0C, 0x00
        ]
    );
    // 85 bytes, so SEND starts at 4113H, where LOOP's first LCALL goes.
    assert_eq!(at, 0x4113);
    assert_eq!(bytes_at(&image, 0x40A4, 3), [0x12, 0x41, 0x13]);
}

/// The frame SEND writes into the transmit buffer: frame information 08H (standard, data,
/// DLC 8), identifier bytes BBH FFH: ID.10..3 = BBH, ID.2..0 = the top three bits of FFH.
fn lab_frame() -> Frame {
    let id = (0xBBu16 << 3) | (0xFF >> 5);
    assert_eq!(id, 0x5DF);
    Frame::base(id, &[0xAA, 0xBB, 0xCC, 0xD4, 0xE5, 0xF6, 0x97, 0x18]).unwrap()
}

#[test]
fn the_lab_frame_on_the_bus() {
    let frame = lab_frame();
    let encoded = bits::encode(&frame);
    // Worked out by hand (SOF, 11-bit identifier, RTR, IDE, r0, DLC, 64 data bits: 83 bits; the
    // CRC-15 with polynomial 4599H over them; a stuff bit after every 5 equal bits): CRC 6366H,
    // 2 stuff bits (after the identifier's five closing 1s, and where the last 1 of E5H runs into
    // the four leading 1s of F6H), 100 bits from SOF to the last CRC bit.
    let expected = "0101110111110000100010101010101110111100110011010100111001011111\
                    001101001011100011000110001101100110";
    assert_eq!(encoded.stuffed.to_string(), expected);
    assert_eq!(encoded.crc, 0x6366);
    assert_eq!(encoded.stuff_bits, 2);
    // Plus CRC delimiter, ACK slot and delimiter, 7 EOF bits, 3 intermission bits: 113.
    assert_eq!(bits::frame_bits(&frame), 113);
    // 30 kbit/s: 1/30000 s a bit, 113 bits = 3766.67 us; 3.456e12 / 30000 = 115.2e6 ticks a bit.
    let rate = BitRate::for_bus(30_000).unwrap();
    let bit = rate.bit_time().unwrap();
    assert_eq!(bit, BusDuration::from_ticks(115_200_000));
    assert_eq!((bit * 113).as_micros(), 3766);
    assert_eq!((bit * 113).as_nanos(), 3_766_666);
}

#[test]
fn only_the_receiving_bench_keeps_the_frame() {
    // Single filter, standard frame: ACR0 against ID.10..3, AMR0 = 00H compares all of it;
    // AMR1..3 = FFH leave ID.2..0, RTR and the first two data bytes free.
    let bench = |acr0| Sja1000Filter {
        mode: Sja1000Mode::Single,
        acr: [acr0, 0xFF, 0xFF, 0xFF],
        amr: [0x00, 0xFF, 0xFF, 0xFF],
    };
    assert!(
        bench(0xBB).accepts(&lab_frame()),
        "the receiving bench (ACR0 = BBH)"
    );
    assert!(
        !bench(0xAA).accepts(&lab_frame()),
        "the sending bench (ACR0 = AAH)"
    );
}

#[test]
fn the_parser_rejects_a_bad_checksum() {
    let good = ":03400000024080FB\n:00000001FF\n";
    assert_eq!(parse_hex(good, "good").len(), 3);
    let bad = std::panic::catch_unwind(|| parse_hex(":03400000024080FC\n:00000001FF\n", "bad"));
    assert!(bad.is_err());
}

#[test]
fn as31_makes_the_shipped_irq_receiver_hex() {
    let source = std::fs::read_to_string(root().join("configs/firmware/irq_receiver.asm")).unwrap();
    let made = parse_hex(&harvemu_e2e::assemble(&source), "irq_receiver.hex made by as31");
    let text = std::fs::read_to_string(root().join("configs/firmware/irq_receiver.hex")).unwrap();
    assert_eq!(
        made,
        parse_hex(&text, "irq_receiver.hex"),
        "rebuild it with as31 (configs/firmware/README.md)"
    );
    // The reset vector jumps to START at 0030H, the INT0 vector (0003H) to the handler.
    assert_eq!(bytes_at(&made, 0x0000, 3), [0x02, 0x00, 0x30]);
    assert_eq!(made.get(&0x0003), Some(&0x02));
}

/// The interrupt-driven receiver's image and its listing (`irq_receiver.lst`, which coverage
/// reads for line numbers) are what as31 makes of `irq_receiver.asm` with the command
/// configs/firmware/README.md gives.
#[test]
fn as31_makes_the_shipped_receiver_and_its_listing() {
    let dir = std::env::temp_dir().join(format!("harvemu-firmware-irq-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(
        root().join("configs/firmware/irq_receiver.asm"),
        dir.join("irq_receiver.asm"),
    )
    .unwrap();
    let out = Command::new("as31")
        .current_dir(&dir)
        .args(["-l", "-Fhex", "-Oirq_receiver.hex", "irq_receiver.asm"])
        .output()
        .unwrap_or_else(|e| panic!("cannot run as31 ({e}): install the Debian package as31"));
    assert!(
        out.status.success(),
        "as31: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    for file in ["irq_receiver.hex", "irq_receiver.lst"] {
        let made = std::fs::read(dir.join(file)).unwrap();
        let shipped = std::fs::read(root().join("configs/firmware").join(file)).unwrap();
        assert!(
            made == shipped,
            "the shipped {file} is not what as31 makes of irq_receiver.asm"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
