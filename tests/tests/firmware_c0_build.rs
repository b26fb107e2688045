//! The C firmware of the alarm module C0 (`configs/firmware/c0/c0_alarm.c`): the shipped
//! `configs/firmware/c0_alarm.hex` is what Debian's SDCC makes of the source with the command
//! the source's opening comment gives, so the HEX never drifts from the C.

use harvemu_e2e::root;
use std::process::Command;

/// Code memory of the AT89C51CC03: 64 KB of flash.
const CODE_BYTES: usize = 0x1_0000;

fn image(text: &str, what: &str) -> mcs51::Image {
    mcs51::hex::parse(text, CODE_BYTES).unwrap_or_else(|e| panic!("{what}: {e}"))
}

#[test]
fn sdcc_makes_the_shipped_hex_from_the_source() {
    let dir = std::env::temp_dir().join(format!("harvemu-c0-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    for file in ["c0_alarm.c", "at89c51cc03.h"] {
        let from = root().join("configs/firmware/c0").join(file);
        std::fs::copy(&from, dir.join(file)).unwrap_or_else(|e| panic!("{}: {e}", from.display()));
    }
    // The build command of c0_alarm.c's opening comment (packihx only regroups the records).
    let out = Command::new("sdcc")
        .current_dir(&dir)
        .args(["-mmcs51", "--model-small", "-o", "c0_alarm.ihx", "c0_alarm.c"])
        .output()
        .unwrap_or_else(|e| panic!("cannot run sdcc ({e}): install the Debian package sdcc"));
    assert!(
        out.status.success(),
        "sdcc failed on c0_alarm.c:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let made = std::fs::read_to_string(dir.join("c0_alarm.ihx")).unwrap();
    let made = image(&made, "c0_alarm.ihx made by sdcc");
    std::fs::remove_dir_all(&dir).unwrap();

    let path = root().join("configs/firmware/c0_alarm.hex");
    let shipped = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let shipped = image(&shipped, "configs/firmware/c0_alarm.hex");

    assert_eq!(
        made.written, shipped.written,
        "sdcc writes other addresses than the shipped HEX"
    );
    let differ: Vec<String> = (0..CODE_BYTES)
        .filter(|&a| made.code[a] != shipped.code[a])
        .take(8)
        .map(|a| {
            format!(
                "{a:04X}H: sdcc {:02X}, shipped {:02X}",
                made.code[a], shipped.code[a]
            )
        })
        .collect();
    assert!(
        differ.is_empty(),
        "the shipped c0_alarm.hex is not what sdcc makes of c0_alarm.c: {differ:?}"
    );
    // Something was built at all: the reset vector jumps somewhere (LJMP, 02h).
    assert_eq!(shipped.code[0], 0x02, "no LJMP at the reset vector");
}
